"""Pick scene, arm IK, success rule, head-camera image and the scripted demonstrator."""

from __future__ import annotations

import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import GroundTruth, Robot
from toddlerbot.runtime.runner import run_policy
from toddlerbot.tasks.base import TaskRobot
from toddlerbot.tasks.camera import resize_and_crop
from toddlerbot.tasks.demonstrator import ScriptedPicker
from toddlerbot.tasks.ik import ArmIK, top_down_rotation
from toddlerbot.tasks.pick import PickTask, SuccessTracker
from toddlerbot.tasks.scenes import grasp_site, scene_model
from toddlerbot.tasks.space import follower_gains


@pytest.fixture(scope="module")
def task() -> PickTask:
    return PickTask()


def test_scenes_compile_only_for_the_gripper_variant():
    gripper = RobotDescription.load(variant="gripper")
    for scene in ("pick", "wagon"):
        model = scene_model(gripper, scene)
        assert model.nu == 32 and model.key("home").qpos.shape == (model.nq,)
    with pytest.raises(ValueError, match="needs the gripper variant"):
        scene_model(RobotDescription.load(), "pick")
    with pytest.raises(ToddlerbotError, match=r"^unknown task 'kitchen'; expected one of pick, wagon"):
        scene_model(gripper, "kitchen")  # refused, never defaulted to a scene


def test_torso_mount_holds_and_cube_rests_on_the_table(task):
    obs = task.reset(3)
    start = task.robot.base_pos
    for _ in range(25):
        obs = task.step(obs.motor_pos)
    assert np.linalg.norm(task.robot.base_pos - start) < 0.003
    assert task.cube_lift() < 0.002 and not task.pinched() and not task.succeeded


def test_cube_pose_is_randomised_per_seed_within_the_region(task):
    positions = []
    for seed in range(5):
        task.reset(seed)
        positions.append(task.cube_pose()[0][:2])
    positions = np.array(positions)
    cfg = task.config
    assert np.all((positions[:, 0] >= cfg.cube_x[0]) & (positions[:, 0] <= cfg.cube_x[1]))
    assert np.all((positions[:, 1] >= cfg.cube_y[0]) & (positions[:, 1] <= cfg.cube_y[1]))
    assert np.ptp(positions[:, 0]) > 0.005
    task.reset(1)
    again = task.cube_pose()[0][:2]
    np.testing.assert_allclose(again, positions[1])


def test_success_needs_one_second_of_continuous_lifted_pinch():
    tracker = SuccessTracker(hold_seconds=1.0)
    for _ in range(49):
        tracker.update(0.05, 0.03, True, 0.02)
    tracker.update(0.05, 0.03, False, 0.02)  # one dropped step restarts the clock
    assert tracker.held_for == 0.0 and not tracker.succeeded
    for _ in range(49):
        tracker.update(0.04, 0.03, True, 0.02)
    assert not tracker.succeeded
    tracker.update(0.04, 0.03, True, 0.02)
    assert tracker.succeeded
    low = SuccessTracker(1.0)
    for _ in range(100):
        low.update(0.02, 0.03, True, 0.02)
    assert not low.succeeded


def test_follower_gains_scale_the_upper_body_only():
    d = RobotDescription.load(variant="gripper")
    kp = follower_gains(d, 0.5)
    arm, leg, grip = d.groups["arm"], d.groups["leg"], d.groups["gripper"]
    np.testing.assert_array_equal(kp[arm], np.round(d.default_kp[arm] * 0.5))
    np.testing.assert_array_equal(kp[leg], d.default_kp[leg])
    np.testing.assert_array_equal(kp[grip], d.default_kp[grip])


def test_ik_jacobian_matches_finite_differences_and_reaches_a_pose(task):
    ik = ArmIK(task.description, task.model, "right", site=grasp_site("right"))
    base = task.model.key("home").qpos
    q0 = task.home_pose()
    pos0, _ = ik.forward(q0, base)
    target = np.array([0.11, -0.1, 0.3])
    rotation = top_down_rotation(np.array([0.0, 1.0]))
    q = q0
    for _ in range(6):
        q, err = ik.solve(q, target, rotation, base)
    pos, rot = ik.forward(q, base)
    assert err < 1e-3 and np.linalg.norm(pos - target) < 1e-3
    assert np.degrees(np.arccos((np.trace(rot.T @ rotation) - 1) / 2)) < 1.0
    changed = np.flatnonzero(q != q0)
    assert set(changed) <= set(ik.arm.tolist())  # only the right arm moved
    assert np.linalg.norm(pos0 - target) > 0.05


def test_resize_then_centre_crop_keeps_the_middle():
    frame = np.zeros((120, 160, 3), np.uint8)
    frame[:, 80:] = 200  # right half bright
    image = resize_and_crop(frame)
    assert image.shape == (96, 96, 3) and image.dtype == np.uint8
    # 160x120 -> 128x96, centre 96 columns: columns 16..112 of the resized frame, edge at 64 -> 48 in the crop
    assert image[:, :47].max() == 0 and image[:, 49:].min() == 200


