"""Ground truth as a capability: the simulator and the hardware-in-the-loop plant report the torso's true pose from
one computation, and the runner logs it only for robots that have it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from toddlerbot.hardware.emulator import EmulatedBus
from toddlerbot.policies import make_policy
from toddlerbot.robot.interface import GroundTruth, Observation, Robot
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


def _tilt(data: mujoco.MjData, model: mujoco.MjModel, angle: float, drop: float) -> None:
    """Roll the floating base by ``angle`` about world x and lower it by ``drop`` m, then recompute kinematics."""
    data.qpos[3:7] = [np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0]
    data.qpos[2] -= drop
    mujoco.mj_forward(model, data)


@pytest.fixture(scope="module")
def sim_and_hil(description):
    return MuJoCoRobot(description), EmulatedBus(description, hil=True).plant


def test_simulator_and_hil_plant_report_the_same_torso_pose(sim_and_hil):
    sim, hil = sim_and_hil
    assert isinstance(sim, GroundTruth) and isinstance(hil, GroundTruth)
    sim.reset()
    assert sim.torso_height() == hil.torso_height() == sim.standing_height == hil.standing_height
    assert sim.torso_uprightness() == hil.torso_uprightness() == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_array_equal(sim.base_pos, hil.base_pos)
    standing = sim.standing_height
    for angle, drop, fallen in [(0.5, 0.0, False), (1.2, 0.0, True), (0.0, 0.5 * standing, True)]:
        _tilt(sim.data, sim.model, angle, drop)
        _tilt(hil.data, hil.model, angle, drop)
        assert sim.torso_uprightness() == hil.torso_uprightness() == pytest.approx(np.cos(angle), abs=1e-9)
        assert sim.torso_height() == hil.torso_height()
        np.testing.assert_array_equal(sim.base_quat, hil.base_quat)
        assert sim.fallen == hil.fallen == fallen
        sim.reset()
        mujoco.mj_resetDataKeyframe(hil.model, hil.data, hil.model.key("home").id)


class _NoTruth(Robot):
    """A robot without the capability that still has a ``base_pos`` attribute: the runner must not take it."""

    def __init__(self, sim: MuJoCoRobot) -> None:
        super().__init__(sim.description, sim.control_dt)
        self.sim = sim
        self.base_pos = np.zeros(3)

    def reset(self) -> Observation:
        return self.sim.reset()

    def observe(self) -> Observation:
        return self.sim.observe()

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        return self.sim.step(motor_targets, kp, kd)


def test_runner_logs_ground_truth_only_from_robots_that_have_it(sim_and_hil):
    sim, _ = sim_and_hil
    stand = lambda robot: run_policy(robot, make_policy("stand", robot), lambda t: np.zeros(3), 0.2)  # noqa: E731
    blind = stand(_NoTruth(sim)).log
    assert np.isnan(blind.base_pos).all() and np.isnan(blind.base_quat).all()
    seen = stand(sim).log
    assert seen.base_pos.shape == (10, 3) and np.isfinite(seen.base_quat).all()
    assert seen.base_pos[0, 2] == pytest.approx(sim.description.model("floating", scene=True).key("home").qpos[2])
    np.testing.assert_array_equal(seen.motor_pos, blind.motor_pos)  # the same run, only the logging differs
