"""Training-curve plot (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from toddlerbot.files import save_figure


def training_curve(history: list[dict], path: Path) -> Path:
    """Reward per step, episode reward and fall rate against environment steps."""
    steps = [h["env_steps"] for h in history]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, key, label in (
        (axes[0], "step_reward", "reward per step"),
        (axes[1], "episode_reward", "episode reward (finished episodes)"),
        (axes[2], "fall_rate", "falls per env step"),
    ):
        ax.plot(steps, [h.get(key, float("nan")) for h in history], marker="o", ms=3)
        ax.set_xlabel("environment steps")
        ax.set_title(label)
        ax.grid(alpha=0.3)
    if any("eval/episode_reward" in h for h in history):
        axes[1].plot(steps, [h.get("eval/episode_reward", float("nan")) for h in history], marker="s", ms=3,
                     label="evaluation")
        axes[1].legend()
    return save_figure(fig, path, dpi=110)