def test_head_camera_sees_the_cube(task):
    task.reset(0)
    image = task.head_image()
    assert image.shape == (96, 96, 3)
    red = (image[..., 0] > 150) & (image[..., 1] < 80) & (image[..., 2] < 80)
    assert red.sum() > 20  # the red cube is in view when looking down at the table


def test_task_robot_is_the_task_through_the_robot_interface(task):
    robot = TaskRobot(task, 2)
    assert isinstance(robot, Robot) and isinstance(robot, GroundTruth) and robot.model is task.model
    obs = robot.reset()
    cube = task.cube_pose()[0]
    np.testing.assert_array_equal(obs.motor_pos, task.ready_pose)  # the arm ready...
    task.reset(2)
    np.testing.assert_array_equal(task.cube_pose()[0], cube)  # ...and the cube where seed 2 puts it
    assert robot.last_targets is None
    targets = task.ready_pose.copy()
    targets[task.gripper_motor] = 10.0  # beyond the drive's range: the simulator's guard clamps it
    robot.step(targets)
    np.testing.assert_array_equal(robot.last_targets, task.robot.last_targets)
    assert robot.last_targets[task.gripper_motor] == task.gripper_range()[1]
    np.testing.assert_array_equal(robot.default_kp, task.kp)  # the gains the task steps at
    np.testing.assert_array_equal(robot.base_pos, task.robot.base_pos)


@pytest.mark.parametrize(("steps", "image_steps"), [(7, [0, 3, 6]), (6, [0, 3])])
def test_demo_recorder_images_the_states_acted_on_every_third_step(task, steps, image_steps):
    from toddlerbot.policies.base import Action, Policy
    from toddlerbot.tasks.record import CAMERA_EVERY, DemoRecorder

    class Hold(Policy):  # the ready pose for `steps` steps
        def reset(self, obs):
            self.count = 0

        def act(self, obs, command):
            self.count += 1
            return Action(task.ready_pose, task.ready_pose, kp=task.kp)

        @property
        def done(self):
            return self.count >= steps

    recorder = DemoRecorder(task)
    run_policy(TaskRobot(task, 0), Hold(task.robot), seconds=1.0, observers=[recorder], stop_on_fall=False)
    episode = recorder.episode(0)
    dt = task.robot.control_dt
    assert CAMERA_EVERY == 3 and episode.state.shape == episode.action.shape == (steps, 16)
    np.testing.assert_allclose(episode.time, dt * np.arange(steps), atol=1e-9)
    np.testing.assert_allclose(episode.image_time, dt * np.array(image_steps), atol=1e-9)  # none after the last
    np.testing.assert_array_equal(episode.action[0], task.ready_pose[task.space.indices])
    assert episode.images.shape == (len(image_steps), 96, 96, 3) and not episode.success


@pytest.mark.slow
def test_scripted_demonstrator_lifts_and_holds_the_cube(task):
    demo = ScriptedPicker(task)
    for seed in (0, 1):
        run_policy(TaskRobot(task, seed), demo, seconds=demo.config.duration, stop_on_fall=False)
        assert task.succeeded, f"seed {seed}: max lift {task.tracker.max_lift:.3f} m"
        assert task.tracker.max_lift > 0.03


def test_wagon_handle_is_at_hand_height_and_the_wagon_rolls():
    import mujoco

    from toddlerbot.tasks.scenes import WAGON_BODY, WAGON_HANDLE_GEOM, WagonLayout

    model = scene_model(RobotDescription.load(variant="gripper"), "wagon")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    assert data.geom(WAGON_HANDLE_GEOM).xpos[2] == pytest.approx(WagonLayout().handle_height, abs=1e-6)
    wagon = model.body(WAGON_BODY).id
    start = data.xpos[wagon].copy()
    for _ in range(500):  # 0.5 s pushed forward with 1 N
        data.xfrc_applied[wagon, 0] = 1.0
        mujoco.mj_step(model, data)
    moved = data.xpos[wagon] - start
    assert moved[0] > 0.05 and abs(moved[1]) < 0.01


def test_side_by_side_video_encodes_every_frame(task, tmp_path):
    av = pytest.importorskip("av")
    from toddlerbot.tasks.video import SideBySideVideo

    task.reset(0)
    video = SideBySideVideo(task, tmp_path / "v.mp4", fps=10, keep={1})
    for _ in range(3):
        video.add(task.head_image())
    video.close()
    with av.open(str(tmp_path / "v.mp4")) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(frames) == 3 and frames[0].shape == (240, 560, 3)
    assert set(video.kept) == {1}
    assert list(tmp_path.iterdir()) == [tmp_path / "v.mp4"]  # no temporary file left behind
