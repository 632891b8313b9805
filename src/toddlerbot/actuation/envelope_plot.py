"""Plot of the actuator's torque-speed envelope (appendix Figure 12): the torque the motor can apply versus joint
speed, acceleration limit along the motion (Eq. 9) and braking limit against it (Eq. 10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams
from toddlerbot.actuation.model import acceleration_limit, actuator_arrays, torque_bounds
from toddlerbot.files import save_figure


def plot_torque_envelope(params: ActuatorParams, title: str, path: str | Path, points: int = 801) -> None:
    """Write a PNG/SVG/PDF (by suffix) of tau_limit versus q_dot and the admissible torque region."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = actuator_arrays([params], [0.0], [0.0])
    speed = np.linspace(-1.2 * params.q_dot_max, 1.2 * params.q_dot_max, points)
    lower, upper = torque_bounds(speed, p)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    positive = speed[speed >= 0]
    left.plot(positive, acceleration_limit(positive, p), color="C0", lw=2, label=r"$\tau_{limit}$ (Eq. 9)")
    left.axhline(params.tau_brake, color="C3", ls="--", lw=1.2, label=r"$\tau_{brake}$")
    for x, label in ((params.q_dot_tau_max, r"$\dot q_{\tau max}$"), (params.q_dot_max, r"$\dot q_{max}$")):
        left.axvline(x, color="0.6", ls=":", lw=1)
        left.annotate(label, (x, 0.02), textcoords="offset points", xytext=(3, 3), fontsize=9)
    left.set(xlabel=r"$|\dot q|$ (rad/s)", ylabel="torque limit (N m)", title=f"{title}: acceleration torque limit",
             ylim=(0, 1.1 * max(params.tau_brake, params.tau_max)))
    left.legend(fontsize=8)
    right.fill_between(speed, lower, upper, color="C0", alpha=0.25, label="admissible motor torque")
    right.plot(speed, upper, color="C0", lw=1.5)
    right.plot(speed, lower, color="C0", lw=1.5)
    right.axhline(0, color="0.3", lw=0.6)
    right.axvline(0, color="0.3", lw=0.6)
    right.set(xlabel=r"$\dot q$ (rad/s)", ylabel=r"$\tau$ (N m)", title="torque-speed envelope (Eq. 9-10)")
    right.legend(fontsize=8, loc="upper right")
    save_figure(fig, path, dpi=120)
