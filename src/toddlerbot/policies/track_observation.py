"""What a motion-tracking policy (`rl train --env track`) observes, defined once for the training environment (JAX)
and the runtime `track` policy (numpy): pass the array namespace ``xp``.

The actor sees a history of `track_frame`s (newest first), then once the reference's phase (row / last row) and the
motion's motor targets a few control steps ahead (`track_actor_obs`). An exported tracking policy carries the
motion's motor targets per control step (`MotionTargets`), so it plays without the training code.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from toddlerbot.errors import ToddlerbotError


def track_frame(motor_pos, home_motor_pos, motor_vel, last_action, gyro, gravity, motor_vel_scale: float,
                gyro_scale: float, xp: ModuleType = np):
    """One sensed frame: motor angles relative to home, scaled motor speeds, the last action (one per motor),
    scaled gyro, gravity direction in the IMU frame."""
    return xp.concatenate([motor_pos - home_motor_pos, motor_vel * motor_vel_scale, last_action, gyro * gyro_scale,
                           gravity])


def track_frame_size(n_motors: int) -> int:
    """Numbers per `track_frame` (the actions command every motor)."""
    return 3 * n_motors + 6


def track_actor_obs(history, row, motor_targets, lookahead, home_motor_pos, xp: ModuleType = np):
    """The actor observation at reference ``row``: the frame history flattened, the phase (row / last row) and the
    motor targets ``lookahead`` rows ahead (clamped to the last row) relative to home."""
    last = motor_targets.shape[0] - 1
    ahead = xp.minimum(row + xp.asarray(lookahead), last)
    return xp.concatenate([history.reshape(-1), xp.reshape(row / last, (1,)),
                           (motor_targets[ahead] - home_motor_pos).reshape(-1)])


@dataclass(frozen=True)
class MotionTargets:
    """The tracked motion in an exported policy: its motor targets per control step and what the actor looks at."""

    name: str
    motor_targets: np.ndarray
    """(rows, n_motors) rad, held from each row to the next; the rows after ``motion_steps`` hold the final pose."""
    motion_steps: int
    """Control steps of the motion itself."""
    lookahead: tuple[int, ...]
    """Rows ahead whose targets the actor sees."""

    @property
    def n_steps(self) -> int:
        """Control steps from the first row to the last (the motion and the hold after it)."""
        return len(self.motor_targets) - 1

    def actor_width(self, history: int, n_motors: int) -> int:
        return history * track_frame_size(n_motors) + 1 + len(self.lookahead) * n_motors

    def arrays(self) -> dict[str, np.ndarray]:
        return {"motion_name": np.array(self.name), "motion_motor_targets": np.asarray(self.motor_targets),
                "motion_steps": np.array(self.motion_steps), "motion_lookahead": np.array(self.lookahead)}

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> MotionTargets:
        return cls(str(data["motion_name"]), data["motion_motor_targets"].astype(float), int(data["motion_steps"]),
                   tuple(int(k) for k in np.asarray(data["motion_lookahead"]).reshape(-1)))

    def check(self, path: Path, n_motors: int) -> None:
        """One line unless the tables fit ``n_motors`` motors and hold finite numbers."""
        targets = self.motor_targets
        if targets.ndim != 2 or targets.shape[1] != n_motors or len(targets) < 2:
            raise ToddlerbotError(f"{path}: motion_motor_targets has shape {targets.shape}; expected (rows >= 2, "
                                  f"{n_motors})")
        if not np.all(np.isfinite(targets)):
            raise ToddlerbotError(f"{path}: motion_motor_targets holds non-finite values (NaN or inf)")
        if not 0 < self.motion_steps <= self.n_steps or not self.lookahead or min(self.lookahead) < 0:
            raise ToddlerbotError(f"{path}: motion_steps {self.motion_steps} and lookahead {self.lookahead}: expected "
                                  f"1..{self.n_steps} steps and look-aheads >= 0")
