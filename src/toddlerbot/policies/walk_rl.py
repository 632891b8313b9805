"""`walk-rl`: an exported RL walking policy run with numpy at the control rate (simulation or real robot).

Around the policy, a heading hold (`HeadingHold`, as walk-zmp's): the commanded yaw rate is integrated into a
desired heading, and the yaw rate given to the policy is corrected by the IMU heading's error against it. The
policies learn the yaw rate only roughly (the instantaneous yaw-rate error in training stays near 0.5 rad/s), and
with no yaw commanded some turn steadily while walking (docs/rl.md, "Heading hold").

At a zero command it stands still (`StandStill`, the option ``stand``): it holds the home pose instead of stepping in
place, and the gait starts again, from phase 0, when a command that is not zero comes (docs/rl.md, "Standing
still")."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.locomotion.config import CommandReach
from toddlerbot.policies.base import Action, Policy
from toddlerbot.policies.rl_inference import RLController, RLPolicyFile
from toddlerbot.policies.stand_still import StandStill
from toddlerbot.policies.walk_feedback import HeadingHold, attitude
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.robot.mirror import robot_mirror

SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights"
DEFAULT_WEIGHTS = SHIPPED_WEIGHTS / "walk_rl.npz"
"""The CPU recipe's policy (docs/rl.md); beside it ``walk_rl_gpu.npz`` is the GPU run's and ``walk_rl_terrain.npz``
the one continued on 1 cm tiles (docs/rl.md "Walking on terrain")."""
WALK_ENVIRONMENT = "walk"
"""The training environment whose exports this policy plays."""


def default_weights(variant: str | None) -> Path:
    """The shipped policy for a spec variant: ``walk_rl.npz`` for the packaged robot, ``walk_rl_<variant>.npz``
    for a variant (trained with ``rl train --variant``; its motors differ)."""
    return DEFAULT_WEIGHTS if variant is None else SHIPPED_WEIGHTS / f"walk_rl_{variant}.npz"


def shipped_names() -> tuple[str, ...]:
    """The walk-rl policies shipped in the package, by the name `resolve_weights` (``--weights NAME``) takes."""
    return tuple(sorted(path.stem for path in SHIPPED_WEIGHTS.glob("walk_rl*.npz")))


def resolve_weights(weights: str | Path) -> Path:
    """A policy file: a path, or the name of one shipped in the package (``walk_rl_gpu`` or ``walk_rl_gpu.npz``)
    when no such file exists here."""
    path = Path(weights)
    if path.is_file() or path.parent != Path("."):
        return path
    shipped = SHIPPED_WEIGHTS / (path.name if path.suffix else f"{path.name}.npz")
    return shipped if shipped.is_file() else path


HEADING_GAIN = 0.5
"""rad/s of yaw-rate command per rad of heading error."""
HEADING_INTEGRAL_GAIN = 0.1
"""rad/s of yaw-rate command per rad*s of integrated heading error (removes a steady turn)."""


class WalkRLPolicy(Policy):
    name = "walk-rl"
    needs_imu = True

    def __init__(self, robot: Robot, weights: str | Path | None = None, symmetric: bool = True,
                 stand: bool = True) -> None:
        """``weights``: a policy file or shipped name (default: the one shipped for the robot's variant);
        ``symmetric``: act with the mean of the policy and its mirror image (`RLController`; docs/rl.md
        "Mirror symmetry"); ``stand``: stand still at a zero command (`StandStill`) rather than step in place."""
        super().__init__(robot)
        if weights is None:
            variant = robot.description.spec.variant
            weights = default_weights(variant)
            if not weights.is_file():
                raise ToddlerbotError(f"no walk-rl policy ships for the {variant} variant ({weights.name}): train one "
                                      f"with `toddlerbot rl train --variant {variant}` (docs/rl.md), or walk with "
                                      "walk-zmp")
        policy = RLPolicyFile(resolve_weights(weights))
        policy.for_robot(robot.motor_names, robot.control_dt, WALK_ENVIRONMENT, self.name)
        self.controller = RLController(policy, robot_mirror(robot.description) if symmetric else None)
        low, high = policy.meta.get("command_low"), policy.meta.get("command_high")
        if low is not None and high is not None:
            self.command_reach = CommandReach(tuple(low), tuple(high))
        self.stance = StandStill(policy.home_motor_pos) if stand else None
        self._t0 = 0.0
        self._targets = policy.home_motor_pos

    def reset(self, obs: Observation) -> None:
        self._start_gait(obs)
        if self.stance is not None:
            self.stance.reset(obs.time, obs.motor_pos)

    def _start_gait(self, obs: Observation) -> None:
        """The gait from phase 0, with no history and the heading held where the robot is."""
        self.controller.reset()
        self._t0 = obs.time
        self.heading = HeadingHold(last_yaw=attitude(obs.imu_quat)[2])

    def _both_feet_down(self, t: float) -> bool:
        """Whether the gait reference at a zero command has both feet down at gait time t (s); a policy without a
        reference has no phase to wait for."""
        reference = self.controller.policy.reference
        return reference is None or bool(np.min(reference.at(np.zeros(3), t)[1]) > 0.99)

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        command = self.within_reach(command)
        if self.stance is not None:
            was_standing = self.stance.standing
            down = not np.any(command) and self._both_feet_down(obs.time - self._t0)
            if self.stance.update(obs.time, command, down, self._targets):
                return self._stand(obs.time)
            if was_standing:
                self._start_gait(obs)
        return self._walk(obs, command)

    def _stand(self, time: float) -> Action:
        targets = self.stance.targets(time)
        scales = self.controller.policy.gain_scales
        kp = None if scales is None else self.robot.default_kp * scales[0]
        return Action(motor_targets=targets, joint_targets=self.transmission.motor_to_joint(targets), kp=kp)

    def _walk(self, obs: Observation, command: np.ndarray) -> Action:
        self.heading.measure(attitude(obs.imu_quat)[2], self.control_dt)
        held = command + np.array([0.0, 0.0, self.heading.correction(HEADING_GAIN, HEADING_INTEGRAL_GAIN)])
        if self.command_reach is not None:
            held = self.command_reach.clamp(held)
        self.heading.advance(command[2], self.control_dt)
        targets, kp_scale = self.controller.step(obs.time - self._t0, held, obs.motor_pos,
                                                 obs.motor_vel, obs.imu_ang_vel, obs.imu_quat)
        self._targets = targets
        kp = None if kp_scale is None else self.robot.default_kp * kp_scale
        return Action(motor_targets=targets, joint_targets=self.transmission.motor_to_joint(targets), kp=kp)
