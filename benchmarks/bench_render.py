"""Offscreen rendering speed of the standing robot from the tracking camera (640x360, the `sim run --video` size):
the model's own render settings (4x multisampling, 4096-pixel shadow map) versus the settings `Recorder` uses on
OSMesa (`toddlerbot.sim.render.SOFTWARE_QUALITY`), the visual geometry versus the collision primitives it replaced
in scene renders, the H.264 encoding of the frames, and the cost of the visual geometry when compiling the model.

Run: PYTHONPATH=src python benchmarks/bench_render.py   (needs OSMesa or EGL)
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from unittest import mock

import mujoco

from toddlerbot.robot.builder import compile_robot
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim import render
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

FRAMES = 20
COMPILES = 10


def _ms_per_frame(robot: MuJoCoRobot, quality: dict[str, int], visuals: bool = True) -> tuple[float, render.Recorder]:
    with mock.patch.dict(render.SOFTWARE_QUALITY, quality):
        recorder = render.Recorder(robot.model, robot.data, visuals=visuals)
    recorder.capture()  # the first frame also compiles shaders
    start = time.perf_counter()
    for _ in range(FRAMES):
        mujoco.mj_step(robot.model, robot.data, nstep=33)  # one frame at 30 fps
        recorder.capture()
    return (time.perf_counter() - start) / FRAMES * 1e3, recorder


def _compile_ms(description: RobotDescription, visuals: bool) -> float:
    times = []
    for _ in range(COMPILES):
        start = time.perf_counter()
        compile_robot(description.spec, "floating", True, description.catalogue, description.transmission, visuals)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def main() -> None:
    robot = MuJoCoRobot()
    robot.reset()
    backend = render.configure_gl()
    model_quality = {"offsamples": robot.model.vis.quality.offsamples, "shadowsize": robot.model.vis.quality.shadowsize}
    full, recorder = _ms_per_frame(robot, model_quality)
    recorder.close()
    primitives, recorder = _ms_per_frame(robot, dict(render.SOFTWARE_QUALITY), visuals=False)
    recorder.close()
    fast, recorder = _ms_per_frame(robot, dict(render.SOFTWARE_QUALITY))
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        recorder.write_video(Path(folder) / "clip.mp4", fps=30.0)
        encode = (time.perf_counter() - start) / len(recorder.frames) * 1e3
    recorder.close()
    print(f"MUJOCO_GL={backend}, 640x360, {FRAMES} frames, visual geometry unless said")
    print(f"model settings {model_quality}: {full:7.1f} ms/frame")
    if backend == "osmesa":
        print(f"OSMesa settings {render.SOFTWARE_QUALITY}: {fast:7.1f} ms/frame")
    print(f"the same, collision primitives (before the visual geometry): {primitives:7.1f} ms/frame")
    print(f"H.264 encoding: {encode:7.1f} ms/frame")
    description = robot.description
    without, with_visuals = _compile_ms(description, False), _compile_ms(description, True)
    print(f"compile the floating model with scene (median of {COMPILES}): {without:.1f} ms without visuals, "
          f"{with_visuals:.1f} ms with")


if __name__ == "__main__":
    main()
