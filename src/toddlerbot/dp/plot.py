"""Training curve: train and validation loss against optimiser steps, written as a PNG."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.files import save_figure


def plot_loss_curve(history: list[dict[str, float]], path: str | Path, title: str = "diffusion policy") -> Path:
    """Plot ``history`` records (step, train_loss, val_loss) on a log scale; written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [h["step"] for h in history]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    ax.plot(steps, [h["train_loss"] for h in history], ".-", label="train (denoising MSE)")
    val = [(h["step"], h["val_loss"]) for h in history if h.get("val_loss") is not None]
    if val:
        ax.plot(*zip(*val), "o-", label="validation episodes (EMA)")
    ax.set_yscale("log")
    ax.set_xlabel("optimiser step")
    ax.set_ylabel("loss")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path)
