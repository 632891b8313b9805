"""Learning curves of training runs (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from toddlerbot.files import save_figure
from toddlerbot.rl.run_files import IMITATION_RECORD, METRICS_RECORD, read_json_lines


def run_records(run_dir: Path) -> tuple[list[dict], list[dict]]:
    """(warm-start records, PPO epoch records) of a run directory."""
    return (read_json_lines(Path(run_dir) / IMITATION_RECORD, "DAgger record"),
            read_json_lines(Path(run_dir) / METRICS_RECORD, "metrics record"))


def learning_curves(runs: dict[str, tuple[list[dict], list[dict]]], path: Path,
                    curves: tuple[tuple[str, str], ...]) -> Path:
    """Each run's PPO metrics (``curves``: (record key, title), an environment's `curves`; episode means of the
    training episodes that ended in the epoch) against environment steps (warm start included, dashed where the
    warm start recorded the key) and against wall time; a dotted line marks where a run's warm start ended."""
    fig, axes = plt.subplots(2, len(curves), figsize=(4.2 * len(curves), 7), squeeze=False)
    for i, (label, (warm, history)) in enumerate(runs.items()):
        offset = warm[-1]["env_steps"] if warm else 0
        for col, (key, title) in enumerate(curves):
            values = [h.get(key, float("nan")) for h in history]
            steps, minutes = [h["env_steps"] + offset for h in history], [h["walltime"] / 60 for h in history]
            for row, x in enumerate((steps, minutes)):
                ax = axes[row, col]
                ax.plot(x, values, marker="o", ms=2, color=f"C{i}", label=label)
                if warm and key in warm[0]:
                    wx = [w["env_steps"] for w in warm] if row == 0 else [w["walltime"] / 60 for w in warm]
                    ax.plot(wx, [w[key] for w in warm], ls="--", marker="s", ms=2, color=f"C{i}")
                if warm:
                    ax.axvline(offset if row == 0 else warm[-1]["walltime"] / 60, color=f"C{i}", ls=":", lw=1)
                ax.set_xlabel("environment steps" if row == 0 else "wall time (min)")
                ax.set_title(title)
                ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    return save_figure(fig, path, dpi=110)


def write_run_curve(run_dir: Path, history: list[dict], curves: tuple[tuple[str, str], ...]) -> Path:
    """``RUN/training_curve.png``: `history` (PPO epochs) after the run's DAgger warm start, if it has one, in the
    panels ``curves`` (its environment's `curves`)."""
    return learning_curves({"this run": (run_records(run_dir)[0], history)}, run_dir / "training_curve.png", curves)
