"""The diffusion policy in the runtime: a 50 Hz loop that never waits for the model, holds on failures and missing
camera frames, a PyAV camera that gives the dataset's image, and `sim run --policy dp` on the pick task."""

from __future__ import annotations

import json
import time

import av
import numpy as np
import pytest
from typer.testing import CliRunner

from dp_live_support import CONFIG, GRIPPER, SPACE, InstantRobot, write_video
from toddlerbot.cli.main import app
from toddlerbot.dp.chunker import ActionChunker
from toddlerbot.dp.data import channel_first
from toddlerbot.dp.live import LiveDPPolicy, LivePolicyError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import WallClock, run_policy
from toddlerbot.tasks.camera import resize_and_crop
from toddlerbot.tasks.video_camera import CameraError, VideoCamera

HOME = GRIPPER.home_motor_pos[SPACE.indices]
IMAGE = np.full((96, 96, 3), 128, np.uint8)
STILL = CommandSchedule.parse("0:0,0,0")
PLAN = ActionChunker().plan
LOW, HIGH = GRIPPER.motor_range.T


def chunk(n: int) -> np.ndarray:
    """The n-th distinct chunk: every motor ramps from home by up to 0.2 rad, n * 0.01 rad apart."""
    return HOME + (0.2 * np.linspace(0.0, 1.0, 16) + 0.01 * n)[:, None]


def policy_targets(robot: InstantRobot) -> np.ndarray:
    return np.array(robot.sent)[:, SPACE.indices]


def test_slow_inference_runs_on_the_worker_and_the_50_hz_loop_keeps_its_period():
    robot = InstantRobot()
    calls = []

    def slow_infer(history):
        time.sleep(0.15)  # 7.5 control periods
        calls.append(history)
        return chunk(len(calls))

    policy = LiveDPPolicy(robot, slow_infer, CONFIG, camera=lambda: IMAGE)
    start = time.perf_counter()
    result = run_policy(robot, policy, STILL, 2.0, clock=WallClock())
    wall = time.perf_counter() - start
    policy.close()
    targets = policy_targets(robot)
    assert len(targets) == 100 and 1.95 < wall < 2.3  # 100 targets in 2 s: about 50 per second
    assert 100 / wall > 43
    # no step waited for the model (one that did would take >= 150 ms); the loop kept its 20 ms period
    assert result.log.compute_time.max() < 0.05
    assert abs(np.median(result.log.step_period) - 0.02) < 0.002
    # held at the start pose for the 3 dropped policy steps, then each chunk from its own tick, seamlessly
    np.testing.assert_array_equal(targets[:15], np.tile(HOME, (15, 1)))
    np.testing.assert_allclose(targets[15:40], PLAN(chunk(1)))
    np.testing.assert_allclose(targets[40:65], PLAN(chunk(2)))
    status = policy.status
    assert status.holding_steps == 15 and status.failures == 0 and status.chunks_used >= 3
    assert 150 <= status.inference_ms < 300
    # every other motor held its start pose; the model saw the 10 Hz history with the camera's image
    others = np.setdiff1d(np.arange(GRIPPER.n_motors), SPACE.indices)
    np.testing.assert_array_equal(np.array(robot.sent)[:, others], np.tile(GRIPPER.home_motor_pos[others], (100, 1)))
    assert calls[0]["observation.images.head"].shape == (2, 3, 96, 96)
    np.testing.assert_array_equal(calls[0]["observation.images.head"][-1], channel_first(IMAGE))


def test_failed_nan_and_out_of_range_inferences_hold_or_clamp_and_the_run_goes_on():
    robot = InstantRobot()
    calls = []

    def flaky_infer(history):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("model crashed")
        if len(calls) == 3:
            return chunk(1) * np.nan
        if len(calls) == 4:
            return chunk(1) + 10.0  # far beyond every motor's range
        return chunk(1)

    policy = LiveDPPolicy(robot, flaky_infer, CONFIG, camera=lambda: IMAGE, synchronous=True)
    result = run_policy(robot, policy, STILL, 2.0)
    targets = policy_targets(robot)
    assert result.completed and len(robot.sent) == 100
    assert policy.status.failures == 2 and "non-finite" in policy.status.last_error
    np.testing.assert_allclose(targets[15:40], PLAN(chunk(1)))
    # the requests at steps 25 and 30 failed: after the plan's end (step 40) its last target is held
    np.testing.assert_allclose(targets[40:50], np.tile(PLAN(chunk(1))[-1], (10, 1)))
    # the out-of-range chunk (asked for at step 35) is clamped into range by the robot's guard
    lo, hi = LOW[SPACE.indices], HIGH[SPACE.indices]
    np.testing.assert_allclose(targets[50:75], np.clip(PLAN(chunk(1) + 10.0), lo, hi))
    np.testing.assert_allclose(targets[75:100], PLAN(chunk(1)))
    sent = np.array(robot.sent)
    assert np.isfinite(sent).all() and np.all(sent >= LOW) and np.all(sent <= HIGH)


