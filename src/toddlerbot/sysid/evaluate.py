"""Tracking error of a parameter set on a manifest's runs, plots of where the model misses, and the torque the
logs say the shaft received against the firmware's PWM duty (what the DC-motor model's torque law is judged by)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.files import save_figure
from toddlerbot.sysid.logs import MotorLog
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.params import Candidates
from toddlerbot.sysid.rigs import SimpleRig
from toddlerbot.sysid.simulate import DT, Replay, RunBatch, simulate


@dataclass(frozen=True)
class RunError:
    file: str
    mae_deg: float
    rmse_deg: float
    kp: float
    """Firmware P gain of the run."""


@dataclass(frozen=True)
class Evaluation:
    mae_deg: float
    """Over all samples of all runs, degrees."""
    rmse_deg: float
    runs: list[RunError]
    simulated: list[Replay]
    """Simulated position (rad), velocity (rad/s) and motor torque (N*m) of each run at its log samples, each (N,)."""

    def to_json(self) -> dict:
        """``{"mae_deg", "rmse_deg", "runs": [{"file", "mae_deg", "rmse_deg", "kp"}, ...]}``."""
        return {"mae_deg": self.mae_deg, "rmse_deg": self.rmse_deg, "runs": [dataclasses.asdict(r) for r in self.runs]}


def evaluate(manifest: Manifest, params: MotorParams, dt: float = DT) -> Evaluation:
    """Replay every run with ``params`` and compare simulated with measured positions."""
    batch = RunBatch.from_runs(manifest.runs, dt, manifest.motor.rated_voltage)
    replay = simulate(batch, manifest.rig, Candidates.of(params), full=True)
    err = np.degrees(replay.position[0] - batch.measured)
    runs = [
        RunError(file=str(run.file.relative_to(manifest.path.parent)) if run.file.is_relative_to(manifest.path.parent)
                 else str(run.file), mae_deg=float(np.mean(np.abs(e))), rmse_deg=float(np.sqrt(np.mean(e**2))),
                 kp=run.kp)
        for run, e in zip(manifest.runs, batch.split(err), strict=True)
    ]
    per_run = zip(*(batch.split(series[0]) for series in replay), strict=True)
    return Evaluation(mae_deg=float(np.mean(np.abs(err))), rmse_deg=float(np.sqrt(np.mean(err**2))), runs=runs,
                      simulated=[Replay(*series) for series in per_run])


def plot_tracking(manifest: Manifest, evaluation: Evaluation, folder: str | Path) -> list[Path]:
    """One PNG per run: goal, measured and simulated position (deg), measured and simulated velocity, and the
    simulated motor torque over time (torque-off time shaded)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for run, sim, err in zip(manifest.runs, evaluation.simulated, evaluation.runs, strict=True):
        fig, (pos, vel, tau) = plt.subplots(3, 1, figsize=(9, 7), sharex=True, height_ratios=(3, 2, 2))
        t = run.time - run.time[0]
        pos.plot(t, np.degrees(run.goal_position), color="0.6", lw=1, label="goal")
        pos.plot(t, np.degrees(run.position), lw=1.2, label="measured")
        pos.plot(t, np.degrees(sim.position), lw=1.2, ls="--", label="simulated")
        pos.set_ylabel("position (deg)")
        pos.set_title(f"{err.file}: kp={run.kp:g} kd={run.kd:g}  "
                      f"MAE {err.mae_deg:.2f} deg  RMSE {err.rmse_deg:.2f} deg")
        if run.velocity is not None:
            vel.plot(t, run.velocity, lw=1, label="measured")
        vel.plot(t, sim.velocity, lw=1, ls="--", color="C1", label="simulated")
        vel.set_ylabel("velocity (rad/s)")
        tau.plot(t, sim.torque, lw=1, color="C2", label="simulated motor torque")
        tau.axhline(0.0, color="0.3", lw=0.5)
        tau.set_ylabel("torque (N m)")
        tau.set_xlabel("time (s)")
        for ax in (pos, vel, tau):
            if run.torque_enable is not None and not run.torque_enable.all():
                ax.fill_between(t, 0, 1, where=run.torque_enable < 0.5, transform=ax.get_xaxis_transform(),
                                color="0.9", label="torque off" if ax is pos else None)
            ax.legend(loc="upper right", fontsize=8)
        target = Path(folder) / f"{Path(err.file).stem}.png"
        written.append(save_figure(fig, target, dpi=100))
    return written


