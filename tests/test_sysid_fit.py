"""The 9-parameter fit on synthetic logs from known parameters plus noise."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.sysid.evaluate import evaluate
from toddlerbot.sysid.excitation import Excitation, excitation
from toddlerbot.sysid.fit import fit
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.rigs import PendulumRig
from toddlerbot.sysid.synthetic import synthesize

NOISE = np.radians(0.1)
TRUTH = default_catalogue()["XC330"].actuator
RIG = PendulumRig(mass=0.49, length=0.1)


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    ex = []
    for profile, kp in (("steps", 2100), ("chirp", 900), ("lift_and_drop", 400), ("sinusoids", 1500)):
        t, goal = excitation(profile, duration=4.0, amplitude=0.6)
        ex.append(Excitation(profile, kp, t, goal))
    runs = synthesize(ex, RIG, TRUTH, NOISE, seed=3)
    return Manifest(Path("synthetic.json"), default_catalogue()["XC330"], RIG, tuple(runs))


def test_truth_tracks_to_the_noise(manifest: Manifest) -> None:
    ev = evaluate(manifest, TRUTH)
    assert ev.mae_deg == pytest.approx(np.degrees(NOISE) * np.sqrt(2 / np.pi), rel=0.1)  # MAE of pure noise
    assert ev.rmse_deg == pytest.approx(np.degrees(NOISE), rel=0.1)


def test_fit_recovers_tracking_and_excited_parameters(manifest: Manifest) -> None:
    fields = dataclasses.asdict(TRUTH)
    start = TRUTH.replace(**{k: v * (1.15 if i % 2 else 0.85) for i, (k, v) in enumerate(fields.items())
                             if k != "kp_scale"})
    before = evaluate(manifest, start)
    result = fit(manifest, evals=1600, popsize=32, sigma0=0.1, start=start, seed=1)
    after = evaluate(manifest, result.params)
    assert before.mae_deg > 3 * np.degrees(NOISE)
    assert after.mae_deg <= 1.5 * np.degrees(NOISE)
    assert result.evals == 1600
    # parameters these runs excite (friction, inertia, stall torque, powered damping, braking) come back within 10 %
    for name in ("armature", "frictionloss", "tau_max", "kd_min", "tau_brake"):
        assert getattr(result.params, name) == pytest.approx(getattr(TRUTH, name), rel=0.10), name
    # seeded: the same call gives the same answer
    again = fit(manifest, evals=64, popsize=32, sigma0=0.1, start=start, seed=1)
    assert again.params == fit(manifest, evals=64, popsize=32, sigma0=0.1, start=start, seed=1).params
