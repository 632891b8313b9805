"""Episodes recorded during teleoperation (a run observer), and their dataset."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toddlerbot.datasets.episode import RawEpisode
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.runtime.runner import RunObserver, Step
from toddlerbot.tasks.camera import CAMERA_EVERY, blank_image
from toddlerbot.tasks.space import ManipulationSpace


@dataclass
class EpisodeRecorder(RunObserver):
    """Records episodes between `toggle`s (the session's Menu): after each step, the follower's arm and gripper
    angles (state), the targets the robot was sent (action) and, every `camera_every` steps, a head-camera image."""

    task: str
    space: ManipulationSpace
    camera: Callable[[], np.ndarray] | None = None
    camera_every: int = CAMERA_EVERY
    episodes: list[RawEpisode] = field(default_factory=list)
    active: bool = False

    def toggle(self) -> str:
        """Start an episode, or end the one running; says which."""
        if self.active:
            self.active = False
            if len(self._time) >= 2:
                self.episodes.append(self._episode())
                return f"episode {len(self.episodes) - 1} ended ({len(self._time)} steps)"
            return "episode discarded (shorter than 2 steps)"
        self.active = True
        self._time, self._state, self._action, self._image_time, self._images = [], [], [], [], []
        return f"episode {len(self.episodes)} started"

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self._robot = robot

    def on_step(self, step: Step) -> None:
        sent = self._robot.last_targets  # after the robot's guard
        self.record(step.next_obs, step.action.motor_targets if sent is None else sent)

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
        images = self._images or [blank_image()]
        image_time = self._image_time or [self._time[0]]
        return RawEpisode(self.task, self.space.names, np.array(self._time), np.array(self._state),
                          np.array(self._action), np.array(image_time), np.array(images))

    def write(self, out: Path, log: Callable[[str], None]) -> None:
        """End an episode still running and write the episodes as a dataset at `out` (LeRobot v3.0, resampled to
        the dataset rate, raw episodes kept)."""
        from toddlerbot.datasets.episode import resample
        from toddlerbot.datasets.lerobot_writer import write_dataset
        from toddlerbot.tasks.record import DATASET_FPS

        if self.active:
            log(self.toggle())
        if not self.episodes:
            log("no episode recorded (press Menu to start and end one)")
            return
        write_dataset(out, [resample(e, DATASET_FPS) for e in self.episodes], self.space.names, DATASET_FPS,
                      raw_episodes=self.episodes)
        log(f"wrote {out}: {len(self.episodes)} episode(s)")
