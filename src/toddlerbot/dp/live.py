"""The diffusion policy in the runtime: a checkpoint as a `Policy` the runner calls at the control rate.

Per control step `act` reads the policy's state motors from ``obs.motor_pos``; on every policy tick (each
``substeps``-th step, 10 Hz) it also takes the camera's latest 96x96 image. `ChunkPolicyRunner` turns these into
targets for the policy's action motors without waiting for the model: in real-time use inference runs on its
worker thread (``synchronous=False``) and the loop keeps its period whatever the model costs. Every other motor
holds the pose the robot started in (the reset's targets). Until a chunk is usable - at the start, after a failed
or non-finite inference, while inference is late, or while the camera delivers no current frame - the last
targets are held. Targets go out at the follower gains the demonstrations were recorded with, and through
`Robot.step`, whose CommandGuard clamps them.

The camera check rides in the observation history (``camera_fresh``): an inference asked for while any image of
the history is missing fails like any other (counted, held), so a stalled camera stops the arm instead of
feeding the model a frozen or blank picture. torch is imported only by `load_live_policy` (the ``[dp]`` extra).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.dp import require_torch
from toddlerbot.dp.chunker import ActionChunker
from toddlerbot.dp.config import DPConfig
from toddlerbot.dp.data import channel_first
from toddlerbot.dp.policy import IMAGE, STATE
from toddlerbot.dp.runner import ChunkPolicyRunner, Infer
from toddlerbot.dp.shipped import shipped_checkpoint
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.tasks.space import follower_gains
from toddlerbot.tasks.video_camera import VideoCamera

CAMERA_FRESH = "camera_fresh"
"""Observation key: whether this tick's image is a current camera frame."""

Camera = Callable[[], np.ndarray | None]
"""Latest (H, W, 3) uint8 policy image, or None when the camera has no current frame."""


class LivePolicyError(ToddlerbotError):
    """A checkpoint does not fit this robot, or a camera it needs is missing."""


def motor_indices(names: Sequence[str], robot: Robot, kind: str, source: str) -> np.ndarray:
    """Indices of ``names`` among the robot's motors; one line naming the missing ones otherwise."""
    missing = [n for n in names if n not in robot.motor_names]
    if missing:
        variant = robot.description.spec.variant or "default"
        raise LivePolicyError(f"{source}: {kind} name(s) {', '.join(missing)} are not motors of this robot (variant "
                              f"{variant}); a gripper policy needs --variant gripper")
    return np.array([robot.motor_names.index(n) for n in names], dtype=int)


@dataclass(frozen=True)
class LiveStatus:
    chunks_used: int
    holding_steps: int
    """Control steps whose targets were held (no usable chunk)."""
    failures: int
    """Inferences that raised, returned non-finite values or were refused for want of a camera frame."""
    stale_dropped: int
    camera_misses: int
    """Policy ticks without a current camera frame."""
    inference_ms: float
    """Mean wall time of one inference, ms (NaN before the first)."""
    last_error: str | None
    camera_stopped: str | None = None
    """How a camera the policy opened stopped (``after N frames (error)``), None while it delivers."""

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in self.__dict__.items()}

    def describe(self) -> str:
        """One line for people."""
        ms = "-" if self.inference_ms != self.inference_ms else f"{self.inference_ms:.1f} ms"
        line = (f"dp: {self.chunks_used} chunks used, {self.holding_steps} steps held, {self.failures} failed "
                f"inferences, {self.stale_dropped} stale chunks, {self.camera_misses} camera misses, inference {ms}")
        line = line if self.last_error is None else f"{line}; last error: {self.last_error}"
        return line if self.camera_stopped is None else f"{line}; camera stopped {self.camera_stopped}"


class _TimedInfer:
    """The model behind the runner: refuses a history with a missing camera frame, times every call."""

    def __init__(self, infer: Infer) -> None:
        self.infer = infer
        self.seconds: list[float] = []

    def __call__(self, history: dict[str, np.ndarray]) -> np.ndarray:
        if CAMERA_FRESH in history and not history[CAMERA_FRESH].all():
            raise RuntimeError("no current camera frame")
        start = time.perf_counter()
        chunk = self.infer(history)
        self.seconds.append(time.perf_counter() - start)
        return chunk


