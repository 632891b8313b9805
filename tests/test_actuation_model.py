"""The actuator model against appendix Eq. 8-10 point by point, and numpy vs JAX."""

from __future__ import annotations

import numpy as np
import pytest

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.model import (
    FRICTION_SMOOTHING,
    acceleration_limit,
    actuator_arrays,
    at_voltage,
    extra_friction,
    limit_torque,
    motor_torque,
    passive_torque,
    pd_torque,
    resistance_torque,
    torque_bounds,
)

MOTORS = ["XC330", "XC430", "XM430", "2XL430", "2XC430"]


def eq9(speed: float, tau_max: float, qd_tau: float, qd_max: float, tau_qd_max: float) -> float:
    """Eq. 9 generalised to a non-zero floor tau_qd_max (the issue's definition), written as the appendix does."""
    s = abs(speed)
    if s <= qd_tau:
        return tau_max
    if s <= qd_max:
        return tau_qd_max + (qd_max - s) / (qd_max - qd_tau) * (tau_max - tau_qd_max)
    return tau_qd_max


@pytest.mark.parametrize("motor", MOTORS)
def test_envelope_point_by_point(motor: str) -> None:
    a = default_catalogue()[motor].actuator
    p = actuator_arrays([a], [0.0], [0.0])
    speeds = [0.0, 0.5 * a.q_dot_tau_max, a.q_dot_tau_max, 0.5 * (a.q_dot_tau_max + a.q_dot_max), a.q_dot_max,
              1.5 * a.q_dot_max]
    for s in speeds:
        expected = eq9(s, a.tau_max, a.q_dot_tau_max, a.q_dot_max, a.tau_q_dot_max)
        assert acceleration_limit(np.array([s]), p)[0] == pytest.approx(expected, abs=1e-12)
        assert acceleration_limit(np.array([-s]), p)[0] == pytest.approx(expected, abs=1e-12)
        lower, upper = torque_bounds(np.array([s]), p)
        if s > 0:  # Eq. 10 (q_dot >= 0): motion-direction torque <= tau_limit, braking torque >= -tau_brake
            assert upper[0] == pytest.approx(expected) and lower[0] == pytest.approx(-a.tau_brake)
            lower_n, upper_n = torque_bounds(np.array([-s]), p)
            assert lower_n[0] == pytest.approx(-expected) and upper_n[0] == pytest.approx(a.tau_brake)
        else:  # at rest both directions accelerate
            assert upper[0] == pytest.approx(a.tau_max) and lower[0] == pytest.approx(-a.tau_max)


def test_eq9_exact_with_zero_floor() -> None:
    a = default_catalogue()["XC330"].actuator.replace(tau_q_dot_max=0.0)
    p = actuator_arrays([a], [0.0], [0.0])
    mid = 0.5 * (a.q_dot_tau_max + a.q_dot_max)
    assert acceleration_limit(np.array([mid]), p)[0] == pytest.approx(0.5 * a.tau_max)  # (qd_max - s)/(...) = 1/2
    assert acceleration_limit(np.array([a.q_dot_max + 1.0]), p)[0] == 0.0


def test_pd_and_clamp_numbers() -> None:
    a = default_catalogue()["XC330"].actuator  # kp_scale 150, kd_min 0.384, tau_max 0.76, tau_brake 1.75
    p = actuator_arrays([a], [1500.0], [150.0])
    # Eq. 8: kp = 10 N*m/rad, kd = 1 N*m*s/rad: 10 * 0.05 - (0.384 + 1) * 0.1 = 0.3616 (below both limits)
    assert pd_torque(0.05, 0.0, 0.1, p)[0] == pytest.approx(0.3616)
    assert motor_torque(0.05, 0.0, 0.1, p)[0] == pytest.approx(0.3616)
    # accelerating along the motion: clamped at tau_max (speed 1.0 < q_dot_tau_max 1.8)
    assert motor_torque(1.0, 0.0, 1.0, p)[0] == pytest.approx(0.76)
    # braking against the motion: clamped at tau_brake
    assert motor_torque(-1.0, 0.0, 1.0, p)[0] == pytest.approx(-1.75)
    assert motor_torque(1.0, 0.0, -1.0, p)[0] == pytest.approx(1.75)


def test_resistance_is_eq6() -> None:
    tau = resistance_torque(np.array([-2.0, 0.0, 3.0]), 0.01, 0.05)
    np.testing.assert_allclose(tau, [-0.05 - 0.02, 0.0, 0.05 + 0.03])


def test_numpy_and_jax_agree() -> None:
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    cat = default_catalogue()
    params = [cat[m].actuator for m in MOTORS]
    p = actuator_arrays(params, [400, 900, 1500, 2100, 2700], [0, 50, 0, 100, 0])
    rng = np.random.default_rng(0)
    q_target, q = rng.uniform(-1, 1, (200, 5)), rng.uniform(-1, 1, (200, 5))
    q_dot = rng.uniform(-10, 10, (200, 5))
    expected = motor_torque(q_target, q, q_dot, p)
    pj = type(p)(*(jnp.asarray(x) for x in p))
    jitted = jax.jit(lambda a, b, c, pp: motor_torque(a, b, c, pp, jnp))
    got = jitted(jnp.asarray(q_target), jnp.asarray(q), jnp.asarray(q_dot), pj)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-5, atol=1e-6)  # JAX computes in float32
    vmapped = jax.vmap(lambda a, b, c: motor_torque(a, b, c, pj, jnp))(q_target, q, q_dot)
    np.testing.assert_allclose(np.asarray(vmapped), expected, rtol=1e-5, atol=1e-6)
    clamped = ~np.isclose(expected, pd_torque(q_target, q, q_dot, p))
    assert 0.2 < clamped.mean() < 0.95  # the sample covers both limited and unlimited torques


