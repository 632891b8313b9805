"""The teleoperation loop ("pupperteering", appendix 8.10): controller -> walking policy + upper body, on any `Robot`.

Per control step: the input source gives a `TeleopCommand`; its walking command drives the walking policy
(walk-zmp or walk-rl); the neck and waist follow the D-pad and Y/A/X/B as rates added to their start angles
(clamped to the joint ranges); the arms and grippers follow the leader (`ArmFollower`, rate-limited, holding when
the leader is stale) or hold their pose; the upper body runs at the follower's reduced gains. Menu marks an
episode's start and end when recording, and toggles teleoperation otherwise. A skill hook (skill chains) may take
over the targets while a skill button is held.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from toddlerbot.datasets.episode import RawEpisode
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.tasks.space import FOLLOWER_KP_SCALE, UPPER_BODY_GROUPS, ManipulationSpace, follower_gains
from toddlerbot.teleop.follower import ArmFollower
from toddlerbot.teleop.gamepad import TeleopCommand
from toddlerbot.teleop.leader_follower import follow_leader
from toddlerbot.teleop.link import LinkSubscriber

NECK_JOINTS = ("neck_pitch", "neck_yaw")
WAIST_JOINTS = ("waist_roll", "waist_yaw")

SkillHook = Callable[[Observation, frozenset[str], np.ndarray], tuple[np.ndarray, np.ndarray] | np.ndarray | None]
"""(observation, skills held, teleop targets) -> motor targets to send instead, or (targets, firmware kp), or None
to leave them."""


class CommandSource(Protocol):
    def poll(self) -> TeleopCommand: ...


@dataclass
class EpisodeRecorder:
    """Records episodes between Menu presses: follower arm/gripper angles (state), their targets (action) and,
    every `camera_every` steps, a head-camera image."""

    task: str
    space: ManipulationSpace
    camera: Callable[[], np.ndarray] | None = None
    camera_every: int = 3
    episodes: list[RawEpisode] = field(default_factory=list)
    active: bool = False

    def toggle(self) -> str:
        if self.active:
            self.active = False
            if len(self._time) >= 2:
                self.episodes.append(self._episode())
                return f"episode {len(self.episodes) - 1} ended ({len(self._time)} steps)"
            return "episode discarded (shorter than 2 steps)"
        self.active = True
        self._time, self._state, self._action, self._image_time, self._images = [], [], [], [], []
        return f"episode {len(self.episodes)} started"

    def record(self, obs: Observation, targets: np.ndarray) -> None:
        if not self.active:
            return
        if self.camera is not None and len(self._time) % self.camera_every == 0:
            self._image_time.append(obs.time)
            self._images.append(self.camera())
        self._time.append(obs.time)
        self._state.append(obs.motor_pos[self.space.indices])
        self._action.append(np.asarray(targets)[self.space.indices])

    def _episode(self) -> RawEpisode:
        images = self._images or [np.zeros((96, 96, 3), np.uint8)]
        image_time = self._image_time or [self._time[0]]
        return RawEpisode(self.task, self.space.names, np.array(self._time), np.array(self._state),
                          np.array(self._action), np.array(image_time), np.array(images))


@dataclass(frozen=True)
class TeleopConfig:
    upper_body_kp_scale: float = FOLLOWER_KP_SCALE


class TeleopSession:
    """Runs teleoperation on `robot`; call `reset` once, then `step` at the control rate."""

    def __init__(self, robot: Robot, source: CommandSource, walker: Policy | None = None,
                 recorder: EpisodeRecorder | None = None, leader: tuple[LinkSubscriber, ArmFollower] | None = None,
                 config: TeleopConfig | None = None, skill_hook: SkillHook | None = None,
                 log: Callable[[str], None] = print) -> None:
        self.robot, self.source, self.walker, self.recorder, self.leader = robot, source, walker, recorder, leader
        self.config = config or TeleopConfig()
        self.skill_hook, self.log = skill_hook, log
        d = robot.description
        self.kp = follower_gains(d, self.config.upper_body_kp_scale)
        self._upper = np.concatenate([d.groups.get(g, np.zeros(0, int)) for g in UPPER_BODY_GROUPS])
        self._arms = np.concatenate([d.groups.get(g, np.zeros(0, int)) for g in ("arm", "gripper")])
        names = list(robot.joint_names)
        self._neck = np.array([names.index(j) for j in NECK_JOINTS])
        self._waist = np.array([names.index(j) for j in WAIST_JOINTS])
        self._home = d.home_joint_pos
        self.neck_waist = np.zeros(4)
        """Offsets from home of (neck pitch, neck yaw, waist roll, waist yaw), rad."""
        self.active = True
        self.last_command = TeleopCommand()
        self._noted_squat = False
        self._events_logged = 0

    def reset(self) -> Observation:
        self.obs = self.robot.reset()
        self.arm_targets = self.obs.motor_pos.copy()
        # neck and waist rates add to the pose the robot starts in (the home pose, or e.g. the pick task's head
        # looking down at the table, which its head-camera policy needs)
        start = self.robot.last_targets if self.robot.last_targets is not None else self.obs.motor_pos
        self._home = self.robot.transmission.motor_to_joint(np.asarray(start, dtype=float))
        if self.walker is not None:
            self.walker.reset(self.obs)
        return self.obs

    def step(self) -> Observation:
        cmd = self.source.poll()
        self.last_command = cmd
        dt = self.robot.control_dt
        if cmd.menu_pressed:
            if self.recorder is not None:
                self.log(self.recorder.toggle())
            else:
                self.active = not self.active
                self.log(f"teleoperation {'on' if self.active else 'off'}")
        walk = cmd.walk if self.active else np.zeros(3)
        if cmd.squat_rate and not self._noted_squat:
            self.log("squat: the walking policies take no torso-height command yet; ignored")
            self._noted_squat = True

        if self.walker is not None:
            action = self.walker.act(self.obs, walk)
            joint = action.joint_targets.copy()
            kp = self.kp.copy() if action.kp is None else np.asarray(action.kp, dtype=float).copy()
        else:
            joint = self.robot.transmission.motor_to_joint(self.arm_targets)
            kp = self.kp.copy()
        kp[self._upper] = self.kp[self._upper]

        if self.active:
            rates = np.concatenate([cmd.neck_rate, cmd.waist_rate])
            self.neck_waist += rates * dt
        idx = np.concatenate([self._neck, self._waist])
        rng = self.robot.description.joint_range[idx]
        self.neck_waist = np.clip(self._home[idx] + self.neck_waist, rng[:, 0], rng[:, 1]) - self._home[idx]
        joint[idx] = self._home[idx] + self.neck_waist
        targets = self.robot.transmission.joint_to_motor(joint)

        if self.leader is not None:
            subscriber, follower = self.leader
            self.arm_targets = follow_leader(subscriber, follower, self.arm_targets)
            for event in follower.events[self._events_logged:]:
                self.log(f"arms: {event}")
            self._events_logged = len(follower.events)
        targets[self._arms] = self.arm_targets[self._arms]

        if self.skill_hook is not None and cmd.skills:
            override = self.skill_hook(self.obs, cmd.skills, targets)
            if isinstance(override, tuple):
                targets, kp = override
            elif override is not None:
                targets = override
        self.obs = self.robot.step(targets, kp=kp)
        if self.recorder is not None:
            self.recorder.record(self.obs, self.robot.last_targets if self.robot.last_targets is not None else targets)
        return self.obs
