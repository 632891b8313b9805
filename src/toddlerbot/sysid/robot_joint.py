"""The ``robot_joint`` rig: one motor joint of the fixed-base robot model, simulated with MuJoCo.

The rig motor follows the replayed goal positions with the candidate parameters (its joint's damping, armature
and friction loss are set in the MuJoCo model); every other motor holds its home position with its catalogue
parameters and the spec's firmware gains. Candidates are simulated one after another (slower than the
vectorised one-degree-of-freedom rigs).
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams, MotorModel, default_catalogue
from toddlerbot.actuation.model import actuator_arrays, motor_torque
from toddlerbot.robot.builder import build_model
from toddlerbot.robot.spec import RobotSpec, load_spec
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.rigs import RobotJointRig

if TYPE_CHECKING:
    from toddlerbot.sysid.simulate import RunBatch


@cache
def _robot() -> tuple[RobotSpec, mujoco.MjModel]:
    spec = load_spec()
    return spec, build_model(spec, base="fixed")


def rig_motor(rig: RobotJointRig) -> MotorModel:
    """The catalogue model of the rig's motor; raise `SysIDError` for a joint that no motor drives."""
    spec, _ = _robot()
    motors = {m.joint: m for m in spec.motors}
    if rig.joint not in motors:
        raise SysIDError(f"rig robot_joint: {rig.joint!r} is not a motor joint; expected one of "
                         f"{', '.join(m.joint for m in spec.motors_by_id)}")
    return default_catalogue()[motors[rig.joint].model]


def simulate_robot_joint(batch: RunBatch, rig: RobotJointRig, fields: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated rig-joint positions (P, N) at every log sample for P candidates."""
    rig_motor(rig)
    spec, base_model = _robot()
    catalogue = default_catalogue()
    motors = spec.motors_by_id
    rig_index = next(i for i, m in enumerate(motors) if m.joint == rig.joint)
    qadr = np.array([base_model.joint(m.joint).qposadr[0] for m in motors])
    vadr = np.array([base_model.joint(m.joint).dofadr[0] for m in motors])
    home = base_model.key("home").qpos.copy()
    n_cand = len(fields["damping"])
    out = np.empty((n_cand, len(batch.measured)))
    for c in range(n_cand):
        cand = ActuatorParams(**{k: float(v[c]) for k, v in fields.items()})
        model = _with_joint_params(base_model, vadr[rig_index], rig_index, cand)
        params = [cand if i == rig_index else catalogue[m.model].actuator for i, m in enumerate(motors)]
        for r, run in enumerate(batch.runs):
            kp = [run.kp if i == rig_index else m.kp for i, m in enumerate(motors)]
            kd = [run.kd if i == rig_index else m.kd for i, m in enumerate(motors)]
            arrays = actuator_arrays(params, kp, kd)
            data = mujoco.MjData(model)
            data.qpos[:] = home
            data.qpos[qadr[rig_index]] = batch.q0[r]
            data.qvel[vadr[rig_index]] = batch.v0[r]
            target = home[qadr].copy()
            record = np.empty(len(batch.goal))
            for k in range(len(batch.goal)):
                record[k] = data.qpos[qadr[rig_index]]
                target[rig_index] = batch.goal[k, r]
                data.ctrl[:] = motor_torque(target, data.qpos[qadr], data.qvel[vadr], arrays)
                mujoco.mj_step(model, data)
            mask = batch.sample_run == r
            out[c, mask] = record[batch.sample_step[mask]]
    return out


def _with_joint_params(base: mujoco.MjModel, dof: int, actuator: int, p: ActuatorParams) -> mujoco.MjModel:
    model = base.__copy__()
    model.dof_damping[dof] = p.damping
    model.dof_armature[dof] = p.armature
    model.dof_frictionloss[dof] = p.frictionloss
    limit = max(p.tau_brake, p.tau_max, p.tau_q_dot_max)
    model.actuator_ctrlrange[actuator] = (-limit, limit)
    return model