def test_a_camera_without_frames_makes_the_policy_hold_then_it_resumes():
    robot = InstantRobot()
    ticks = []

    def camera():  # fresh for the ticks at steps 0-10, none at 15-35, fresh again from step 40
        ticks.append(1)
        return None if 4 <= len(ticks) <= 8 else IMAGE

    policy = LiveDPPolicy(robot, lambda history: chunk(1), CONFIG, camera, synchronous=True)
    run_policy(robot, policy, STILL, 2.0)
    targets = policy_targets(robot)
    status = policy.status
    assert status.camera_misses == 5
    # the requests at steps 25, 30, 35 and 40 each had a missing frame in their history: refused, not crashed
    assert status.failures == 4 and status.last_error == "RuntimeError: no current camera frame"
    np.testing.assert_allclose(targets[40:60], np.tile(PLAN(chunk(1))[-1], (20, 1)))
    np.testing.assert_allclose(targets[60:85], PLAN(chunk(1)))  # asked for at step 45 with 2 fresh frames
    assert len(targets) == 100


def test_checkpoint_names_that_are_not_motors_of_this_robot_are_refused_in_one_line():
    robot = InstantRobot(RobotDescription.load())  # no grippers
    with pytest.raises(LivePolicyError) as refused:
        LiveDPPolicy(robot, lambda history: chunk(1), CONFIG, camera=lambda: IMAGE, source="pick.pt")
    message = str(refused.value)
    assert "pick.pt: state name(s) left_gripper_drive, right_gripper_drive are not motors" in message
    assert "--variant gripper" in message and "\n" not in message
    with pytest.raises(LivePolicyError, match=r"pick\.pt: the policy sees the head camera; give it a camera"):
        LiveDPPolicy(InstantRobot(), lambda history: chunk(1), CONFIG, camera=None, source="pick.pt")


def test_video_file_camera_gives_the_dataset_image_at_the_file_rate_then_goes_stale(tmp_path):
    path = write_video(tmp_path / "head.mp4", frames=10, fps=20)  # 0.5 s
    with av.open(str(path)) as container:
        expected = [resize_and_crop(f.to_ndarray(format="rgb24")) for f in container.decode(video=0)]
    seen = []
    start = time.perf_counter()
    with VideoCamera(str(path), max_age_s=0.1) as camera:
        while not camera.finished and time.perf_counter() - start < 5.0:
            image = camera()
            if image is not None and (not seen or not np.array_equal(image, seen[-1])):
                seen.append(image)
            time.sleep(0.005)
        elapsed = time.perf_counter() - start
        time.sleep(0.15)
        assert camera() is None  # the file ended: no current frame
    assert camera.frames == 10 and camera.error is None
    assert 0.4 < elapsed < 2.0  # played at its 20 fps, not decoded all at once
    assert len(seen) >= 5 and seen[0].shape == (96, 96, 3) and seen[0].dtype == np.uint8
    assert all(any(np.array_equal(image, e) for e in expected) for image in seen)  # exactly the dataset's path
    with pytest.raises(CameraError, match=r"camera .*missing\.mp4: cannot open"):
        VideoCamera(str(tmp_path / "missing.mp4"))


@pytest.mark.slow
def test_sim_run_dp_on_the_pick_task_moves_the_arm_to_the_cube(tmp_path):
    summary_file = tmp_path / "summary.json"
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "dp", "--task", "pick", "--seed", "1000",
                                      "--seconds", "2", "--summary-json", str(summary_file)])
    assert result.exit_code == 0, result.output
    summary = json.loads(summary_file.read_text())
    task, dp = summary["task"], summary["dp"]
    assert task["start_distance_m"] > 0.08  # the ready pose: 10 cm from the cube
    assert task["end_distance_m"] < 0.4 * task["start_distance_m"]  # measured 0.101 -> 0.019 m at 2 s
    # chunks asked for at steps 0, 25, 50 and 75, each used from 15 steps later
    assert dp["chunks_used"] == 4 and dp["failures"] == 0 and dp["holding_steps"] == 15
    assert summary["duration_s"] == pytest.approx(2.0, abs=0.03)


def test_dp_options_are_checked_before_anything_runs():
    runner = CliRunner()
    wrong_policy = runner.invoke(app, ["sim", "run", "--policy", "stand", "--checkpoint", "pick.pt"])
    assert str(wrong_policy.exception) == "--checkpoint is not an option of policy 'stand'"
    unknown_task = runner.invoke(app, ["sim", "run", "--policy", "dp", "--task", "fly"])
    assert str(unknown_task.exception) == "unknown task 'fly'; expected one of pick, wagon"
    unknown = runner.invoke(app, ["hw", "run", "--port", "/dev/null", "--calibration", "c.yaml", "--policy", "dpx"])
    assert str(unknown.exception) == ("unknown policy 'dpx'; expected one of stand, replay, walk-zmp, walk-rl, dp, "
                                      "get-up, track")
