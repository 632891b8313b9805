"""Closed-loop evaluation of a diffusion-policy checkpoint on a simulated task (``toddlerbot dp eval``).

An episode is a run of the checkpoint's runtime policy (`LiveDPPolicy`, in synchronous mode: the simulation does
not run in real time, so a worker's wall-clock latency would mean nothing) on the task's `TaskRobot` through
`run_policy`, whose reset is the task's reset for the seed: 50 Hz control, observations at the policy rate
(10 Hz), each one the follower's arm and gripper motor angles and the head camera's 96x96 image, made as the
recorder makes a dataset row (the checkpoint's motor names, which `check_fits` holds to the task's
`ManipulationSpace`; `HeadCamera.image`). The policy drives the dataset's motors (arms and grippers) at the
task's gains; every other motor holds the task's start pose. `EpisodeOutcome` stops the run on the task's own
success (`PickTask.succeeded`; the wagon task's is the wagon chain's ``grasped`` check); `PolicyTickVideo`
writes the optional video.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from toddlerbot.dp.checkpoint import load_policy
from toddlerbot.dp.config import DPConfig
from toddlerbot.dp.inference import PolicyInference
from toddlerbot.dp.live import LiveDPPolicy
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.runtime.runner import RunObserver, Step, run_policy
from toddlerbot.tasks import make_task
from toddlerbot.tasks.base import Task, TaskRobot

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
    failure: str | None = None
    """What a failed episode ended in (`Task.failure_kind`); None on success."""


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
                "failed_seeds": [e.seed for e in self.episodes if not e.success],
                "failures": {str(e.seed): e.failure for e in self.episodes if not e.success}}


def check_fits(config: DPConfig, task: Task) -> None:
    """The checkpoint's state and action must be the task's arm and gripper motors, in the same order."""
    names = task.space.names
    if (config.state_dim, config.action_dim) != (len(names), len(names)):
        raise EvalError(f"checkpoint has state {config.state_dim} / action {config.action_dim} dimensions; task "
                        f"{task.name!r} records {len(names)} motors")
    for kind, got in (("state", config.state_names), ("action", config.action_names)):
        if got and tuple(got) != names:
            raise EvalError(f"checkpoint {kind} names {list(got)} differ from task {task.name!r}'s {list(names)}")


class EpisodeOutcome(RunObserver):
    """Stops the run once the task has succeeded; keeps the simulated time at the end and how far the policy's
    targets for the recorded motors moved from the task's start pose."""

    def __init__(self, task: Task) -> None:
        self.task = task
        self.indices = task.space.indices
        self.start = task.ready_pose[self.indices]
        self.sim_seconds = 0.0
        self.max_target_offset = 0.0

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self.sim_seconds = obs.time

    def on_step(self, step: Step) -> None:
        offset = float(np.abs(step.action.motor_targets[self.indices] - self.start).max())
        self.max_target_offset = max(self.max_target_offset, offset)
        self.sim_seconds = step.next_obs.time

    @property
    def stop_requested(self) -> bool:
        return self.task.succeeded


class PolicyTickVideo(RunObserver):
    """Side-by-side video frames of the states the policy's ticks saw (the first step and every ``every``-th
    after); none after the run's last step: the run ends after ``steps`` steps or once the task has succeeded."""

    def __init__(self, task: Task, video: SideBySideVideo, every: int, steps: int) -> None:
        self.task, self.video, self.every, self.steps = task, video, every, steps

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self.video.add(self.task.head_image())

    def on_step(self, step: Step) -> None:
        following = step.index + 1
        if following % self.every == 0 and following < self.steps and not self.task.succeeded:
            self.video.add(self.task.head_image())


def run_episode(task: Task, robot: TaskRobot, policy: LiveDPPolicy, seed: int, seconds: float,
                video: SideBySideVideo | None = None) -> EpisodeResult:
    """One closed-loop episode from the task's start for ``seed`` (``robot`` is the task's, the one ``policy``
    drives), at most ``seconds`` (simulated); stops early once the task has succeeded."""
    robot.seed = seed
    outcome = EpisodeOutcome(task)
    observers: list[RunObserver] = [outcome]
    if video is not None:
        steps = round(seconds / robot.control_dt)
        observers.append(PolicyTickVideo(task, video, policy.chunker.substeps, steps))
    # a robot that tips over (the wagon task stands on the floor) is a failed episode, run to its end as before
    run_policy(robot, policy, seconds=seconds, observers=observers, stop_on_fall=False)
    return EpisodeResult(seed, task.succeeded, float(outcome.sim_seconds), policy.status.chunks_used,
                         outcome.max_target_offset, None if task.succeeded else task.failure_kind())


def evaluate(checkpoint: str | Path, episodes: int, seed: int, seconds: float | None = None,
             task: Task | str = "pick", video_path: str | Path | None = None,
             on_episode: Callable[[EpisodeResult], None] | None = None, device: str = "cpu") -> EvalResult:
    """Success rate of ``checkpoint`` on ``task`` (a task or its name) over seeds ``seed .. seed + episodes - 1``,
    at most ``seconds`` each (default: the task's `episode_seconds`); the network runs on ``device`` (``cpu`` or
    e.g. ``cuda``)."""
    if episodes < 1:
        raise EvalError(f"--episodes must be >= 1, got {episodes}")
    network = load_policy(checkpoint).to(device)
    own_task = isinstance(task, str)
    task = make_task(task) if isinstance(task, str) else task
    seconds = task.episode_seconds if seconds is None else seconds
    check_fits(network.config, task)
    robot = TaskRobot(task, seed)
    policy = LiveDPPolicy(robot, PolicyInference(network, seed), network.config, task.head_image, str(checkpoint),
                          synchronous=True, kp=task.kp)
    result = EvalResult(task.name, str(checkpoint), seed)
    video = None
    if video_path is not None:
        from toddlerbot.tasks.video import SideBySideVideo

        video = SideBySideVideo(task, video_path, round(network.config.policy_hz))
    try:
        for s in range(seed, seed + episodes):
            episode = run_episode(task, robot, policy, s, seconds, video)
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
    result.inference_seconds = policy.inference_seconds
    return result
