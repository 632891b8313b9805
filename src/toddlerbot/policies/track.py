"""`track`: an exported motion-tracking policy (`rl train --env track`, `rl export`) played with numpy at the control
rate, in simulation or on the real robot.

Each control step the policy sees what the robot senses and the motion ahead (`policies.track_observation`), and
its action corrects the motion's motor targets: target = the motion's target at this step + ``action_scale`` x
action, every motor. It starts the motion at its first step on `reset` and is `done` once the motion and the hold
after it (as trained) have played.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.policies.rl_inference import RLPolicyFile, gravity_in_frame
from toddlerbot.policies.track_observation import track_actor_obs, track_frame
from toddlerbot.robot.interface import Observation, Robot

TRACK_ENVIRONMENT = "track"
"""The training environment whose exports this policy plays."""


class TrackController:
    """The observation history, last action and the motion's step of a tracking policy; robot state in, motor
    targets out."""

    def __init__(self, policy: RLPolicyFile) -> None:
        if policy.motion is None:
            raise ToddlerbotError(f"{policy.path}: not a motion-tracking policy (no motion_motor_targets)")
        self.policy, self.motion, self.cfg = policy, policy.motion, policy.obs_config
        self.reset()

    def reset(self) -> None:
        self.row = 0
        """The motion's control step the next action is for."""
        self.history: np.ndarray | None = None
        self.last_action = np.zeros(self.policy.n_actions)

    @property
    def finished(self) -> bool:
        """The motion and its hold have played."""
        return self.row >= self.motion.n_steps

    def observe(self, motor_pos: np.ndarray, motor_vel: np.ndarray, gyro: np.ndarray,
                imu_quat: np.ndarray) -> np.ndarray:
        """Push the robot's new frame into the history; the actor observation at the current step."""
        p, cfg = self.policy, self.cfg
        frame = track_frame(motor_pos, p.home_motor_pos, motor_vel, self.last_action, gyro,
                            gravity_in_frame(np.asarray(imu_quat, float)), cfg.motor_vel_scale, cfg.gyro_scale)
        self.history = np.tile(frame, (cfg.history, 1)) if self.history is None else \
            np.concatenate([frame[None], self.history[:-1]])
        return track_actor_obs(self.history, self.row, self.motion.motor_targets, self.motion.lookahead,
                               p.home_motor_pos)

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The motor targets (rad, motor-id order) of the policy's action on ``obs`` (`observe`); the motion
        advances one step."""
        p = self.policy
        action = p.action(obs)
        targets = self.motion.motor_targets[self.row].copy()
        targets[p.action_motor_index] += self.cfg.action_scale * action
        self.last_action = action
        self.row = min(self.row + 1, self.motion.n_steps)
        return targets

    def step(self, motor_pos: np.ndarray, motor_vel: np.ndarray, gyro: np.ndarray,
             imu_quat: np.ndarray) -> np.ndarray:
        """One control step: observation -> action -> motor targets."""
        return self.act(self.observe(motor_pos, motor_vel, gyro, imu_quat))


@dataclass(frozen=True)
class TrackStatus:
    """What the track policy reports (`Policy.status`)."""

    motion: str
    step: int
    steps: int

    def to_dict(self) -> dict:
        return {"motion": self.motion, "step": self.step, "steps": self.steps, "done": self.step >= self.steps}

    def describe(self) -> str:
        return f"track {self.motion}: step {self.step} of {self.steps}"


class TrackPolicy(Policy):
    name = "track"
    needs_imu = True

    def __init__(self, robot: Robot, weights: str | Path | None = None) -> None:
        """``weights``: an exported tracking policy (``rl export`` of an ``rl train --env track`` run)."""
        super().__init__(robot)
        if weights is None:
            raise ToddlerbotError("policy 'track' needs --weights: a policy exported from `rl train --env track` "
                                  "(docs/rl.md, \"Motion tracking\")")
        policy = RLPolicyFile(weights)
        policy.for_robot(robot.motor_names, robot.control_dt, TRACK_ENVIRONMENT, self.name)
        self.controller = TrackController(policy)

    @property
    def done(self) -> bool:
        return self.controller.finished

    @property
    def status(self) -> TrackStatus:
        c = self.controller
        return TrackStatus(c.motion.name, c.row, c.motion.n_steps)

    def reset(self, obs: Observation) -> None:
        self.controller.reset()

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        targets = self.controller.step(obs.motor_pos, obs.motor_vel, obs.imu_ang_vel, obs.imu_quat)
        return Action(motor_targets=targets, joint_targets=self.transmission.motor_to_joint(targets))
