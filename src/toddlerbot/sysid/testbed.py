"""Test-bed analysis (appendix section 8.8): friction loss and damping from constant-speed back-driving, armature
from a spin-down.

* Back-drive: at constant speed the measured resisting torque is tau_r = frictionloss + damping * |q_dot|
  (Eq. 6). A linear fit of |torque| against |speed| per direction gives friction loss (intercept) and damping
  (slope); R^2 reports the fit quality; the two directions are averaged.
* Spin-down: after power is cut the stored kinetic energy E = 1/2 * I * w0^2 is dissipated by the resistance, so
  E = integral of tau_r(w) * |w| dt until the shaft stops and I = 2 E / w0^2. (The appendix's Eq. 7 writes
  E = I * w^2, which is off by the factor 1/2.) I is the total inertia; the armature is I minus the test bed's
  known load inertia.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate, stats

from toddlerbot.actuation.model import resistance_torque
from toddlerbot.sysid.errors import SysIDError


@dataclass(frozen=True)
class LineFit:
    intercept: float
    slope: float
    r2: float
    samples: int


@dataclass(frozen=True)
class FrictionFit:
    frictionloss: float
    """N*m: mean of the two directions' intercepts."""
    damping: float
    """N*m*s/rad: mean of the two directions' slopes."""
    directions: dict[str, LineFit]
    """'positive' / 'negative' speed fits of |torque| = frictionloss + damping * |speed|."""


def fit_friction(speed: np.ndarray, torque: np.ndarray, min_speed: float = 1e-3, source: str = "data") -> FrictionFit:
    """Friction loss and damping from back-drive samples (speed rad/s, resisting torque N*m, same length)."""
    speed, torque = np.asarray(speed, float), np.asarray(torque, float)
    fits = {}
    for name, mask in (("positive", speed > min_speed), ("negative", speed < -min_speed)):
        if np.unique(np.round(speed[mask], 6)).size < 2:
            continue
        res = stats.linregress(np.abs(speed[mask]), np.abs(torque[mask]))
        fits[name] = LineFit(float(res.intercept), float(res.slope), float(res.rvalue**2), int(mask.sum()))
    if not fits:
        raise SysIDError(f"{source}: back-drive data needs at least two distinct speeds in one direction "
                         f"(|speed| > {min_speed} rad/s)")
    return FrictionFit(
        frictionloss=float(np.mean([f.intercept for f in fits.values()])),
        damping=float(np.mean([f.slope for f in fits.values()])),
        directions=fits,
    )


@dataclass(frozen=True)
class SpinDown:
    omega0: float
    """Speed at power cut, rad/s."""
    energy: float
    """Kinetic energy at power cut, J."""
    inertia: float
    """Total inertia of the spinning parts, kg*m^2."""
    armature: float
    """inertia minus the known load inertia, kg*m^2."""
    stop_time: float
    """Time from the cut to the stop, s."""


def armature_from_spindown(
    time: np.ndarray, velocity: np.ndarray, damping: float, frictionloss: float, load_inertia: float = 0.0,
    stop_fraction: float = 0.02, source: str = "data",
) -> SpinDown:
    """Inertia from a spin-down speed trace starting at power cut (time s, velocity rad/s).

    The trace is integrated until the speed first falls below ``stop_fraction`` of its initial value; the initial
    speed is a straight-line fit through the first 5 % of that span, evaluated at the cut (robust to noise).
    """
    time, velocity = np.asarray(time, float) - float(time[0]), np.asarray(velocity, float)
    sign = np.sign(np.median(velocity[: max(3, len(velocity) // 20)]))
    if sign == 0:
        raise SysIDError(f"{source}: spin-down trace does not start moving")
    speed = sign * velocity
    below = np.flatnonzero(speed < stop_fraction * speed[0])
    if below.size == 0:
        raise SysIDError(f"{source}: the motor never stops (speed stays above {stop_fraction:.0%} of its start)")
    stop = int(below[0])
    head = max(5, stop // 20)
    if stop < 10:
        raise SysIDError(f"{source}: spin-down has only {stop} samples before stopping; log faster or longer")
    omega0 = float(np.polyval(np.polyfit(time[:head], speed[:head], 1), 0.0))
    power = resistance_torque(np.clip(speed[: stop + 1], 0.0, None), damping, frictionloss) * np.clip(
        speed[: stop + 1], 0.0, None)
    energy = float(integrate.trapezoid(power, time[: stop + 1]))
    inertia = 2.0 * energy / omega0**2
    return SpinDown(omega0=omega0, energy=energy, inertia=inertia, armature=inertia - load_inertia,
                    stop_time=float(time[stop]))
