"""Gait parameters of the ZMP walking pattern generator and the command reach of a walking policy (plain data,
validated early)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toddlerbot.robot.interface import CONTROL_DT

AXES = ("vx", "vy", "yaw rate")
UNITS = ("m/s", "m/s", "rad/s")


@dataclass(frozen=True)
class CommandReach:
    """The velocity commands (vx m/s, vy m/s, yaw rate rad/s, robot frame) a walking policy is measured to follow:
    each axis within [low, high]. Commands beyond it are clamped to it."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]

    def __post_init__(self) -> None:
        for axis, lo, hi in zip(AXES, self.low, self.high, strict=True):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= 0.0 <= hi):
                raise ValueError(f"CommandReach {axis}: expected finite low <= 0 <= high, got [{lo}, {hi}]")

    def clamp(self, command: np.ndarray) -> np.ndarray:
        """The command clamped into the reach."""
        return np.clip(np.asarray(command, dtype=float), self.low, self.high)

    def describe(self) -> str:
        return ", ".join(f"{axis} [{lo:g}, {hi:g}] {unit}"
                         for axis, lo, hi, unit in zip(AXES, self.low, self.high, UNITS, strict=True))


WALK_REACH = CommandReach(low=(-0.1, -0.08, -0.4), high=(0.15, 0.08, 0.4))
"""The reach of the walking policies: walk-zmp walks every command in it without a fall under the perturbations of
`benchmarks/bench_walk_robustness.py` (docs/simulation.md), and RL training samples its commands from it."""


@dataclass(frozen=True)
class WalkConfig:
    dt: float = CONTROL_DT
    """Generator time step, s (the control period: one reference per control tick)."""
    cycle_time: float = 0.6
    """Gait cycle (two steps), s. 0.6 s rather than 0.72: the faster cadence keeps the swing foot off the floor
    for more of its swing (10 % instead of 21 % of swing ticks scuffing at 0.15 m/s) and made the fast walk robust
    (0 of 16 micro-perturbed 10 s walks fell instead of 1; docs/simulation.md)."""
    double_support_ratio: float = 0.25
    """Fraction of each step spent with both feet on the ground."""
    step_height: float = 0.025
    """Peak swing-foot lift, m."""
    stance_width: float | None = None
    """Lateral distance between the foot centres, m; None keeps the home pose's stance."""
    start_time: float = 0.4
    """Standing time before the first step, s (the CoM starts its shift during it)."""
    preview_time: float = 1.2
    """Preview horizon of the ZMP preview controller, s."""
    zmp_weight: float = 1.0
    """Weight on the ZMP tracking error in the preview controller's cost."""
    jerk_weight: float = 1e-6
    """Weight on the CoM jerk in the preview controller's cost."""
    leg_mass_correction: bool = False
    """Place the torso so that the whole-robot CoM at the current leg angles (moving swing leg included) follows
    the planned CoM; False (default) keeps the home pose's CoM offset in the torso frame. Off by default: on the
    simulated robot it did not make walking more robust (docs/simulation.md, "What was tried")."""
    com_iterations: int = 2
    """Torso placement / leg IK alternations per tick for the leg-mass correction."""
    max_vx: float = 0.3
    """Largest forward/backward speed accepted, m/s (commands are clipped to the limits)."""
    max_vy: float = 0.15
    """Largest sideways speed accepted, m/s."""
    max_yaw_rate: float = 1.0
    """Largest turning rate accepted, rad/s."""
    reach: CommandReach = field(default=WALK_REACH)
    """The commands the walking policy promises to follow (inside the generator's limits above, which leave room
    for the policy's velocity corrections)."""

    def __post_init__(self) -> None:
        positive = ("dt", "cycle_time", "preview_time", "zmp_weight", "jerk_weight", "max_vx", "max_vy", "max_yaw_rate")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"WalkConfig.{name} must be > 0, got {getattr(self, name)}")
        if not 0.0 < self.double_support_ratio < 1.0:
            raise ValueError(f"WalkConfig.double_support_ratio must be in (0, 1), got {self.double_support_ratio}")
        if self.step_height < 0 or self.start_time < 0:
            raise ValueError("WalkConfig.step_height and start_time must be >= 0")
        if self.stance_width is not None and self.stance_width <= 0:
            raise ValueError(f"WalkConfig.stance_width must be > 0 m, got {self.stance_width}")
        limits = (self.max_vx, self.max_vy, self.max_yaw_rate)
        if any(max(-lo, hi) > limit for lo, hi, limit in zip(self.reach.low, self.reach.high, limits, strict=True)):
            raise ValueError(f"WalkConfig.reach ({self.reach.describe()}) exceeds the generator's limits {limits}")
        if self.step_ticks < 2 or self.double_support_ticks < 1 or self.double_support_ticks >= self.step_ticks:
            raise ValueError(
                f"cycle_time {self.cycle_time} s and double_support_ratio {self.double_support_ratio} leave no "
                f"single- and double-support ticks at dt {self.dt} s"
            )

    @property
    def step_ticks(self) -> int:
        """Ticks per step (half a cycle)."""
        return round(self.cycle_time / 2 / self.dt)

    @property
    def double_support_ticks(self) -> int:
        return max(1, round(self.double_support_ratio * self.step_ticks))

    @property
    def start_ticks(self) -> int:
        return round(self.start_time / self.dt)

    @property
    def preview_ticks(self) -> int:
        return round(self.preview_time / self.dt)
