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


# ---- visual geometry ---------------------------------------------------------------------------------------------
def _collision_set(model: mujoco.MjModel) -> list[tuple]:
    """Every geom that can touch anything, with what the physics reads of it."""
    return [
        (model.geom(g).name, model.body(model.geom_bodyid[g]).name, int(model.geom_type[g]),
         *model.geom_size[g], *model.geom_pos[g], *model.geom_quat[g], int(model.geom_contype[g]),
         int(model.geom_conaffinity[g]), *model.geom_friction[g], int(model.geom_condim[g]))
        for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]
    ]


@pytest.mark.parametrize("variant", ["floating", "gripper"])
def test_visual_geometry_adds_no_contact_no_mass_and_its_own_group(variant):
    from toddlerbot.robot.visuals import VISUAL_GROUP

    description, base = load_variant(variant)
    spec = description.spec
    plain = build_model(spec, base, scene=True, visuals=False)
    drawn = build_model(spec, base, scene=True)
    visual = drawn.geom_group == VISUAL_GROUP
    # housings, a horn per motor, shells, brackets, bars, rods, lens (and jaws): 89 geoms (floating), 105 (gripper)
    assert visual.sum() == {"floating": 89, "gripper": 105}[variant]
    assert not np.any(plain.geom_group == VISUAL_GROUP)
    assert not np.any(drawn.geom_contype[visual]) and not np.any(drawn.geom_conaffinity[visual])
    assert _collision_set(drawn) == _collision_set(plain)
    assert drawn.npair == plain.npair and drawn.nexclude == plain.nexclude
    for field in ("body_mass", "body_inertia", "body_ipos", "body_iquat", "body_subtreemass"):
        assert np.array_equal(getattr(drawn, field), getattr(plain, field)), field
    assert np.array_equal(drawn.key_qpos, plain.key_qpos)  # the home pose stands on the same soles


def test_two_seconds_of_standing_are_bit_identical_with_and_without_visuals(spec):
    trajectories = []
    for visuals in (False, True):
        model = build_model(spec, "floating", scene=True, visuals=visuals)
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        pd = MotorPD(model, spec)
        targets = data.qpos[pd.qadr].copy()
        for _ in range(round(2.0 / model.opt.timestep)):
            pd.apply(data, targets)
            mujoco.mj_step(model, data)
        trajectories.append((data.qpos.copy(), data.qvel.copy(), data.ncon))
    (qpos_a, qvel_a, ncon_a), (qpos_b, qvel_b, ncon_b) = trajectories
    assert np.array_equal(qpos_a, qpos_b) and np.array_equal(qvel_a, qvel_b) and ncon_a == ncon_b > 0


def test_every_motor_has_a_housing_at_its_catalogue_size_with_the_horn_at_its_joint(gripper_spec):
    from toddlerbot.actuation.catalogue import default_catalogue
    from toddlerbot.robot.visuals import place_housings

    catalogue = default_catalogue()
    housings = place_housings(gripper_spec, catalogue)
    motors = [s.motor.id for h in housings for s in h.shafts]
    assert sorted(motors) == sorted(m.id for m in gripper_spec.motors)  # each motor in exactly one housing
    dual = [h for h in housings if len(h.shafts) == 2]
    # the 2XC430 hips and 2XL430 shoulders, elbows and wrists: 8 units of two axes; 32 - 16 single motors
    assert len(dual) == 8 and len(housings) == 24
    assert all(catalogue[s.motor.model].axes == 2 for h in dual for s in h.shafts)
    model = build_model(gripper_spec, "floating")
    for h in housings:
        assert np.allclose(h.dims * 1000, catalogue[h.shafts[0].motor.model].dimensions_mm)
        assert np.allclose(model.geom(f"{h.shafts[0].motor.joint}_motor").size, h.dims / 2, atol=1e-9)
        assert np.allclose(h.rot.T @ h.rot, np.eye(3)) and np.linalg.det(h.rot) == pytest.approx(1.0)
        for shaft, behind in zip(h.shafts, h.behind):
            local = h.rot.T @ (shaft.point - h.centre)  # the shaft meets the housing's surface
            assert np.max(np.abs(local) - h.dims / 2) == pytest.approx(0.0, abs=1e-9)
            assert abs(behind @ shaft.axis) == pytest.approx(1.0)
            assert np.all(np.abs(h.rot.T @ (shaft.point + 1e-4 * behind - h.centre)) <= h.dims / 2)  # inward


