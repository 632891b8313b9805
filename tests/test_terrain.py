"""Terrain (`toddlerbot.sim.terrain`): every kind builds a height field that MuJoCo collides with where `Ground` says
the ground is, from its seed alone; parameters are checked in one line; and heights are measured above the ground
under the robot (the simulator's fall check and foot contact, the RL backends' contact classification, the training
env's termination and feet heights)."""

import math

import mujoco
import numpy as np
import pytest

from cli_support import one_line_error, run_main
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.walk_zmp import WalkZMPPolicy
from toddlerbot.robot.interface import FALL_TILT_RAD
from toddlerbot.runtime.robustness import conditions, run_trial
from toddlerbot.sim.ground_truth import FALL_HEIGHT_FRACTION, TorsoTruth
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import (
    MIN_START,
    START,
    TERRAIN_GEOM,
    TERRAINS,
    Ground,
    Terrain,
    TerrainParameter,
    ground_geoms,
    parse_terrain,
    register_terrain,
    terrain_heights,
    terrain_model,
)

BUILT_IN = ("flat", "rough", "bumps", "slope", "stairs", "mix")
STEP = "stairs:height=0.02,depth=0.5"
"""A 2 cm step up from the start square, 0.5 m deep: the robot stands on it at x = 0.5 m."""


