"""Stepping to catch a push: where the swinging foot should land, given the measured DCM (capture point) error.

With the ZMP held on the stance foot p, the linear inverted pendulum's divergent component of motion (DCM)
ξ = c + ċ/ω moves as ξ(t) − p = (ξ(0) − p)·e^{ωt} (Englsberger et al. 2015), so an error δ of the DCM against the
plan now has grown to δ·e^{ωT} when the swinging foot lands T s later. Landing that much further along the error
puts the new stance foot under the DCM's deviation and the plan goes on from there (footstep adjustment with the
capture point: Griffin et al. 2017; Khadiv et al. 2016/2020 also adapt the step's duration). The shift is bounded
by a box around the planned footstep: the leg's reach forward, backward and outward, and the gap to the stance
foot inward (a leg cannot cross the other).

Pure numpy, no state: `WalkZMPPolicy` (`toddlerbot.policies.walk_zmp`) calls it every tick during a step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.locomotion.footsteps import LEFT


@dataclass(frozen=True)
class StepAdjustment:
    """How far the swinging foot's target moves for a DCM error (all lengths in m, torso-heading frame)."""

    gain: tuple[float, float] = (0.0, 0.7)
    """(x, y) fraction of the DCM error predicted at touchdown that the footstep moves (1: all of it)."""
    deadband: tuple[float, float] = (0.01, 0.02)
    """(x, y) part of the DCM error (after the gait's periodic part is removed) that moves no footstep: the
    estimate's noise on an unpushed walk."""
    forward: float = 0.06
    """Largest shift forward of the planned footstep."""
    backward: float = 0.06
    """Largest shift backward."""
    outward: float = 0.06
    """Largest shift away from the stance foot (to the left for the left foot)."""
    inward: float = 0.015
    """Largest shift towards the stance foot (the feet's gap at the home stance is about 3 cm)."""
    max_speed: float = 0.5
    """m/s: how fast the target may move (a kick makes the DCM error jump)."""
    hold: float = 0.9
    """Fraction of the swing after which the target is held (the foot is about to land)."""
    follow: float = 1.0
    """Fraction of a landed foot's shift the plan walks on from (`toddlerbot.locomotion.zmp_walk.WalkState`);
    the rest returns to the planned path with the next step."""
    hurry: float = 0.03
    """Sideways DCM error, m, beyond which the walk hurries (step timing): while the swinging foot is the one
    that cannot step that way (it would cross the stance foot), the plan advances `hurry_ticks` ticks per
    control tick so that the foot that can catch the push swings sooner."""
    hurry_ticks: int = 2
    """Generator ticks per control tick while hurrying (2: the step's rest takes half its planned time)."""

    def __post_init__(self) -> None:
        for name in ("forward", "backward", "outward", "inward", "max_speed"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"StepAdjustment.{name} must be finite and >= 0, got {getattr(self, name)}")
        if self.hurry_ticks < 1 or self.hurry < 0:
            raise ValueError(f"StepAdjustment: hurry_ticks {self.hurry_ticks} must be >= 1, hurry {self.hurry} >= 0 m")
        if min(self.gain) < 0 or min(self.deadband) < 0 or not 0.0 <= self.hold <= 1.0:
            raise ValueError(f"StepAdjustment: deadband {self.deadband} must be >= 0 m and hold {self.hold} in [0, 1]")

    def reach(self, swing_leg: int) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) (x, y) bounds of the shift of ``swing_leg``'s footstep (LEFT or RIGHT)."""
        if swing_leg == LEFT:
            return np.array([-self.backward, -self.inward]), np.array([self.forward, self.outward])
        return np.array([-self.backward, -self.outward]), np.array([self.forward, self.inward])


def hurries(dcm_error: np.ndarray, swing_leg: int, adjustment: StepAdjustment) -> bool:
    """Whether to hurry the step (`StepAdjustment.hurry`): the sideways DCM error is beyond ``hurry`` towards
    the swinging leg's inside, where only the other foot's next step can catch it."""
    outward = 1.0 if swing_leg == LEFT else -1.0
    return float(dcm_error[1]) * outward < -adjustment.hurry


def touchdown_dcm_error(dcm_error: np.ndarray, omega: float, time_to_touchdown: float) -> np.ndarray:
    """The DCM error (m) grown over ``time_to_touchdown`` s with the ZMP on the stance foot: δ·e^{ωT}."""
    return np.asarray(dcm_error, dtype=float) * np.exp(omega * max(time_to_touchdown, 0.0))


def dead_zone(value: np.ndarray, width: tuple[float, float]) -> np.ndarray:
    """``value`` moved towards zero by ``width`` per axis (zero inside it): continuous, no jump at the edge."""
    value = np.asarray(value, dtype=float)
    return np.sign(value) * np.maximum(np.abs(value) - np.asarray(width), 0.0)


def footstep_shift(dcm_error: np.ndarray, omega: float, time_to_touchdown: float, swing_leg: int,
                   adjustment: StepAdjustment) -> np.ndarray:
    """Where the swinging foot's target should move (x, y, m, torso-heading frame) for a DCM error (m) against
    the plan: the error beyond the dead band, grown to touchdown, times the gain, within the leg's reach."""
    grown = touchdown_dcm_error(dead_zone(dcm_error, adjustment.deadband), omega, time_to_touchdown)
    low, high = adjustment.reach(swing_leg)
    return np.clip(np.asarray(adjustment.gain) * grown, low, high)