class LiveDPPolicy(Policy):
    """``infer`` maps an observation history to an action chunk (a `PolicyInference`, or a stand-in in tests)."""

    name = "dp"

    def __init__(self, robot: Robot, infer: Infer, config: DPConfig, camera: Camera | None,
                 source: str = "checkpoint", synchronous: bool = False, kp: np.ndarray | None = None) -> None:
        super().__init__(robot)
        if config.uses_images and camera is None:
            raise LivePolicyError(f"{source}: the policy sees the head camera; give it a camera (--camera)")
        self.config = config
        self.state_indices = motor_indices(config.state_names, robot, "state", source)
        self.action_indices = motor_indices(config.action_names, robot, "action", source)
        if len(self.state_indices) != config.state_dim or len(self.action_indices) != config.action_dim:
            raise LivePolicyError(f"{source}: the checkpoint names {len(self.state_indices)} state and "
                                  f"{len(self.action_indices)} action motors for {config.state_dim}/"
                                  f"{config.action_dim} dimensions (trained without joint names?)")
        self.camera = camera if config.uses_images else None
        self.synchronous = synchronous
        self.kp = follower_gains(robot.description) if kp is None else kp
        self.chunker = ActionChunker(config.latency_drop, config.n_action_steps, 1.0 / config.policy_hz,
                                     robot.control_dt)
        self._infer = _TimedInfer(infer)
        self._blank = np.zeros((3, config.image_size, config.image_size), np.uint8)
        self.runner: ChunkPolicyRunner | None = None
        self.owned_camera: VideoCamera | None = None
        """A camera `dp_policy` opened for this policy (closed with it)."""

    def reset(self, obs: Observation) -> None:
        self._stop_worker()
        start = self.robot.last_targets
        self.hold = np.array(obs.motor_pos if start is None else start, dtype=float)
        self.runner = ChunkPolicyRunner(self._infer, self.chunker, self.config.n_obs_steps,
                                        self.hold[self.action_indices], synchronous=self.synchronous)
        self._step = 0
        self._holding_steps = 0
        self._camera_misses = 0

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        observation = {STATE: obs.motor_pos[self.state_indices].astype(np.float32)}
        if self.camera is not None and self._step % self.chunker.substeps == 0:  # images only at the policy rate
            image = self.camera()
            fresh = image is not None
            observation[IMAGE] = channel_first(image) if fresh else self._blank
            observation[CAMERA_FRESH] = np.array(fresh)
            self._camera_misses += not fresh
        targets = self.hold.copy()
        targets[self.action_indices] = self.runner.step(observation)
        self._holding_steps += self.runner.status.holding
        self._step += 1
        return Action(targets, self.transmission.motor_to_joint(targets), kp=self.kp)

    @property
    def inference_seconds(self) -> list[float]:
        """Wall time of every inference since the policy was made (over all its runs), s."""
        return list(self._infer.seconds)  # a copy: the worker appends while we read

    @property
    def status(self) -> LiveStatus:
        s = self.runner.status
        seconds = self.inference_seconds
        video = self.owned_camera
        stopped = None if video is None or not video.error else f"after {video.frames} frames ({video.error})"
        return LiveStatus(s.chunks_used, self._holding_steps, s.failures, s.stale_dropped, self._camera_misses,
                          1e3 * float(np.mean(seconds)) if seconds else float("nan"), s.last_error, stopped)

    def close(self) -> None:
        """Stop the inference worker and a camera the policy opened."""
        self._stop_worker()
        if self.owned_camera is not None:
            self.owned_camera.close()

    def _stop_worker(self) -> None:
        if self.runner is not None:
            self.runner.close()


def load_live_policy(robot: Robot, checkpoint: str | Path, camera: Camera | None, synchronous: bool = False,
                     seed: int = 0, kp: np.ndarray | None = None) -> LiveDPPolicy:
    """A checkpoint (`dp train`/`dp export`) as a runtime policy on ``robot``, at firmware gains ``kp`` (default:
    the follower gains); needs torch (the ``[dp]`` extra)."""
    require_torch()
    from toddlerbot.dp.inference import PolicyInference

    inference = PolicyInference.from_checkpoint(checkpoint, seed)
    return LiveDPPolicy(robot, inference, inference.policy.config, camera, str(checkpoint), synchronous, kp)


def dp_policy(robot: Robot, checkpoint: str | Path | None = None, camera: Camera | str | None = None,
              threads: int | None = None, synchronous: bool = False, task: str | None = None) -> LiveDPPolicy:
    """The registered ``dp`` policy (`sim run`, `hw run --policy dp`): ``checkpoint`` (default: the one shipped
    for ``task``), images from ``camera`` (a function returning the latest image, e.g. a task's head camera, or a
    V4L2 device or video file, opened here and closed with the policy), torch on ``threads`` CPU threads (1 by
    default), inference inline when ``synchronous`` (a simulation not run in real time) else on a worker thread.
    Everything is checked before the robot moves."""
    if checkpoint is None:
        if task is None:
            raise LivePolicyError("--policy dp needs --checkpoint (a checkpoint from `dp train` or `dp export`)")
        checkpoint = shipped_checkpoint(task)
    require_torch(threads or 1)
    video = VideoCamera(camera) if isinstance(camera, str) else None
    try:
        policy = load_live_policy(robot, checkpoint, video if video is not None else camera, synchronous)
    except BaseException:
        if video is not None:
            video.close()
        raise
    policy.owned_camera = video
    return policy