def _ray_height(model, data, x, y) -> float:
    """Where a ray cast straight down from 1 m hits the static geoms (the ground), m."""
    geom = np.zeros(1, np.int32)
    return 1.0 - mujoco.mj_ray(model, data, np.array([x, y, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)


def _standing_at(model, x: float, ground: Ground | None) -> mujoco.MjData:
    """The home pose moved to (x, 0), raised by the ground under it (at home the soles touch z = 0)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    data.qpos[0] = x
    data.qpos[2] += 0.0 if ground is None else float(ground.height(x, 0.0))
    mujoco.mj_forward(model, data)
    return data


def test_the_built_in_terrains_are_registered():
    assert TERRAINS.names()[:6] == BUILT_IN


@pytest.mark.parametrize("name", BUILT_IN)
def test_each_terrain_builds_a_ground_that_mujoco_collides_with_where_ground_says(description, name):
    model = terrain_model(description, parse_terrain(name), seed=5)
    ground = Ground.of(model)
    if name == "flat":  # no height field: the description's own model, the floor plane at z = 0
        assert ground is None and model is description.model("floating", scene=True)
        return
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    points = np.random.default_rng(0).uniform(-1.9, 1.9, (100, 2))
    points = points[np.max(np.abs(points), axis=1) > START + 0.05]  # outside the robot's square
    rays = [_ray_height(model, data, x, y) for x, y in points]
    np.testing.assert_allclose(ground.height(points[:, 0], points[:, 1]), rays, atol=1e-9)
    assert np.ptp(rays) > 0.005  # not flat
    # the start square is flat at z = 0, so the home keyframe stands on it unchanged
    corners = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1], [0, 0]]) * START
    np.testing.assert_array_equal(ground.height(corners[:, 0], corners[:, 1]), 0.0)
    assert model.key("home").qpos[2] == description.model().key("home").qpos[2]


def test_slopes_and_stairs_have_the_declared_angles_and_steps():
    slope = terrain_heights(parse_terrain("slope:degrees=10"), seed=0)
    row = slope.z[slope.z.shape[0] // 2]  # the x axis: y = 0
    x = np.linspace(-slope.extent, slope.extent, row.size)
    beyond = x > START + 0.1
    np.testing.assert_allclose(np.diff(row[beyond]) / slope.cell, math.tan(math.radians(10)), rtol=1e-9)
    down = terrain_heights(parse_terrain("slope:degrees=-10"), seed=0)
    np.testing.assert_allclose(down.z, -slope.z)
    stairs = terrain_heights(parse_terrain("stairs:height=0.03,depth=0.2"), seed=0)
    row = stairs.z[stairs.z.shape[0] // 2]
    at = lambda v: row[np.argmin(np.abs(x - v))]  # noqa: E731
    assert [at(v) for v in (0.0, 0.3, 0.5, 0.7, -0.7, 1.0)] == pytest.approx([0.0, 0.03, 0.06, 0.09, 0.09, 0.12])


@pytest.mark.parametrize("text", ["rough:height=0.02", "bumps:height=0.03", "mix"])
def test_the_same_seed_draws_the_same_ground_and_another_seed_another(text):
    terrain = parse_terrain(text)
    first, again, other = (terrain_heights(terrain, seed).z for seed in (7, 7, 8))
    np.testing.assert_array_equal(first, again)
    assert np.mean(first != other) > 0.5
    assert first.min() >= 0.0 and first.max() <= 0.1


def test_rough_tiles_are_cell_wide_and_at_most_height_high():
    grid = terrain_heights(parse_terrain("rough:height=0.02,cell=0.1"), seed=1)
    assert 0.019 < grid.z.max() <= 0.02 and grid.z.min() == 0.0
    assert len(np.unique(grid.z[0])) == pytest.approx(2 * grid.extent / 0.1, abs=1)  # one height per 0.1 m tile


def test_the_start_square_is_flat_to_its_half_width_and_tiled_beyond():
    """Training may shrink the start square to the feet (`EnvConfig.terrain_start`); the simulator keeps `START`."""
    for start in (START, MIN_START):
        grid = terrain_heights(parse_terrain("rough:height=0.02"), seed=1, start=start)
        axis = np.linspace(-grid.extent, grid.extent, grid.z.shape[0])
        x, y = np.meshgrid(axis, axis)
        ring = np.maximum(np.abs(x), np.abs(y))
        assert np.all(grid.z[ring < start + 0.015] == 0.0)  # the square and the cells touching it
        assert np.count_nonzero(grid.z[(ring > start + 0.03) & (ring < start + 0.1)]) > 0.9 * np.count_nonzero(
            (ring > start + 0.03) & (ring < start + 0.1))  # tiles right beyond it
    with pytest.raises(ToddlerbotError, match=r"^start square half-width 0\.05 m: expected 0\.08-1\.0 m$"):
        terrain_heights(parse_terrain("rough:height=0.02"), seed=1, start=0.05)


@pytest.mark.parametrize(("text", "message"), [
    ("hills", "unknown terrain 'hills'; expected one of flat, rough, bumps, slope, stairs, mix"),
    ("rough:hieght=0.01", "unknown parameter 'hieght'; rough takes height, cell"),
    ("rough:height=0.5", "height=0.5: expected 0 to 0.1 m (largest tile height)"),
    ("rough:height=-0.01", "height=-0.01: expected 0 to 0.1 m"),
    ("rough:height=nan", "height=nan: expected 0 to 0.1 m"),
    ("rough:height=abc", "height='abc': expected a number"),
    ("rough:height", "height: expected height=VALUE"),
    ("slope:degrees=45", "degrees=45: expected -30 to 30 deg"),
    ("flat:height=1", "unknown parameter 'height'; flat takes no parameters"),
])
def test_bad_terrains_are_refused_in_one_line_naming_the_option(text, message):
    with pytest.raises(ToddlerbotError) as info:
        parse_terrain(text)
    assert str(info.value).startswith(f"--terrain {text!r}: ") and message in str(info.value)
    assert "\n" not in str(info.value)


def test_parameters_default_and_print_back_as_they_parse():
    terrain = parse_terrain("stairs:depth=0.3")
    assert dict(terrain.values) == {"height": 0.03, "depth": 0.3}
    assert str(terrain) == "stairs:height=0.03,depth=0.3" and parse_terrain(str(terrain)) == terrain


def test_an_installed_package_or_script_adds_a_terrain(monkeypatch):
    monkeypatch.setattr(TERRAINS, "_targets", dict(TERRAINS._targets))

    class Ridge(Terrain):
        parameters = (TerrainParameter("height", 0.01, 0.0, 0.05, "m", "ridge height"),)

        def heights(self, x, y, rng):
            return np.where(np.abs(x - 0.5) < 0.05, self.height, 0.0)

    register_terrain("ridge", Ridge)
    grid = terrain_heights(parse_terrain("ridge:height=0.02"), seed=0)
    assert grid.z.max() == 0.02
    with pytest.raises(ToddlerbotError, match="already registered"):
        register_terrain("rough", Ridge)


def test_the_fall_check_measures_the_torso_above_the_slope_under_it(description):
    """On a 10 degree slope down, 1 m out from the start square, the ground is 0.176 m lower: the torso standing there
    is as high above it as at home, not fallen, though its z is below 0.6 x the standing height."""
    model = terrain_model(description, parse_terrain("slope:degrees=-10"), seed=0)
    data = _standing_at(model, START + 1.0, Ground.of(model))
    truth = TorsoTruth(model, data, description.handles.torso)
    home = TorsoTruth(description.model(), _standing_at(description.model(), 0.0, None), description.handles.torso)
    standing = home.height_and_uprightness()[0]
    assert truth.height_and_uprightness()[0] == pytest.approx(standing, abs=1e-9)
    assert data.xpos[model.body(description.handles.torso).id, 2] == pytest.approx(standing - math.tan(
        math.radians(10)), abs=1e-6)  # the height field holds float32
    assert data.xpos[model.body(description.handles.torso).id, 2] < FALL_HEIGHT_FRACTION * standing  # old check: fell
    assert not truth.fallen(standing, FALL_TILT_RAD, FALL_HEIGHT_FRACTION)


def test_a_robot_standing_on_a_2_cm_step_is_measured_above_the_step_with_its_feet_on_it(description):
    model = terrain_model(description, parse_terrain(STEP), seed=0)
    robot = MuJoCoRobot(description, model=model)
    flat = MuJoCoRobot(description)
    robot.start_qpos = _standing_at(model, 0.5, Ground.of(model)).qpos.copy()
    robot.reset()
    for _ in range(50):  # 1 s holding home
        obs = robot.step(description.home_motor_pos)
    torso = robot.data.xpos[model.body(description.handles.torso).id, 2]
    assert torso == pytest.approx(flat.standing_height + 0.02, abs=0.003)  # really up on the step
    assert robot.torso_height() == pytest.approx(flat.standing_height, abs=0.003)
    assert not robot.fallen and obs.foot_contact.tolist() == [True, True]
    terrain = model.geom(TERRAIN_GEOM).id
    touching = {g for pair in robot.data.contact.geom[:robot.data.ncon].tolist() for g in pair}
    assert terrain in touching and model.geom("floor").id not in touching
    assert ground_geoms(model) == {terrain, model.geom("floor").id}


def test_walk_zmp_walks_from_the_start_onto_5_mm_rough_ground_without_falling(description):
    nominal = conditions()[0]
    for seed in (0, 1):
        trial = run_trial(description, WalkZMPPolicy, (0.15, 0.0, 0.0), nominal, seed, 4.0,
                          parse_terrain("rough:height=0.005"))
        assert not trial.fell, trial
        assert trial.displacement[0] > START + 0.1  # its feet are on the tiles, not in the flat start square
        assert trial.terrain == "rough:height=0.005,cell=0.1"


def test_sim_run_walks_on_a_terrain_and_refuses_a_bad_one(monkeypatch, capsys, tmp_path):
    summary = tmp_path / "walk.json"
    code, out, _ = run_main(monkeypatch, capsys, "sim", "run", "--policy", "walk-zmp", "--terrain",
                            "rough:height=0.005", "--terrain-seed", "3", "--seconds", "1", "--summary-json", summary)
    assert code == 0 and "no fall" in out
    import json

    report = json.loads(summary.read_text())
    assert report["fell"] is False and report["duration_s"] == pytest.approx(1.0, abs=0.03)
    code, _, err = run_main(monkeypatch, capsys, "sim", "run", "--terrain", "stairs:height=0.2")
    assert "--terrain 'stairs:height=0.2': height=0.2: expected -0.1 to 0.1 m" in one_line_error(code, err)
    code, _, err = run_main(monkeypatch, capsys, "sim", "run", "--terrain", "rough", "--task", "pick",
                            "--policy", "stand", "--seconds", "1")
    assert "a task's scene has its own floor" in one_line_error(code, err)
