"""Teleoperation ("pupperteering", appendix 8.10) as a `Policy` on any `Robot`: controller -> walking policy + upper
body. `runtime.run_policy` runs it with a `WallClock` (`teleop.launch.run_teleop`).

Per control step: the input source gives a `TeleopCommand`; its walking command drives the walking policy
(walk-zmp or walk-rl); the neck and waist follow the D-pad and Y/A/X/B as rates added to their start angles
(clamped to the joint ranges); the arms and grippers follow the leader (`ArmFollower`, rate-limited, holding when
the leader is stale) or hold their pose; the upper body runs at the follower's reduced gains. Menu calls `on_menu`
(the episode recorder marks an episode's start and end) or, without one, toggles teleoperation. Skill chains take
over while their button is held by wrapping the session (`skills.teleop_hook.ChainButtons`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.tasks.space import FOLLOWER_KP_SCALE, UPPER_BODY_GROUPS, follower_gains
from toddlerbot.teleop.follower import ArmFollower
from toddlerbot.teleop.gamepad import TeleopCommand
from toddlerbot.teleop.leader_follower import follow_leader
from toddlerbot.teleop.link import LinkSubscriber

NECK_JOINTS = ("neck_pitch", "neck_yaw")
WAIST_JOINTS = ("waist_roll", "waist_yaw")

class CommandSource(Protocol):
    def poll(self) -> TeleopCommand: ...


@dataclass(frozen=True)
class TeleopConfig:
    upper_body_kp_scale: float = FOLLOWER_KP_SCALE


class TeleopSession(Policy):
    """Teleoperation of `robot` from `source`; the velocity command `run_policy` passes is ignored (the walking
    command comes from the controller). `done` once the source asks to quit (Esc)."""

    name = "teleop"

    def __init__(self, robot: Robot, source: CommandSource, walker: Policy | None = None,
                 leader: tuple[LinkSubscriber, ArmFollower] | None = None, config: TeleopConfig | None = None,
                 on_menu: Callable[[], str] | None = None, log: Callable[[str], None] = print) -> None:
        super().__init__(robot)
        self.source, self.walker, self.leader, self.on_menu, self.log = source, walker, leader, on_menu, log
        self.config = config or TeleopConfig()
        d = robot.description
        self.kp = follower_gains(d, self.config.upper_body_kp_scale)
        self._upper = np.concatenate([d.groups.get(g, np.zeros(0, int)) for g in UPPER_BODY_GROUPS])
        self._arms = np.concatenate([d.groups.get(g, np.zeros(0, int)) for g in ("arm", "gripper")])
        names = list(robot.joint_names)
        self._neck_waist = np.array([names.index(j) for j in (*NECK_JOINTS, *WAIST_JOINTS)])
        self._home = d.home_joint_pos
        self.neck_waist = np.zeros(4)
        """Offsets from home of (neck pitch, neck yaw, waist roll, waist yaw), rad."""
        self.active = True
        self.last_command = TeleopCommand()
        self._noted_squat = False
        self._events_logged = 0

    def reset(self, obs: Observation) -> None:
        self.arm_targets = obs.motor_pos.copy()
        # neck and waist rates add to the pose the robot starts in (the home pose, or e.g. the pick task's head
        # looking down at the table, which its head-camera policy needs)
        start = self.robot.last_targets if self.robot.last_targets is not None else obs.motor_pos
        self._home = self.transmission.motor_to_joint(np.asarray(start, dtype=float))
        self.neck_waist = np.zeros(4)
        if self.walker is not None:
            self.walker.reset(obs)

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        cmd = self.source.poll()
        self.last_command = cmd
        if cmd.menu_pressed:
            self._menu()
        if cmd.squat_rate and not self._noted_squat:
            self.log("squat: the walking policies take no torso-height command yet; ignored")
            self._noted_squat = True
        joint, kp = self._walking(obs, cmd.walk if self.active else np.zeros(3))
        if self.active:
            self.neck_waist += np.concatenate([cmd.neck_rate, cmd.waist_rate]) * self.control_dt
        idx = self._neck_waist
        rng = self.robot.description.joint_range[idx]
        self.neck_waist = np.clip(self._home[idx] + self.neck_waist, rng[:, 0], rng[:, 1]) - self._home[idx]
        joint[idx] = self._home[idx] + self.neck_waist
        targets = self.transmission.joint_to_motor(joint)
        if self.leader is not None:
            self._follow_leader()
        targets[self._arms] = self.arm_targets[self._arms]
        return Action(targets, self.transmission.motor_to_joint(targets), kp)

    def _menu(self) -> None:
        if self.on_menu is not None:
            self.log(self.on_menu())
        else:
            self.active = not self.active
            self.log(f"teleoperation {'on' if self.active else 'off'}")

    def _walking(self, obs: Observation, walk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(joint targets, firmware kp) of the walking policy (or the held pose), the upper body at teleop's kp."""
        if self.walker is not None:
            action = self.walker.act(obs, walk)
            joint = action.joint_targets.copy()
            kp = self.kp.copy() if action.kp is None else np.asarray(action.kp, dtype=float).copy()
        else:
            joint = self.transmission.motor_to_joint(self.arm_targets)
            kp = self.kp.copy()
        kp[self._upper] = self.kp[self._upper]
        return joint, kp

    def _follow_leader(self) -> None:
        subscriber, follower = self.leader  # type: ignore[misc]
        self.arm_targets = follow_leader(subscriber, follower, self.arm_targets)
        for event in follower.events[self._events_logged:]:
            self.log(f"arms: {event}")
        self._events_logged = len(follower.events)

    @property
    def done(self) -> bool:
        return bool(getattr(self.source, "quit_requested", False))

    def close(self) -> None:
        if self.walker is not None:
            self.walker.close()
