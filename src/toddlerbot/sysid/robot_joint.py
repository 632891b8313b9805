"""The ``robot_joint`` rig: one motor joint of the fixed-base robot model, simulated with MuJoCo.

The rig motor follows the replayed goal positions with the candidate parameters (its joint's damping, armature
and friction loss are set in the MuJoCo model, the friction loss raised every step by the model's load-dependent
budget, `toddlerbot.actuation.model.friction_excess`), at the run's supply voltage and applying no torque while it
was off; every other motor holds its home position with the description's parameters and the spec's firmware
gains. The model steps through the simulator's actuated plant (`toddlerbot.sim.actuated.step_actuated`), one
physics step at a time as the goal changes every step.
Candidates are simulated one after another (slower than the vectorised one-degree-of-freedom rigs).
"""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import MotorModel
from toddlerbot.actuation.model import actuator_arrays, at_voltage
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.sim.actuated import MotorAddresses, step_actuated
from toddlerbot.sim.motor_drive import MotorDrive
from toddlerbot.sysid.batch import Replay, RunBatch
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.params import Candidates
from toddlerbot.sysid.rigs import RobotJointRig


def rig_motor(rig: RobotJointRig) -> MotorModel:
    """The catalogue model of the rig's motor; raise `SysIDError` for a joint that no motor drives."""
    description = rig.robot
    if rig.joint not in description.motor_names:
        raise SysIDError(f"rig robot_joint: {rig.joint!r} is not a motor joint; expected one of "
                         f"{', '.join(description.motor_names)}")
    return description.motor_models[description.motor_names.index(rig.joint)]


def simulate_robot_joint(batch: RunBatch, rig: RobotJointRig, candidates: Candidates,
                         full: bool = False) -> Replay:
    """Simulated rig-joint replay (each (P, N)) for P candidates; ``full``:
    also velocity and torque."""
    rig_motor(rig)
    description = rig.robot
    base_model = description.model(base="fixed", scene=False)
    names = description.motor_names
    rig_index = names.index(rig.joint)
    motors = MotorAddresses.of(base_model, names)
    qadr, vadr = motors.qpos, motors.dof
    rig_off = np.arange(len(names)) != rig_index  # the torque enable with the rig motor off
    home = base_model.key("home").qpos.copy()
    out = [np.empty((len(candidates), len(batch.measured))) for _ in range(3 if full else 1)]
    for c in range(len(candidates)):
        cand = candidates.params(c)
        model = _with_joint_params(base_model, vadr[rig_index], rig_index, cand, float(batch.voltage_ratio.max()))
        params = [cand if i == rig_index else p for i, p in enumerate(description.actuator_params)]
        for r, run in enumerate(batch.runs):
            kp, kd = description.default_kp.copy(), description.default_kd.copy()
            kp[rig_index], kd[rig_index] = run.kp, run.kd
            scale = np.ones(len(names))
            scale[rig_index] = batch.voltage_ratio[r]
            p = at_voltage(actuator_arrays(params, kp, kd), scale)
            powered, unpowered = MotorDrive(p), MotorDrive(p, torque_on=rig_off)
            data = mujoco.MjData(model)
            data.qpos[:] = home
            data.qpos[qadr[rig_index]] = batch.q0[r]
            data.qvel[vadr[rig_index]] = batch.v0[r]
            target = home[qadr].copy()
            record = np.empty((len(batch.goal), 3))
            for k in range(len(batch.goal)):
                target[rig_index] = batch.goal[k, r]
                q, q_dot = data.qpos[qadr[rig_index]], data.qvel[vadr[rig_index]]
                drive = powered if batch.torque_on[k, r] else unpowered
                tau = step_actuated([model], [data], motors, target[None], drive, 1)
                record[k] = q, q_dot, tau[0, rig_index]
            mask = batch.sample_run == r
            for i, values in enumerate(out):
                values[c, mask] = record[batch.sample_step[mask], i]
    return Replay(*out)


def _with_joint_params(base: mujoco.MjModel, dof: int, actuator: int, p: MotorParams,
                       voltage_ratio: float) -> mujoco.MjModel:
    model = base.__copy__()
    model.dof_damping[dof] = p.damping
    model.dof_armature[dof] = p.armature
    model.dof_frictionloss[dof] = p.frictionloss
    limit = max(p.tau_brake, p.tau_max) * max(voltage_ratio, 1.0)
    model.actuator_ctrlrange[actuator] = (-limit, limit)
    return model
