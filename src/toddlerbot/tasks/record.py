"""Record scripted demonstrations of a task into raw episodes and a LeRobot v3.0 dataset, with an optional video.

Seeds run from `seed` upwards; only successful demonstrations enter the dataset (failed seeds are reported),
up to a bounded number of attempts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toddlerbot.datasets.episode import RawEpisode, resample
from toddlerbot.datasets.lerobot_writer import write_dataset
from toddlerbot.tasks import make_task
from toddlerbot.tasks.demonstrator import ScriptedPicker
from toddlerbot.tasks.pick import PickTask
from toddlerbot.tasks.video import SideBySideVideo, write_png

"""Task name -> its scripted demonstrator for a task instance (`reset(obs, rng)`, `act(obs)`, `duration`)."""

DATASET_FPS = 10
CAMERA_EVERY = 3
"""Render the head camera every this many control steps (16.7 Hz at 50 Hz control; the 10 Hz dataset takes
the nearest frame)."""


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


def run_demo(task: PickTask, demo: ScriptedPicker, seed: int, render: bool = True,
             video: SideBySideVideo | None = None) -> RawEpisode:
    """One scripted episode of `task` for `seed`: 50 Hz follower state and commanded targets, head-camera
    images every `CAMERA_EVERY` steps (if `render`)."""
    obs = task.reset(seed)
    demo.reset(obs, np.random.default_rng(seed))
    space = task.space
    steps = round(demo.duration / task.robot.control_dt)
    times, states, actions, image_times, images = [], [], [], [], []
    for k in range(steps):
        if render and k % CAMERA_EVERY == 0:
            image = task.head_image()
            image_times.append(obs.time)
            images.append(image)
            if video is not None:
                video.add(image)
        targets = demo.act(obs)
        times.append(obs.time)
        states.append(obs.motor_pos[space.indices])
        actions.append(targets[space.indices])
        obs = task.step(targets)
    if not images:
        images, image_times = [np.zeros((96, 96, 3), np.uint8)], [times[0]]
    return RawEpisode(
        task=task.instruction, names=space.names, time=np.array(times), state=np.array(states),
        action=np.array(actions), image_time=np.array(image_times), images=np.array(images),
        success=task.succeeded, seed=seed,
    )


def record_demos(out: str | Path, episodes: int, seed: int, task: PickTask | str = "pick",
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
