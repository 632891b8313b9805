"""Imitation reference for RL: tables precomputed from the ZMP walking generator (numpy, built once).

The walking generator is a function of a velocity command and time. Inside a jitted environment we cannot call
it, so we tabulate it on a grid of commands x gait phase:

* ``leg_motor_pos[i, j, k, p]``: the leg motor angles (rad, the description's ``leg`` group order) for command
  ``(vx[i], vy[j], yaw[k])`` at phase ``p / n_phase`` of the steady-state gait cycle;
* ``contact[i, j, k, p]``: (left, right) reference stance flags (1.0 = foot on the ground).

Commands the environment samples are snapped to this grid (`CommandGrid.snap`), so a lookup is two integer
indexings and needs no interpolation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.rl_inference import LEG_GROUP
from toddlerbot.rl.config import CommandConfig
from toddlerbot.robot.description import RobotDescription


class WalkGenerator(Protocol):
    """What we need from the ZMP walking generator (``toddlerbot.locomotion.zmp_walk.ZMPWalk``): the reference
    at time t (s) of a walk started from home at t = 0 under a constant command, with ``joint_pos`` (output
    joints, rad, transmission-map order) and ``contact`` ((left, right) feet on the floor)."""

    def reference(self, command: np.ndarray, t: float) -> Any: ...


@dataclass(frozen=True)
class CommandGrid:
    """Grid axes of the command space (vx m/s, vy m/s, yaw rad/s), each including 0 when its range does."""

    vx: np.ndarray
    vy: np.ndarray
    yaw: np.ndarray

    @classmethod
    def from_config(cls, cfg: CommandConfig) -> CommandGrid:
        return cls(*(_axis(lo, hi, n) for (lo, hi), n in zip((cfg.vx, cfg.vy, cfg.yaw), cfg.grid, strict=True)))

    @property
    def shape(self) -> tuple[int, int, int]:
        return len(self.vx), len(self.vy), len(self.yaw)

    def snap(self, command, xp=np):
        """Nearest grid indices (..., 3) of commands (..., 3); works with numpy and jax.numpy."""
        return xp.stack([xp.argmin(xp.abs(command[..., i, None] - xp.asarray(axis)), axis=-1)
                         for i, axis in enumerate((self.vx, self.vy, self.yaw))], axis=-1)

    def command(self, index, xp=np):
        """Command (..., 3) at grid indices (..., 3)."""
        return xp.stack([xp.asarray(axis)[index[..., i]] for i, axis in enumerate((self.vx, self.vy, self.yaw))],
                        axis=-1)


def _axis(lo: float, hi: float, n: int) -> np.ndarray:
    axis = np.linspace(lo, hi, n)
    if lo < 0 < hi:  # make 0 a grid point: replace the point nearest to it
        axis[np.argmin(np.abs(axis))] = 0.0
    return axis


@dataclass(frozen=True)
class ReferenceTable:
    grid: CommandGrid
    period: float
    """Gait cycle, s."""
    leg_motor_pos: np.ndarray
    """(n_vx, n_vy, n_yaw, n_phase, 12) leg motor angles, rad."""
    contact: np.ndarray
    """(n_vx, n_vy, n_yaw, n_phase, 2) reference stance of (left, right) feet, 0/1."""

    @property
    def n_phase(self) -> int:
        return self.leg_motor_pos.shape[3]

    def phase_index(self, t, xp=np):
        """Phase bin of time t (s) since the start of the gait."""
        return xp.floor(xp.mod(t, self.period) / self.period * self.n_phase).astype(int) % self.n_phase


def leg_motor_indices(description: RobotDescription) -> np.ndarray:
    """Motor indices (motor-id order) of the robot's leg motors, the policy's actions."""
    return np.asarray(description.groups[LEG_GROUP])


def standing_table(description: RobotDescription, cfg: CommandConfig, period: float,
                   n_phase: int = 40) -> ReferenceTable:
    """A reference that stands in the home pose with both feet down for every command (tests use it: it needs
    no walking generator)."""
    grid = CommandGrid.from_config(cfg)
    legs = description.home_motor_pos[leg_motor_indices(description)]
    shape = (*grid.shape, n_phase)
    return ReferenceTable(grid, period, np.broadcast_to(legs, (*shape, len(legs))).copy(), np.ones((*shape, 2)))


def zmp_table(description: RobotDescription, generator: WalkGenerator, cfg: CommandConfig, period: float,
              start_time: float, n_phase: int = 36, warmup_cycles: int = 2) -> ReferenceTable:
    """Tabulate a walking generator: for each grid command, one steady-state gait cycle, sampled ``warmup_cycles``
    cycles after the generator's standing start of ``start_time`` s (phase 0 = the start of a cycle).

    The zero command is standing still: the home pose with both feet down (a walking generator steps in place)."""
    grid = CommandGrid.from_config(cfg)
    tmap = description.transmission
    legs = leg_motor_indices(description)
    leg_pos = np.zeros((*grid.shape, n_phase, len(legs)))
    contact = np.zeros((*grid.shape, n_phase, 2))
    home = description.home_motor_pos[legs]
    for index in np.ndindex(*grid.shape):
        command = grid.command(np.array(index))
        if not np.any(command):
            leg_pos[index], contact[index] = home, 1.0
            continue
        for p in range(n_phase):
            try:
                ref = generator.reference(command, start_time + (warmup_cycles + p / n_phase) * period)
            except ToddlerbotError as exc:
                raise ToddlerbotError(f"walking generator failed for command {command.tolist()} (narrow "
                                      f"CommandConfig's ranges): {exc}") from exc
            leg_pos[(*index, p)] = tmap.joint_to_motor(np.asarray(ref.joint_pos))[legs]
            contact[(*index, p)] = np.asarray(ref.contact, dtype=float)
    return ReferenceTable(grid, period, leg_pos, contact)


def load_reference(description: RobotDescription, cfg: CommandConfig) -> tuple[ReferenceTable, str]:
    """The ZMP walking reference of ``toddlerbot.locomotion`` and its source name ("zmp").

    Tables are cached per (spec name, variant, command config) for the life of the process: they depend on the
    kinematics only, not on the actuator parameters."""
    spec = description.spec
    key = (spec.name, spec.variant, cfg)
    if key not in _CACHE:
        _CACHE[key] = _load_reference(description, cfg)
    return _CACHE[key]


_CACHE: dict[tuple, tuple[ReferenceTable, str]] = {}


def _load_reference(description: RobotDescription, cfg: CommandConfig) -> tuple[ReferenceTable, str]:
    from toddlerbot.locomotion.zmp_walk import ZMPWalk

    walk = ZMPWalk(description)
    return zmp_table(description, walk, cfg, walk.config.cycle_time, walk.config.start_time), "zmp"
