"""The extended friction model in the fit: torque-off (passive) replay, the supply-voltage law, a known extended
model recovered from synthetic logs with drops, the 9-parameter model visibly worse on them, bounds reported, the
friction budget applied by the robot simulator."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.actuation.appendix import ActuatorParams
from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.params_file import load_params
from toddlerbot.cli.main import app
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.evaluate import evaluate
from toddlerbot.sysid.excitation import TORQUE_SCHEDULES, Excitation, excitation
from toddlerbot.sysid.fit import fit
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.params import at_bounds, parameter_names
from toddlerbot.sysid.rigs import PendulumRig
from toddlerbot.sysid.synthetic import synthesize, write_runs

# an XL330-M288 in the appendix's terms (the catalogue's values before the DC-motor fit: the XC330's scaled by the
# datasheet), at the 7.4 V
MOTOR = dataclasses.replace(default_catalogue()["XL330-M288"], actuator=ActuatorParams(
    damping=0.0019, armature=0.0040, frictionloss=0.019, tau_max=0.40, q_dot_tau_max=2.60, q_dot_max=9.50,
    tau_q_dot_max=0.25, kd_min=0.137, tau_brake=0.91, kp_scale=334.0))
TRUTH = MOTOR.actuator.replace(stiction=0.06, stribeck_velocity=0.2, load_friction=0.35)
RIG = PendulumRig(mass=0.49, length=0.1)
NOISE = np.radians(0.1)
SUPPLY = 7.4  # V, as the XL330-M288 pendulum logs (rated 5.0 V)


def _excitation(profile: str, kp: int, duration: float = 3.0) -> Excitation:
    t, goal = excitation(profile, duration=duration, amplitude=0.5)
    enable = TORQUE_SCHEDULES[profile](t, duration) if profile in TORQUE_SCHEDULES else None
    return Excitation(profile, kp, t, goal, enable)


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    ex = [_excitation(p, kp) for p, kp in (("steps", 400), ("sinusoids", 100), ("drop", 400), ("chirp", 100))]
    runs = synthesize(ex, RIG, TRUTH, NOISE, seed=5, voltage=SUPPLY, rated_voltage=MOTOR.rated_voltage)
    return Manifest(Path("extended.json"), MOTOR, RIG, tuple(runs))


def test_torque_off_is_passive_and_voltage_scales_the_motor() -> None:
    plain = MOTOR.actuator
    held = synthesize([_excitation("drop", 400)], RIG, plain)[0]
    powered = dataclasses.replace(_excitation("drop", 400), torque_enable=None)
    kept = synthesize([powered], RIG, plain)[0]
    late = held.time > 2.5
    # with torque on the motor holds the raised pendulum near its goal (1 rad, sagging under gravity) ...
    assert np.all(kept.position[late] > 0.5)
    # ... with torque off from 1.5 s it falls and swings through the bottom (q = 0)
    assert np.min(held.position[held.time > 1.5]) < -0.3
    # torque off throughout: the same free swing from 1 rad at any gain and goal (no PD torque, no kd_min),
    # decaying only through the passive friction loss, damping and static friction
    t = np.arange(0, 2.0, 0.005)
    off = [Excitation("off", kp, t, np.full_like(t, goal), np.zeros_like(t)) for kp, goal in ((100, 0.0), (2000, 1.5))]
    swing_a, swing_b = synthesize(off, RIG, TRUTH, q0=1.0)
    np.testing.assert_array_equal(swing_a.position, swing_b.position)
    assert np.min(swing_a.position) < -0.3 and np.abs(swing_a.position[-100:]).max() < 0.9
    # at 7.4 V the gains grow by 1.48 (PWM duty x supply): holding 0.5 rad at kp 100, the pendulum sags to the
    # equilibrium kp_phys * s * (0.5 - q) = m g l sin(q), less at the higher supply
    hold = [Excitation("hold", 100, t, np.full_like(t, 0.5))]
    from scipy.optimize import brentq

    for volts in (5.0, 7.4):
        run = synthesize(hold, RIG, plain, q0=0.5, voltage=volts, rated_voltage=5.0)[0]
        kp = 100 / plain.kp_scale * volts / 5.0
        q_eq = brentq(lambda q, kp=kp: kp * (0.5 - q) - RIG.gravity_gain * np.sin(q), 0.0, 0.5)
        assert run.position[-1] == pytest.approx(q_eq, abs=0.03), volts
    assert q_eq - brentq(lambda q: 100 / plain.kp_scale * (0.5 - q) - RIG.gravity_gain * np.sin(q), 0, 0.5) > 0.04


@pytest.mark.slow
def test_extended_fit_recovers_the_model_that_the_appendix_model_cannot(manifest: Manifest) -> None:
    noise_mae = np.degrees(NOISE) * np.sqrt(2 / np.pi)
    assert evaluate(manifest, TRUTH).mae_deg == pytest.approx(noise_mae, rel=0.15)
    fields = dataclasses.asdict(TRUTH)
    start = TRUTH.replace(**{k: v * (1.15 if i % 2 else 0.85) for i, (k, v) in enumerate(fields.items())
                             if k != "kp_scale"})
    extended = fit(manifest, model="extended", evals=1600, popsize=24, sigma0=0.1, start=start, seed=1)
    appendix = fit(manifest, model="appendix", evals=960, popsize=24, sigma0=0.1, seed=1,
                   start=start.replace(stiction=0.0, load_friction=0.0))
    mae_ext, mae_app = (evaluate(manifest, r.params).mae_deg for r in (extended, appendix))
    assert mae_ext <= 1.5 * noise_mae
    for name in ("stiction", "stribeck_velocity", "load_friction", "tau_max", "kd_min", "armature"):
        assert getattr(extended.params, name) == pytest.approx(getattr(TRUTH, name), rel=0.15), name
    assert mae_app > 8 * mae_ext  # measured: 2.4 deg against 0.099 deg
    assert extended.fitted == parameter_names(False, "extended") and extended.model == "extended"


def test_bounds_are_reported() -> None:
    names = parameter_names(True, "extended")
    u = np.full(len(names), 0.5)
    u[names.index("kp_scale")], u[names.index("stiction")] = 0.995, 0.004
    assert at_bounds(u, names) == {"kp_scale": "upper", "stiction": "lower"}
    with pytest.raises(SysIDError, match="unknown model 'richest'; expected one of appendix, extended, dc_motor"):
        parameter_names(False, "richest")


def test_cli_fit_extended_writes_all_parameters_and_keeps_a_good_file(tmp_path: Path, manifest: Manifest) -> None:
    path = write_runs(tmp_path / "logs", MOTOR.name, RIG, list(manifest.runs))
    header = (tmp_path / "logs" / "drop_kp400.csv").read_text().splitlines()[0]
    assert header == "time,goal_position,position,torque_enable,voltage"
    out = tmp_path / "params.json"
    result = CliRunner().invoke(app, ["sysid", "fit", str(path), "-o", str(out), "--model", "extended",
                                      "--evals", "48", "--popsize", "24"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    body = json.loads(out.read_text())
    assert body["fit"]["model"] == "extended" and len(body["fitted"]) == 12
    assert isinstance(body["fit"]["at_bounds"], dict)
    name, params = load_params(out)
    assert name == "XL330-M288-T" and params.load_friction == body["actuator"]["load_friction"]
    # a fit that fails (a log turned into degrees) leaves the good params.json as it was
    good = out.read_text()
    csv = tmp_path / "logs" / "steps_kp400.csv"
    lines = csv.read_text().splitlines()
    cells = lines[50].split(",")
    cells[2] = "28.6"
    csv.write_text("\n".join([*lines[:50], ",".join(cells), *lines[51:]]) + "\n")
    with pytest.raises(SysIDError, match=r"steps_kp400.csv: line 51: column 'position' is 28.6; .*not degrees"):
        CliRunner().invoke(app, ["sysid", "fit", str(path), "-o", str(out), "--model", "extended"],
                           catch_exceptions=False)
    assert out.read_text() == good


def test_the_simulator_applies_a_fitted_friction_budget(tmp_path: Path) -> None:
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig
    from toddlerbot.sysid.params import save_params

    xc330 = default_catalogue()["XC330"]

    def moved(params) -> np.ndarray:
        files = [save_params(tmp_path / "p.json", xc330.name, params, parameter_names(False, "extended"), {})]
        robot = MuJoCoRobot(RobotDescription.load(motor_params=files), SimConfig(control_dt=0.02))
        targets = robot.description.home_motor_pos + 0.2
        for _ in range(5):
            obs = robot.step(targets)
        return obs.motor_pos

    xc = np.array([m.model == "XC330-T288" for m in RobotDescription.load().motors])
    appendix = moved(xc330.actuator)
    # the extended fields at their defaults, written to a params.json, give the appendix model bit for bit
    np.testing.assert_array_equal(moved(xc330.actuator.replace(stribeck_velocity=0.5)), appendix)
    # a fitted friction budget (load-dependent Coulomb friction) slows the XC330s on their way to the targets
    extended = moved(xc330.actuator.replace(stiction=0.05, load_friction=0.3))
    start = RobotDescription.load().home_motor_pos
    assert np.all(np.abs(extended - start)[xc] < np.abs(appendix - start)[xc])
