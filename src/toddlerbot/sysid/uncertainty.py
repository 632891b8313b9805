"""How tightly the logs pin each fitted parameter: a local (Gauss-Newton) standard error at the fit's optimum.

The residuals of a replay are the measured minus the simulated positions (and velocities, where logged, as the
fit's objective uses them). Around the optimum ``u`` (a point of the unit cube the fit searches) they change
linearly with the parameters, ``J = d sim / d u``, found by central differences (one batched simulation of 2n + 1
candidates). Weighting each run and channel by the inverse of its mean squared residual (as the fit's per-run
log-MSE objective does) gives the information ``sum_r J_r^T J_r / (MSE_r tau_r)``, whose inverse is the
covariance. ``tau_r`` is the run's integrated residual autocorrelation time
in samples: the residuals of a replay are model error that stays correlated for hundreds of milliseconds, not
independent noise, and counting every 5 ms sample as independent would make the errors look ten times smaller.
It is a linearised, local figure: a parameter the logs do not constrain shows up as a large standard error (or a
strong correlation with another), not as an exact interval.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from toddlerbot.sysid.batch import Replay, RunBatch
from toddlerbot.sysid.params import search_range

STEP = 1e-3
"""Finite-difference step in the unit cube."""
MSE_FLOOR = 1e-12
"""rad^2 (or rad^2/s^2) added to each run's mean squared residual, here and in the fit's objective (a perfect replay
would give log 0 and divide by zero)."""


@dataclass(frozen=True)
class Uncertainty:
    """Standard error of one fitted parameter."""

    std: float
    """In the parameter's unit (for q_dot_max and tau_q_dot_max: of the span / fraction the fit searches)."""
    relative: float
    """std / |value|."""
    strongest_correlation: tuple[str, float]
    """The other fitted parameter it is most correlated with, and the correlation coefficient."""


def autocorrelation_time(x: np.ndarray, window: float = 5.0) -> float:
    """Integrated autocorrelation time of a series, samples (>= 1): 1 + 2 x the sum of its autocorrelation over the
    first M lags, M the smallest lag with M >= ``window`` x the estimate (Sokal's window: long enough to hold the
    correlation, short enough to keep the noise of the far lags out)."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    if not np.any(x):
        return 1.0
    spectrum = np.fft.rfft(x, 2 * len(x))
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[: len(x)]
    tau = 2.0 * np.cumsum(acf / acf[0]) - 1.0
    within = np.flatnonzero(np.arange(len(tau)) >= window * tau)
    return max(1.0, float(tau[within[0] if len(within) else -1]))


def local_uncertainty(replay: Callable[[np.ndarray], Replay], batch: RunBatch, u: np.ndarray,
                      names: Sequence[str], values: dict[str, float]) -> dict[str, Uncertainty]:
    """Standard error of each parameter ``names`` at the unit-cube point ``u``; ``replay(points)`` simulates the
    runs for unit-cube points (P, n) (velocity included where ``batch`` has measured velocities); ``values``: each
    parameter's (searched) value at ``u``."""
    n = len(names)
    u = np.asarray(u, dtype=float)
    up, down = np.minimum(u + STEP, 1.0), np.maximum(u - STEP, 0.0)
    eye = np.eye(n, dtype=bool)
    sim = replay(np.vstack([u[None], np.where(eye, up[None], u[None]), np.where(eye, down[None], u[None])]))
    channels = [(sim.position, batch.measured)]
    if batch.measured_velocity is not None:
        channels.append((sim.velocity, batch.measured_velocity))
    information = np.zeros((n, n))
    for simulated, measured in channels:
        jacobian = (simulated[1:n + 1] - simulated[n + 1:]) / (up - down)[:, None]
        for res, jac in zip(batch.split(measured - simulated[0]), batch.split(jacobian), strict=True):
            information += jac @ jac.T / ((np.mean(res**2) + MSE_FLOOR) * autocorrelation_time(res))
    # a direction the logs do not constrain has (almost) no information: give it a huge variance, not pinv's zero
    eigenvalues, eigenvectors = np.linalg.eigh(information)
    eigenvalues = np.maximum(eigenvalues, max(eigenvalues.max() * 1e-12, 1e-30))
    covariance = (eigenvectors / eigenvalues) @ eigenvectors.T
    sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    correlation = covariance / np.maximum(np.outer(sigma, sigma), 1e-300)
    out = {}
    for i, name in enumerate(names):
        lo, hi, log, _ = search_range(name)
        value = values[name]
        if log:  # sigma of u is sigma of ln(value) / ln(hi / lo)
            relative = float(sigma[i] * np.log(hi / lo))
            std = relative * abs(value)
        else:
            std = float(sigma[i] * (hi - lo))
            relative = std / abs(value) if value else float("inf")
        others = [j for j in range(n) if j != i]
        j = max(others, key=lambda k: abs(correlation[i, k])) if others else i
        out[name] = Uncertainty(std=std, relative=relative,
                                strongest_correlation=(names[j], float(correlation[i, j])))
    return out
