"""Fallen robots in the simulator and the get-up policy tried on them (`benchmarks/bench_get_up.py` and the tests).

A fallen state: the nominal robot walks with `walk-rl` at a seeded command within its reach, one seeded horizontal
kick of 1-2 m/s towards its back or its front knocks it over, and it is left `SETTLE_S` with torque on and the last
targets held. A trial then hands it to the `get-up` policy: it succeeded when, within `LIMIT_S`, the torso stays at
least `HEIGHT_FRACTION` of its standing height with uprightness at least `UPRIGHTNESS` for `STABLE_S` (the
simulator's ground truth judges; the policy itself reads only the IMU). A robot that stood is then handed to
`walk-rl`, which walks `WALK_ON_S` at the seed's command from the get-up's final pose without falling, or not.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from toddlerbot.locomotion.config import WALK_REACH
from toddlerbot.policies import make_policy
from toddlerbot.policies.get_up import GetUpPolicy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.runtime.robustness import DirectedKick
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

Side = Literal["back", "front", "left", "right"]
KICK_DIRECTION = {"back": np.pi, "front": 0.0, "left": np.pi / 2, "right": -np.pi / 2}
"""Kick direction from the heading, rad, per side kicked towards: towards the back knocks the robot onto its back;
kicked sideways it lands on its back or on that side."""
KICK_SPEED = (1.0, 2.0)
KICK_TIME = (1.5, 2.5)
"""s of walking before the kick, drawn per seed (a different phase of the gait each time)."""
FALL_WAIT_S = 3.0
"""s after the kick within which the robot must have fallen (else the seed gives no fallen state)."""
SETTLE_S = 1.5
LIMIT_S = 10.0
HEIGHT_FRACTION = 0.9
UPRIGHTNESS = 0.9
STABLE_S = 0.5
WALK_ON_S = 5.0


@dataclass(frozen=True)
class Fallen:
    """A robot knocked over (`fallen_robot`), ready for a get-up trial."""

    robot: MuJoCoRobot
    seed: int
    side: Side
    command: np.ndarray
    kick_speed: float


@dataclass(frozen=True)
class Trial:
    """One get-up trial's outcome."""

    seed: int
    side: Side
    stood: bool
    time_to_stand: float | None
    """s from the hand-over until the torso stood (the start of the stable stretch); None when it did not."""
    attempts: int
    longest_over_stall: float
    """Longest time, s, any motor's torque stayed above its stall torque (motor catalogue) during the trial."""
    lowered_gain_steps: int
    """Control steps in which the shared layer's fall guard lowered the gains (it took a get-up move for a fall)."""
    lying: tuple[str, ...]
    walked_on: bool | None = None
    """Whether walk-rl then walked `WALK_ON_S` from the get-up's final pose without a fall; None: it did not stand."""


def fallen_robot(description: RobotDescription, seed: int, side: Side) -> Fallen | None:
    """The robot of ``seed`` knocked onto its ``side``, settled; None if the kick did not knock it over."""
    rng = np.random.default_rng([seed, list(KICK_DIRECTION).index(side)])
    command = rng.uniform(WALK_REACH.low, WALK_REACH.high)
    speed, kick_time = rng.uniform(*KICK_SPEED), rng.uniform(*KICK_TIME)
    robot = MuJoCoRobot(description)
    kick = DirectedKick(robot, speed, KICK_DIRECTION[side], kick_time)
    result = run_policy(robot, make_policy("walk-rl", robot), lambda t: command, kick_time + FALL_WAIT_S,
                        observers=[kick], record_log=False)
    if not result.fell:
        return None
    held = robot.last_targets
    for _ in range(round(SETTLE_S / robot.control_dt)):
        robot.step(held)
    return Fallen(robot, seed, side, command, float(speed))


def get_up_trial(fallen: Fallen, trackers: Mapping[str, str | Path] | None = None) -> Trial:
    """Hand ``fallen.robot`` to the get-up policy (with ``trackers``, `GetUpPolicy`'s: None the shipped ones) for
    `LIMIT_S` and judge it by the simulator's ground truth."""
    robot = fallen.robot
    description = robot.description
    stall = np.array([model.stall_torque_nm for model in description.motor_models])
    policy = GetUpPolicy(robot, trackers)
    obs = robot.observe()
    policy.reset(obs)
    start, dt = obs.time, robot.control_dt
    over = np.zeros(len(stall))
    longest, lowered, standing_since = 0.0, 0, None
    for _ in range(round(LIMIT_S / dt)):
        action = policy.act(obs, np.zeros(3))
        obs = robot.step(action.motor_targets, action.kp, action.kd)
        over = np.where(np.abs(obs.motor_torque) > stall, over + dt, 0.0)
        longest = max(longest, float(over.max()))
        lowered += robot.fall_guard.falling
        standing = (robot.torso_height() >= HEIGHT_FRACTION * robot.standing_height
                    and robot.torso_uprightness() >= UPRIGHTNESS)
        standing_since = (obs.time if standing_since is None else standing_since) if standing else None
        if standing_since is not None and obs.time - standing_since >= STABLE_S:
            return Trial(fallen.seed, fallen.side, True, standing_since - start, policy.attempts, longest, lowered,
                         policy.status.lying, walks_on(robot, policy, obs, fallen.command))
    return Trial(fallen.seed, fallen.side, False, None, policy.attempts, longest, lowered, policy.status.lying)


def walks_on(robot: MuJoCoRobot, get_up: GetUpPolicy, obs: Observation, command: np.ndarray) -> bool:
    """Whether `walk-rl`, handed the robot once ``get_up`` (standing at ``obs``) is done, as the run loop does, walks
    `WALK_ON_S` at ``command`` without a fall."""
    for _ in range(round(LIMIT_S / robot.control_dt)):  # its check: at most a few s more
        if get_up.done:
            break
        action = get_up.act(obs, np.zeros(3))
        obs = robot.step(action.motor_targets, action.kp, action.kd)
    if not get_up.succeeded:
        return False
    walk = make_policy("walk-rl", robot)
    walk.reset(obs)
    for _ in range(round(WALK_ON_S / robot.control_dt)):
        action = walk.act(obs, command)
        obs = robot.step(action.motor_targets, action.kp, action.kd)
        if robot.fallen:
            return False
    return True
