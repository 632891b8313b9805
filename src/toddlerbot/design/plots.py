"""Figures of the design report (PNG): power factor vs active DoF (appendix Fig. 8), range of motion (Fig. 6),
torque requirement vs available torque."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from toddlerbot.design.report import DesignReport
from toddlerbot.files import save_figure


def plot_power_factor(report: DesignReport, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for h in report.humanoids:
        marker = "s" if h.name.startswith("Human") else "o"
        ax.scatter(h.active_dof, h.power_factor, marker=marker, facecolors="none" if h.estimated else None,
                   edgecolors="tab:blue", color="tab:blue")
        ax.annotate(h.name + (" (est.)" if h.estimated else ""), (h.active_dof, h.power_factor),
                    textcoords="offset points", xytext=(5, 4), fontsize=8)
    pf = report.power_factor
    ax.bar(report.active_dof, pf.lower, width=0.8, color="tab:orange", alpha=0.6, label="ToddlerBot lower body")
    ax.bar(report.active_dof, pf.upper, bottom=pf.lower, width=0.8, color="tab:red", alpha=0.6,
           label="ToddlerBot upper body")
    ax.scatter(report.active_dof, pf.total, color="tab:red", marker="*", s=150, zorder=3)
    ax.annotate(f"ToddlerBot p={pf.total:.2f}", (report.active_dof, pf.total), textcoords="offset points",
                xytext=(-40, 8), fontsize=9, color="tab:red")
    ax.set_xlabel("active degrees of freedom")
    ax.set_ylabel("power factor  Σ|τmax| / (h·m·g)")
    ax.set_title("Power factor vs active DoF (appendix Eq. 4, Fig. 8)")
    ax.set_ylim(0, 1.15 * max([pf.total] + [h.power_factor for h in report.humanoids]))
    ax.legend(loc="lower left", fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path, dpi=120)


def plot_range_of_motion(report: DesignReport, path: Path) -> None:
    rows = report.range_of_motion
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(rows) + 1.5))
    for i, r in enumerate(rows):
        ax.barh(i + 0.18, r.robot_span_deg, left=r.robot_deg[0], height=0.35, color="tab:orange",
                label="ToddlerBot (joint frame)" if i == 0 else None)
        if r.human_deg:
            ax.barh(i - 0.18, r.human_span_deg, left=r.human_deg[0], height=0.35, color="tab:gray",
                    label="typical human" if i == 0 else None)
    ax.set_yticks(range(len(rows)), [r.joint for r in rows], fontsize=8)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("degrees")
    ax.set_title("Range of motion (appendix Fig. 6)")
    ax.legend(fontsize=8)
    save_figure(fig, path, dpi=120)


def plot_torque_requirement(report: DesignReport, path: Path) -> None:
    checks = report.joint_checks
    fig, ax = plt.subplots(figsize=(7, 3.5))
    x = range(len(checks))
    ax.bar([i - 0.2 for i in x], [c.required_nm for c in checks], width=0.4, label="required (Eq. 5)",
           color="tab:gray")
    ax.bar([i + 0.2 for i in x], [c.available_nm for c in checks], width=0.4, label="stall torque at joint",
           color=["tab:green" if c.sufficient else "tab:red" for c in checks])
    ax.set_xticks(list(x), [c.joint for c in checks], rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("N·m")
    ax.set_title(f"Torque requirement for h={report.height_m:.2f} m, m={report.mass_kg:.2f} kg")
    ax.legend(fontsize=8)
    save_figure(fig, path, dpi=120)


def write_plots(report: DesignReport, directory: Path) -> list[Path]:
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, plot in (("power_factor", plot_power_factor), ("range_of_motion", plot_range_of_motion),
                       ("torque_requirement", plot_torque_requirement)):
        path = directory / f"{name}.png"
        plot(report, path)
        paths.append(path)
    return paths
