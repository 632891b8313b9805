"""The one actuated plant: `MotorDrive` (the actuator model as the physics substeps evaluate it, with torque enable
and torque limits) and `step_actuated`, and the hardware-in-the-loop plant stepping through them."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from toddlerbot.actuation.model import motor_torque
from toddlerbot.hardware.control_table import MODE_CURRENT_BASED_POSITION, traits
from toddlerbot.hardware.emulator import EmulatedBus
from toddlerbot.hardware.plant import commands
from toddlerbot.sim.actuated import MotorAddresses, step_actuated
from toddlerbot.sim.motor_drive import MotorDrive


def _states(n_motors: int, batch: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Targets, angles and speeds (rad, rad/s) from holding still to saturating at full speed, with exact zeros."""
    rng = np.random.default_rng(seed)
    shape = (batch, n_motors)
    speed = rng.normal(0.0, 4.0, shape) * rng.integers(0, 2, shape)  # half the motors exactly at rest
    return rng.normal(0.0, 1.0, shape), rng.normal(0.0, 1.0, shape), speed


@pytest.mark.parametrize("model", ["appendix", "dc_motor"])
def test_drive_equals_the_actuator_model_bit_for_bit(description, model):
    params = description.actuator_arrays()
    n = len(params.kp)
    if model == "dc_motor":  # PWM shape, back-EMF and a friction budget: the terms the appendix model lacks
        params = params._replace(pwm_exponent=np.full(n, 0.8), back_emf_damping=np.full(n, 0.03),
                                 stiction=np.full(n, 0.01), load_friction=np.full(n, 0.2))
    drive = MotorDrive(params)
    for seed, scale in enumerate([0.01, 1.0, 30.0]):  # within the limits, some motors saturated, all saturated
        targets, q, q_dot = _states(n, 64, seed)
        expected = motor_torque(targets * scale, q * scale, q_dot, params)
        actual = drive.torque(targets * scale, q * scale, q_dot)
        if model == "dc_motor":  # pow: numpy's vector form (AVX-512) and the C library's may differ in the last bit
            np.testing.assert_allclose(actual, expected, rtol=1e-14, atol=1e-14)  # (4 ulp seen)
        else:  # no transcendental function: the same operations, the same bits
            np.testing.assert_array_equal(actual, expected)
    assert drive.has_friction_excess == (model == "dc_motor")


def test_torque_off_motors_apply_exactly_zero(description):
    params = description.actuator_arrays()
    n = len(params.kp)
    torque_on = np.arange(n) % 3 != 0
    targets, q, q_dot = _states(n, 8, 4)
    tau = MotorDrive(params, torque_on=torque_on).torque(targets, q, q_dot)
    assert np.all(tau[:, ~torque_on] == 0.0)
    np.testing.assert_array_equal(tau[:, torque_on], motor_torque(targets, q, q_dot, params)[:, torque_on])
    assert np.count_nonzero(tau[:, torque_on]) == tau[:, torque_on].size  # the others really push


def test_torque_limit_clamps_and_leaves_smaller_torques_alone(description):
    params = description.actuator_arrays()
    n = len(params.kp)
    limit = np.full(n, 0.3)
    targets, q, q_dot = _states(n, 8, 5)
    free = motor_torque(targets, q, q_dot, params)
    tau = MotorDrive(params, torque_limit=limit).torque(targets, q, q_dot)
    assert np.abs(free).max() > 0.6  # the test's torques do exceed the limit
    np.testing.assert_array_equal(tau, np.clip(free, -0.3, 0.3))
    with pytest.raises(ValueError, match="torque_limit must be >= 0"):
        MotorDrive(params, torque_limit=np.full(n, -1.0))


def test_step_applies_the_drive_every_substep(description):
    """Torque-off motors get zero ctrl in MuJoCo, limited ones at most their limit, and the state advances."""
    model = description.model("floating", scene=True)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    motors = MotorAddresses.of(model, description.motor_names)
    n = len(description.motor_names)
    torque_on, limit = np.arange(n) >= 4, np.full(n, 0.05)
    targets = np.asarray(description.home_motor_pos)[None] + 0.5  # far from home: every motor wants > 0.05 N*m
    drive = MotorDrive(description.actuator_arrays(), torque_on=torque_on, torque_limit=limit)
    tau = step_actuated([model], [data], motors, targets, drive, 3)
    assert data.time == pytest.approx(3 * model.opt.timestep)
    np.testing.assert_array_equal(data.ctrl[motors.actuator], tau[0])
    assert np.all(tau[0, :4] == 0.0)
    np.testing.assert_array_equal(np.abs(tau[0, 4:]), 0.05)
    with pytest.raises(ValueError, match="n_substeps must be >= 1"):
        step_actuated([model], [data], motors, targets, drive, 0)


