"""What a fall is, and what the motors may do during one: shared by every `Robot` backend, so the simulator and the
real robot fall alike.

While the robot falls (its torso tilted beyond `FALL_TILT_RAD` and still turning), `FallGuard` lowers the P gains
that reach the motors to `FALL_KP_FRACTION` of those asked for: compliant joints at impact instead of servos
fighting the floor at full stiffness. It restores them once the torso has landed (turning slower than
`LANDED_RATE_RAD_S` for `LANDED_S`) or is upright again. It reads only the IMU, which every backend has.

A fall starts from upright: the guard is armed by a reading of the torso within `FALL_TILT_RAD` of upright and
disarmed by a landing, so a robot that turns its torso while it lies (the `get-up` policy pushing itself up) keeps
the gains its motion asks for, and falling back down from a crouch or from standing lowers them again.
"""

from __future__ import annotations

import numpy as np

FALL_TILT_RAD = 1.0
"""Torso tilt from upright (angle between its z axis and the world's), rad, beyond which a robot has fallen:
the simulator's fall detector and the real robot's (from its IMU) use this one threshold."""
FALL_KP_FRACTION = 0.2
"""P gains while falling, as a fraction of those asked for (docs/hardware.md, "Falling": about a tenth less impact
torque than full gains)."""
LANDED_RATE_RAD_S = 1.0
"""The torso has landed when its angular speed (IMU gyro) stays below this..."""
LANDED_S = 0.1
"""...for this long, s."""


def tilt(quat: np.ndarray) -> float:
    """Angle between the z axis of a frame with orientation ``quat`` (w, x, y, z) and the world's z axis, rad."""
    _, x, y, _ = quat
    return float(np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)))


class FallGuard:
    """Lowers the P gains between the detection of a fall and the landing (`gains`, then `update` with each new
    observation's IMU reading)."""

    def __init__(self, control_dt: float, kp_fraction: float = FALL_KP_FRACTION) -> None:
        if not 0.0 < kp_fraction <= 1.0:
            raise ValueError(f"kp_fraction {kp_fraction}: expected a fraction in (0, 1]")
        self.kp_fraction = kp_fraction
        self.landed_steps = max(1, round(LANDED_S / control_dt))
        self.reset()

    def reset(self) -> None:
        self.falling = False
        self._still_steps = 0
        self._restore = False
        self._armed = False
        """A reading of the torso upright since the last landing: only then can a fall start."""

    def update(self, imu_quat: np.ndarray, imu_ang_vel: np.ndarray) -> None:
        """Advance with the IMU reading after a control step."""
        tilted = tilt(imu_quat) > FALL_TILT_RAD
        turning = float(np.linalg.norm(imu_ang_vel)) > LANDED_RATE_RAD_S
        self._armed = self._armed or not tilted
        if not self.falling:
            self.falling = self._armed and tilted and turning
            self._still_steps = 0
            return
        self._still_steps = 0 if turning else self._still_steps + 1
        if not tilted or self._still_steps >= self.landed_steps:
            self.falling, self._restore = False, True
            self._armed = not tilted

    def gains(self, kp: np.ndarray | None, default_kp: np.ndarray) -> np.ndarray | None:
        """The P gains to send for ``kp`` asked (None: the backend keeps its gains): lowered while falling, and
        sent explicitly once on landing so that a backend holding the lowered ones gets the asked ones back."""
        if self.falling:
            return self.kp_fraction * (default_kp if kp is None else kp)
        if self._restore:
            self._restore = False
            return default_kp if kp is None else kp
        return kp
