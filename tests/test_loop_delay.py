"""`DelayedRobot`: the simulated robot with a real loop's delays (late targets, an old IMU reading, jittered
periods), checked against `MuJoCoRobot` stepped by hand the same way."""

import numpy as np
import pytest

from toddlerbot.sim.loop_delay import HIL_LOOP_DELAY, DelayedRobot, LoopDelay
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


def _hip_bent(robot) -> np.ndarray:
    targets = robot.description.home_motor_pos.copy()
    targets[robot.motor_names.index("left_hip_pitch")] += 0.05
    return targets


def test_targets_act_late_and_the_imu_reading_is_old(description):
    delayed = DelayedRobot(description, LoopDelay(target_ms=5, imu_ms=8))
    plain = MuJoCoRobot(description)
    delayed.reset(), plain.reset()
    targets = _hip_bent(plain)
    obs = delayed.step(targets)
    plain.advance(5)  # the home targets hold for 5 ms
    plain.command(targets)
    plain.advance(20 - 5 - 8)
    imu_then = plain.observe()
    plain.advance(8)
    now = plain.observe()
    np.testing.assert_allclose(obs.motor_pos, now.motor_pos, atol=1e-12)
    np.testing.assert_allclose(obs.imu_ang_vel, imu_then.imu_ang_vel, atol=1e-12)
    np.testing.assert_allclose(obs.imu_quat, imu_then.imu_quat, atol=1e-12)
    assert np.abs(obs.imu_ang_vel - now.imu_ang_vel).max() > 1e-4  # the hip's move is felt: the age matters
    assert obs.time == pytest.approx(0.020)


def test_periods_jitter_within_bounds_reproducibly(description):
    def times(seed: int) -> np.ndarray:
        robot = DelayedRobot(description, LoopDelay(jitter_ms=4, seed=seed))
        robot.reset()
        home = robot.description.home_motor_pos
        return np.array([robot.step(home).time for _ in range(40)])

    periods = np.diff(np.concatenate([[0.0], times(3)]))
    assert periods.min() >= 0.016 - 1e-9 and periods.max() <= 0.024 + 1e-9
    assert len(np.unique(np.round(periods, 6))) >= 5  # really jittered, across the band
    np.testing.assert_array_equal(times(3), times(3))
    assert not np.array_equal(times(3), times(4))


def test_bad_delays_are_refused_in_one_line(description):
    with pytest.raises(ValueError, match=r"LoopDelay.imu_ms must be >= 0 ms, got -1"):
        LoopDelay(imu_ms=-1)
    with pytest.raises(ValueError, match=r"jitter_ms 20 must be < the control period \(20 physics steps\)"):
        DelayedRobot(description, LoopDelay(jitter_ms=20))
    assert LoopDelay(5, 10, 4).scaled(2) == LoopDelay(10, 20, 4)


def test_the_hil_imu_age_is_the_emulated_imus_latency_plus_half_its_report_interval():
    from toddlerbot.hardware.imu import REPORT_INTERVAL_S
    from toddlerbot.hardware.imu_stream import LATENCY_S

    assert HIL_LOOP_DELAY.imu_ms == round(1000 * (LATENCY_S + REPORT_INTERVAL_S / 2))
