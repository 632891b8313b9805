"""`get-up`: stand a fallen robot up with keyframed motions, knowing which way is down from the IMU alone (so it
works on the real robot as in the simulator).

An attempt: wait until the torso is still, read how it lies (`policies.lying`); from the back or a side, roll onto
the front first (``roll_from_back``, mirrored for the right side) and read again; then play
``get_up_front``, each motion blended in from where the joints are, and hold the home pose for `CHECK_S` and until
the robot is still. A motion with a tracking policy (`rl train --env track`, exported; `trackers`) is played by it
after the blend, closed-loop: the policy corrects the motion's targets from what the robot senses
(`policies.track`); the others open-loop. The robot stood up when the IMU's uprightness is at least
`STOOD_UPRIGHTNESS` then; otherwise it tries again, `MAX_ATTEMPTS` in all, and gives up holding the joints where
they are. Its last targets after a success are the home pose, so a walking policy can take over.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.policies.lying import Lying, lying_on, uprightness
from toddlerbot.policies.motions import Motion, full_pose, load_motion, mirrored
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.policies.track import TRACK_ENVIRONMENT, TrackController
from toddlerbot.policies.walk_rl import SHIPPED_WEIGHTS
from toddlerbot.robot.interface import Observation, Robot

MAX_ATTEMPTS = 3
STOOD_UPRIGHTNESS = 0.9
"""The IMU's uprightness that counts as standing at the end of an attempt."""
CHECK_S = 0.5
"""s of holding the home pose after a motion before checking that the robot stands..."""
STANDING_STILL_RAD_S = 0.15
"""...and until the gyro reads less than this (rad/s) for `STILL_S`, at most `WAIT_MAX_S` more: a robot still swaying
from the motion is not handed to a walking policy."""
STILL_RAD_S = 0.5
"""The torso is still when the gyro reads less than this (rad/s)..."""
STILL_S = 0.2
"""...for this long (s); the policy waits for it, at most `WAIT_MAX_S`, before reading how the robot lies."""
WAIT_MAX_S = 1.5
BLEND_RAD_S = 2.5
"""Mean joint speed, rad/s, of the move from where the joints are to a motion's first keyframe: the joint furthest
from it sets the move's time..."""
BLEND_S = (0.2, 0.8)
"""...within these bounds, s (a roll that ends where the next motion starts is followed at once)."""
MOTIONS = {"back": "roll_from_back", "front": "get_up_front", "left side": "roll_from_back"}
"""The motion each lying state plays; lying on the right side plays ``roll_from_back`` mirrored (from a side it
first lies back, then rolls over the side it came from). Every motion but the front's is a roll, after which the
policy reads how the robot lies again."""


def shipped_trackers() -> dict[str, Path]:
    """The tracking policies shipped for the get-up motions: ``weights/track_<motion>.npz`` where one exists."""
    paths = {name: SHIPPED_WEIGHTS / f"track_{name}.npz" for name in MOTIONS.values()}
    return {name: path for name, path in paths.items() if path.is_file()}


@dataclass(frozen=True)
class GetUpStatus:
    """What the get-up policy reports (`Policy.status`)."""

    attempts: int
    succeeded: bool
    done: bool
    phase: str
    """wait, roll, get-up, check, stood or gave up."""
    lying: tuple[str, ...]
    """How the robot lay at the start of each motion played (back, front, left side, right side, upright)."""
    stood_at: float | None
    """s from the hand-over to the check that found it standing; None before."""

    def to_dict(self) -> dict:
        return {"attempts": self.attempts, "succeeded": self.succeeded, "done": self.done, "phase": self.phase,
                "lying": list(self.lying), "stood_at_s": None if self.stood_at is None else round(self.stood_at, 3)}

    def describe(self) -> str:
        """One line for people."""
        seen = ", then ".join(self.lying) or "not read yet"
        if self.succeeded:
            return f"get-up: stood up in {self.stood_at:.2f} s after {self.attempts} attempt(s); lying on {seen}"
        ended = "gave up" if self.done else f"{self.phase}, attempt {self.attempts}"
        return f"get-up: {ended}; lying on {seen}"


