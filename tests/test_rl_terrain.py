"""Terrain in the RL training model and environment: the pruned model's feet and hands collide with a terrain's
height field (classic MuJoCo and MJX alike), a foot on it counts as ground contact, not robot-robot, and the walking
env's termination and feet heights are heights above the ground under them (on the flat floor: z, as before)."""

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

jax = pytest.importorskip("jax")
mjx = pytest.importorskip("mujoco.mjx")
jnp = jax.numpy

from toddlerbot.rl.config import smoke_env_config  # noqa: E402
from toddlerbot.rl.model import contact_geoms, training_model  # noqa: E402
from toddlerbot.rl.physics import Addresses, contact_state, frames_of  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.sim.terrain import (  # noqa: E402
    START,
    TERRAIN_GEOM,
    Ground,
    add_terrain,
    parse_terrain,
    terrain_heights,
)

STEP = parse_terrain("stairs:height=0.02,depth=0.5")
"""A 2 cm step up from the start square; the robot stands on it at x = 0.5 m."""
SLOPE = parse_terrain("slope:degrees=-10")


def _on_the_ground(model, x: float) -> mujoco.MjData:
    """The home pose at (x, 0), raised by the ground under it, 0.5 mm into it (a penetrating contact)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    ground = Ground.of(model)
    data.qpos[0] = x
    data.qpos[2] += (0.0 if ground is None else float(ground.height(x, 0.0))) - 0.0005
    mujoco.mj_forward(model, data)
    return data


@pytest.fixture(scope="module")
def step_model(description):
    return training_model(description, replace(smoke_env_config(), terrain=str(STEP)))


def test_the_pruned_training_model_keeps_the_feet_and_hands_colliding_with_the_terrain(description, step_model):
    m = step_model
    terrain = m.geom(TERRAIN_GEOM).id
    colliding = {m.geom(g).name for g in range(m.ngeom) if m.geom_contype[g] & m.geom_conaffinity[terrain]}
    assert colliding == set(contact_geoms(description))  # feet and hands: nothing else pruned back in
    assert m.geom_type[terrain] == mujoco.mjtGeom.mjGEOM_HFIELD


def test_a_foot_on_the_terrain_is_ground_contact_not_a_robot_robot_contact(description, step_model):
    a = Addresses.of(step_model, description)
    data = _on_the_ground(step_model, 0.5)
    terrain = step_model.geom(TERRAIN_GEOM).id
    pairs = {tuple(sorted(p)) for p in data.contact.geom[:data.ncon].tolist()}
    assert {(terrain, f) for f in a.foot_geoms.tolist()} <= pairs  # the soles touch the step, not the floor
    frame = frames_of(a, [data], np.zeros((1, step_model.nu)))
    assert frame.contact.tolist() == [[1.0, 1.0]] and frame.self_collision.tolist() == [0.0]
    # one penetrating terrain-foot contact and one foot-foot contact: ground for the left foot, one robot-robot
    left, right = a.foot_geoms.tolist()
    contact, robot = contact_state(a, np.array([[terrain, left], [left, right]]), np.array([-1e-3, -1e-3]), xp=np)
    assert contact.tolist() == [1.0, 0.0] and float(robot) == 1.0


def _foot_on(terrain, points) -> tuple[mujoco.MjModel, list[mujoco.MjData]]:
    """A free box the size of a foot sole on ``terrain`` (seed 0), 0.5 mm into the ground at each of ``points``."""
    mj = mujoco.MjSpec()
    mj.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=(0, 0, 0.05), contype=0, conaffinity=1)
    add_terrain(mj, terrain_heights(terrain, seed=0))
    foot = mj.worldbody.add_body(name="foot")
    foot.add_freejoint()
    foot.add_geom(name="sole", type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.06, 0.0245, 0.021), contype=1, conaffinity=0)
    model = mj.compile()
    ground = Ground.of(model)
    datas = []
    for x, y in points:
        data = mujoco.MjData(model)
        corners = np.array([[x + sx * 0.06, y + sy * 0.0245] for sx in (-1, 1) for sy in (-1, 1)])
        data.qpos[:3] = x, y, np.max(ground.height(corners[:, 0], corners[:, 1])) + 0.021 - 0.0005
        mujoco.mj_forward(model, data)
        datas.append(data)
    return model, datas


@pytest.mark.slow
def test_mjx_collides_a_sole_with_the_height_field_where_mujoco_does():
    """A sole on round hills, at points that are not symmetric in x and y (a transposed height field would show):
    MJX's deepest contact is MuJoCo's within 0.3 mm. On curved ground the two split a sole's contact into prisms
    differently (MJX keeps 4 points, MuJoCo up to 48); on the flat tops of steps, slopes and tiles they agreed to
    1 um (measured while writing this test). One compile of MJX's collision: 50-260 s on the shared 2-core VM."""
    model, datas = _foot_on(parse_terrain("bumps:height=0.05,width=0.4"), [(0.83, -0.41), (-0.37, 1.12), (1.3, 0.6)])
    starts = []
    for data in datas:
        start = mujoco.MjData(model)  # no contacts yet: MuJoCo keeps more of them (48) than MJX has room for (4)
        start.qpos[:] = data.qpos
        starts.append(mjx.put_data(model, start))
    batch = jax.tree.map(lambda *x: jnp.stack(x), *starts)
    contact = jax.jit(jax.vmap(mjx.forward, in_axes=(None, 0)))(mjx.put_model(model), batch)._impl.contact
    deepest = np.min(np.asarray(contact.dist), axis=1)
    expected = [np.min(d.contact.dist[:d.ncon]) for d in datas]
    np.testing.assert_allclose(deepest, expected, atol=3e-4)
    ground = np.array([d.qpos[2] for d in datas]) - 0.021  # under the sole's highest corner
    assert np.all(deepest < 0) and ground.min() > 0.01 and np.ptp(ground) > 0.003  # up hills of different heights


