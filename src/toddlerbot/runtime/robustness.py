"""How often a walking policy falls across its command reach under seeded perturbations (`sim.perturbation`).

A trial walks one constant command for a few seconds on a perturbed robot, optionally kicked, on the flat floor or a
seeded terrain (`sim.terrain`); what is reported and
asserted is the count of falls over many trials, never one trajectory (walking is chaotic: the last bit of a
floating-point sum can decide a marginal step). `benchmarks/bench_walk_robustness.py` prints the full table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from toddlerbot.locomotion.config import CommandReach
from toddlerbot.policies.base import Policy
from toddlerbot.policies.held_upper_body import HeldUpperBody
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.robot.upper_body import random_upper_body_pose
from toddlerbot.runtime.runner import RunObserver, Step, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.perturbation import Perturbation, perturbed_robot
from toddlerbot.sim.terrain import TerrainSpec

PolicyFactory = Callable[[Robot], Policy]


def reach_commands(reach: CommandReach) -> list[tuple[float, float, float]]:
    """Ten commands across a reach: each axis at both ends, half forward, two combined commands, standing."""
    lo, hi = reach.low, reach.high
    return [
        (hi[0], 0.0, 0.0), (hi[0] / 2, 0.0, 0.0), (lo[0], 0.0, 0.0),
        (0.0, hi[1], 0.0), (0.0, lo[1], 0.0),
        (0.0, 0.0, hi[2]), (0.0, 0.0, lo[2]),
        (hi[0] / 2, hi[1] / 2, hi[2] / 2), (lo[0] / 2, lo[1] / 2, lo[2] / 2),
        (0.0, 0.0, 0.0),
    ]


STOP_S = 3.0
"""s a trial with stops holds a zero command (`stop_schedule`)."""


def stop_schedule(command: tuple[float, float, float], seed: int) -> Callable[[float], np.ndarray]:
    """A walk with a stop: ``command``, a zero command for `STOP_S` s from 2.4 + 0.1 x (seed mod 6) s (six seeds
    stop at six moments 0.1 s apart, a gait cycle of walk-rl), then ``command`` again. Under kicks (at 2, 4.5 and
    7 s) an 8 s trial is kicked walking, standing and walking again."""
    start = 2.4 + 0.1 * (seed % 6)
    walk, stop = np.asarray(command, dtype=float), np.zeros(3)
    return lambda t: stop if start <= t < start + STOP_S else walk


class KickSchedule(RunObserver):
    """A run observer: adds a horizontal velocity of ``kick_speed`` m/s in a random
    direction (from the perturbation's seed) to the torso at the kick times. `kicks` lists (time, dvx, dvy)."""

    def __init__(self, robot: MuJoCoRobot, perturbation: Perturbation) -> None:
        self.robot = robot
        self.speed = perturbation.kick_speed
        self.timing = perturbation.kick_timing
        self.rng = np.random.default_rng([perturbation.seed, 1])
        self.next_time = self.timing.start
        self.kicks: list[tuple[float, float, float]] = []

    def on_step(self, step: Step) -> None:
        self.kick_at(step.next_obs)

    def kick_at(self, obs: Observation) -> None:
        """Kick now if a kick is due at the observation's time."""
        if self.speed <= 0 or obs.time + 1e-9 < self.next_time:
            return
        angle = self.rng.uniform(0.0, 2 * np.pi)
        dv = self.speed * np.array([np.cos(angle), np.sin(angle)])
        self.robot.push(dv)
        self.kicks.append((obs.time, float(dv[0]), float(dv[1])))
        self.next_time += self.timing.period


class DirectedKick(RunObserver):
    """A run observer: one kick of ``speed`` m/s at ``time`` s, ``direction`` rad from the torso's heading (0
    forward, pi/2 to the left), so that a grid of directions means the same to a robot that has turned."""

    def __init__(self, robot: MuJoCoRobot, speed: float, direction: float, time: float) -> None:
        self.robot, self.speed, self.direction, self.time = robot, speed, direction, time
        self.kicked = False

    def on_step(self, step: Step) -> None:
        if self.kicked or step.next_obs.time + 1e-9 < self.time:
            return
        angle = self.direction + self.robot.torso_truth.planar_pose()[1]
        self.robot.push(self.speed * np.array([np.cos(angle), np.sin(angle)]))
        self.kicked = True


def kick_grid(directions: int = 8, phases: int = 6, period: float = 0.6,
              start: float = 2.0) -> list[tuple[int, int, float, float]]:
    """(row, column, direction rad, kick time s) of a grid of single kicks: ``directions`` evenly spaced around the
    heading (the first forward, counter-clockwise) by ``phases`` times evenly spaced over one gait ``period``
    from ``start``."""
    return [(i, j, 2 * np.pi * i / directions, start + j * period / phases)
            for i in range(directions) for j in range(phases)]


def directed_kick_trial(description: RobotDescription, make_policy: PolicyFactory,
                        command: tuple[float, float, float], speed: float, direction: float, kick_time: float,
                        after: float = 3.0) -> float | None:
    """Fall time (None: no fall) of the nominal robot walking ``command``, kicked once and walked ``after`` s on."""
    robot = MuJoCoRobot(description)
    kick = DirectedKick(robot, speed, direction, kick_time)
    return run_policy(robot, make_policy(robot), lambda t: np.asarray(command), kick_time + after,
                      observers=[kick]).fall_time


@dataclass(frozen=True)
class Condition:
    """A named way of perturbing the trials: one perturbation per seed, and the upper body held at a pose drawn
    from the seed (up to ``upper_body_pose`` of the way to the motors' limits; 0: the policy's own targets)."""

    name: str
    perturb: Callable[[RobotDescription, int], Perturbation]
    upper_body_pose: float = 0.0


def conditions(kicks: tuple[float, ...] = (0.1, 0.2, 0.3), poses: tuple[float, ...] = (0.3, 0.5)) -> list[Condition]:
    """The benchmark's conditions: nominal, torso 10 % heavier, floor friction 0.5, small random perturbations
    (`Perturbation.sample`: joint offsets 0.01 rad, torso mass +-10 %, friction 0.5-1.0, motor parameters
    +-10 %), each kick speed on the nominal robot (directions from the seed) and each upper-body pose fraction
    (arms, grippers and neck held from the start at a pose drawn from the seed)."""
    def nominal(description: RobotDescription, seed: int) -> Perturbation:
        return Perturbation(seed=seed)

    out = [
        Condition("nominal", nominal),
        Condition("torso +10%", lambda d, s: Perturbation(seed=s, torso_mass_scale=1.1)),
        Condition("friction 0.5", lambda d, s: Perturbation(seed=s, friction=0.5)),
        Condition("perturbed", lambda d, s: Perturbation.sample(s, d)),
    ]
    out += [Condition(f"kicks {v:g} m/s", lambda d, s, v=v: Perturbation(seed=s, kick_speed=v)) for v in kicks]
    out += [Condition(f"posed {f:g}", nominal, upper_body_pose=f) for f in poses]  # the nominal robot, posed
    return out


@dataclass(frozen=True)
class Trial:
    command: tuple[float, float, float]
    condition: str
    seed: int
    fall_time: float | None
    """s, None when the robot walked the whole trial."""
    displacement: tuple[float, float]
    """Torso (dx, dy) over the trial, m, world frame."""
    terrain: str = "flat"
    """The ground (`toddlerbot.sim.terrain`), drawn from ``seed``."""

    @property
    def fell(self) -> bool:
        return self.fall_time is not None


def run_trial(description: RobotDescription, make_policy: PolicyFactory, command: tuple[float, float, float],
              condition: Condition, seed: int, seconds: float, terrain: TerrainSpec | None = None,
              stops: bool = False) -> Trial:
    """Walk ``command`` for ``seconds`` on the robot perturbed by ``condition`` at ``seed``, on ``terrain`` drawn from
    ``seed`` (None: the flat floor); with ``stops``, stopping once on the way (`stop_schedule`)."""
    perturbation = replace(condition.perturb(description, seed), terrain=terrain)
    robot = perturbed_robot(description, perturbation)
    policy = make_policy(robot)
    if condition.upper_body_pose > 0:
        pose = random_upper_body_pose(description, condition.upper_body_pose, np.random.default_rng([seed, 2]))
        policy = HeldUpperBody(policy, pose)
    commands = stop_schedule(command, seed) if stops else lambda t: np.asarray(command)
    result = run_policy(robot, policy, commands, seconds, observers=[KickSchedule(robot, perturbation)])
    moved = robot.base_pos - result.log.base_pos[0]
    return Trial(tuple(command), condition.name, seed, result.fall_time, (float(moved[0]), float(moved[1])),
                 str(terrain or "flat"))
