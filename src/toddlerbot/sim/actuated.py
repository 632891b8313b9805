"""The actuated plant: MuJoCo physics with the actuator model in the loop, for one robot or a batch of robots.

Every physics substep the actuator model (`toddlerbot.actuation.model.motor_torque`, numpy) turns each robot's
motor targets into motor torques, vectorised over the batch, and ``mujoco.mj_step`` advances each robot (it
releases the GIL, so callers may step disjoint batches on several threads). `MuJoCoRobot` steps a batch of one;
the RL environment's CPU backend (`toddlerbot.rl.physics`) steps chunks of its batch on a thread pool.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.actuation.model import ActuatorArrays, friction_excess, has_friction_excess, motor_torque


@dataclass(frozen=True)
class MotorAddresses:
    """Where each motor (motor-id order) lives in a MuJoCo model: its joint's qpos and dof address and its torque
    actuator's index."""

    qpos: np.ndarray
    dof: np.ndarray
    actuator: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, motor_names: Sequence[str]) -> MotorAddresses:
        """Addresses of the named motors (each motor's joint and actuator share its name)."""
        joints = [model.joint(name) for name in motor_names]
        return cls(np.array([j.qposadr[0] for j in joints]), np.array([j.dofadr[0] for j in joints]),
                   np.array([model.actuator(name).id for name in motor_names]))


def step_actuated(models: Sequence[mujoco.MjModel], datas: Sequence[mujoco.MjData], motors: MotorAddresses,
                  targets: np.ndarray, params: ActuatorArrays, n_substeps: int,
                  sensors_last_only: bool = False) -> np.ndarray:
    """Advance each robot ``n_substeps`` physics steps holding its motor targets (``targets`` (batch, n_motors),
    rad); ``params`` holds (n_motors,) arrays shared by the batch or (batch, n_motors) arrays, one row per robot.
    Returns the motor torques of the last substep, (batch, n_motors) N*m. A fitted load-dependent friction
    (`toddlerbot.actuation.model.friction_excess`) raises the motor joints' frictionloss every substep and is
    taken off again on return. ``sensors_last_only``: MuJoCo's sensors are evaluated in the last substep only (the
    dynamics do not read them; this toggles the models' sensor flag, so only for models no other thread steps)."""
    tau = np.zeros_like(targets)
    budget = has_friction_excess(params)
    frictionloss = [m.dof_frictionloss[motors.dof].copy() for m in models] if budget else []
    if sensors_last_only:
        for m in models:
            m.opt.disableflags |= _NO_SENSOR
    for k in range(n_substeps):
        # stack whole state vectors, then index once: one fancy index per robot costs more than the stack
        q = np.stack([d.qpos for d in datas])[:, motors.qpos]
        q_dot = np.stack([d.qvel for d in datas])[:, motors.dof]
        tau = motor_torque(targets, q, q_dot, params)
        excess = friction_excess(q_dot, tau, params) if budget else None
        if sensors_last_only and k == n_substeps - 1:
            for m in models:
                m.opt.disableflags &= ~_NO_SENSOR
        for i, (m, d, row) in enumerate(zip(models, datas, tau, strict=True)):
            d.ctrl[motors.actuator] = row
            if budget:
                m.dof_frictionloss[motors.dof] = frictionloss[i] + excess[i]
            mujoco.mj_step(m, d)
    for m, own in zip(models, frictionloss, strict=False):
        m.dof_frictionloss[motors.dof] = own
    return tau


_NO_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
