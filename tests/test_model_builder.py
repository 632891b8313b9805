import mujoco
import numpy as np
import pytest

from conftest import MotorPD
from toddlerbot.robot.builder import build_model, build_xml
from toddlerbot.robot.description import RobotDescription, load_variant
from toddlerbot.robot.summary import standing_height


def test_same_spec_gives_byte_identical_mjcf(spec):
    assert build_xml(spec, "floating", scene=True) == build_xml(spec, "floating", scene=True)
    assert RobotDescription(spec).mjspec("floating", scene=True).to_xml() == build_xml(spec, "floating", scene=True)


@pytest.mark.parametrize("variant,actuators", [("floating", 30), ("fixed", 30), ("gripper", 32)])
def test_generated_mjcf_loads_with_one_actuator_per_motor(variant, actuators):
    description, base = load_variant(variant)
    model = mujoco.MjModel.from_xml_string(description.mjspec(base, scene=True).to_xml())
    assert model.nu == actuators
    assert model.nkey == 1
    assert (model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE) == (base == "floating")


def test_floating_model_mass_height_and_counts(spec):
    model = build_model(spec, "floating")
    assert model.body_subtreemass[0] == pytest.approx(3.358, rel=0.01)
    assert standing_height(model) == pytest.approx(0.55, abs=0.02)
    assert (model.nq, model.nv, model.neq, model.ntendon) == (63, 62, 15, 2)


def test_home_keyframe_puts_soles_on_the_floor(spec):
    model = build_model(spec, "floating", scene=True)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    for foot in ("left_foot_collision", "right_foot_collision"):
        g = model.geom(foot).id
        lowest = data.geom_xpos[g][2] - np.abs(data.geom_xmat[g].reshape(3, 3)[2]) @ model.geom_size[g]
        assert lowest == pytest.approx(0.0, abs=2e-3)


@pytest.mark.parametrize("variant", ["floating", "gripper"])
def test_models_load_in_mjx(variant):
    pytest.importorskip("jax")
    mjx = pytest.importorskip("mujoco.mjx")
    description, base = load_variant(variant)
    mx = mjx.put_model(description.model(base, scene=True))
    assert mx.nu == (32 if variant == "gripper" else 30)


def test_robot_held_at_home_by_joint_pd_stands_for_ten_seconds(spec):
    model = build_model(spec, "floating", scene=True)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    pd = MotorPD(model, spec)
    targets = data.qpos[pd.qadr].copy()
    start = data.qpos[:3].copy()
    for _ in range(round(10.0 / model.opt.timestep)):
        pd.apply(data, targets)
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos))
    # README: torso height within 2 mm after 10 s (measured 1.8 mm lower, 6 mm horizontal drift, 2.6 deg tilt)
    assert abs(data.qpos[2] - start[2]) < 0.002
    assert np.linalg.norm(data.qpos[:2] - start[:2]) < 0.01
    assert 2 * np.arccos(min(1.0, abs(data.qpos[3]))) < np.radians(4)
