"""Timings of the manipulation pipeline on this machine: one control step of the pick task (physics with the
actuator model, 20 substeps), one demonstrator step (DLS IK, gravity feed-forward), one 96x96 head-camera image
(render 160x120, resize, crop), one scripted episode without images, and writing + validating a LeRobot v3.0
dataset of recorded episodes.

Run: MUJOCO_GL=osmesa PYTHONPATH=src python benchmarks/bench_manip.py [--episodes 2]
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from toddlerbot.datasets.episode import resample
from toddlerbot.datasets.lerobot_reader import load_dataset
from toddlerbot.datasets.lerobot_writer import write_dataset
from toddlerbot.tasks.demonstrator import ScriptedPicker
from toddlerbot.tasks.pick import PickTask
from toddlerbot.tasks.record import DATASET_FPS, run_demo


def _per_call_ms(fn, n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - start) / n * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=2)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, python {platform.python_version()}")

    task = PickTask()
    demo = ScriptedPicker(task)
    obs = task.reset(0)
    demo.reset(obs, np.random.default_rng(0))
    step_ms = _per_call_ms(lambda: task.step(obs.motor_pos), 100)
    print(f"pick task control step (20 ms, 20 physics steps): {step_ms:.1f} ms")
    print(f"demonstrator step (IK + gravity feed-forward): {_per_call_ms(lambda: demo.act(obs), 100):.2f} ms")
    task.head_image()  # first call creates the GL context
    print(f"head-camera image 96x96: {_per_call_ms(task.head_image, 20):.1f} ms")

    start = time.perf_counter()
    raw = run_demo(task, demo, 0, render=False)
    print(f"scripted episode without images ({raw.duration:.1f} s simulated): {time.perf_counter() - start:.1f} s, "
          f"success {raw.success}")

    raws = [run_demo(task, demo, seed) for seed in range(args.episodes)]
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        root = write_dataset(Path(tmp) / "ds", [resample(r, DATASET_FPS) for r in raws], task.space.names,
                             DATASET_FPS, raw_episodes=raws)
        written = time.perf_counter() - start
        start = time.perf_counter()
        ds = load_dataset(root)
        loaded = time.perf_counter() - start
    print(f"dataset of {len(raws)} episodes ({len(ds)} frames at {DATASET_FPS} Hz): write {written:.2f} s, "
          f"validate + decode {loaded:.2f} s")


if __name__ == "__main__":
    main()