SMOOTHING_SAMPLES = 9
"""Window of the Savitzky-Golay filter (quadratic) that differentiates the logged velocity, samples (45 ms at
200 Hz)."""


def received_torque(run: MotorLog, rig: SimpleRig, params: MotorParams) -> np.ndarray:
    """The torque the output shaft received at each sample, N*m: (load inertia + armature) x acceleration, plus the
    rig's gravity and the passive damping x velocity, from the logged velocity (the position's where none is
    logged) differentiated over `SMOOTHING_SAMPLES`. While the motor drives the shaft this is its torque less the
    Coulomb friction budget; it depends on the model only through the armature and damping."""
    from scipy.signal import savgol_filter

    dt = float(np.median(np.diff(run.time)))
    if run.velocity is not None:
        velocity = savgol_filter(run.velocity, SMOOTHING_SAMPLES, 2)
        acceleration = savgol_filter(run.velocity, SMOOTHING_SAMPLES, 2, deriv=1, delta=dt)
    else:
        velocity = savgol_filter(run.position, SMOOTHING_SAMPLES, 2, deriv=1, delta=dt)
        acceleration = savgol_filter(run.position, SMOOTHING_SAMPLES, 2, deriv=2, delta=dt)
    inertia = rig.load_inertia + params.armature
    return inertia * acceleration + rig.gravity_gain * np.sin(run.position) + params.damping * velocity


def firmware_duty(run: MotorLog, params: MotorParams) -> np.ndarray:
    """The PWM duty (-1..1) the firmware's P controller sets at each sample of a DC-motor model's run."""
    return np.clip(params.pwm_per_rad * run.kp * (run.goal_position - run.position), -1.0, 1.0)


def plot_torque_map(manifest: Manifest, params: MotorParams, target: str | Path) -> Path:
    """One panel per firmware gain: the torque the shaft received (`received_torque`) against the firmware's duty
    (`firmware_duty`, DC-motor parameters) while powered and moving (|q_dot| > 0.3 rad/s), blue where the motor
    drives the motion and red where it brakes. At one duty the points of every gain should lie together if the
    duty is what sets the torque."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gains = sorted({run.kp for run in manifest.runs})
    fig, axes = plt.subplots(1, len(gains), figsize=(5 * len(gains), 4.5), sharex=True, sharey=True, squeeze=False)
    for ax, kp in zip(axes[0], gains, strict=True):
        for run in (r for r in manifest.runs if r.kp == kp):
            duty, tau = firmware_duty(run, params), received_torque(run, manifest.rig, params)
            velocity = run.velocity if run.velocity is not None else np.gradient(run.position, run.time)
            on = np.ones(len(duty), bool) if run.torque_enable is None else run.torque_enable > 0.5
            moving = on & (np.abs(velocity) > 0.3)
            driving = np.sign(velocity) == np.sign(duty)
            ax.scatter(duty[moving & driving], tau[moving & driving], s=2, color="C0")
            ax.scatter(duty[moving & ~driving], tau[moving & ~driving], s=2, color="C3")
        ax.set_title(f"kp {kp:g}: blue drives the motion, red brakes")
        ax.set_xlabel("firmware PWM duty")
        ax.grid(True)
    axes[0][0].set_ylabel("torque the shaft received (N m)")
    return save_figure(fig, Path(target), dpi=100)
