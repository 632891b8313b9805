"""`--policy dp` for `sim run` and `hw run`: a diffusion-policy checkpoint, its camera, and what to report."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.dp import require_torch
from toddlerbot.errors import ToddlerbotError

SIM_DP_TASKS = ("pick",)
"""Tasks `sim run --policy dp` runs (the wagon grasp runs closed-loop in `dp eval --task wagon` and in
`chain run wagon`)."""


def sim_dp_policy(description, task: str, checkpoint: Path | None, seed: int, realtime: bool, control_dt: float,
                  threads: int):
    """(robot, policy, progress) for `sim run --policy dp`: the task's scene reset for ``seed``, the simulated head
    camera, and inference on the worker thread when the loop runs in real time (inline otherwise: a simulation
    that runs faster or slower than the clock makes a worker's latency meaningless)."""
    from toddlerbot.dp.live import load_live_policy
    from toddlerbot.dp.shipped import shipped_checkpoint
    from toddlerbot.tasks.pick import PickConfig, PickProgress, PickTask, TaskRobot

    if task not in SIM_DP_TASKS:
        raise ToddlerbotError(f"--task {task!r}: expected one of {', '.join(SIM_DP_TASKS)}")
    require_torch(threads)
    pick = PickTask(description, PickConfig(control_dt=control_dt))
    robot = TaskRobot(pick, seed)
    policy = load_live_policy(robot, checkpoint or shipped_checkpoint(task), pick.head_image,
                              synchronous=not realtime)
    pick.reset(seed)
    return robot, policy, PickProgress(pick, pick.grasp_distance())


def hw_dp_policy(robot, checkpoint: Path | None, camera: str | None, threads: int):
    """(policy, camera or None) for `hw run --policy dp`: inference on the worker thread, images from a V4L2
    device or a video file. Both are checked before the bus opens."""
    from toddlerbot.dp.live import load_live_policy
    from toddlerbot.tasks.video_camera import VideoCamera

    if checkpoint is None:
        raise ToddlerbotError("--policy dp needs --checkpoint (a checkpoint from `dp train` or `dp export`)")
    require_torch(threads)
    source = None if camera is None else VideoCamera(camera)
    try:
        return load_live_policy(robot, checkpoint, source), source
    except BaseException:
        if source is not None:
            source.close()
        raise


def describe_status(status) -> str:
    """One line of a `LiveStatus`."""
    ms = "-" if status.inference_ms != status.inference_ms else f"{status.inference_ms:.1f} ms"
    line = (f"dp: {status.chunks_used} chunks used, {status.holding_steps} steps held, {status.failures} failed "
            f"inferences, {status.stale_dropped} stale chunks, {status.camera_misses} camera misses, inference {ms}")
    return line if status.last_error is None else f"{line}; last error: {status.last_error}"
