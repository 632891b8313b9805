"""The joint fit of the actuator parameters (appendix section 8.9) with CMA-ES.

The objective is the mean squared error between simulated and measured positions over every sample of every run
of a manifest (each run replayed from its logged initial state). CMA-ES (the ``cma`` package) searches the unit
cube mapped onto `toddlerbot.sysid.params.BOUNDS`, starting from the catalogue's values for the motor; each
generation is evaluated as one vectorised simulation of all candidates x all runs. Same manifest, seed and
options give the same result.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import cma
import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.params import from_unit, parameter_names, params_at, to_unit
from toddlerbot.sysid.simulate import DT, RunBatch, simulate


@dataclass(frozen=True)
class FitResult:
    params: ActuatorParams
    fitted: tuple[str, ...]
    rmse_deg: float
    """Tracking RMSE of the best candidate over all samples, degrees."""
    evals: int
    generations: int
    wall_s: float
    seed: int


def fit(
    manifest: Manifest, fit_kp_scale: bool = False, seed: int = 1, evals: int = 2000, popsize: int = 32,
    sigma0: float = 0.25, dt: float = DT, start: ActuatorParams | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> FitResult:
    """Fit the 9 model parameters (plus kp_scale if asked) to the manifest's runs.

    ``evals``: candidate evaluations (rounded up to whole generations of ``popsize``); ``sigma0``: initial step
    size in the unit cube; ``start``: initial guess (default: the catalogue's parameters of the manifest's motor);
    ``progress(evals_done, best_rmse_deg)`` is called after each generation.
    """
    if seed < 1:
        raise SysIDError(f"seed must be >= 1 (cma treats 0 as 'seed from the clock'), got {seed}")
    if evals < popsize or popsize < 4:
        raise SysIDError(f"need popsize >= 4 and evals >= popsize, got popsize={popsize}, evals={evals}")
    t0 = time.perf_counter()
    names = parameter_names(fit_kp_scale)
    base = start or manifest.motor.actuator
    batch = RunBatch.from_runs(manifest.runs, dt)

    def loss(u: np.ndarray) -> np.ndarray:
        err = simulate(batch, manifest.rig, from_unit(u, names, base)) - batch.measured
        return np.mean(err**2, axis=1)

    options = {
        "bounds": [0.0, 1.0], "popsize": popsize, "seed": seed, "verbose": -9, "maxfevals": evals,
        "tolfun": 1e-15, "tolfunhist": 0, "tolx": 1e-12, "tolstagnation": 10**6, "CMA_stds": None,
    }
    es = cma.CMAEvolutionStrategy(to_unit(base, names), sigma0, options)
    best_u, best_f, done, generations = None, np.inf, 0, 0
    while done < evals and not es.stop():
        candidates = np.array(es.ask())
        values = loss(candidates)
        es.tell(list(candidates), values.tolist())
        done += len(candidates)
        generations += 1
        i = int(np.argmin(values))
        if values[i] < best_f:
            best_u, best_f = candidates[i], float(values[i])
        if progress is not None:
            progress(done, float(np.degrees(np.sqrt(best_f))))
    params = params_at(from_unit(best_u[None, :], names, base), 0)
    return FitResult(params=params, fitted=names, rmse_deg=float(np.degrees(np.sqrt(best_f))), evals=done,
                     generations=generations, wall_s=time.perf_counter() - t0, seed=seed)
