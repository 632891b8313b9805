"""The actuator models (appendix Eq. 8-10, the DC motor) point by point, and numpy vs JAX."""

from __future__ import annotations

import numpy as np
import pytest

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.model import (
    acceleration_limit,
    actuator_arrays,
    at_voltage,
    friction_excess,
    has_friction_excess,
    limit_torque,
    motor_torque,
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


DC = DCMotorParams(damping=0.002, armature=0.002, frictionloss=0.02, stall_torque=0.5, no_load_speed=10.0,
                   pwm_per_rad=0.003, pwm_exponent=0.8, load_friction=0.4)


def test_dc_motor_numbers() -> None:
    p = actuator_arrays([DC], [400.0], [0.0])
    # 0.2 rad of error at kp 400: duty 0.003 * 400 * 0.2 = 0.24, torque 0.5 * 0.24^0.8, less back-EMF 0.05 * q_dot
    assert motor_torque(0.2, 0.0, 2.0, p)[0] == pytest.approx(0.5 * 0.24**0.8 - 0.05 * 2.0)
    # saturated duty: the stall torque falls linearly to zero at the no-load speed, and grows when braking
    assert motor_torque(1.0, 0.0, 0.0, p)[0] == pytest.approx(0.5)
    assert motor_torque(1.0, 0.0, 10.0, p)[0] == pytest.approx(0.0, abs=1e-12)
    assert motor_torque(-1.0, 0.0, 5.0, p)[0] == pytest.approx(-0.75)
    lower, upper = torque_bounds(np.array([5.0]), p)
    assert (lower[0], upper[0]) == (pytest.approx(-0.75), pytest.approx(0.25))
    # the firmware gain enters in its own units: the same error at kp 100 is a quarter of the duty
    assert motor_torque(0.2, 0.0, 0.0, actuator_arrays([DC], [100.0], [0.0]))[0] == pytest.approx(0.5 * 0.06**0.8)
    # what the model builder, the slew limit and the summaries read
    assert (DC.tau_max, DC.tau_brake, DC.q_dot_max, DC.back_emf_damping) == (0.5, 1.0, 10.0, 0.05)
    assert DC.kp_scale == pytest.approx(1 / 0.0015)


def test_dc_motor_at_voltage_scales_stall_and_gain_not_back_emf() -> None:
    p = at_voltage(actuator_arrays([DC], [400.0], [0.0]), 1.5)
    assert p.tau_max[0] == pytest.approx(0.75) and p.kp[0] == pytest.approx(1.5 * 400 * 0.003 * 0.5)
    assert p.back_emf_damping[0] == 0.05
    # the no-load speed V / k_e scales with the supply: full duty at 1.5 x 10 rad/s gives no torque
    assert motor_torque(5.0, 0.0, 15.0, p)[0] == pytest.approx(0.0, abs=1e-12)


def test_friction_excess_numbers() -> None:
    a = default_catalogue()["XC330"].actuator.replace(stiction=0.04, stribeck_velocity=0.3, load_friction=0.2)
    p = actuator_arrays([a, DC], [1500.0, 400.0], [150.0, 0.0])
    assert has_friction_excess(p)
    # static friction decays as exp(-(q_dot / v_s)^2), load friction grows with |tau|, in either direction
    excess = friction_excess(np.array([0.3, -2.0]), np.array([-0.5, 0.25]), p)
    np.testing.assert_allclose(excess, [0.04 * np.exp(-1.0) + 0.2 * 0.5, 0.4 * 0.25])
    # the extended model's friction is only a budget: its motor torque is the appendix's limited PD torque
    assert motor_torque(0.05, 0.0, 0.3, p)[0] == pytest.approx(10 * 0.05 - (0.384 + 1) * 0.3)


def test_the_appendix_model_is_left_bit_for_bit() -> None:
    cat = default_catalogue()
    params = [cat[m].actuator for m in MOTORS]
    p = actuator_arrays(params, [400, 900, 1500, 2100, 2700], [0, 50, 0, 100, 0])
    rng = np.random.default_rng(1)
    q_target, q, q_dot = rng.uniform(-1, 1, (100, 5)), rng.uniform(-1, 1, (100, 5)), rng.uniform(-9, 9, (100, 5))
    np.testing.assert_array_equal(motor_torque(q_target, q, q_dot, p), limit_torque(
        pd_torque(q_target, q, q_dot, p), q_dot, p))
    assert not has_friction_excess(p) and np.all(friction_excess(q_dot, q, p) == 0.0)


def test_voltage_scales_limits_speeds_and_gains_but_not_kd_min() -> None:
    a = default_catalogue()["XL330-M077"].actuator
    p = actuator_arrays([a], [400.0], [0.0])
    hi = at_voltage(p, 7.4 / 5.0)
    assert hi.tau_max[0] == pytest.approx(a.tau_max * 1.48) and hi.q_dot_max[0] == pytest.approx(a.q_dot_max * 1.48)
    assert hi.kp[0] == pytest.approx(400.0 / a.kp_scale * 1.48) and hi.kd_min[0] == a.kd_min
    # the limit at a scaled speed is the scaled limit: the whole torque-speed curve stretches by s
    assert acceleration_limit(np.array([6.0 * 1.48]), hi)[0] == pytest.approx(
        1.48 * acceleration_limit(np.array([6.0]), p)[0])


def test_numpy_and_jax_agree_on_both_models() -> None:
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    cat = default_catalogue()
    kp, kd = [400, 900, 1500, 2100, 2700, 400], [0, 50, 0, 100, 0, 0]
    params = [cat[m].actuator.replace(stiction=0.01 * (i + 1), stribeck_velocity=0.1 + 0.1 * i,
                                      load_friction=0.05 * i) for i, m in enumerate(MOTORS)] + [DC]
    p = at_voltage(actuator_arrays(params, kp, kd), 0.9)
    rng = np.random.default_rng(2)
    q_target, q = rng.uniform(-1, 1, (300, 6)), rng.uniform(-1, 1, (300, 6))
    q_dot = np.concatenate([rng.uniform(-10, 10, (150, 6)), rng.uniform(-0.1, 0.1, (150, 6))])
    expected = motor_torque(q_target, q, q_dot, p)
    pj = type(p)(*(jnp.asarray(x) for x in p))
    got = jax.jit(lambda a, b, c, pp: motor_torque(a, b, c, pp, jnp))(q_target, q, q_dot, pj)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-5, atol=1e-5)  # JAX computes in float32
    vmapped = jax.vmap(lambda a, b, c: motor_torque(a, b, c, pj, jnp))(q_target, q, q_dot)
    np.testing.assert_allclose(np.asarray(vmapped), expected, rtol=1e-5, atol=1e-5)
    excess = jax.jit(lambda c, t, pp: friction_excess(c, t, pp, jnp))(q_dot, expected, pj)
    np.testing.assert_allclose(np.asarray(excess), friction_excess(q_dot, expected, p), rtol=1e-5, atol=1e-6)
    clamped = ~np.isclose(expected, pd_torque(q_target, q, q_dot, p))
    assert 0.2 < clamped[:, :5].mean() < 0.95  # the sample covers both limited and unlimited torques
    # the DC motor's PWM shape and back-EMF are in the sample (not just the linear limited PD torque again)
    assert np.mean(np.abs(expected[:, 5] - limit_torque(pd_torque(q_target, q, q_dot, p), q_dot, p)[:, 5])) > 0.02
