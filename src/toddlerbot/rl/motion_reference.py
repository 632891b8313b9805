"""The tracking reference of a keyframe motion (`toddlerbot.policies.motions`): the motion played open-loop on the
training model, as the CPU physics backend steps it, built once per run with numpy (no JAX).

From the home keyframe (or lying where the motion starts lying), every control period holds the motion's motor
targets at that time (its joints through the transmissions; unlisted joints at home) for ``n_substeps`` physics
steps through the actuated plant (`toddlerbot.sim.actuated.step_actuated`, the actuator model in the loop, nominal
parameters), and after the motion the final pose is held for ``hold_s``. Row ``i`` is the state after ``i`` control
steps: the full qpos/qvel (and the solver's warm start, so that an episode started there continues exactly as the
reference did), the torso's orientation and height, and the end effectors (feet, then hands) relative to the torso.
``motor_targets[i]`` is held from row ``i`` to row ``i + 1``; the last row's is the final pose. The end effectors
are read from the step's kinematics as the physics backends' `Frame` reads them (MuJoCo's of the last substep), so
an environment that follows the reference exactly reads the same numbers. Building the squat's (7 s and a 2 s hold)
takes about 0.6 s on one core, so a run builds it rather than caching it; the run's folder records it.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import mujoco
import numpy as np

from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.motions import Motion, full_pose
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.floor_pose import place_on_floor
from toddlerbot.sim.actuated import MotorAddresses, step_actuated
from toddlerbot.sim.motor_drive import MotorDrive


def in_torso_frame(torso_pos, torso_quat, points, xp: ModuleType = np):
    """World points (..., 3) in the frame of a torso at ``torso_pos`` (3,) with orientation ``torso_quat`` (w, x,
    y, z; torso -> world), numpy or JAX: the rotation by the conjugate quaternion of ``points - torso_pos``."""
    v = points - torso_pos
    w, u = torso_quat[0], torso_quat[1:4]
    t = -2.0 * xp.cross(u, v)
    return v + w * t - xp.cross(u, t)


@dataclass(frozen=True)
class MotionReference:
    """A motion as the training model plays it (see the module docstring); ``n_steps + 1`` rows."""

    motion: str
    """The motion's name."""
    dt: float
    """Control period, s."""
    motion_steps: int
    """Control steps of the motion itself; the rows after it hold its final pose."""
    motor_targets: np.ndarray
    """(rows, n_motors) rad, held from each row to the next."""
    qpos: np.ndarray
    """(rows, nq)"""
    qvel: np.ndarray
    """(rows, nv)"""
    qacc_warmstart: np.ndarray
    """(rows, nv) the constraint solver's warm start."""
    end_effectors: np.ndarray
    """(rows, 4, 3) left foot, right foot, left hand, right hand sites in the torso frame, m."""

    @property
    def n_steps(self) -> int:
        """Control steps from the first row to the last."""
        return len(self.qpos) - 1

    @property
    def torso_quat(self) -> np.ndarray:
        """(rows, 4) w, x, y, z in the world frame."""
        return self.qpos[:, 3:7]

    @property
    def torso_height(self) -> np.ndarray:
        """(rows,) m."""
        return self.qpos[:, 2]

    def datas(self, model: mujoco.MjModel) -> list[mujoco.MjData]:
        """One MuJoCo data per row, at its state, everything computed (`mj_forward`)."""
        out = []
        for q, v, w in zip(self.qpos, self.qvel, self.qacc_warmstart, strict=True):
            d = mujoco.MjData(model)
            d.qpos[:], d.qvel[:], d.qacc_warmstart[:] = q, v, w
            mujoco.mj_forward(model, d)
            out.append(d)
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        """The tables by name (a run's record of what it tracked)."""
        return {"motion": np.array(self.motion), "dt": np.array(self.dt), "motion_steps": np.array(self.motion_steps),
                "motor_targets": self.motor_targets, "qpos": self.qpos, "qvel": self.qvel,
                "qacc_warmstart": self.qacc_warmstart, "end_effectors": self.end_effectors}


def end_effector_sites(model: mujoco.MjModel, description: RobotDescription) -> np.ndarray:
    """Site ids of the feet and the hands, in `MotionReference.end_effectors` order."""
    handles = description.handles
    return np.array([model.site(name).id for name in (*handles.feet_sites, *handles.hand_sites)])


def build_reference(motion: Motion, description: RobotDescription, model: mujoco.MjModel, dt: float,
                    n_substeps: int, hold_s: float) -> MotionReference:
    """``motion`` played open-loop on ``model`` (the training model) at control period ``dt`` (``n_substeps``
    physics steps each), then its final pose held ``hold_s`` (see the module docstring). It starts at rest from the
    home keyframe or, where the motion gives a starting base pose (lying on the floor), in its first keyframe's pose
    placed there (`toddlerbot.robot.floor_pose.place_on_floor`, as the simulator plays it)."""
    motion_steps = round(motion.duration / dt)
    n_steps = motion_steps + round(hold_s / dt)
    motors = MotorAddresses.of(model, description.motor_names)
    drive = MotorDrive(ActuatorArrays(*description.actuator_arrays()))
    sites = end_effector_sites(model, description)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    base = motion.start_base
    if base is not None:
        place_on_floor(model, data, description.transmission, full_pose(motion, description), base.roll, base.pitch,
                       base.z)
    mujoco.mj_forward(model, data)
    targets = np.stack([description.transmission.joint_to_motor(full_pose(motion, description, i * dt))
                        for i in range(n_steps + 1)])
    rows = []
    for i in range(n_steps + 1):
        rows.append((data.qpos.copy(), data.qvel.copy(), data.qacc_warmstart.copy(),
                     in_torso_frame(data.qpos[0:3], data.qpos[3:7], data.site_xpos[sites])))
        if i == n_steps:
            break
        data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 0
        step_actuated([model], [data], motors, targets[i][None], drive, n_substeps, sensors_last_only=True)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            raise ToddlerbotError(f"motion {motion.name!r}: the simulation diverged at {(i + 1) * dt:.2f} s")
    qpos, qvel, warmstart, effectors = (np.stack(column) for column in zip(*rows, strict=True))
    return MotionReference(motion.name, dt, motion_steps, targets, qpos, qvel, warmstart, effectors)
