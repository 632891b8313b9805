"""Rendering: frames show the robot, videos hold every captured frame, and a machine without the GL library still
simulates the README's main command and says how to enable the video."""

import copy
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.sim.render import missing_gl_library

needs_osmesa = pytest.mark.skipif(
    missing_gl_library("osmesa") is not None or os.environ.get("MUJOCO_GL", "osmesa") != "osmesa",
    reason="offscreen rendering tests need OSMesa (apt-get install libosmesa6; CI installs it)",
)

MISSING = {
    "osmesa": "MUJOCO_GL=osmesa needs libOSMesa, which cannot be loaded; to enable rendering, install OSMesa: "
              "sudo apt-get install libosmesa6",
    "egl": "MUJOCO_GL=egl needs libEGL, which cannot be loaded; to enable rendering, install EGL and a GPU driver "
           "(sudo apt-get install libegl1), or use MUJOCO_GL=osmesa with libosmesa6",
}
SRC = str(Path(__file__).resolve().parents[1] / "src")
# Makes every dlopen of OSMesa or EGL fail the way it does on a machine without them, then runs the CLI.
HIDE_GL_AND_RUN_CLI = """
import ctypes, runpy, sys
load = ctypes.CDLL.__init__
def refuse_gl(self, name, *args, **kwargs):
    if name and ("OSMesa" in str(name) or "EGL" in str(name)):
        raise OSError(f"{name}: cannot open shared object file: No such file or directory")
    load(self, name, *args, **kwargs)
ctypes.CDLL.__init__ = refuse_gl
sys.argv = ["toddlerbot", *sys.argv[1:]]
runpy.run_module("toddlerbot.cli.main", run_name="__main__")
"""


@pytest.mark.parametrize("mujoco_gl", [None, "osmesa", "egl"], ids=["MUJOCO_GL unset", "MUJOCO_GL=osmesa",
                                                                    "MUJOCO_GL=egl"])
def test_main_command_without_gl_library_simulates_and_says_how_to_enable_video(tmp_path, mujoco_gl):
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["PYTHONPATH"] = SRC
    if mujoco_gl:
        env["MUJOCO_GL"] = mujoco_gl
    video = tmp_path / "walk.mp4"
    proc = subprocess.run(
        [sys.executable, "-c", HIDE_GL_AND_RUN_CLI, "sim", "run", "--policy", "walk-zmp", "--command", "0:0.1,0,0",
         "--seconds", "1", "--video", str(video), "--summary-json", str(tmp_path / "s.json")],
        env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stdout.splitlines() if line.strip()]
    assert lines[0].startswith("walk-zmp 1.00 s: no fall; displacement")  # the summary comes first
    skipped = [line for line in lines if "skipped" in line]
    backend = mujoco_gl or ("egl" if Path("/dev/nvidia0").exists() else "osmesa")  # the default with a GPU is EGL
    assert skipped == [f"video {video} skipped: {MISSING[backend]}"]
    assert lines[-1] == skipped[0]
    assert not video.exists()
    assert (tmp_path / "s.json").read_text().count("displacement_m") == 1  # the run itself completed


@pytest.fixture(scope="module")
def standing_robot():
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot

    robot = MuJoCoRobot()
    robot.reset()
    return robot


@needs_osmesa
def test_a_frame_shows_the_robot_in_the_middle_of_the_image(standing_robot):
    from toddlerbot.sim.render import Recorder

    robot = standing_robot
    recorder = Recorder(robot.model, robot.data, "perspective", width=160, height=96)
    frame = recorder.capture()
    recorder.close()
    empty_model = copy.deepcopy(robot.model)
    empty_model.geom_rgba[empty_model.geom_bodyid > 0, 3] = 0.0  # everything but the floor invisible
    empty = Recorder(empty_model, robot.data, "perspective", width=160, height=96)
    background = empty.capture()
    empty.close()
    assert frame.shape == (96, 160, 3) and frame.dtype == np.uint8
    changed = np.abs(frame.astype(int) - background.astype(int)).max(axis=2) > 30
    # measured: 7.6 % of the pixels at 160x90 (the robot standing, perspective camera tracking it)
    assert 0.03 < changed.mean() < 0.3
    rows, cols = np.nonzero(changed)
    assert 0.25 < rows.mean() / 96 < 0.75 and 0.25 < cols.mean() / 160 < 0.75  # the camera tracks the robot


@needs_osmesa
def test_software_render_settings_look_like_the_models_and_leave_it_unchanged(standing_robot):
    from unittest import mock

    from toddlerbot.sim import render

    robot = standing_robot
    quality = robot.model.vis.quality
    before = (quality.offsamples, quality.shadowsize)
    fast = render.Recorder(robot.model, robot.data, "perspective", width=320, height=180)
    assert (quality.offsamples, quality.shadowsize) == before == (4, 4096)  # the model is not changed
    with mock.patch.dict(render.SOFTWARE_QUALITY, {"offsamples": 4, "shadowsize": 4096}):
        full = render.Recorder(robot.model, robot.data, "perspective", width=320, height=180)
    difference = np.abs(fast.capture().astype(float) - full.capture().astype(float))
    fast.close()
    full.close()
    # no multisampling and a 4x smaller shadow map: edges alias slightly (so the frames differ), nothing else
    # measured: 0.22 levels on average, 0.1 % of the pixels off by more than 60
    assert 0.0 < difference.mean() < 1.0 and np.mean(difference.max(axis=2) > 60) < 0.01


