"""The joint fit of an actuator model's parameters (appendix section 8.9) with IPOP-CMA-ES.

The objective is the mean over the manifest's runs of the log of each run's mean squared error between simulated
and measured positions (each run replayed from its logged initial state): the log of the geometric mean of the runs'
MSE; where every run logged its velocity, plus the same for the velocity. Unlike the pooled MSE it is not dominated
by the runs with the largest errors (fast full-swing steps, where a few ms of timing error is degrees of position
error), so every run pulls on the parameters it excites (measured: fits started from other motor models' values
converge more reliably). The velocity pins the dynamics that position alone leaves loose on real logs (passive
damping against friction loss): on the XL330-M288 kp-100 logs, fits from the catalogue's and from the datasheet's
values reach the same parameters with it (1.93 deg on kp 400 from both) and different ones without (1.97 and
2.38 deg).

CMA-ES (the ``cma`` package) searches the unit cube mapped onto the parameters' fit bounds
(each motor model's parameter table; log-scaled for the positive, multi-decade parameters), the first run
starting from the catalogue's values for the motor (converted to the fitted model where the catalogue has the other
one, `toddlerbot.sysid.params.start_params`). Each generation
is evaluated as one vectorised simulation of all candidates x all runs. A run that stagnates (its best loss improves
by less than ``STAGNATION_TOL`` over ``patience`` generations) or that meets one of cma's own stopping criteria
(e.g. flat fitness) is restarted with twice the population (IPOP), from the middle of the search cube, until the
evaluation budget or the allowed restarts are spent; the best candidate of all runs is returned, with the standard
error of each fitted parameter (`toddlerbot.sysid.uncertainty`). Same manifest, seed and options give the same
result.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import cma
import numpy as np

from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.params import (
    DEFAULT_MODEL,
    at_bounds,
    fit_model,
    from_unit,
    parameter_names,
    searched_value,
    start_params,
    to_unit,
)
from toddlerbot.sysid.simulate import DT, Replay, RunBatch, simulate
from toddlerbot.sysid.uncertainty import MSE_FLOOR, Uncertainty, local_uncertainty

DEFAULT_EVALS = 2000
"""Default candidate-evaluation budget of a fit (over all restarts)."""
STAGNATION_TOL = 0.01
"""A CMA-ES run is restarted when its best loss (mean log MSE) improved by less than this over its patience
window (0.01: the geometric mean of the runs' MSE fell by less than 1 %)."""


@dataclass(frozen=True)
class FitResult:
    params: MotorParams
    fitted: tuple[str, ...]
    rmse_deg: float
    """Tracking RMSE of the best candidate over all samples, degrees."""
    evals: int
    generations: int
    wall_s: float
    seed: int
    restarts: int
    """IPOP restarts made (0: one CMA-ES run)."""
    at_bounds: dict[str, str]
    """Fitted parameters that ended within 1 % of a search bound: name -> "lower" / "upper". Such a value is not
    identified: the data wants it beyond the bound (a model or unit error) or does not constrain it."""
    model: str = DEFAULT_MODEL
    uncertainty: dict[str, Uncertainty] = dataclasses.field(default_factory=dict)
    """Standard error of each fitted parameter at the optimum (`toddlerbot.sysid.uncertainty`)."""
    fixed: dict[str, str] = dataclasses.field(default_factory=dict)
    """Parameters of the model the fit left at their start, with the reason."""


def fit(
    manifest: Manifest, fit_kp_scale: bool = False, model: str = DEFAULT_MODEL, seed: int = 1,
    evals: int = DEFAULT_EVALS, popsize: int = 32,
    sigma0: float = 0.25, restarts: int = 4, dt: float = DT, start: MotorParams | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> FitResult:
    """Fit ``model``'s parameters (`toddlerbot.sysid.params.fit_models`: ``dc_motor``, ``appendix``, whose 9
    parameters ``extended`` adds stiction, Stribeck velocity and load friction to; plus the gain conversion if
    asked) to the manifest's runs.

    ``evals``: candidate evaluations over all runs (each generation is evaluated whole, so the total is rounded up
    to the last generation); ``popsize``: population of the first CMA-ES run (doubled at each restart);
    ``sigma0``: initial step size in the unit cube; ``restarts``: at most this many IPOP restarts; ``start``:
    initial guess of the first run (default: the catalogue's parameters of the manifest's motor, converted to
    ``model`` where the catalogue has the other one);
    ``progress(evals_done, best_rmse_deg)`` is called after each generation.

    From a start without extended friction (the catalogue's values) the extended model is fitted in two stages,
    since its 12-13 dimensional landscape is harder to enter than the appendix model's: the 9 appendix parameters
    with half the budget, then all of them from that result (plus a little static and load friction, off their
    bounds) with the rest and a first step of at most 0.1. The second stage contains the first one's result (to
    within the 1e-4 N m floor of stiction), so it should only improve on it; where it does not, the first stage's
    parameters are returned.
    """
    if seed < 1:
        raise SysIDError(f"seed must be >= 1 (cma treats 0 as 'seed from the clock'), got {seed}")
    if evals < popsize or popsize < 4:
        raise SysIDError(f"need popsize >= 4 and evals >= popsize, got popsize={popsize}, evals={evals}")
    if restarts < 0:
        raise SysIDError(f"restarts must be >= 0, got {restarts}")
    base = start_params(model, start or manifest.motor.actuator)
    if model != "extended" or evals < 2 * popsize or base.stiction > 0 or base.load_friction > 0:
        return _fit_stage(manifest, fit_kp_scale, model, seed, evals, popsize, sigma0, restarts, dt, base,
                          progress)[0]
    t0 = time.perf_counter()
    first, first_loss = _fit_stage(manifest, fit_kp_scale, "appendix", seed, evals // 2, popsize, sigma0, restarts,
                                   dt, base, progress)
    offset = (lambda n, rmse: progress(first.evals + n, rmse)) if progress is not None else None
    seeded = first.params.replace(stiction=max(first.params.stiction, 0.01),
                                  load_friction=max(first.params.load_friction, 0.05))
    # a smaller first step: the second stage starts next to a fitted optimum and should refine it, not leave it
    second, second_loss = _fit_stage(manifest, fit_kp_scale, "extended", seed, evals - first.evals, popsize,
                                     min(sigma0, 0.1), restarts, dt, seeded, offset)
    best = second if second_loss <= first_loss else dataclasses.replace(
        first, fitted=second.fitted, at_bounds={k: v for k, v in second.at_bounds.items() if k in first.fitted},
        fixed=second.fixed)
    return dataclasses.replace(best, evals=first.evals + second.evals, wall_s=time.perf_counter() - t0,
                               generations=first.generations + second.generations,
                               restarts=first.restarts + second.restarts, model="extended")


def _fit_stage(
    manifest: Manifest, fit_kp_scale: bool, model: str, seed: int, evals: int, popsize: int, sigma0: float,
    restarts: int, dt: float, base: MotorParams, progress: Callable[[int, float], None] | None,
) -> tuple[FitResult, float]:
    """One IPOP-CMA-ES fit of ``model``'s parameters from ``base``; (result, best loss)."""
    t0 = time.perf_counter()
    names = parameter_names(fit_kp_scale, model)
    batch = RunBatch.from_runs(manifest.runs, dt, manifest.motor.rated_voltage)
    with_velocity = batch.measured_velocity is not None

    def replay(u: np.ndarray) -> Replay:
        return simulate(batch, manifest.rig, from_unit(u, names, base), full=with_velocity)

    def mean_log_mse(err: np.ndarray) -> np.ndarray:
        per_run = np.stack([np.mean(e**2, axis=1) for e in batch.split(err)], axis=1)
        return np.mean(np.log(per_run + MSE_FLOOR), axis=1)

    def loss(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(objective, position MSE over all samples in rad^2) of each candidate."""
        sim = replay(u)
        err = sim.position - batch.measured
        objective = mean_log_mse(err)
        if with_velocity:
            objective = objective + mean_log_mse(sim.velocity - batch.measured_velocity)
        return objective, np.mean(err**2, axis=1)

    best_u, best_f, best_mse, done, generations, made = to_unit(base, names), np.inf, np.inf, 0, 0, 0
    for run in range(restarts + 1):
        made = run
        # IPOP doubles the population; near the end of the budget it is capped so a restart still gets 8 generations
        pop = max(popsize, min(popsize * 2**run, (evals - done) // 8))
        x0 = to_unit(base, names) if run == 0 else np.full(len(names), 0.5)
        options = {
            "bounds": [0.0, 1.0], "popsize": pop, "seed": seed + run, "verbose": -9, "maxfevals": evals - done,
            "tolfun": 1e-15, "tolfunhist": 0, "tolx": 1e-9, "tolstagnation": 0, "CMA_stds": None,
        }
        es = cma.CMAEvolutionStrategy(x0, sigma0, options)
        patience = 10 + int(np.ceil(30 * len(names) / pop))
        history: list[float] = []
        while done < evals and not es.stop():
            candidates = np.array(es.ask())
            values, mse = loss(candidates)
            es.tell(list(candidates), values.tolist())
            done += len(candidates)
            generations += 1
            i = int(np.argmin(values))
            if values[i] < best_f:
                best_u, best_f, best_mse = candidates[i], float(values[i]), float(mse[i])
            history.append(min(float(values[i]), history[-1] if history else np.inf))
            if progress is not None:
                progress(done, float(np.degrees(np.sqrt(best_mse))))
            if len(history) > patience and history[-1] > history[-1 - patience] - STAGNATION_TOL:
                break
        if done >= evals:
            break
    if not np.isfinite(best_f):
        raise SysIDError(f"{manifest.path}: the fit found no candidate with a finite tracking error")
    params = from_unit(best_u[None, :], names, base).params(0)
    uncertainty = local_uncertainty(replay, batch, best_u, names, {n: searched_value(n, params) for n in names})
    gain = fit_model(model).gain_parameter
    fixed = {**fit_model(model).fixed, **({} if gain in names else {
        gain: "the firmware's gain conversion, kept from the start (fitted with --fit-kp-scale)"})}
    return FitResult(params=params, fitted=names, rmse_deg=float(np.degrees(np.sqrt(best_mse))), evals=done,
                     generations=generations, wall_s=time.perf_counter() - t0, seed=seed, restarts=made,
                     at_bounds=at_bounds(best_u, names), model=model, uncertainty=uncertainty,
                     fixed=fixed), best_f
