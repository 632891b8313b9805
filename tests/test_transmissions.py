import mujoco
import numpy as np
import pytest

from conftest import MotorPD
from toddlerbot.robot.spec import BevelDifferential, ParallelLinkage, SpurGear
from toddlerbot.robot.transmission import build_transmission_map


def test_map_round_trips_and_torques_follow_virtual_work(spec):
    tmap = build_transmission_map(spec)
    rng = np.random.default_rng(0)
    q_motor = rng.uniform(-1, 1, len(tmap.motor_names))
    assert np.allclose(tmap.joint_to_motor(tmap.motor_to_joint(q_motor)), q_motor)
    tau_joint = rng.uniform(-1, 1, len(tmap.joint_names))
    tau_motor = tmap.joint_to_motor_torque(tau_joint)
    dq = rng.uniform(-1, 1, len(q_motor))  # equal power at motors and joints
    assert tau_motor @ dq == pytest.approx(tau_joint @ tmap.motor_to_joint(dq))


def test_gear_ratios_come_from_tooth_counts(spec):
    tmap = build_transmission_map(spec)
    hip = tmap.motor_to_joint(np.eye(len(tmap.motor_names))[tmap.motor_names.index("left_hip_yaw_drive")])
    assert hip[tmap.joint_names.index("left_hip_yaw")] == pytest.approx(-18 / 21)
    neck = tmap.motor_to_joint(np.eye(len(tmap.motor_names))[tmap.motor_names.index("neck_yaw_drive")])
    assert neck[tmap.joint_names.index("neck_yaw")] == pytest.approx(-20 / 22)


def test_waist_differential_formula(spec):
    tmap = build_transmission_map(spec)
    q = np.zeros(len(tmap.motor_names))
    q[tmap.motor_names.index("waist_drive_1")], q[tmap.motor_names.index("waist_drive_2")] = 0.4, 1.0
    joints = dict(zip(tmap.joint_names, tmap.motor_to_joint(q)))
    assert joints["waist_roll"] == pytest.approx(0.29166667 * (1.0 - 0.4))
    assert joints["waist_yaw"] == pytest.approx(0.20833333 * (1.0 + 0.4))


def _settle(model, spec, targets, seconds=1.5):
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    pd = MotorPD(model, spec)
    for _ in range(round(seconds / model.opt.timestep)):
        pd.apply(data, targets)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    return data


def _q(model, data, joint):
    return data.qpos[model.joint(joint).qposadr[0]]


def test_spur_gears_move_their_joint_by_the_ratio(spec, fixed_model):
    tmap = build_transmission_map(spec)
    gears = [t for t in spec.transmissions if isinstance(t, SpurGear)]
    targets = np.zeros(len(tmap.motor_names))
    for i, gear in enumerate(gears):
        targets[tmap.motor_names.index(gear.drive)] = 0.3 if i % 2 else -0.4
    data = _settle(fixed_model, spec, targets)
    for gear in gears:
        motor = _q(fixed_model, data, gear.drive)
        assert abs(motor) > 0.2, gear.name  # the motor really moved
        assert abs(_q(fixed_model, data, gear.driven) + gear.ratio * motor) < 1e-3, gear.name


def test_waist_motors_produce_differential_roll_and_yaw(spec, fixed_model):
    waist = next(t for t in spec.transmissions if isinstance(t, BevelDifferential))
    tmap = build_transmission_map(spec)
    targets = np.zeros(len(tmap.motor_names))
    targets[tmap.motor_names.index("waist_drive_1")] = 0.6
    targets[tmap.motor_names.index("waist_drive_2")] = 1.4
    data = _settle(fixed_model, spec, targets)
    m1, m2 = (_q(fixed_model, data, j) for j in waist.drives)
    roll, yaw = _q(fixed_model, data, waist.roll), _q(fixed_model, data, waist.yaw)
    assert yaw == pytest.approx(waist.yaw_coef * (m1 + m2), abs=waist.yaw_backlash + 1e-3)
    assert roll == pytest.approx(waist.roll_coef * (m2 - m1), abs=waist.roll_backlash + 1e-3)
    assert yaw > 0.35 and roll > 0.15  # both outputs moved well beyond the backlash


def _weld_residuals(model, data):
    """Translational residual (m) of every weld equality."""
    out = {}
    for eq in range(model.neq):
        if model.eq_type[eq] == mujoco.mjtEq.mjEQ_WELD:
            rows = np.flatnonzero((data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (data.efc_id == eq))
            out[model.equality(eq).name] = float(np.linalg.norm(data.efc_pos[rows[:3]]))
    return out


@pytest.mark.parametrize("linkage", ["neck_pitch", "left_knee", "right_knee"])
def test_linkage_loops_stay_closed_across_the_range(spec, fixed_model, linkage):
    t = next(t for t in spec.transmissions if isinstance(t, ParallelLinkage) and t.name == linkage)
    lo, hi = spec.joints[t.drive].range
    tmap = build_transmission_map(spec)
    worst = 0.0
    for fraction in (0.05, 0.5, 0.95):
        targets = np.zeros(len(tmap.motor_names))
        targets[tmap.motor_names.index(t.drive)] = lo + fraction * (hi - lo)
        data = _settle(fixed_model, spec, targets, seconds=1.0)
        welds = {k: v for k, v in _weld_residuals(fixed_model, data).items() if k.startswith(linkage)}
        assert len(welds) == 2
        worst = max(worst, *welds.values())
        assert _q(fixed_model, data, t.driven) == pytest.approx(_q(fixed_model, data, t.drive), abs=0.02)
    assert worst < 1e-3
