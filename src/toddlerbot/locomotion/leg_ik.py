"""Leg inverse kinematics on the description's compiled fixed-base model (no link lengths retyped anywhere).

Each leg's chain (hip pitch, hip roll, hip yaw, knee, ankle pitch, ankle roll on ToddlerBot) is found from the
model's body tree: the joints between the foot site's body and the bodies both legs share. Foot poses are the
description's foot sites (``handles.feet_sites``), expressed in the torso frame (x forward, y left, z up), with
every non-leg joint at the home pose. The solver is damped Gauss-Newton on MuJoCo's site Jacobians, warm-started
from the last solution, so it is deterministic for a given sequence of targets.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.robot.builder import home_qpos
from toddlerbot.robot.description import RobotDescription


@dataclass(frozen=True)
class LegChains:
    joint_names: tuple[tuple[str, ...], tuple[str, ...]]
    """(left, right) joint names, hip to ankle."""


def _body_path(model: mujoco.MjModel, body: int) -> list[int]:
    path = []
    while body > 0:
        path.append(body)
        body = model.body_parentid[body]
    return path


class LegIK:
    """Foot-site poses <-> leg joint angles (rad) for both legs, relative to the torso."""

    def __init__(self, description: RobotDescription, tolerance: float = 1e-6, max_iterations: int = 30) -> None:
        self.model = description.model("fixed", scene=False)
        """The description's shared fixed-base model (read-only; the solver writes only its own `data`)."""
        self.data = mujoco.MjData(self.model)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        m, d = self.model, self.data
        handles = description.handles
        self._sites = [m.site(s).id for s in handles.feet_sites]
        paths = [_body_path(m, m.site_bodyid[s]) for s in self._sites]
        shared = set(paths[0]) & set(paths[1])
        chains = []
        for path in paths:
            joints = [j for b in reversed(path) if b not in shared for j in range(m.body_jntadr[b],
                      m.body_jntadr[b] + m.body_jntnum[b])]
            chains.append(joints)
        self.chains = LegChains(tuple(tuple(m.joint(j).name for j in c) for c in chains))  # type: ignore[arg-type]
        self._qadr = np.array([[m.jnt_qposadr[j] for j in c] for c in chains])
        self._dadr = np.array([[m.jnt_dofadr[j] for j in c] for c in chains])
        self._range = np.array([[m.jnt_range[j] for j in c] for c in chains])
        self._torso = m.body(handles.torso).id
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))
        d.qpos[:] = home_qpos(m, description.transmission, description.home_joint_pos)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        self.home_q = d.qpos[self._qadr].copy()
        """(2, 6) leg joint angles of the home pose."""
        self.home_foot_pos, self.home_foot_rot = self._foot_poses()
        self.home_com = d.subtree_com[self._torso] - d.xpos[self._torso]
        """Whole-robot CoM in the torso frame at the home pose, m."""
        self._q = self.home_q.copy()

    def joint_axes(self, q: np.ndarray | None = None) -> np.ndarray:
        """(2, 6, 3) rotation axis of each leg joint in the torso frame at leg angles q (default: home); mirrored
        joints of the two legs have opposite axes."""
        m, d = self.model, self.data
        d.qpos[self._qadr] = self.home_q if q is None else q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        axes = np.empty((2, 6, 3))
        for leg in range(2):
            mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self._sites[leg])
            axes[leg] = self._jacr[:, self._dadr[leg]].T
        return axes

    def com(self, q: np.ndarray) -> np.ndarray:
        """Whole-robot CoM (m) in the torso frame with the legs at angles q (2, 6) and every other joint at home."""
        m, d = self.model, self.data
        d.qpos[self._qadr] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        return d.subtree_com[self._torso] - d.xpos[self._torso]

    def _foot_poses(self) -> tuple[np.ndarray, np.ndarray]:
        d = self.data
        torso_pos = d.xpos[self._torso]
        pos = np.array([d.site_xpos[s] - torso_pos for s in self._sites])
        rot = np.array([d.site_xmat[s].reshape(3, 3) for s in self._sites])
        return pos, rot

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Foot-site positions (2, 3) and rotation matrices (2, 3, 3) in the torso frame for leg angles (2, 6)."""
        self.data.qpos[self._qadr] = q
        mujoco.mj_kinematics(self.model, self.data)
        return self._foot_poses()

    def solve(self, foot_pos: np.ndarray, foot_rot: np.ndarray, q_init: np.ndarray | None = None) -> np.ndarray:
        """Leg angles (2, 6) placing each foot site at foot_pos (2, 3) with orientation foot_rot (2, 3, 3)."""
        m, d = self.model, self.data
        q = (self._q if q_init is None else np.asarray(q_init, float)).copy()
        err = np.inf
        for _ in range(self.max_iterations):
            d.qpos[self._qadr] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            pos, rot = self._foot_poses()
            err = 0.0
            for leg in range(2):
                e_pos = foot_pos[leg] - pos[leg]
                e_rot = np.zeros(3)
                mujoco.mju_mat2Quat(quat := np.zeros(4), (foot_rot[leg] @ rot[leg].T).ravel())
                mujoco.mju_quat2Vel(e_rot, quat, 1.0)
                e = np.concatenate([e_pos, e_rot])
                err = max(err, float(np.max(np.abs(e))))
                mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self._sites[leg])
                J = np.vstack([self._jacp[:, self._dadr[leg]], self._jacr[:, self._dadr[leg]]])
                q[leg] += J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), e)
            q = np.clip(q, self._range[..., 0], self._range[..., 1])
            if err < self.tolerance:
                break
        self.residual = err
        """Largest position (m) / orientation (rad) error of the last solution: > 0 when a target was out of reach
        (the legs then stop at their joint limits, closest to the target)."""
        self._q = q
        return q