def test_hil_plant_steps_with_each_motors_torque_enable_and_current_limit(description):
    """The emulator's control tables reach the shared step: torque off gives zero torque, a current-based
    position motor is held to its goal current's torque."""
    plant = EmulatedBus(description, hil=True).plant
    off, limited = plant.motors[0], plant.motors[7]  # motor 7: an XM430, which senses current
    for motor in plant.motors[1:]:
        motor.set("torque_enable", 1)
        motor.set("goal_position", motor.get("goal_position") + 300)  # 26 degrees off: a large torque
    limited.set("operating_mode", MODE_CURRENT_BASED_POSITION)
    limited.set("goal_current", 20)
    t = traits(limited.model)
    cmd = commands(plant.motors, plant.params)
    plant.advance(cmd, 5)
    tau = plant.data.ctrl[[plant.model.actuator(motor.name).id for motor in plant.motors]]
    assert plant.sim_time == pytest.approx(5 * plant.model.opt.timestep)
    assert tau[0] == 0.0 and not off.torque_on
    assert abs(tau[7]) == pytest.approx(20 * t.current_unit_a * t.torque_per_amp, rel=1e-12)  # 0.070 N*m
    assert np.count_nonzero(tau[1:]) == len(tau) - 1
    assert plant.powered_min_upright > 0.99  # bookkeeping of the powered motion ran


def test_one_robot_with_its_own_parameter_row_steps_like_the_shared_parameters(description):
    """A batch of one with per-robot parameter rows ((1, n_motors), as the RL environment's chunks pass them) gives
    the shared-parameter torques exactly, also when the drive limit clamps (targets 1 rad off: every motor at its
    limit)."""
    model = description.model("floating", scene=True)
    motors = MotorAddresses.of(model, description.motor_names)
    shared = description.actuator_arrays()
    rows = type(shared)(*(np.asarray(x)[None] for x in shared))
    taus = []
    for params in (shared, rows):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
        targets = (description.home_motor_pos + 1.0)[None]
        taus.append(step_actuated([model], [data], motors, targets, MotorDrive(params), 3))
    assert MotorDrive(rows).per_robot and not MotorDrive(shared).per_robot
    assert np.abs(taus[0]).max() > 0.1
    np.testing.assert_array_equal(taus[0], taus[1])


def test_a_batch_in_one_compiled_call_steps_each_robot_as_step_actuated_does(description):
    """`step_batch` writes each robot's fields and state, steps it and reads it back: the same torques, state and
    last-substep sensors as writing them in Python and calling `step_actuated`, bit for bit; the sensor flag it
    toggles is restored, and a robot MuJoCo had to reset is reported."""
    from toddlerbot.sim.actuated import BatchArrays, step_batch

    model = description.model("floating", scene=True)
    motors = MotorAddresses.of(model, description.motor_names)
    rng = np.random.default_rng(3)
    n, n_substeps = 3, 4
    shared = description.actuator_arrays()
    rows = type(shared)(*(np.asarray(x) * rng.uniform(0.9, 1.1, (n, len(np.asarray(x)))) for x in shared))
    targets = description.home_motor_pos + rng.uniform(-0.3, 0.3, (n, len(description.motor_names)))
    home = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, home, model.key("home").id)
    qvel = rng.normal(0.0, 0.1, (n, model.nv))
    pull = np.zeros((n, model.nbody, 6))
    pull[2, 1, 2] = 1e15  # N: MuJoCo finds a bad acceleration, resets this robot and warns
    damping = model.dof_damping * rng.uniform(0.5, 2.0, (n, model.nv))
    flags = model.opt.disableflags

    def pairs():
        models = [copy.copy(model) for _ in range(n)]
        datas = [mujoco.MjData(model) for _ in range(n)]
        for d in datas:
            mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
        return models, datas

    models, datas = pairs()  # as the RL backend did it: Python writes, then step_actuated
    for i, (m, d) in enumerate(zip(models, datas, strict=True)):
        m.dof_damping[:] = damping[i]
        d.qvel[:] = qvel[i]
        d.xfrc_applied[:] = pull[i]
    expected = step_actuated(models, datas, motors, targets, MotorDrive(rows), n_substeps, sensors_last_only=True)

    models2, datas2 = pairs()
    arrays = BatchArrays.of(models2, datas2, ("model.dof_damping", "data.qpos", "data.qvel", "data.xfrc_applied"),
                            ("data.qpos", "data.qvel", "data.sensordata"))
    written = np.concatenate([damping, np.tile(home.qpos, (n, 1)), qvel, pull.reshape(n, -1)], axis=1)
    torques, reads, warned = step_batch(arrays, np.arange(n), motors, targets, MotorDrive(rows), n_substeps,
                                        written, sensors_last_only=True)
    np.testing.assert_array_equal(torques, expected)
    nq, nv = model.nq, model.nv
    for i, d in enumerate(datas):
        np.testing.assert_array_equal(reads[i, :nq], d.qpos)
        np.testing.assert_array_equal(reads[i, nq:nq + nv], d.qvel)
        np.testing.assert_array_equal(reads[i, nq + nv:], d.sensordata)
        np.testing.assert_array_equal(datas2[i].qpos, d.qpos)
        assert models2[i].opt.disableflags == flags  # the sensors' flag is back
    assert np.abs(torques).max() > 0.1 and np.abs(reads[0, :nq] - home.qpos).max() > 1e-4  # it moved
    assert warned.tolist() == [False, False, True]
    assert datas[2].warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
    with pytest.raises(ValueError, match=r"written has shape \(3, \d+\), expected \(2, "):
        step_batch(arrays, np.arange(2), motors, targets[:2], MotorDrive(rows), n_substeps, written)
