"""The DC-motor model in the fit: its own parameters recovered from synthetic logs with their standard errors,
runs selected by firmware gain, per-run plots of position, velocity and torque, params.json files of either model,
the robot simulator applying a DC-motor file, and (where the real logs are present) the cross-gain goal."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.params_file import load_params
from toddlerbot.cli.main import app
from toddlerbot.errors import ParamsError
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.evaluate import evaluate, firmware_duty, plot_torque_map, plot_tracking, received_torque
from toddlerbot.sysid.excitation import TORQUE_SCHEDULES, Excitation, excitation
from toddlerbot.sysid.fit import fit
from toddlerbot.sysid.manifest import Manifest, load_manifest, select_gains
from toddlerbot.sysid.params import save_params
from toddlerbot.sysid.rigs import PendulumRig
from toddlerbot.sysid.synthetic import synthesize, write_runs
from toddlerbot.sysid.uncertainty import autocorrelation_time

MOTOR = default_catalogue()["XL330-M288"]
TRUTH = DCMotorParams(damping=0.009, armature=0.0018, frictionloss=0.022, stall_torque=0.5, no_load_speed=14.0,
                      pwm_per_rad=0.00288, pwm_exponent=0.8, load_friction=0.38)
RIG = PendulumRig(mass=0.49, length=0.1)
NOISE = np.radians(0.1)
NOISE_MAE = np.degrees(NOISE) * np.sqrt(2 / np.pi)
SUPPLY = 7.3  # V, as the XL330-M288 pendulum logs (rated 5.0 V)
REAL_LOGS = Path(os.environ.get("TODDLERBOT_XL330_LOGS", Path(__file__).parents[2] / "shared/data/xl330_pendulum"))


def _excitation(profile: str, kp: int, duration: float = 3.0) -> Excitation:
    t, goal = excitation(profile, duration=duration, amplitude=0.6)
    enable = TORQUE_SCHEDULES[profile](t, duration) if profile in TORQUE_SCHEDULES else None
    return Excitation(profile, kp, t, goal, enable)


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    ex = [_excitation(p, kp) for p, kp in (("steps", 400), ("sinusoids", 100), ("drop", 400), ("chirp", 100))]
    runs = synthesize(ex, RIG, TRUTH, NOISE, seed=7, voltage=SUPPLY, rated_voltage=MOTOR.rated_voltage)
    return Manifest(Path("dc.json"), MOTOR, RIG, tuple(runs))


def test_dc_motor_fit_recovers_its_own_parameters(manifest: Manifest) -> None:
    assert evaluate(manifest, TRUTH).mae_deg == pytest.approx(NOISE_MAE, rel=0.1)
    fitted = ("stall_torque", "no_load_speed", "pwm_exponent", "load_friction", "frictionloss", "damping", "armature")
    start = TRUTH.replace(**{k: getattr(TRUTH, k) * (1.15 if i % 2 else 0.85) for i, k in enumerate(fitted)})
    assert evaluate(manifest, start).mae_deg > 5 * NOISE_MAE
    result = fit(manifest, evals=1200, popsize=24, sigma0=0.1, start=start, seed=1)
    assert result.model == "dc_motor" and result.fitted == fitted and result.at_bounds == {}
    assert evaluate(manifest, result.params).mae_deg <= 1.2 * NOISE_MAE
    for name in ("stall_torque", "no_load_speed", "pwm_exponent", "load_friction", "armature"):
        value, truth, u = getattr(result.params, name), getattr(TRUTH, name), result.uncertainty[name]
        assert value == pytest.approx(truth, rel=0.1), name
        # the standard error is small for what the runs pin, and the truth lies within 4 of them
        assert u.relative < 0.1 and abs(value - truth) < 4 * u.std, (name, u)
    assert result.params.pwm_per_rad == TRUTH.pwm_per_rad and "pwm_per_rad" in result.fixed


def test_autocorrelation_time_counts_correlated_samples() -> None:
    from scipy.signal import lfilter

    noise = np.random.default_rng(0).normal(size=200_000)
    assert autocorrelation_time(noise) == pytest.approx(1.0, abs=0.05)
    for rho in (0.5, 0.9, 0.98):  # an AR(1) series: (1 + rho) / (1 - rho) = 3, 19, 99 samples
        assert autocorrelation_time(lfilter([1.0], [1.0, -rho], noise)) == pytest.approx((1 + rho) / (1 - rho),
                                                                                         rel=0.1), rho


def test_runs_are_selected_by_gain(manifest: Manifest) -> None:
    assert [r.kp for r in select_gains(manifest, [100]).runs] == [100, 100]
    assert len(select_gains(manifest, [100, 400]).runs) == 4
    with pytest.raises(SysIDError, match=r"dc.json: no runs at kp 200, 800; its runs have kp 100, 400"):
        select_gains(manifest, [800, 200, 400])


def test_evaluation_returns_velocity_and_torque_and_plots_them(manifest: Manifest, tmp_path: Path) -> None:
    ev = evaluate(manifest, TRUTH)
    drop = ev.simulated[2]
    run = manifest.runs[2]
    off = run.torque_enable < 0.5
    assert off.any() and np.all(drop.torque[off] == 0.0) and np.abs(drop.torque[~off]).max() > 0.2
    # the simulated velocity is the rate of the simulated position (5 ms samples)
    rate = np.gradient(drop.position, run.time)
    assert np.median(np.abs(rate - drop.velocity)) < 0.05 * np.abs(drop.velocity).max()
    written = plot_tracking(manifest, ev, tmp_path)
    assert [p.name for p in written] == ["steps_kp400.png", "sinusoids_kp100.png", "drop_kp400.png", "chirp_kp100.png"]
    assert all(p.stat().st_size > 20_000 for p in written)


def test_cli_fit_and_eval_select_gains(manifest: Manifest, tmp_path: Path) -> None:
    path = write_runs(tmp_path / "logs", MOTOR.name, RIG, list(manifest.runs))
    out = tmp_path / "p.json"
    runner = CliRunner()
    result = runner.invoke(app, ["sysid", "fit", str(path), "-o", str(out), "--kp", "400", "--evals", "48",
                                 "--popsize", "24"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    body = json.loads(out.read_text())
    assert body["fit"]["kp"] == [400] and body["fit"]["runs"] == 2 and body["actuator"]["model"] == "dc_motor"
    assert "stall_torque" in result.output and "most correlated with" in result.output
    ev = json.loads(runner.invoke(app, ["sysid", "eval", str(path), str(out), "--kp", "100", "--json"],
                                  catch_exceptions=False).output)
    assert [r["kp"] for r in ev["runs"]] == [100, 100]


def test_params_files_of_either_model(tmp_path: Path) -> None:
    path = tmp_path / "p.json"
    save_params(path, "XC330", dataclasses.replace(TRUTH, stall_torque=0.9), ["stall_torque"], {})
    name, params = load_params(path)
    assert name == "XC330-T288" and isinstance(params, DCMotorParams) and params.stall_torque == 0.9
    # a partial file of the model the catalogue has keeps the other fields; of another model it must give them all
    path.write_text(json.dumps({"motor": "XL330-M288", "actuator": {"model": "dc_motor", "load_friction": 0.1}}))
    assert load_params(path)[1] == MOTOR.actuator.replace(load_friction=0.1)
    path.write_text(json.dumps({"motor": "XC330", "actuator": {"model": "dc_motor", "load_friction": 0.1}}))
    with pytest.raises(ParamsError, match=r"p.json: actuator: the dc_motor model needs damping, armature, "
                                          r"frictionloss, stall_torque, no_load_speed, pwm_per_rad"):
        load_params(path)
    path.write_text(json.dumps({"motor": "XC330", "actuator": {"model": "bam"}}))
    with pytest.raises(ParamsError, match=r"unknown actuator model 'bam'; expected one of appendix, dc_motor"):
        load_params(path)
    path.write_text(json.dumps({"motor": "XC330", "actuator": {"model": "dc_motor", "kp_scale": 150}}))
    with pytest.raises(ParamsError, match=r"unknown dc_motor field\(s\) kp_scale"):
        load_params(path)


def test_the_simulator_applies_a_dc_motor_file(tmp_path: Path) -> None:
    from toddlerbot.actuation.dc_motor import DCMotorParams
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig

    xc330 = default_catalogue()["XC330"]
    nominal = RobotDescription.load()

    def run(params) -> tuple[np.ndarray, MuJoCoRobot]:
        files = [save_params(tmp_path / "p.json", xc330.name, params, [], {})]
        robot = MuJoCoRobot(RobotDescription.load(motor_params=files), SimConfig(control_dt=0.02))
        for _ in range(5):
            obs = robot.step(robot.description.home_motor_pos + 0.2)
        return obs.motor_pos, robot

    xc = np.array([m.model == "XC330-T288" for m in nominal.motors])
    start = nominal.home_motor_pos
    appendix, _ = run(xc330.actuator)
    like = DCMotorParams.like(xc330.actuator)
    dc, _ = run(like)
    loaded, robot = run(like.replace(load_friction=0.5))
    # the DC motor moves the XC330s to their targets as the appendix model does, not identically
    assert np.all(np.abs(dc - start)[xc] > 0.1) and np.abs(dc - appendix)[xc].max() > 1e-4
    # its load-dependent friction budget slows them; the joint's own frictionloss is back after each step
    assert np.all(np.abs(loaded - start)[xc] < np.abs(dc - start)[xc])
    dof = robot.model.joint(nominal.motor_names[int(np.argmax(xc))]).dofadr[0]
    assert robot.model.dof_frictionloss[dof] == like.frictionloss


@pytest.mark.slow
@pytest.mark.skipif(not (REAL_LOGS / "manifest.json").is_file(), reason="the XL330-M288 pendulum logs are not here")
def test_real_servo_logs_cross_gain_goal() -> None:
    real = load_manifest(REAL_LOGS / "manifest.json")
    # started, as benchmarks/bench_sysid_crossgain.py is, from the e-Manual (stall torque and no-load speed at 5 V)
    # and the former catalogue guesses, not from the catalogue's fit of these logs
    start = MOTOR.actuator.replace(stall_torque=0.52, no_load_speed=103 * 2 * np.pi / 60, pwm_exponent=1.0,
                                   load_friction=0.0, frictionloss=0.019, damping=0.0019, armature=0.004)
    for trained, held in ((100, 400), (400, 100)):
        result = fit(select_gains(real, [trained]), evals=2000, start=start)
        assert evaluate(select_gains(real, [held]), result.params).mae_deg <= 2.0, (trained, held)


@pytest.mark.skipif(not (REAL_LOGS / "manifest.json").is_file(), reason="the XL330-M288 pendulum logs are not here")
def test_the_catalogue_xl330_tracks_every_real_run_including_kp_800() -> None:
    """The catalogue's XL330-M288 is the fit of all ten real runs (kp 100, 400 and 800): it replays each within
    3 deg MAE (worst: lift_and_drop at kp 800, 2.93 deg, where the real servo stalls 10 deg below the model)."""
    real = load_manifest(REAL_LOGS / "manifest.json")
    result = evaluate(real, MOTOR.actuator)
    per_run = {run.file: run.mae_deg for run in result.runs}
    assert len(per_run) == 10 and {run.kp for run in real.runs} == {100.0, 400.0, 800.0}
    assert result.mae_deg == pytest.approx(1.58, abs=0.02)
    assert max(per_run.values()) <= 3.0 and max(per_run, key=per_run.get) == "lift_and_drop_kp800.csv"


def test_received_torque_is_the_models_torque_on_its_own_run(tmp_path: Path) -> None:
    """On a noise-free run of the DC-motor model itself (no Coulomb friction, so the shaft receives the motor's
    torque whole), the torque reconstructed from the logged motion is the model's, and the duty is the firmware's."""
    truth = TRUTH.replace(load_friction=0.0, frictionloss=0.001)
    ex = [_excitation("sinusoids", 400, duration=2.0)]
    run = synthesize(ex, RIG, truth, 0.0, voltage=SUPPLY, rated_voltage=MOTOR.rated_voltage)[0]
    manifest = Manifest(Path("own.json"), MOTOR, RIG, (run,))
    model = evaluate(manifest, truth).simulated[0].torque
    received = received_torque(run, RIG, truth)
    inner = slice(10, -10)  # the filter's window reaches past the ends there
    assert np.median(np.abs(received - model)[inner]) < 0.01 * np.max(np.abs(model))
    assert np.corrcoef(received[inner], model[inner])[0, 1] > 0.996  # 0.994 with the armature 2x off
    duty = firmware_duty(run, truth)
    assert duty == pytest.approx(np.clip(0.00288 * 400 * (run.goal_position - run.position), -1, 1))
    assert plot_torque_map(manifest, truth, tmp_path / "map.png").stat().st_size > 10_000
