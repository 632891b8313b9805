"""Test-bed analysis on synthetic data from known parameters plus realistic noise: within 5 % of the truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.testbed import armature_from_spindown, fit_friction

DAMPING, FRICTIONLOSS, ARMATURE, LOAD = 0.0036, 0.036, 0.0040, 0.0010  # XC330 (Table 3) on a small load


def test_friction_and_damping_from_backdrive() -> None:
    rng = np.random.default_rng(1)
    speed = np.repeat(np.concatenate([np.linspace(0.5, 6, 12), -np.linspace(0.5, 6, 12)]), 50)
    # torque sensor noise 3e-4 N*m (the appendix's precision) plus 2 % ripple of the friction torque
    torque = np.sign(speed) * FRICTIONLOSS + DAMPING * speed
    torque += rng.normal(0, 3e-4, speed.shape) + rng.normal(0, 0.02 * FRICTIONLOSS, speed.shape)
    fit = fit_friction(speed, torque)
    assert fit.frictionloss == pytest.approx(FRICTIONLOSS, rel=0.05)
    assert fit.damping == pytest.approx(DAMPING, rel=0.05)
    assert set(fit.directions) == {"positive", "negative"}
    assert all(d.r2 > 0.95 and d.samples == 600 for d in fit.directions.values())


def test_armature_from_spindown_uses_half_i_omega_squared() -> None:
    inertia = ARMATURE + LOAD

    def decel(_t, w):
        return [-(FRICTIONLOSS * np.sign(w[0]) + DAMPING * w[0]) / inertia if w[0] > 0 else 0.0]

    t = np.arange(0, 1.0, 0.001)
    w = solve_ivp(decel, (0, 1.0), [6.0], t_eval=t, max_step=1e-3).y[0]
    w_noisy = w + np.random.default_rng(2).normal(0, 0.01, w.shape)  # 0.01 rad/s encoder-derivative noise
    result = armature_from_spindown(t, w_noisy, DAMPING, FRICTIONLOSS, load_inertia=LOAD)
    assert result.omega0 == pytest.approx(6.0, rel=0.01)
    assert result.inertia == pytest.approx(inertia, rel=0.05)
    assert result.armature == pytest.approx(ARMATURE, rel=0.05)
    # E = 1/2 I w^2, not the appendix's I w^2
    assert result.energy == pytest.approx(0.5 * inertia * 36.0, rel=0.05)


def test_spindown_that_never_stops_is_an_error() -> None:
    t = np.linspace(0, 1, 100)
    with pytest.raises(SysIDError, match=r"spin.csv: the motor never stops"):
        armature_from_spindown(t, np.full_like(t, 5.0), DAMPING, FRICTIONLOSS, source="spin.csv")


def test_backdrive_needs_two_speeds() -> None:
    with pytest.raises(SysIDError, match=r"bd.csv: back-drive data needs at least two distinct speeds"):
        fit_friction(np.ones(10), np.ones(10), source="bd.csv")
