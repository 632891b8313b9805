"""The wagon scene's declared ranges (`skills.wagon.WagonRanges`, named in `VARIATIONS`): each seed draws the
wagon's shift, the handle's height, the arms' start pose and the light level, alike for the task and the chain; in
the ``wide`` variation a share of the task's episodes starts where a chain's re-grasp does, and the scripted grasp
grasps from there without dragging the handle. The ``default`` variation is the scene the shipped policy was
measured in."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.skills.wagon import VARIATIONS, WagonTask, draw_scene
from toddlerbot.tasks import make_task
from toddlerbot.tasks.base import StartPerturbation
from toddlerbot.tasks.scenes import WAGON_HANDLE_GEOM, grasp_site

WIDE = VARIATIONS["wide"]


@pytest.fixture(scope="module")
def task():
    return make_task("wagon:wide")


def _handle(model, data):
    return data.geom_xpos[model.geom(WAGON_HANDLE_GEOM).id].copy()


def test_each_seed_draws_every_range_within_its_bounds_and_the_same_seed_draws_the_same(task):
    assert task.variation == "wide" and task.ranges == WIDE
    scenes = [draw_scene(np.random.default_rng(seed), task.description, WIDE) for seed in range(400)]
    shifts = np.array([s.shift for s in scenes])
    assert shifts[:, 0].min() >= WIDE.wagon_x[0] and shifts[:, 0].max() <= WIDE.wagon_x[1]
    assert shifts[:, 1].min() >= WIDE.wagon_y[0] and shifts[:, 1].max() <= WIDE.wagon_y[1]
    heights = np.array([s.handle_height for s in scenes])
    assert heights.min() >= WIDE.handle_height[0] and heights.max() <= WIDE.handle_height[1]
    assert np.ptp(heights) > 0.9 * (WIDE.handle_height[1] - WIDE.handle_height[0])  # used, not a point
    lights = np.array([s.light for s in scenes])
    assert lights.min() >= WIDE.light[0] and lights.max() <= WIDE.light[1]
    offsets = np.array([s.arm_offset for s in scenes])
    arms = task.description.groups["arm"]
    others = np.setdiff1d(np.arange(task.description.n_motors), arms)
    assert np.abs(offsets[:, arms]).max() <= WIDE.arm_pose and np.abs(offsets[:, arms]).max() > 0.045
    assert not offsets[:, others].any()  # legs, neck, waist and grippers start at home
    share = np.mean([s.regrasp for s in scenes])
    assert abs(share - WIDE.regrasp_share) < 0.06  # 400 draws: one standard deviation is 0.022
    again = draw_scene(np.random.default_rng(7), task.description, WIDE)
    assert np.array_equal(again.shift, scenes[7].shift) and again.light == scenes[7].light


def test_the_handle_height_moves_the_bar_and_its_posts_and_a_new_height_starts_from_the_layout(task):
    model = task.model
    task.reset(0)
    bar_z = model.geom_pos[model.geom(WAGON_HANDLE_GEOM).id, 2] - draw_scene(
        np.random.default_rng(0), task.description, WIDE).handle_height  # the layout's height, in the wagon's frame
    for offset in (0.01, -0.01, 0.0):
        task.handle_height.set(offset)
        assert model.geom_pos[model.geom(WAGON_HANDLE_GEOM).id, 2] == pytest.approx(bar_z + offset, abs=1e-12)
        for side in ("left", "right"):
            post = model.geom(f"wagon_post_{side}").id
            axis = np.zeros(9)
            mujoco.mju_quat2Mat(axis, model.geom_quat[post])
            top = model.geom_pos[post] + model.geom_size[post, 1] * axis.reshape(3, 3)[:, 2]
            assert top[2] == pytest.approx(bar_z + offset, abs=1e-9)  # the post still ends at the bar


def test_the_light_level_scales_the_scene_lights_from_the_models_own(task):
    model = task.model
    task.light.set(1.0)
    diffuse, head = model.light_diffuse.copy(), model.vis.headlight.diffuse.copy()
    task.light.set(0.5)
    task.light.set(0.6)  # scales do not multiply
    assert np.allclose(model.light_diffuse, 0.6 * diffuse) and np.allclose(model.vis.headlight.diffuse, 0.6 * head)
    task.light.set(1.0)


def test_the_task_and_the_chain_put_the_wagon_and_the_handle_alike_for_a_seed(task):
    seed = next(s for s in range(100) if not draw_scene(np.random.default_rng(s), task.description, WIDE).regrasp)
    obs = task.reset(seed)
    task_handle = _handle(task.model, task.robot.data)
    start, targets = task.chain_start(seed, StartPerturbation())
    chain_obs = start.reset()
    assert np.allclose(_handle(start.model, start.data), task_handle, atol=1e-9)
    assert np.allclose(chain_obs.motor_pos, obs.motor_pos, atol=1e-9)
    assert np.allclose(targets, obs.motor_pos, atol=1e-9)  # the chain commands its start pose first


@pytest.mark.slow
def test_a_regrasp_start_has_the_open_hands_at_the_slipped_handle_and_the_script_grasps_it_in_place(task):
    seeds = [s for s in range(80) if draw_scene(np.random.default_rng(s), task.description, WIDE).regrasp][:6]
    model, data = task.model, task.robot.data
    grasped = []
    for seed in seeds:
        scene = draw_scene(np.random.default_rng(seed), task.description, WIDE)
        obs = task.reset(seed)
        assert obs.time == 0.0 and np.abs(obs.motor_vel).max() == 0.0
        handle = _handle(model, data)
        for side in ("left", "right"):
            gripper = task.description.motor_names.index(f"{side}_gripper_drive")
            assert obs.motor_pos[gripper] == pytest.approx(task.ready_pose[gripper], abs=0.05)  # open
            to_bar = data.site_xpos[model.site(grasp_site(side)).id] - handle
            assert abs(to_bar[0] + scene.slip[0]) < 0.015 and abs(to_bar[2]) < 0.015  # at the bar before it slipped
        demo = task.demonstrator()
        demo.reset(obs)
        while not demo.done:
            action = demo.act(obs, np.zeros(3))
            obs = task.step(action.motor_targets, action.kp)
            if task.succeeded and seed not in grasped:
                grasped.append(seed)
                # grasped where it lay: backing out first dragged the bar 3 cm
                assert np.linalg.norm(_handle(model, data) - handle) < 0.008, seed
    assert len(grasped) >= 5, (seeds, grasped)


def test_a_failed_wagon_episode_says_how_it_started_and_what_each_hand_ended_in(task):
    from toddlerbot.dp.evaluate import EpisodeResult, EvalResult
    from toddlerbot.skills.library import range_fraction

    seed = next(s for s in range(100) if not draw_scene(np.random.default_rng(s), task.description, WIDE).regrasp)
    task.reset(seed)
    for _ in range(5):
        task.step(task.ready_pose)
    assert task.failure_kind() == "home start: left open, right open"
    grippers = [task.description.motor_names.index(f"{side}_gripper_drive") for side in ("left", "right")]
    closed = task.ready_pose.copy()
    closed[grippers] = range_fraction(task.description, grippers, task.check.params.closed_fraction)
    for _ in range(5):
        task.step(closed)
    assert task.failure_kind() == "home start: left closed off the bar, right closed off the bar"
    regrasp = next(s for s in range(100) if draw_scene(np.random.default_rng(s), task.description, WIDE).regrasp)
    task.reset(regrasp)
    task.step(task.robot.observe().motor_pos)
    assert task.failure_kind().startswith("re-grasp start: ")
    result = EvalResult("wagon", "x.pt", 0, [EpisodeResult(0, True, 3.0, 5, 0.5),
                                            EpisodeResult(1, False, 6.0, 12, 0.4, "home start: left open, right open")])
    assert result.summary()["failures"] == {"1": "home start: left open, right open"}


def test_the_default_variation_is_the_measured_scene_and_a_variation_is_named_or_refused_in_one_line():
    default = WagonTask()
    assert default.variation == "default" and WagonTask.variations == ("default", "wide")
    for seed in range(50):
        scene = draw_scene(np.random.default_rng(seed), default.description, default.ranges)
        old = np.random.default_rng(seed)  # the shift is the generator's first two draws, as before the ranges
        assert np.array_equal(scene.shift, [old.uniform(-0.01, 0.01), old.uniform(-0.03, 0.03)])
        assert scene.handle_height == 0.0 and scene.light == 1.0 and not scene.arm_offset.any() and not scene.regrasp
    with pytest.raises(ToddlerbotError, match=r"^task 'wagon' has no scene variation 'windy'; expected one of "
                                              r"default, wide$"):
        make_task("wagon:windy")
    with pytest.raises(ToddlerbotError, match=r"^task 'pick' has no scene variation 'wide'; expected one of default$"):
        make_task("pick:wide")
