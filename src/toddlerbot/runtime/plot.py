"""Plots of a run log (matplotlib, Agg backend): per-joint tracking, IMU, and the loop-time histogram."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toddlerbot.files import save_figure
from toddlerbot.runtime.log import RunLog


def plot_log(log: RunLog, out_dir: str | Path) -> list[Path]:
    """Write tracking.png (target vs measured per joint), imu.png and loop_time.png into out_dir."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    n = len(log.joint_names)
    cols = 5
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.0 * rows), sharex=True)
    for i, ax in enumerate(axes.flat):
        if i >= n:
            ax.axis("off")
            continue
        ax.plot(log.time, log.joint_target[:, i], label="target", lw=1)
        ax.plot(log.time, log.joint_pos[:, i], label="measured", lw=1)
        ax.set_title(log.joint_names[i], fontsize=8)
        ax.tick_params(labelsize=7)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"joint tracking ({log.policy}), rad")
    paths.append(save_figure(fig, out / "tracking.png", dpi=80))

    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True)
    for ax, key, unit in zip(axes, ("imu_quat", "imu_ang_vel", "imu_lin_acc"), ("", "rad/s", "m/s^2"), strict=False):
        data = getattr(log, key)
        labels = "wxyz" if key == "imu_quat" else "xyz"
        for j in range(data.shape[1]):
            ax.plot(log.time, data[:, j], label=labels[j], lw=1)
        ax.set_ylabel(f"{key} {unit}")
        ax.legend(fontsize=7, ncol=4)
    axes[-1].set_xlabel("time (s)")
    paths.append(save_figure(fig, out / "imu.png", dpi=80))

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.hist(log.compute_time * 1e3, bins=50, alpha=0.7, label="compute (policy + step)")
    ax.hist(log.step_period * 1e3, bins=50, alpha=0.7, label="step period")
    ax.axvline(log.control_dt * 1e3, color="k", ls="--", label="control period")
    ax.set_xlabel("ms")
    ax.legend()
    paths.append(save_figure(fig, out / "loop_time.png", dpi=80))
    return paths
