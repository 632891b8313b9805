"""Damped-least-squares inverse kinematics of one arm, in motor space, on MuJoCo Jacobians.

The hand site's Jacobian over the model's degrees of freedom (``mj_jacSite``) is mapped to the arm's motors
through the transmission map (``q_model = model_matrix @ q_motor``: spur gears turn the driven joint by the
drive's angle times the gear ratio), so a step of the solver is directly a change of motor targets.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription

CORRECTION_GAIN = 0.05
"""Per-step fraction of the grasp-point error added to the task-space correction."""
MAX_CORRECTION = 0.04
"""Largest task-space correction, m."""


class GraspPointCorrection:
    """A slow task-space integral of the grasp point's measured error, added to the IK target: it removes what the
    low-gain arm's sag and the IK's own error leave, clipped so a blocked arm cannot wind it up."""

    def __init__(self, gain: float = CORRECTION_GAIN, limit: float = MAX_CORRECTION) -> None:
        self.gain, self.limit = gain, limit
        self.value = np.zeros(3)

    def target(self, desired: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """The IK target for this step, m (``desired`` plus the updated correction)."""
        self.value = np.clip(self.value + self.gain * (desired - measured), -self.limit, self.limit)
        return desired + self.value


@dataclass(frozen=True)
class IKConfig:
    damping: float = 0.03
    """Levenberg-Marquardt damping lambda (m, and rad scaled by `orientation_weight`)."""
    orientation_weight: float = 0.05
    """m per rad: how much 1 rad of orientation error counts against 1 m of position error."""
    max_step: float = 0.15
    """Largest change of any motor per iteration, rad."""
    iterations: int = 8


class ArmIK:
    """IK for a site on one arm (``left`` or ``right``) on a kinematic copy of a model; the site is the hand
    site of the description unless `site` names another (e.g. a scene's grasp site)."""

    def __init__(self, description: RobotDescription, model: mujoco.MjModel, side: str,
                 config: IKConfig | None = None, site: str | None = None) -> None:
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        self.config = config or IKConfig()
        self.model = model
        self.data = mujoco.MjData(model)
        tmap = description.transmission
        names = description.motor_names
        self.arm = np.array([i for i in description.groups["arm"] if names[i].startswith(side)])
        self.site = model.site(site or description.handles.hand_sites[0 if side == "left" else 1]).id
        joints = [model.joint(name) for name in tmap.model_joint_names]
        self._qadr = np.array([j.qposadr[0] for j in joints])
        self._dadr = np.array([j.dofadr[0] for j in joints])
        self._map = tmap.model_matrix
        self._range = description.motor_range[self.arm]

    def forward(self, q_motor: np.ndarray, base_qpos: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Hand-site position (m) and rotation matrix in the world for motor angles `q_motor` (rad).
        `base_qpos` (the model's full qpos) sets the base and any free bodies; default: the model's qpos0."""
        d = self.data
        d.qpos[:] = self.model.qpos0 if base_qpos is None else base_qpos
        d.qpos[self._qadr] = self._map @ q_motor
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        return d.site_xpos[self.site].copy(), d.site_xmat[self.site].reshape(3, 3).copy()

    def gravity_torque(self, q_motor: np.ndarray, base_qpos: np.ndarray | None = None) -> np.ndarray:
        """Motor torques (N*m, this arm's motors) that hold the arm still against gravity at `q_motor`."""
        self.forward(q_motor, base_qpos)
        self.data.qvel[:] = 0.0
        bias = np.zeros(self.model.nv)
        mujoco.mj_rne(self.model, self.data, 0, bias)
        return (self._map[:, self.arm].T @ bias[self._dadr]).copy()

    def solve(self, q_motor: np.ndarray, target_pos: np.ndarray, target_rot: np.ndarray | None,
              base_qpos: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """Motor angles (rad, all motors; only this arm's change) that bring the hand site to `target_pos` (m,
        world) and, if given, `target_rot` (3x3). Starts from `q_motor`; returns (q, position error in m)."""
        cfg = self.config
        q = np.array(q_motor, dtype=float)
        jac_pos, jac_rot = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        for _ in range(cfg.iterations):
            pos, rot = self.forward(q, base_qpos)
            err = target_pos - pos
            mujoco.mj_jacSite(self.model, self.data, jac_pos, jac_rot, self.site)
            rows = [jac_pos[:, self._dadr] @ self._map[:, self.arm]]
            errs = [err]
            if target_rot is not None:
                rows.append(cfg.orientation_weight * jac_rot[:, self._dadr] @ self._map[:, self.arm])
                errs.append(cfg.orientation_weight * _rotation_error(target_rot, rot))
            jac, e = np.vstack(rows), np.concatenate(errs)
            dq = jac.T @ np.linalg.solve(jac @ jac.T + cfg.damping**2 * np.eye(len(e)), e)
            dq = np.clip(dq, -cfg.max_step, cfg.max_step)
            q[self.arm] = np.clip(q[self.arm] + dq, self._range[:, 0], self._range[:, 1])
        pos, _ = self.forward(q, base_qpos)
        return q, float(np.linalg.norm(target_pos - pos))


def top_down_rotation(closing_axis: np.ndarray) -> np.ndarray:
    """Grasp-site orientation (world) with the fingers pointing down (site y = -z) and closing along
    `closing_axis` (site z, horizontal)."""
    approach = np.array([0.0, 0.0, -1.0])
    close = np.array([closing_axis[0], closing_axis[1], 0.0])
    close /= np.linalg.norm(close)
    return np.column_stack([np.cross(approach, close), approach, close])


def _rotation_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Axis-angle (world frame, rad) rotating `current` onto `target`."""
    quat_err = np.zeros(4)
    mujoco.mju_mat2Quat(quat_err, (target @ current.T).ravel())
    axis_angle = np.zeros(3)
    mujoco.mju_quat2Vel(axis_angle, quat_err, 1.0)
    return axis_angle
