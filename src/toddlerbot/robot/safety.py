"""Command safety shared by every `Robot` backend: no motor is ever commanded to a bad goal.

Every command passes `CommandGuard.check` before a backend sees it:

* targets and gains must be finite numbers of the right shape, gains within the firmware's 0..16383, else
  `UnsafeCommandError` (the runner then stops the policy and the backend turns torque off);
* targets are clamped to the motor joints' ranges and, through the transmission map, to the output joints'
  ranges (a waist-roll command never asks the differential for more than its limit);
* optionally (hardware), each target moves at most ``max_step`` rad from the previous command per control step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.errors import ToddlerbotError

MAX_FIRMWARE_GAIN = 16383
"""Largest value of a Dynamixel X-series position/velocity gain register."""
SLEW_SPEEDS = 2.0
"""On hardware a target moves at most this many times the motor's no-load speed (``q_dot_max``) per second. The
limit is there to spread out a jump (a new policy, a reconnect), not to slow a gait: a position target leads the
measured angle of a motor running near full speed, and walk-zmp's knee targets move at up to 1.38 no-load speeds
at 0.15 m/s (at a limit of 1.0, clipping 8 % of its steps made it fall in hardware-in-the-loop)."""


def slew_step(max_motor_speed: np.ndarray, control_dt: float, speeds: float = SLEW_SPEEDS) -> np.ndarray:
    """The hardware's slew limit per control step, rad per motor: ``speeds`` x each motor's no-load speed (rad/s)
    x the control period (s)."""
    return speeds * np.asarray(max_motor_speed) * control_dt


class UnsafeCommandError(ToddlerbotError):
    """A policy asked for a non-finite or malformed target or gain; nothing was sent to the motors."""


@dataclass(frozen=True)
class CommandGuard:
    motor_names: tuple[str, ...]
    motor_range: np.ndarray
    """(n, 2) motor-joint limits, rad."""
    joint_range: np.ndarray
    """(n, 2) output-joint limits through the transmissions."""
    matrix: np.ndarray
    """q_joint = matrix @ q_motor."""
    inverse: np.ndarray
    max_step: np.ndarray | None = None
    """Largest change of a target per control step, rad (None: no slew limit)."""

    def targets(self, motor_targets: object, previous: np.ndarray | None = None) -> np.ndarray:
        """Validated, clamped (and slew-limited against `previous`) motor targets, rad."""
        q = self._in_range(self._finite(motor_targets, "motor target"))
        if self.max_step is not None and previous is not None:
            # the ranges win over the slew limit when the previous target lay outside them (start-up pose)
            q = self._in_range(np.clip(q, previous - self.max_step, previous + self.max_step))
        return q

    def _in_range(self, q: np.ndarray) -> np.ndarray:
        """Clamp to the motor joints' ranges and, through the transmission map, the output joints' ranges."""
        q = np.clip(q, self.motor_range[:, 0], self.motor_range[:, 1])
        joint = self.matrix @ q
        clipped = np.clip(joint, self.joint_range[:, 0], self.joint_range[:, 1])
        if np.any(clipped != joint):
            q = np.clip(self.inverse @ clipped, self.motor_range[:, 0], self.motor_range[:, 1])
        return q

    def gains(self, gains: object, what: str) -> np.ndarray:
        """Validated firmware gains (Dynamixel units, 0..16383)."""
        g = self._finite(gains, what)
        bad = np.flatnonzero((g < 0) | (g > MAX_FIRMWARE_GAIN))
        if bad.size:
            i = int(bad[0])
            raise UnsafeCommandError(
                f"{what} for {self.motor_names[i]} is {g[i]:g}; expected 0..{MAX_FIRMWARE_GAIN} (firmware units)"
            )
        return g

    def _finite(self, values: object, what: str) -> np.ndarray:
        try:
            array = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise UnsafeCommandError(f"{what}s must be numbers, got {type(values).__name__}") from None
        n = len(self.motor_names)
        if array.shape != (n,):
            raise UnsafeCommandError(f"{what}s must have shape ({n},), got {array.shape}")
        bad = np.flatnonzero(~np.isfinite(array))
        if bad.size:
            names = ", ".join(self.motor_names[i] for i in bad[:3]) + (" ..." if bad.size > 3 else "")
            raise UnsafeCommandError(f"non-finite {what} for {bad.size} motor(s) ({names}); nothing was sent")
        return array