@needs_osmesa
def test_video_holds_every_captured_frame(standing_robot, tmp_path):
    import imageio.v2 as imageio
    import mujoco

    from toddlerbot.sim.render import Recorder

    robot = standing_robot
    data = copy.deepcopy(robot.data)
    recorder = Recorder(robot.model, data, "side", width=160, height=96)
    for _ in range(12):
        mujoco.mj_step(robot.model, data, nstep=20)
        recorder.capture()
    path = recorder.write_video(tmp_path / "clip.mp4", fps=30.0)
    recorder.close()
    reader = imageio.get_reader(path)
    decoded = np.array([frame for frame in reader])
    assert reader.get_meta_data()["fps"] == pytest.approx(30.0)
    reader.close()
    assert decoded.shape == (12, 96, 160, 3)
    # H.264 is lossy: each decoded frame is close to the frame captured at that index
    error = np.abs(decoded.astype(float) - np.array(recorder.frames, dtype=float)).mean(axis=(1, 2, 3))
    assert np.all(error < 4.0), error


def _orange(frame: np.ndarray) -> np.ndarray:
    """Pixels in the collision primitives' orange (any shade)."""
    r, g, b = (frame[..., i].astype(int) for i in range(3))
    return (r > 60) & (r > 1.3 * g) & (g > 1.3 * b)


@needs_osmesa
def test_scene_renders_draw_white_links_and_black_motors_instead_of_orange_primitives(standing_robot):
    from toddlerbot.sim.render import Recorder

    robot = standing_robot
    empty_model = copy.deepcopy(robot.model)
    empty_model.geom_rgba[empty_model.geom_bodyid > 0, 3] = 0.0  # only the floor and the sky
    frames = {}
    for name, model, visuals in (("drawn", robot.model, True), ("primitives", robot.model, False),
                                 ("background", empty_model, True)):
        recorder = Recorder(model, robot.data, "front", width=160, height=120, visuals=visuals)
        frames[name] = recorder.capture().astype(int)
        recorder.close()
    robot_pixels = np.abs(frames["drawn"] - frames["background"]).max(axis=2) > 30
    brightness = frames["drawn"].sum(axis=2) / 3
    # measured: no orange pixel with visuals, 7.5 % of the frame without; of the robot's pixels 50 % are white
    # (printed links) and 22 % black (motors)
    assert _orange(frames["drawn"]).sum() == 0 and _orange(frames["primitives"]).mean() > 0.05
    assert (brightness[robot_pixels] > 180).mean() > 0.3 and (brightness[robot_pixels] < 40).mean() > 0.1


@needs_osmesa
def test_head_camera_image_is_pixel_identical_to_the_model_without_visuals():
    """The diffusion policies were trained on head images of the collision primitives: the visual geometry must
    not change one pixel of them (pick scene, after the task's reset and 0.5 s of holding its ready pose)."""
    pytest.importorskip("PIL")
    from unittest import mock

    from toddlerbot.robot import builder
    from toddlerbot.tasks.pick import PickTask

    def head_images(task: PickTask) -> tuple[np.ndarray, np.ndarray]:
        task.reset(3)
        images = [task.head_image()]
        for _ in range(25):
            task.step(task.ready_pose)
        images.append(task.head_image())
        task.camera.close()
        return np.array(images), task.robot.data.qpos.copy()

    with_visuals, qpos = head_images(PickTask())
    # the model as it was built before visual geometry existed: no visual geoms, primitives in group 0
    with mock.patch.object(builder, "_add_visuals", lambda *args: None), \
            mock.patch.object(builder, "COLLISION_GROUP", 0):
        before, qpos_before = head_images(PickTask())
    assert np.array_equal(qpos, qpos_before)
    assert np.array_equal(with_visuals, before)
    red = (before[..., 0] > 150) & (before[..., 1] < 80) & (before[..., 2] < 80)
    assert red[0].sum() > 20  # the images show the cube (not an empty frame)


@needs_osmesa
def test_model_render_writes_the_robot_seen_from_each_camera_side_by_side(tmp_path):
    import imageio.v2 as imageio
    from typer.testing import CliRunner

    from toddlerbot.cli.main import app

    images = {}
    for shapes in ("visual", "collision"):
        path = tmp_path / f"{shapes}.png"
        result = CliRunner().invoke(app, ["model", "render", "-o", str(path), "--shapes", shapes, "--camera", "front",
                                          "--camera", "side", "--width", "120", "--height", "90"])
        assert result.exit_code == 0, result.output
        images[shapes] = imageio.imread(path)
    assert images["visual"].shape == (90, 240, 3)
    # the README's before/after pair: orange primitives before, none after (measured: 6.9 % and 0)
    assert _orange(images["visual"]).sum() == 0 and _orange(images["collision"]).mean() > 0.02
