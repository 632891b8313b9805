"""The ``robot_joint`` rig: one motor joint of the fixed-base robot model, simulated with MuJoCo.

The rig motor follows the replayed goal positions with the candidate parameters (its joint's damping, armature
and friction loss are set in the MuJoCo model), at the logged supply voltage and passive while torque was off;
every other motor holds its home position with the description's parameters and the spec's firmware gains.
Candidates are simulated one after another (slower than the vectorised one-degree-of-freedom rigs).
"""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams, MotorModel
from toddlerbot.actuation.model import actuator_arrays, at_voltage, motor_torque, passive_torque
from toddlerbot.sysid.batch import RunBatch
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.rigs import RobotJointRig


def rig_motor(rig: RobotJointRig) -> MotorModel:
    """The catalogue model of the rig's motor; raise `SysIDError` for a joint that no motor drives."""
    description = rig.robot
    if rig.joint not in description.motor_names:
        raise SysIDError(f"rig robot_joint: {rig.joint!r} is not a motor joint; expected one of "
                         f"{', '.join(description.motor_names)}")
    return description.motor_models[description.motor_names.index(rig.joint)]


def simulate_robot_joint(batch: RunBatch, rig: RobotJointRig, fields: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated rig-joint positions (P, N) at every log sample for P candidates."""
    rig_motor(rig)
    description = rig.robot
    base_model = description.model(base="fixed", scene=False)
    names = description.motor_names
    rig_index = names.index(rig.joint)
    qadr = np.array([base_model.joint(name).qposadr[0] for name in names])
    vadr = np.array([base_model.joint(name).dofadr[0] for name in names])
    home = base_model.key("home").qpos.copy()
    n_cand = len(fields["damping"])
    out = np.empty((n_cand, len(batch.measured)))
    for c in range(n_cand):
        cand = ActuatorParams(**{k: float(v[c]) for k, v in fields.items()})
        model = _with_joint_params(base_model, vadr[rig_index], rig_index, cand, float(batch.voltage_ratio.max()))
        params = [cand if i == rig_index else p for i, p in enumerate(description.actuator_params)]
        for r, run in enumerate(batch.runs):
            kp, kd = description.default_kp.copy(), description.default_kd.copy()
            kp[rig_index], kd[rig_index] = run.kp, run.kd
            arrays = actuator_arrays(params, kp, kd)
            data = mujoco.MjData(model)
            data.qpos[:] = home
            data.qpos[qadr[rig_index]] = batch.q0[r]
            data.qvel[vadr[rig_index]] = batch.v0[r]
            target = home[qadr].copy()
            scale = np.ones(len(names))
            record = np.empty(len(batch.goal))
            for k in range(len(batch.goal)):
                record[k] = data.qpos[qadr[rig_index]]
                target[rig_index] = batch.goal[k, r]
                scale[rig_index] = batch.voltage_ratio[k, r]
                p = at_voltage(arrays, scale)
                q_dot = data.qvel[vadr]
                tau = motor_torque(target, data.qpos[qadr], q_dot, p)
                if not batch.torque_on[k, r]:
                    tau[rig_index] = passive_torque(q_dot, p)[rig_index]
                data.ctrl[:] = tau
                mujoco.mj_step(model, data)
            mask = batch.sample_run == r
            out[c, mask] = record[batch.sample_step[mask]]
    return out


def _with_joint_params(base: mujoco.MjModel, dof: int, actuator: int, p: ActuatorParams,
                       voltage_ratio: float) -> mujoco.MjModel:
    model = base.__copy__()
    model.dof_damping[dof] = p.damping
    model.dof_armature[dof] = p.armature
    model.dof_frictionloss[dof] = p.frictionloss
    limit = max(p.tau_brake, p.tau_max, p.tau_q_dot_max) * max(voltage_ratio, 1.0)
    model.actuator_ctrlrange[actuator] = (-limit, limit)
    return model
