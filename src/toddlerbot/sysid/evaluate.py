"""Tracking error of a parameter set on a manifest's runs, and plots of measured vs simulated tracking."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams
from toddlerbot.files import save_figure
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.simulate import DT, RunBatch, simulate


@dataclass(frozen=True)
class RunError:
    file: str
    mae_deg: float
    rmse_deg: float


@dataclass(frozen=True)
class Evaluation:
    mae_deg: float
    """Over all samples of all runs, degrees."""
    rmse_deg: float
    runs: list[RunError]
    simulated: list[np.ndarray]
    """Simulated position of each run at its log samples, rad."""

    def to_json(self) -> dict:
        """``{"mae_deg", "rmse_deg", "runs": [{"file", "mae_deg", "rmse_deg"}, ...]}``."""
        return {"mae_deg": self.mae_deg, "rmse_deg": self.rmse_deg, "runs": [dataclasses.asdict(r) for r in self.runs]}


def evaluate(manifest: Manifest, params: ActuatorParams, dt: float = DT) -> Evaluation:
    """Replay every run with ``params`` and compare simulated with measured positions."""
    batch = RunBatch.from_runs(manifest.runs, dt, manifest.motor.rated_voltage)
    fields = {k: np.array([float(v)]) for k, v in dataclasses.asdict(params).items()}
    sim = simulate(batch, manifest.rig, fields)[0]
    err = np.degrees(sim - batch.measured)
    runs = [
        RunError(file=str(run.file.relative_to(manifest.path.parent)) if run.file.is_relative_to(manifest.path.parent)
                 else str(run.file), mae_deg=float(np.mean(np.abs(e))), rmse_deg=float(np.sqrt(np.mean(e**2))))
        for run, e in zip(manifest.runs, batch.split(err), strict=True)
    ]
    return Evaluation(mae_deg=float(np.mean(np.abs(err))), rmse_deg=float(np.sqrt(np.mean(err**2))), runs=runs,
                      simulated=batch.split(sim))


def plot_tracking(manifest: Manifest, evaluation: Evaluation, folder: str | Path) -> list[Path]:
    """One PNG per run: goal, measured and simulated position (deg) over time (torque-off time shaded), and the
    error below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for run, sim, err in zip(manifest.runs, evaluation.simulated, evaluation.runs, strict=True):
        fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5), sharex=True, height_ratios=(3, 1))
        t = run.time - run.time[0]
        top.plot(t, np.degrees(run.goal_position), color="0.6", lw=1, label="goal")
        top.plot(t, np.degrees(run.position), lw=1.2, label="measured")
        top.plot(t, np.degrees(sim), lw=1.2, ls="--", label="simulated")
        if run.torque_enable is not None and not run.torque_enable.all():
            top.fill_between(t, 0, 1, where=run.torque_enable < 0.5, transform=top.get_xaxis_transform(),
                             color="0.9", label="torque off")
        top.set_ylabel("position (deg)")
        top.set_title(f"{err.file}: kp={run.kp:g} kd={run.kd:g}  "
                      f"MAE {err.mae_deg:.2f} deg  RMSE {err.rmse_deg:.2f} deg")
        top.legend(loc="upper right", fontsize=8)
        bottom.plot(t, np.degrees(sim - run.position), color="C3", lw=1)
        bottom.set_ylabel("sim - meas (deg)")
        bottom.set_xlabel("time (s)")
        target = Path(folder) / f"{Path(err.file).stem}.png"
        written.append(save_figure(fig, target, dpi=100))
    return written
