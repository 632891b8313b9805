"""Tracking error of a parameter set on a manifest's runs, and plots of where the model misses."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.files import save_figure
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.params import Candidates
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
