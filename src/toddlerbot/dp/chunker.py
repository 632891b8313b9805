"""One 10 Hz action chunk -> 50 Hz control targets (numpy only).

Convention: ``chunk[i]`` is the target for ``t0 + i * policy_dt``, t0 the time of the newest observation the chunk
was predicted from (the dataset's windows start their actions at the observation frame). The first
``latency_drop`` actions are dropped (their time passed while inference ran); the next ``n_action_steps`` are
executed, linearly interpolated at the control rate: control step j of the plan, at ``t0 + (latency_drop + j /
substeps) * policy_dt``, gets ``lerp(chunk[latency_drop + k], chunk[latency_drop + k + 1], (j % substeps) /
substeps)`` with ``k = j // substeps``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.interface import CONTROL_DT
from toddlerbot.tasks.space import POLICY_HZ


@dataclass(frozen=True)
class ActionChunker:
    latency_drop: int = 3
    """Leading actions skipped."""
    n_action_steps: int = 5
    """Actions executed (each for one policy period)."""
    policy_dt: float = 1.0 / POLICY_HZ
    """Period of the chunk's actions, s."""
    control_dt: float = CONTROL_DT
    """Period of the control loop, s."""

    def __post_init__(self) -> None:
        ratio = self.policy_dt / self.control_dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"policy_dt {self.policy_dt} s must be a whole multiple of control_dt {self.control_dt} s")
        if self.latency_drop < 0 or self.n_action_steps < 1:
            raise ValueError("latency_drop >= 0 and n_action_steps >= 1 expected")

    @property
    def substeps(self) -> int:
        """Control steps per policy step (5 for 10 Hz -> 50 Hz)."""
        return round(self.policy_dt / self.control_dt)

    @property
    def plan_steps(self) -> int:
        """Control steps one chunk covers (25)."""
        return self.n_action_steps * self.substeps

    def plan(self, chunk: np.ndarray) -> np.ndarray:
        """Control targets (plan_steps, A) from a chunk (horizon, A) with horizon > latency_drop + n_action_steps."""
        chunk = np.asarray(chunk, dtype=float)
        first, last = self.latency_drop, self.latency_drop + self.n_action_steps
        if chunk.ndim != 2 or chunk.shape[0] <= last:
            raise ValueError(f"chunk of shape {chunk.shape}: needs (horizon > {last}, action_dim)")
        j = np.arange(self.plan_steps)
        k = first + j // self.substeps
        frac = ((j % self.substeps) / self.substeps)[:, None]
        return (1 - frac) * chunk[k] + frac * chunk[k + 1]
