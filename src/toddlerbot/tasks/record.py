"""Record scripted demonstrations of a task into raw episodes and a LeRobot v3.0 dataset, with an optional video.

An episode is a run of the task's demonstrator (a `Policy`) on the task's `TaskRobot` through `run_policy`, whose
reset is the task's reset for the seed; `DemoRecorder` watches the run and builds the raw episode. Seeds run
from `seed` upwards; only successful demonstrations enter the dataset (failed seeds are reported), up to a
bounded number of attempts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toddlerbot.datasets.episode import RawEpisode, resample
from toddlerbot.datasets.lerobot_writer import write_dataset
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.runtime.runner import RunObserver, Step, run_policy
from toddlerbot.tasks import make_task
from toddlerbot.tasks.base import Task, TaskRobot
from toddlerbot.tasks.camera import CAMERA_EVERY, blank_image
from toddlerbot.tasks.space import POLICY_HZ
from toddlerbot.tasks.video import SideBySideVideo, write_png

DATASET_FPS = POLICY_HZ
"""Frames per second of a recorded dataset: the policy's rate."""


@dataclass
class DemoReport:
    """What a recording run did."""

    succeeded_seeds: list[int] = field(default_factory=list)
    failed_seeds: list[int] = field(default_factory=list)
    seconds_per_episode: float = 0.0

    @property
    def success_rate(self) -> float:
        attempts = len(self.succeeded_seeds) + len(self.failed_seeds)
        return len(self.succeeded_seeds) / attempts if attempts else 0.0


class DemoRecorder(RunObserver):
    """A run observer building the `RawEpisode` of a demonstration: the follower state and commanded targets of
    the task's recorded motors at every step, and (if `render`) the head-camera image of the state the policy
    acted on every `CAMERA_EVERY` steps from the first, each also a frame of `video` when one is given. The run
    must end when the policy is done (no image is taken after the last step)."""

    def __init__(self, task: Task, render: bool = True, video: SideBySideVideo | None = None) -> None:
        self.task, self.render, self.video = task, render, video

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self.policy = policy
        self.times, self.states, self.actions, self.image_times, self.images = [], [], [], [], []
        self._capture(obs.time)

    def on_step(self, step: Step) -> None:
        indices = self.task.space.indices
        self.times.append(step.obs.time)
        self.states.append(step.obs.motor_pos[indices])
        self.actions.append(step.action.motor_targets[indices])
        if (step.index + 1) % CAMERA_EVERY == 0 and not self.policy.done:  # the image the next step acts on
            self._capture(step.next_obs.time)

    def _capture(self, at: float) -> None:
        if not self.render:
            return
        image = self.task.head_image()
        self.image_times.append(at)
        self.images.append(image)
        if self.video is not None:
            self.video.add(image)

    def episode(self, seed: int) -> RawEpisode:
        """The recorded run as a raw episode; success is the task's."""
        images, image_times = self.images, self.image_times
        if not images:  # not rendered: one blank image keeps the episode's shape
            images, image_times = [blank_image()], [self.times[0]]
        return RawEpisode(
            task=self.task.instruction, names=self.task.space.names, time=np.array(self.times),
            state=np.array(self.states), action=np.array(self.actions), image_time=np.array(image_times),
            images=np.array(images), success=self.task.succeeded, seed=seed,
        )


def run_demo(task: Task, demo: Policy, seed: int, render: bool = True,
             video: SideBySideVideo | None = None) -> RawEpisode:
    """One scripted episode of `task` for `seed` (the demonstrator run until done on the task's robot): 50 Hz
    follower state and commanded targets, head-camera images every `CAMERA_EVERY` steps (if `render`)."""
    recorder = DemoRecorder(task, render, video)
    # the demonstration runs its full length, as the dataset's episodes do, whatever the robot does
    run_policy(TaskRobot(task, seed), demo, seconds=demo.duration, observers=[recorder], stop_on_fall=False)
    return recorder.episode(seed)


def record_demos(out: str | Path, episodes: int, seed: int, task: Task | str = "pick",
                 video_path: str | Path | None = None, overwrite: bool = False,
                 on_episode: Callable[[int, bool], None] | None = None,
                 snapshot_path: str | Path | None = None) -> DemoReport:
    """Record `episodes` successful demonstrations (seeds from `seed` upwards, at most 2*episodes+5 attempts)
    into a dataset at `out` (raw 50 Hz episodes under ``out/raw``); optionally a side-by-side video of all
    attempts and a PNG of the first attempt's approach (cube and gripper in view)."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if snapshot_path is not None and video_path is None:
        raise ValueError("a snapshot needs a video (video_path)")
    task = make_task(task) if isinstance(task, str) else task
    demo = task.demonstrator()
    frames_per_episode = -(-round(demo.duration / task.robot.control_dt) // CAMERA_EVERY)
    snapshot_frame = int(0.2 * frames_per_episode)
    video = None
    if video_path is not None:
        fps = round(1 / (task.robot.control_dt * CAMERA_EVERY))
        video = SideBySideVideo(task, video_path, fps, keep={snapshot_frame})
    report = DemoReport()
    raws: list[RawEpisode] = []
    started = time.perf_counter()
    attempt_seed = seed
    try:
        while len(raws) < episodes and attempt_seed < seed + 2 * episodes + 5:
            raw = run_demo(task, demo, attempt_seed, video=video)
            (report.succeeded_seeds if raw.success else report.failed_seeds).append(attempt_seed)
            if raw.success:
                raws.append(raw)
            if on_episode:
                on_episode(attempt_seed, raw.success)
            attempt_seed += 1
    except BaseException:
        if video is not None:
            video.abort()
        raise
    attempts = len(report.succeeded_seeds) + len(report.failed_seeds)
    report.seconds_per_episode = (time.perf_counter() - started) / attempts
    if raws:
        write_dataset(out, [resample(r, DATASET_FPS) for r in raws], task.space.names, DATASET_FPS,
                      overwrite=overwrite, raw_episodes=raws)
    if video is not None:
        video.close()
        if snapshot_path is not None:
            write_png(snapshot_path, video.kept[snapshot_frame])
    task.camera.close()
    return report


def demo_success_rate(task: str, episodes: int, seed: int,
                      on_episode: Callable[[int, bool], None] | None = None) -> DemoReport:
    """The scripted demonstrator of `task` on seeds `seed` .. `seed + episodes - 1`, without rendering or
    recording; `on_episode` hears each seed and whether it succeeded."""
    sim_task = make_task(task)
    demo = sim_task.demonstrator()
    report = DemoReport()
    started = time.perf_counter()
    for episode_seed in range(seed, seed + episodes):
        success = run_demo(sim_task, demo, episode_seed, render=False).success
        (report.succeeded_seeds if success else report.failed_seeds).append(episode_seed)
        if on_episode:
            on_episode(episode_seed, success)
    report.seconds_per_episode = (time.perf_counter() - started) / episodes
    sim_task.camera.close()
    return report
