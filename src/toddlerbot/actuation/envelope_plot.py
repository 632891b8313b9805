"""Plot of the actuator's torque-speed envelope (appendix Figure 12): the torque the motor can apply versus joint
speed, along the motion (Eq. 9; the DC motor: its stall torque less the back-EMF) and against it (Eq. 10; the DC
motor: stall torque plus back-EMF), for either actuator model."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toddlerbot.actuation.model import actuator_arrays, torque_bounds
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.files import save_figure


def plot_torque_envelope(params: MotorParams, title: str, path: str | Path, points: int = 801) -> None:
    """Write a PNG/SVG/PDF (by suffix) of the torque limit versus q_dot and the admissible torque region."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = actuator_arrays([params], [0.0], [0.0])
    speed = np.linspace(-1.2 * params.q_dot_max, 1.2 * params.q_dot_max, points)
    lower, upper = torque_bounds(speed, p)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    positive = speed >= 0
    left.plot(speed[positive], upper[positive], color="C0", lw=2, label=r"$\tau_{limit}$ along the motion")
    left.plot(speed[positive], -lower[positive], color="C3", ls="--", lw=1.2, label="braking limit")
    markers = {r"$\dot q_{\tau max}$": getattr(params, "q_dot_tau_max", None), r"$\dot q_{max}$": params.q_dot_max}
    for label, x in markers.items():
        if x is not None:
            left.axvline(x, color="0.6", ls=":", lw=1)
            left.annotate(label, (x, 0.02), textcoords="offset points", xytext=(3, 3), fontsize=9)
    left.set(xlabel=r"$|\dot q|$ (rad/s)", ylabel="torque limit (N m)", title=f"{title}: torque limit",
             ylim=(0, 1.1 * float(max(-lower[positive].max(), upper.max()))))
    left.legend(fontsize=8)
    right.fill_between(speed, lower, upper, color="C0", alpha=0.25, label="admissible motor torque")
    right.plot(speed, upper, color="C0", lw=1.5)
    right.plot(speed, lower, color="C0", lw=1.5)
    right.axhline(0, color="0.3", lw=0.6)
    right.axvline(0, color="0.3", lw=0.6)
    right.set(xlabel=r"$\dot q$ (rad/s)", ylabel=r"$\tau$ (N m)", title=f"torque-speed envelope ({params.model})")
    right.legend(fontsize=8, loc="upper right")
    save_figure(fig, path, dpi=120)
