"""Named switch/success predicates. Each has a sim form (reads the scene through a `SceneProbe`) and, where the
hardware can sense it, a hardware form (reads only observations and the commanded targets); asking a sim-only
predicate of the hardware is a one-line error when the chain is built, not a condition that never fires."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.interface import FALL_TILT_RAD, Observation, Robot, tilt
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import SIDES

Hands = Literal["both", "either", "left", "right"]


class PredicateError(ToddlerbotError):
    """A predicate that cannot be evaluated where the chain runs."""


@dataclass(frozen=True)
class Context:
    robot: Robot
    obs: Observation
    targets: np.ndarray
    """The motor targets last commanded, rad."""
    probe: SceneProbe | None
    """None on hardware."""


@dataclass(frozen=True)
class GraspedParams:
    target: str
    """Geom the fingers hold (sim form)."""
    hands: Hands = "both"
    closed_fraction: float = 0.5
    """Both forms: the gripper is commanded at least this fraction of the way from open to closed (so a grasp
    counts once the closing command is complete, not at the first touch)..."""
    stall_error: float = 0.15
    """...and (hardware form) its motor stays more than this short of its target, rad (stalled on the object)."""


@dataclass(frozen=True)
class HoldingParams:
    hands: Hands = "both"
    closed_fraction: float = 0.5
    """The gripper is commanded at least this fraction of the way from open to closed..."""
    min_torque: float = 0.15
    """...and its motor pushes towards closed with at least this torque, N*m (the observation's motor torque:
    simulated, or estimated from the present current on hardware). A gripper closed on the wagon handle pushes
    0.28-0.30 N*m at `grip_fraction` 0.78, one that closed on nothing 0.03-0.04 (docs/manipulation.md)."""

    def __post_init__(self) -> None:
        if not self.min_torque > 0:
            raise ValueError(f"min_torque: expected a positive torque, N*m, got {self.min_torque}")


@dataclass(frozen=True)
class MovedParams:
    body: str
    at_least: float
    """Horizontal displacement since the chain started, m."""


@dataclass(frozen=True)
class LiftedParams:
    body: str
    at_least: float
    """Height the body's origin rose since the chain started, m."""


@dataclass(frozen=True)
class UprightParams:
    max_tilt: float = FALL_TILT_RAD
    """Largest angle between the torso's (IMU's) z axis and the vertical, rad (default: the one fall threshold)."""


@dataclass(frozen=True)
class Predicate:
    params: type
    sim: Callable[[object, Context], bool]
    hardware: Callable[[object, Context], bool] | None


def _sides(hands: Hands) -> tuple[tuple[str, ...], Callable]:
    if hands in SIDES:
        return (hands,), all
    return SIDES, all if hands == "both" else any


def commanded_closed(p: GraspedParams | HoldingParams, ctx: Context, side: str) -> tuple[bool, int]:
    """(whether the `side` gripper is commanded at least ``p.closed_fraction`` closed, its motor index)."""
    d = ctx.robot.description
    i = d.motor_names.index(f"{side}_gripper_drive")
    lo, hi = d.motor_range[i]
    return (ctx.targets[i] - lo) / (hi - lo) >= p.closed_fraction - 1e-6, i


def _grasped_sim(p: GraspedParams, ctx: Context) -> bool:
    sides, combine = _sides(p.hands)
    return combine(commanded_closed(p, ctx, side)[0] and ctx.probe.pinching(side, p.target)  # type: ignore
                   for side in sides)


def _grasped_hardware(p: GraspedParams, ctx: Context) -> bool:
    sides, combine = _sides(p.hands)
    held = []
    for side in sides:
        closed, i = commanded_closed(p, ctx, side)
        held.append(closed and abs(ctx.targets[i] - ctx.obs.motor_pos[i]) > p.stall_error)
    return combine(held)


def _holding(p: HoldingParams, ctx: Context) -> bool:
    """Sensed alike in sim and on hardware: the gripper commanded closed and its motor pushing on something."""
    sides, combine = _sides(p.hands)
    d = ctx.robot.description
    held = []
    for side in sides:
        closed, i = commanded_closed(p, ctx, side)
        closing = np.sign(d.motor_range[i, 1] - d.motor_range[i, 0])
        held.append(closed and closing * ctx.obs.motor_torque[i] >= p.min_torque)
    return combine(held)


def _moved_sim(p: MovedParams, ctx: Context) -> bool:
    return ctx.probe.displacement(p.body) >= p.at_least  # type: ignore[union-attr]


def _lifted_sim(p: LiftedParams, ctx: Context) -> bool:
    return ctx.probe.rise(p.body) >= p.at_least  # type: ignore[union-attr]


def _upright(p: UprightParams, ctx: Context) -> bool:
    return tilt(ctx.obs.imu_quat) <= p.max_tilt


PREDICATES: dict[str, Predicate] = {
    "grasped": Predicate(GraspedParams, _grasped_sim, _grasped_hardware),
    "holding": Predicate(HoldingParams, _holding, _holding),
    "moved": Predicate(MovedParams, _moved_sim, None),
    "lifted": Predicate(LiftedParams, _lifted_sim, None),
    "upright": Predicate(UprightParams, _upright, _upright),
}


def check_available(name: str, on_hardware: bool, where: str) -> None:
    if on_hardware and PREDICATES[name].hardware is None:
        raise PredicateError(f"{where}: predicate {name!r} needs the simulator (it reads the scene); on hardware "
                             "use one with a hardware form (" + ", ".join(
                                 n for n, p in PREDICATES.items() if p.hardware is not None) + ") or after/button")


def holds(name: str, params: object, ctx: Context) -> bool:
    predicate = PREDICATES[name]
    form = predicate.sim if ctx.probe is not None else predicate.hardware
    return bool(form(params, ctx))  # type: ignore[misc]
