"""The robot's left-right mirror (`robot.mirror`) and walk-rl's symmetric controller built on it."""

from types import SimpleNamespace

import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.rl_inference import RLController, RLPolicyFile, mirror_frame, mirror_leg_action
from toddlerbot.policies.walk_rl import resolve_weights
from toddlerbot.robot.mirror import robot_mirror


@pytest.fixture(scope="module")
def mirror(description):
    return robot_mirror(description)


@pytest.fixture(scope="module")
def policy():
    return RLPolicyFile(resolve_weights("walk_rl"))


def test_each_motor_mirrors_its_partner_with_the_sign_its_axes_give(description, mirror):
    names = description.motor_names
    pairs = {names[i]: (names[j], s) for i, (j, s) in enumerate(zip(mirror.partner, mirror.sign, strict=True))}
    assert pairs["left_hip_pitch"] == ("right_hip_pitch", -1.0)  # the axes point the same way: a bend is -q
    assert pairs["right_hip_roll"] == ("left_hip_roll", 1.0)  # opposite axes: an outward roll is +q on both
    assert pairs["neck_yaw_drive"] == ("neck_yaw_drive", -1.0)  # on the midline: its own partner
    assert pairs["neck_pitch_drive"] == ("neck_pitch_drive", 1.0)
    q = np.random.default_rng(0).normal(size=len(names))
    np.testing.assert_array_equal(mirror.motors(mirror.motors(q)), q)  # mirroring twice is the identity
    np.testing.assert_allclose(mirror.imu_reflection, np.diag([1.0, -1.0, 1.0]), atol=1e-9)  # the IMU sits square


def test_the_gait_reference_is_its_own_mirror_half_a_cycle_later(mirror, policy):
    """The ZMP reference was made by IK for each command, independently of the mirror: its mirror image at
    (vx, -vy, -yaw) half a cycle on is the reference itself, which checks every leg motor's sign."""
    legs, period = policy.leg_motor_index, policy.obs_config.gait_period
    home = policy.home_motor_pos[legs]
    for command in [(0.1, 0.0, 0.0), (0.0, 0.05, 0.0), (0.05, -0.04, 0.2), (0.0, 0.0, -0.3)]:
        for t in np.linspace(3.0, 3.6, 7):
            legs_now, contact = policy.reference.at(np.array(command), t)
            mirrored, mirrored_contact = policy.reference.at(np.array([command[0], -command[1], -command[2]]),
                                                             t + period / 2)
            np.testing.assert_allclose(mirror_leg_action(legs_now - home, mirror, legs), mirrored - home, atol=0.02)
            np.testing.assert_allclose(contact[::-1], mirrored_contact, atol=1e-6)  # the other foot stands


def test_a_mirrored_frame_mirrors_every_part_and_twice_is_the_identity(mirror, policy):
    legs = policy.leg_motor_index
    frame = np.random.default_rng(1).normal(size=policy.obs_mean.size // policy.obs_config.history)
    once = mirror_frame(frame, mirror, legs)
    np.testing.assert_allclose(mirror_frame(once, mirror, legs), frame, atol=1e-12)
    n = len(mirror.partner)
    np.testing.assert_array_equal(once[:2], -frame[:2])  # half a cycle on
    np.testing.assert_array_equal(once[2:5], frame[2:5] * [1, -1, -1])  # sideways and turning commands negated
    np.testing.assert_array_equal(once[5:5 + n], mirror.motors(frame[5:5 + n]))
    np.testing.assert_allclose(once[-3:], frame[-3:] * [1, -1, 1])  # gravity: a vector
    np.testing.assert_allclose(once[-6:-3], frame[-6:-3] * [-1, 1, -1])  # angular velocity: a pseudo-vector


def test_the_frame_mirror_is_one_implementation_for_numpy_and_jax(mirror, policy):
    jnp = pytest.importorskip("jax.numpy")
    history = np.random.default_rng(2).normal(size=(3, policy.obs_mean.size // policy.obs_config.history))
    np.testing.assert_allclose(np.asarray(mirror_frame(jnp.asarray(history), mirror, policy.leg_motor_index,
                                                       xp=jnp)),
                               mirror_frame(history, mirror, policy.leg_motor_index), atol=1e-6)


def test_the_symmetric_controller_acts_as_the_mirror_of_itself_on_a_mirrored_state(mirror, policy):
    """Equivariance, what makes it symmetric: mirroring the robot's history mirrors the action. The policy alone
    does not have it."""
    legs, size = policy.leg_motor_index, policy.obs_mean.size // policy.obs_config.history
    history = policy.obs_mean.reshape(policy.obs_config.history, size) + 0.3 * np.random.default_rng(3).normal(
        size=(policy.obs_config.history, size))
    mirrored = mirror_frame(history, mirror, legs)
    controller = RLController(policy, mirror)

    def symmetric(h):
        controller.history = h
        return controller.action()

    np.testing.assert_allclose(symmetric(mirrored), mirror_leg_action(symmetric(history), mirror, legs), atol=1e-6)
    alone = np.abs(policy.action(mirrored.reshape(-1)) - mirror_leg_action(policy.action(history.reshape(-1)),
                                                                           mirror, legs))
    assert alone.max() > 0.05


def test_a_robot_that_is_not_symmetric_is_refused_naming_the_motor(description):
    home = np.asarray(description.home_motor_pos).copy()
    home[description.motor_names.index("left_hip_roll")] += 0.1
    lopsided = SimpleNamespace(model=description.model, motor_names=description.motor_names, home_motor_pos=home)
    with pytest.raises(ToddlerbotError, match="robot mirror: the home pose is not symmetric at left_hip_roll"):
        robot_mirror(lopsided)
    renamed = SimpleNamespace(model=description.model, home_motor_pos=home,
                              motor_names=tuple(n.replace("right_knee", "right_shin") for n in description.motor_names))
    with pytest.raises(ToddlerbotError, match="robot mirror: motor left_knee_drive has no partner right_knee_drive"):
        robot_mirror(renamed)
