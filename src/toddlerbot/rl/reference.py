"""Imitation reference for RL: the ZMP walking generator tabulated on a command grid (numpy, built once).

The walking generator is a function of a velocity command and time. Inside a jitted environment we cannot call
it, so we tabulate one steady-state gait cycle per grid command, one phase bin per control tick, into a
`toddlerbot.policies.rl_inference.GaitReference`, which interpolates between grid points (any command in the
reach has a reference) and is what the environment and the robot (numpy inference) both read.

Every grid command is walked with the same leading foot (the generator's start with a zero command: the left foot
stands first), and phase bin p holds the gait at tick p (mod the cycle) of a walk started at t = 0, so
neighbouring grid points swing the same leg at the same phase (interpolation mixes like with like) and walk-zmp,
started the same way at the start of an episode, is in phase with the reference (the DAgger teacher,
`toddlerbot.rl.imitation`). The zero command steps in place, as walk-zmp does.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.rl_inference import LEG_GROUP, GaitReference
from toddlerbot.rl.config import CommandConfig
from toddlerbot.robot.description import RobotDescription


class WalkGenerator(Protocol):
    """What we need from the ZMP walking generator (``toddlerbot.locomotion.zmp_walk.ZMPWalk``): every tick's
    reference of a walk from the home pose under a command schedule t -> (3,) command, with ``joint_pos`` (ticks,
    output joints) rad in transmission-map order and ``contact`` (ticks, 2)."""

    def trajectory(self, commands: Any, duration: float) -> Any: ...


def grid_axes(cfg: CommandConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tabulated commands along vx, vy and yaw rate (each including 0 when its range does)."""
    return tuple(_axis(lo, hi, n) for (lo, hi), n in zip((cfg.vx, cfg.vy, cfg.yaw), cfg.grid, strict=True))


def _axis(lo: float, hi: float, n: int) -> np.ndarray:
    axis = np.linspace(lo, hi, n)
    if lo < 0 < hi:  # make 0 a grid point: replace the point nearest to it
        axis[np.argmin(np.abs(axis))] = 0.0
    return axis


def leg_motor_indices(description: RobotDescription) -> np.ndarray:
    """Motor indices (motor-id order) of the robot's leg motors, the policy's actions."""
    return np.asarray(description.groups[LEG_GROUP])


def standing_table(description: RobotDescription, cfg: CommandConfig, period: float,
                   n_phase: int = 30) -> GaitReference:
    """A reference that stands in the home pose with both feet down for every command (tests use it: it needs
    no walking generator)."""
    axes = grid_axes(cfg)
    legs = description.home_motor_pos[leg_motor_indices(description)]
    shape = (*(len(a) for a in axes), n_phase)
    return GaitReference(*axes, period, np.broadcast_to(legs, (*shape, len(legs))).copy(), np.ones((*shape, 2)))


def zmp_table(description: RobotDescription, generator: WalkGenerator, cfg: CommandConfig, period: float,
              dt: float, warmup_cycles: int) -> GaitReference:
    """Tabulate a walking generator: for each grid command a walk of ``warmup_cycles + 1`` cycles from home (zero
    command at t = 0, so the left foot stands first), of which the last cycle is kept: bin p = tick p mod the
    cycle's ``period / dt`` ticks."""
    axes = grid_axes(cfg)
    n_phase = round(period / dt)
    if abs(n_phase * dt - period) > 1e-9:
        raise ValueError(f"gait period {period} s is not a multiple of the control period {dt} s")
    tmap = description.transmission
    legs = leg_motor_indices(description)
    shape = tuple(len(a) for a in axes)
    leg_pos = np.zeros((*shape, n_phase, len(legs)))
    contact = np.zeros((*shape, n_phase, 2))
    last = slice(warmup_cycles * n_phase, (warmup_cycles + 1) * n_phase)
    for index in np.ndindex(*shape):
        command = np.array([axis[i] for axis, i in zip(axes, index, strict=True)])
        try:
            traj = generator.trajectory(lambda t, c=command: c if t > 0 else np.zeros(3),
                                        (warmup_cycles + 1) * period)
        except ToddlerbotError as exc:
            raise ToddlerbotError(f"walking generator failed for command {command.tolist()} (narrow "
                                  f"CommandConfig's ranges): {exc}") from exc
        leg_pos[index] = [tmap.joint_to_motor(q)[legs] for q in np.asarray(traj.joint_pos)[last]]
        contact[index] = np.asarray(traj.contact, dtype=float)[last]
    return GaitReference(*axes, period, leg_pos, contact)


def load_reference(description: RobotDescription, cfg: CommandConfig, dt: float) -> tuple[GaitReference, str]:
    """The ZMP walking reference of ``toddlerbot.locomotion`` and its source name ("zmp").

    Tables are cached per (spec name, variant, command config, dt) for the life of the process: they depend on the
    kinematics only, not on the actuator parameters."""
    spec = description.spec
    key = (spec.name, spec.variant, cfg, dt)
    if key not in _CACHE:
        _CACHE[key] = _load_reference(description, cfg, dt)
    return _CACHE[key]


_CACHE: dict[tuple, tuple[GaitReference, str]] = {}
WARMUP_CYCLES = 3
"""Gait cycles walked before the tabulated one (the standing start and the preview controller's transient)."""


def _load_reference(description: RobotDescription, cfg: CommandConfig, dt: float) -> tuple[GaitReference, str]:
    from toddlerbot.locomotion.config import WalkConfig
    from toddlerbot.locomotion.zmp_walk import ZMPWalk

    walk = ZMPWalk(description, WalkConfig(dt=dt))
    return zmp_table(description, walk, cfg, walk.config.cycle_time, dt, WARMUP_CYCLES), "zmp"