@pytest.fixture(scope="module")
def envs(description):
    cfg = smoke_env_config()
    table = standing_table(description, cfg.command, period=0.6)
    flat = WalkEnv(cfg, description, reference=table, gain_scales=(np.ones(30), np.zeros((2, 30))))
    slope = WalkEnv(replace(cfg, terrain=str(SLOPE)), description, reference=table, gain_scales=flat.gain_scales)
    return flat, slope


def test_the_env_terminates_on_the_height_above_the_ground_under_the_torso(envs):
    """1 m out on a 10 degree slope down the torso is 0.176 m lower than at home but as high above the ground: the
    flat-floor termination would end the episode, the terrain's does not."""
    flat, slope = envs
    assert flat.ground is None and slope.ground is not None
    x = START + 1.0
    qpos = np.asarray(slope.physics.home_frame.qpos).copy()
    qpos[0] = x
    qpos[2] -= math.tan(math.radians(10))
    frame = slope.physics.home_frame._replace(qpos=jnp.asarray(qpos))
    assert float(slope.height_above_ground(frame.qpos[:3])) == pytest.approx(float(flat.physics.home_frame.qpos[2]),
                                                                              abs=2e-6)
    assert not bool(slope.terminated(frame))
    assert bool(flat.terminated(frame))  # z 0.151 m < min_torso_height 0.2 m


def test_feet_heights_are_above_the_ground_under_each_foot_and_unchanged_on_the_flat_floor(envs):
    flat, slope = envs
    feet = np.asarray(flat.physics.home_frame.feet_pos)
    lowered = feet + np.array([START + 1.0, 0.0, 0.0])  # both feet moved about 1 m down the slope, onto it
    lowered[:, 2] -= math.tan(math.radians(10)) * (lowered[:, 0] - START)
    np.testing.assert_allclose(np.asarray(slope.height_above_ground(jnp.asarray(lowered))), feet[:, 2], atol=2e-6)
    assert np.array_equal(np.asarray(flat.height_above_ground(jnp.asarray(feet))), feet[:, 2])