def test_housings_lie_within_the_reference_bounding_shapes_of_their_links(gripper_spec):
    from toddlerbot.actuation.catalogue import default_catalogue
    from toddlerbot.robot.visuals import _BOX_SAMPLES, _outside, place_housings

    bodies = {b.name: b for b in gripper_spec.bodies}
    for h in place_housings(gripper_spec, default_catalogue()):
        link = bodies[h.holder]
        corners = h.centre + (_BOX_SAMPLES * h.dims / 2) @ h.rot.T
        # measured: at most 6.1 mm (gripper XC330), 5.3 mm (ankle XM430), 5.4 mm (arm units' corners)
        assert _outside(corners, link.collision).max() < 0.007, h.holder
        for sphere in (g for g in link.collision if g.type == "sphere"):
            # the reference's arm spheres bound a 2XL430: its centre is the unit's to 2.5 mm (measured)
            assert np.linalg.norm(h.centre - np.array(sphere.pos)) < 0.003


def test_shells_enclose_the_collision_primitives_and_the_lens_is_at_the_head_camera(spec):
    from toddlerbot.robot.visuals import Appearance

    margin = Appearance().shell_margin
    model = build_model(spec, "floating")
    shells = {model.geom(g).name for g in range(model.ngeom) if "_shell" in model.geom(g).name}
    for body in spec.bodies:
        for g in body.collision:
            if f"{g.name}_shell" in shells:
                shell = model.geom(f"{g.name}_shell")
                assert np.allclose(shell.size[: len(g.size)], np.array(g.size) + margin)
                assert np.allclose(shell.pos, g.pos) and shell.bodyid[0] == model.body(body.name).id
            elif g.type == "box":  # a servo bracket: plates on two opposite faces, outside the box
                plates = [model.geom(f"{g.name}_bracket_{side}") for side in "ab"]
                assert np.allclose(plates[0].pos + plates[1].pos, 2 * np.array(g.pos))
            else:
                assert g.type == "sphere"  # an arm unit's bounding sphere: the housing is drawn instead
    assert {"torso_collision_shell", "head_collision_shell", "left_foot_collision_shell"} <= shells
    camera, lens = model.camera("head_camera"), model.geom("head_camera_lens")
    assert lens.bodyid[0] == camera.bodyid[0]
    look = np.zeros(9)
    mujoco.mju_quat2Mat(look, camera.quat)
    # on the camera's axis, reaching past the head's shell in front of the camera
    assert np.allclose(lens.pos - camera.pos, -look.reshape(3, 3)[:, 2] * margin, atol=1e-9)


def test_gripper_jaws_meet_when_the_rack_closes(gripper_spec):
    model = build_model(gripper_spec, "floating")
    data = mujoco.MjData(model)
    gaps = {}
    for state, fraction in (("open", 0.0), ("closed", 1.0)):
        for side in ("left", "right"):
            fingers = (f"{side}_gripper_finger", f"{side}_gripper_finger_mirror")
            for finger in fingers:
                joint = model.joint(finger)
                lo, hi = joint.range
                data.qpos[joint.qposadr[0]] = hi + fraction * (lo - hi)  # 0 is open, the range's end closed
            mujoco.mj_kinematics(model, data)
            jaws = [model.geom(f"{finger}_jaw").id for finger in fingers]
            axis = data.xmat[model.body(fingers[0]).id].reshape(3, 3)[:, 2]  # the slide axis
            centres = [data.geom_xpos[j] @ axis for j in jaws]
            halves = [float(np.abs(data.geom_xmat[j].reshape(3, 3).T @ axis) @ model.geom_size[j]) for j in jaws]
            near, far = sorted(range(2), key=lambda i: centres[i])
            gaps[state, side] = (centres[far] - halves[far]) - (centres[near] + halves[near])
    travel = np.ptp(model.joint("left_gripper_finger").range)
    for side in ("left", "right"):
        assert gaps["open", side] == pytest.approx(2 * travel, abs=1e-6)  # 50 mm apart when open
        assert gaps["closed", side] == pytest.approx(0.0, abs=1e-6)  # inner faces touch when closed
