"""The actuated plant: MuJoCo physics with the actuator model in the loop, for one robot or a batch of robots.

`step_actuated` is the one physics substep loop with motors: every substep a `MotorDrive` (the actuator model,
`toddlerbot.actuation.model.motor_torque`, plus the firmware's torque enable and torque limit) turns each robot's
motor targets into motor torques, vectorised over the batch, and ``mujoco.mj_step`` advances each robot (it
releases the GIL, so callers may step disjoint batches on several threads). Everything that simulates motors in
MuJoCo steps through it: `toddlerbot.sim.mujoco_robot.MuJoCoRobot` (a batch of one), the RL environment's CPU
backend (`toddlerbot.rl.physics`, chunks of its batch on a thread pool), the hardware-in-the-loop plant behind
the Dynamixel emulator (`toddlerbot.hardware.plant.HilPlant`) and the sysID ``robot_joint`` rig.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.sim.motor_drive import MotorDrive


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
                  targets: np.ndarray, drive: MotorDrive, n_substeps: int,
                  sensors_last_only: bool = False) -> np.ndarray:
    """Advance each robot ``n_substeps`` physics steps holding its motor targets (``targets`` (batch, n_motors),
    rad) with the drive's parameters ((n_motors,) arrays shared by the batch or (batch, n_motors), one row per
    robot). Returns the motor torques of the last substep, (batch, n_motors) N*m. A fitted load-dependent friction
    (`toddlerbot.actuation.model.friction_excess`) raises the motor joints' frictionloss every substep and is
    taken off again on return. ``sensors_last_only``: MuJoCo's sensors are evaluated in the last substep only (the
    dynamics do not read them, so the state is the same; this toggles the models' sensor flag, so only for models
    no other thread steps)."""
    if n_substeps < 1:
        raise ValueError(f"n_substeps must be >= 1, got {n_substeps}")
    # every substep costs a few numpy calls next to mj_step: take MjData's views (their memory never moves),
    # addresses and methods once, not every substep
    qpos, qvel = [d.qpos for d in datas], [d.qvel for d in datas]
    robots = list(enumerate(zip(models, datas, [d.ctrl for d in datas], strict=True)))
    qadr, dofs, actuators = motors.qpos, motors.dof, motors.actuator
    torque, step, batch = drive.torque, mujoco.mj_step, len(datas)
    single = batch == 1 and not drive.per_robot
    if single:  # (n_motors,) arithmetic: broadcasting against (1, n_motors) costs more than the math
        targets = targets[0]
    budget = drive.has_friction_excess
    frictionloss = [m.dof_frictionloss[dofs].copy() for m in models] if budget else []
    if sensors_last_only:
        for m in models:
            m.opt.disableflags |= _NO_SENSOR
    for k in range(n_substeps):
        if single:
            q, q_dot = qpos[0][qadr], qvel[0][dofs]
        else:  # stack whole state vectors, then index once: one fancy index per robot costs more than the stack
            q, q_dot = np.stack(qpos)[:, qadr], np.stack(qvel)[:, dofs]
        tau = torque(targets, q, q_dot).reshape(batch, -1)
        excess = drive.friction_excess(q_dot, tau).reshape(batch, -1) if budget else None
        if sensors_last_only and k == n_substeps - 1:
            for m in models:
                m.opt.disableflags &= ~_NO_SENSOR
        for i, (m, d, ctrl) in robots:
            ctrl[actuators] = tau[i]
            if budget:
                m.dof_frictionloss[dofs] = frictionloss[i] + excess[i]
            step(m, d)
    for m, own in zip(models, frictionloss, strict=False):
        m.dof_frictionloss[dofs] = own
    return tau


_NO_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