EXTENDED = dict(stiction=0.04, stribeck_velocity=0.3, load_friction=0.2)


def test_extended_friction_numbers() -> None:
    a = default_catalogue()["XC330"].actuator.replace(**EXTENDED)
    p = actuator_arrays([a], [1500.0], [150.0])
    # well above the smoothing speed tanh = 1: at 0.3 rad/s the Stribeck term is 0.04 / e
    tau = 10 * 0.05 - (0.384 + 1) * 0.3  # unlimited PD torque 0.0848 N*m
    expected = tau - (0.04 * np.exp(-1.0) + 0.2 * tau)
    assert motor_torque(0.05, 0.0, 0.3, p)[0] == pytest.approx(expected)
    # unpowered: only the Stribeck static friction, opposing the motion
    assert passive_torque(np.array([-0.3]), p)[0] == pytest.approx(0.04 * np.exp(-1.0), rel=1e-6)
    # smooth through zero speed: zero at rest, half of tanh(1) of the stiction at the smoothing speed
    assert extra_friction(np.array([0.0]), 0.0, p)[0] == 0.0
    assert extra_friction(np.array([FRICTION_SMOOTHING]), 0.0, p)[0] == pytest.approx(
        0.04 * np.exp(-((FRICTION_SMOOTHING / 0.3) ** 2)) * np.tanh(1.0))


def test_default_extended_fields_leave_the_appendix_model_unchanged() -> None:
    cat = default_catalogue()
    params = [cat[m].actuator for m in MOTORS]
    p = actuator_arrays(params, [400, 900, 1500, 2100, 2700], [0, 50, 0, 100, 0])
    rng = np.random.default_rng(1)
    q_target, q, q_dot = rng.uniform(-1, 1, (100, 5)), rng.uniform(-1, 1, (100, 5)), rng.uniform(-9, 9, (100, 5))
    np.testing.assert_array_equal(motor_torque(q_target, q, q_dot, p), limit_torque(
        pd_torque(q_target, q, q_dot, p), q_dot, p))
    assert np.all(passive_torque(q_dot, p) == 0.0)


def test_voltage_scales_limits_speeds_and_gains_but_not_kd_min() -> None:
    a = default_catalogue()["XL330-M288"].actuator
    p = actuator_arrays([a], [400.0], [0.0])
    hi = at_voltage(p, 7.4 / 5.0)
    assert hi.tau_max[0] == pytest.approx(a.tau_max * 1.48) and hi.q_dot_max[0] == pytest.approx(a.q_dot_max * 1.48)
    assert hi.kp[0] == pytest.approx(400.0 / a.kp_scale * 1.48) and hi.kd_min[0] == a.kd_min
    # the limit at a scaled speed is the scaled limit: the whole torque-speed curve stretches by s
    assert acceleration_limit(np.array([6.0 * 1.48]), hi)[0] == pytest.approx(
        1.48 * acceleration_limit(np.array([6.0]), p)[0])


def test_extended_model_numpy_and_jax_agree() -> None:
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    cat = default_catalogue()
    kp, kd = [400, 900, 1500, 2100, 2700], [0, 50, 0, 100, 0]
    params = [cat[m].actuator.replace(stiction=0.01 * (i + 1), stribeck_velocity=0.1 + 0.1 * i,
                                      load_friction=0.05 * i) for i, m in enumerate(MOTORS)]
    p = at_voltage(actuator_arrays(params, kp, kd), 0.9)
    rng = np.random.default_rng(2)
    q_target, q = rng.uniform(-1, 1, (300, 5)), rng.uniform(-1, 1, (300, 5))
    q_dot = np.concatenate([rng.uniform(-10, 10, (150, 5)), rng.uniform(-0.1, 0.1, (150, 5))])
    expected = motor_torque(q_target, q, q_dot, p)
    pj = type(p)(*(jnp.asarray(x) for x in p))
    got = jax.jit(lambda a, b, c, pp: motor_torque(a, b, c, pp, jnp))(q_target, q, q_dot, pj)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-5, atol=1e-5)  # JAX computes in float32
    vmapped = jax.vmap(lambda a, b, c: motor_torque(a, b, c, pj, jnp))(q_target, q, q_dot)
    np.testing.assert_allclose(np.asarray(vmapped), expected, rtol=1e-5, atol=1e-5)
    passive = jax.jit(lambda c, pp: passive_torque(c, pp, jnp))(q_dot, pj)
    np.testing.assert_allclose(np.asarray(passive), passive_torque(q_dot, p), rtol=1e-5, atol=1e-6)
    # the extended terms matter in the sample (else this would only compare the 9-parameter model again)
    plain = at_voltage(actuator_arrays([x.replace(stiction=0.0, load_friction=0.0) for x in params], kp, kd), 0.9)
    assert np.mean(np.abs(expected - motor_torque(q_target, q, q_dot, plain))) > 5e-3
