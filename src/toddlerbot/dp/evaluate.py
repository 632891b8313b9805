"""Closed-loop evaluation of a diffusion-policy checkpoint on a simulated task (``toddlerbot dp eval``).

The checkpoint runs through `ChunkPolicyRunner` in synchronous mode (the simulation does not run in real time, so
a worker's wall-clock latency would mean nothing): 50 Hz control, observations at the policy rate (10 Hz), each
one the follower's arm and gripper motor angles and the head camera's 96x96 image, made exactly as the recorder
makes a dataset row (`ManipulationSpace` indices, `HeadCamera.image`) and laid out by the same `channel_first` as
the training windows. The policy drives the dataset's motors (arms and grippers); every other motor holds the
task's start pose. Success is the task's own (`PickTask.succeeded`; the wagon task's is the wagon chain's
``grasped`` check).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from toddlerbot.dp.checkpoint import load_policy
from toddlerbot.dp.chunker import ActionChunker
from toddlerbot.dp.config import DPConfig
from toddlerbot.dp.data import channel_first
from toddlerbot.dp.inference import PolicyInference
from toddlerbot.dp.policy import IMAGE, STATE
from toddlerbot.dp.runner import ChunkPolicyRunner
from toddlerbot.errors import ToddlerbotError
from toddlerbot.tasks import make_task
from toddlerbot.tasks.pick import PickTask

if TYPE_CHECKING:  # PyAV (the manip extra) is needed only to write a video
    from toddlerbot.tasks.video import SideBySideVideo


class EvalError(ToddlerbotError):
    """A checkpoint that does not fit the task, or a bad evaluation setting."""


@dataclass
class EpisodeResult:
    seed: int
    success: bool
    sim_seconds: float
    """Simulated time until success (or the episode's limit)."""
    chunks_used: int
    max_target_offset: float
    """Largest |policy target - start pose| over the policy's motors and steps, rad (0: the policy never moved)."""


@dataclass
class EvalResult:
    task: str
    checkpoint: str
    seed: int
    episodes: list[EpisodeResult] = field(default_factory=list)
    inference_seconds: list[float] = field(default_factory=list)
    """Wall time of every inference (one `policy.sample`), s."""

    @property
    def success_rate(self) -> float:
        return sum(e.success for e in self.episodes) / len(self.episodes) if self.episodes else 0.0

    @property
    def inference_ms(self) -> float:
        return 1e3 * float(np.mean(self.inference_seconds)) if self.inference_seconds else float("nan")

    def summary(self) -> dict:
        return {"success_rate": self.success_rate, "episodes": len(self.episodes), "inference_ms": self.inference_ms,
                "task": self.task, "checkpoint": self.checkpoint, "seed": self.seed,
                "failed_seeds": [e.seed for e in self.episodes if not e.success]}


class TimedInference:
    """`PolicyInference` that keeps the wall time of every call."""

    def __init__(self, inference: PolicyInference) -> None:
        self.inference = inference
        self.seconds: list[float] = []

    def __call__(self, history: dict[str, np.ndarray]) -> np.ndarray:
        start = time.perf_counter()
        chunk = self.inference(history)
        self.seconds.append(time.perf_counter() - start)
        return chunk


def check_fits(config: DPConfig, task: PickTask) -> None:
    """The checkpoint's state and action must be the task's arm and gripper motors, in the same order."""
    names = task.space.names
    if (config.state_dim, config.action_dim) != (len(names), len(names)):
        raise EvalError(f"checkpoint has state {config.state_dim} / action {config.action_dim} dimensions; task "
                        f"{task.name!r} records {len(names)} motors")
    for kind, got in (("state", config.state_names), ("action", config.action_names)):
        if got and tuple(got) != names:
            raise EvalError(f"checkpoint {kind} names {list(got)} differ from task {task.name!r}'s {list(names)}")


def run_episode(task: PickTask, infer: Callable[[dict[str, np.ndarray]], np.ndarray], config: DPConfig,
                seed: int, seconds: float, video: SideBySideVideo | None = None) -> EpisodeResult:
    """One closed-loop episode of at most ``seconds`` (simulated); stops early once the task has succeeded."""
    obs = task.reset(seed)
    indices = task.space.indices
    hold = task.ready_pose.copy()
    chunker = ActionChunker(config.latency_drop, config.n_action_steps, 1.0 / config.policy_hz,
                            task.robot.control_dt)
    runner = ChunkPolicyRunner(infer, chunker, config.n_obs_steps, hold[indices], synchronous=True)
    targets = hold.copy()
    offset = 0.0
    for k in range(round(seconds / task.robot.control_dt)):
        observation = {STATE: obs.motor_pos[indices].astype(np.float32)}
        if k % chunker.substeps == 0:  # the runner keeps only the observations at the policy rate
            image = task.head_image() if config.uses_images or video is not None else None
            if config.uses_images:
                observation[IMAGE] = channel_first(image)
            if video is not None:
                video.add(image)
        targets[indices] = runner.step(observation)
        offset = max(offset, float(np.abs(targets[indices] - hold[indices]).max()))
        obs = task.step(targets)
        if task.succeeded:
            break
    runner.close()
    return EpisodeResult(seed, task.succeeded, float(obs.time), runner.status.chunks_used, offset)


def evaluate(checkpoint: str | Path, episodes: int, seed: int, seconds: float | None = None,
             task: PickTask | str = "pick", video_path: str | Path | None = None,
             on_episode: Callable[[EpisodeResult], None] | None = None, device: str = "cpu") -> EvalResult:
    """Success rate of ``checkpoint`` on ``task`` (a task or its name) over seeds ``seed .. seed + episodes - 1``,
    at most ``seconds`` each (default: the task's `episode_seconds`); the network runs on ``device`` (``cpu`` or
    e.g. ``cuda``)."""
    if episodes < 1:
        raise EvalError(f"--episodes must be >= 1, got {episodes}")
    policy = load_policy(checkpoint).to(device)
    own_task = isinstance(task, str)
    task = make_task(task) if isinstance(task, str) else task
    seconds = task.episode_seconds if seconds is None else seconds
    check_fits(policy.config, task)
    infer = TimedInference(PolicyInference(policy, seed))
    result = EvalResult(task.name, str(checkpoint), seed)
    video = None
    if video_path is not None:
        from toddlerbot.tasks.video import SideBySideVideo

        video = SideBySideVideo(task, video_path, round(policy.config.policy_hz))
    try:
        for s in range(seed, seed + episodes):
            episode = run_episode(task, infer, policy.config, s, seconds, video)
            result.episodes.append(episode)
            if on_episode:
                on_episode(episode)
    except BaseException:
        if video is not None:
            video.abort()
        raise
    if video is not None:
        video.close()
    if own_task:
        task.camera.close()
    result.inference_seconds = infer.seconds
    return result