class GetUpPolicy(Policy):
    name = "get-up"
    needs_imu = True

    def __init__(self, robot: Robot, trackers: Mapping[str, str | Path] | None = None) -> None:
        """``trackers``: an exported tracking policy per motion name (e.g. ``{"get_up_front": "track.npz"}``), each
        trained on that motion; None: those shipped (`shipped_trackers`); ``{}``: every motion open-loop."""
        super().__init__(robot)
        description = robot.description
        self._motions: dict[Lying, Motion] = {lying: load_motion(name, description) for lying, name in MOTIONS.items()}
        self._motions["right side"] = mirrored(self._motions["left side"], description)
        self._trackers = {}
        for name, path in (shipped_trackers() if trackers is None else trackers).items():
            tracker = RLPolicyFile(path)
            tracker.for_robot(robot.motor_names, robot.control_dt, TRACK_ENVIRONMENT, self.name)
            if name not in MOTIONS.values() or tracker.motion is None or tracker.motion.name != name:
                raise ToddlerbotError(f"{path}: a tracker for {name!r} must be a tracking policy of that motion, "
                                      f"one of {', '.join(sorted(set(MOTIONS.values())))}")
            self._trackers[name] = tracker
        self._home = self.joint_action(self.home_joint_pos)
        # nothing is read from the robot before `reset` (the hand-over): it may not be running yet
        self._phase, self._attempts, self._lying, self._stood_at = "wait", 0, [], None

    # -- the interface the run loop and `--on-fall get-up` rely on ---------------------------------------------
    @property
    def done(self) -> bool:
        """True once it stood up or gave up."""
        return self._phase in ("stood", "gave up")

    @property
    def succeeded(self) -> bool:
        return self._phase == "stood"

    @property
    def attempts(self) -> int:
        return self._attempts

    @property
    def status(self) -> GetUpStatus:
        return GetUpStatus(self._attempts, self.succeeded, self.done, self._phase, tuple(self._lying),
                           self._stood_at)

    def reset(self, obs: Observation) -> None:
        self._start = obs.time
        self._attempts = 0
        self._lying: list[str] = []
        self._stood_at: float | None = None
        self._after_roll = False
        self._wait(obs)

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        elapsed = obs.time - self._phase_start
        if self._phase == "wait":
            return self._waiting(obs, elapsed)
        if self._phase in ("roll", "get-up"):
            return self._playing(obs, elapsed)
        if self._phase == "check":
            return self._checking(obs, elapsed)
        return self._home if self._phase == "stood" else self._hold

    # -- phases ----------------------------------------------------------------------------------------------
    def _enter(self, phase: str, obs: Observation) -> None:
        self._phase, self._phase_start = phase, obs.time

    def _wait(self, obs: Observation) -> None:
        self._enter("wait", obs)
        self._still_since: float | None = None
        self._hold = self.joint_action(obs.joint_pos)

    def _check(self, obs: Observation) -> None:
        self._enter("check", obs)
        self._still_since = None

    def _settled(self, obs: Observation, below_rad_s: float) -> bool:
        """Whether the gyro has read less than ``below_rad_s`` for the last `STILL_S`."""
        still = float(np.linalg.norm(obs.imu_ang_vel)) < below_rad_s
        self._still_since = (self._still_since if self._still_since is not None else obs.time) if still else None
        return self._still_since is not None and obs.time - self._still_since >= STILL_S

    def _waiting(self, obs: Observation, elapsed: float) -> Action:
        if not (self._settled(obs, STILL_RAD_S) or elapsed >= WAIT_MAX_S):
            return self._hold
        lying = lying_on(obs.imu_quat, STOOD_UPRIGHTNESS)
        if lying == "upright":
            self._check(obs)
            return self._home
        if not (self._after_roll and lying == "front"):  # a roll and the get-up after it: one attempt
            if self._attempts >= MAX_ATTEMPTS:
                self._enter("gave up", obs)
                return self._hold
            self._attempts += 1
        self._after_roll = False
        self._play(lying, obs)
        return self._hold

    def _play(self, lying: Lying, obs: Observation) -> None:
        self._lying.append(lying)
        self._motion = self._motions[lying]
        tracker = self._trackers.get(self._motion.name)  # none for a mirrored motion ("... (mirrored)")
        self._tracking = None if tracker is None else TrackController(tracker)
        self._from = obs.joint_pos.copy()
        self._move = full_pose(self._motion, self.robot.description) - self._from  # to the first keyframe
        self._blend_s = float(np.clip(np.max(np.abs(self._move)) / BLEND_RAD_S, *BLEND_S))
        self._enter("get-up" if lying == "front" else "roll", obs)

    def _playing(self, obs: Observation, elapsed: float) -> Action:
        motion = self._motion
        if elapsed < self._blend_s:
            s = elapsed / self._blend_s
            return self.joint_action(self._from + s * s * (3 - 2 * s) * self._move)
        t = elapsed - self._blend_s
        if t > motion.duration:
            if self._phase == "roll":
                self._after_roll = True
                self._wait(obs)
                return self._hold
            self._check(obs)
            return self._home
        if self._tracking is not None:
            targets = self._tracking.step(obs.motor_pos, obs.motor_vel, obs.imu_ang_vel, obs.imu_quat)
            return Action(motor_targets=targets, joint_targets=self.transmission.motor_to_joint(targets))
        return self.joint_action(full_pose(motion, self.robot.description, t))

    def _checking(self, obs: Observation, elapsed: float) -> Action:
        if elapsed < CHECK_S or not (self._settled(obs, STANDING_STILL_RAD_S) or elapsed >= CHECK_S + WAIT_MAX_S):
            return self._home
        if uprightness(obs.imu_quat) >= STOOD_UPRIGHTNESS:
            self._stood_at = obs.time - self._start
            self._enter("stood", obs)
            return self._home
        self._wait(obs)  # then it reads how the robot lies again, and tries again or gives up
        return self._hold
