"""Benchmark: cross-gain validation of the actuator models on real servo logs.

The XL330-M288 pendulum logs (public BAM dataset, 7.3 V, 200 Hz, four trajectories per gain incl. a torque-off
drop; firmware kp 100 and 400) live outside the repository; pass their manifest. Each model is fitted on one
gain's runs and evaluated on the other's (kp 100 -> 400 and 400 -> 100), then on all runs pooled; the MAE of every
held-out run, the fit's CPU and wall time and each parameter's standard error are printed. Goal: at most 2.0 deg
MAE on the gain not fitted, each direction, in at most 60 s of one core.

The fits start from what was known before these logs (not from the catalogue, which now holds the pooled fit):
the DC-motor model from the e-Manual (stall torque 0.52 N m and no-load speed 103 rpm at 5.0 V) with the XL330
firmware's PWM per position error (kept, as `sysid fit` does by default; ``--fit-kp-scale`` fits it too), the
appendix models from the catalogue's former, unidentified values with their kp_scale fitted (as in the issue's
baseline: the XL330's is not known).

Run: ``PYTHONPATH=src python benchmarks/bench_sysid_crossgain.py /work/shared/data/xl330_pendulum/manifest.json
[--model dc_motor] [--evals 2000] [--seed 1] [--plot DIR] [--save DIR]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from toddlerbot.actuation.appendix import ActuatorParams
from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.sysid.evaluate import evaluate, plot_tracking
from toddlerbot.sysid.fit import fit
from toddlerbot.sysid.manifest import load_manifest, select_gains
from toddlerbot.sysid.params import fit_models, save_params

GUESS = ActuatorParams(damping=0.0019, armature=0.0040, frictionloss=0.019, tau_max=0.40, q_dot_tau_max=2.60,
                       q_dot_max=9.50, tau_q_dot_max=0.25, kd_min=0.137, tau_brake=0.91, kp_scale=334.0)
"""The XL330-M288's catalogue values before this fit: the XC330's scaled by the datasheet."""
STARTS = {"dc_motor": DCMotorParams(damping=GUESS.damping, armature=GUESS.armature, frictionloss=GUESS.frictionloss,
                                    stall_torque=0.52, no_load_speed=103 * 2 * np.pi / 60,
                                    pwm_per_rad=4096 / (2 * np.pi) / (256 * 885)),
          "appendix": GUESS, "extended": GUESS}
"""Start of each model's fit. pwm_per_rad: the XL330 firmware's PWM (885 = 100 %) per encoder count (4096 per turn)
of error and unit of P gain, gain / 256 (BAM's measurement; the e-Manual says 128)."""
SPLITS = (((100.0,), (400.0,)), ((400.0,), (100.0,)), ((100.0, 400.0), (100.0, 400.0)))
"""(gains fitted, gains evaluated)."""


def _gains(kp: tuple[float, ...]) -> str:
    return "+".join(f"{k:g}" for k in kp)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("manifest", type=Path)
    parser.add_argument("--model", action="append", choices=tuple(fit_models()))
    parser.add_argument("--evals", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--fit-kp-scale", action="store_true", help="also fit the DC motor's pwm_per_rad")
    parser.add_argument("--plot", type=Path, help="folder for the held-out tracking plots of each model and split")
    parser.add_argument("--save", type=Path, help="folder for the params.json of each model and split")
    args = parser.parse_args()
    manifest = load_manifest(args.manifest)
    print(f"machine: {platform.machine()} {os.cpu_count()} cores, numpy {np.__version__}, "
          f"load average {os.getloadavg()[0]:.1f}; {len(manifest.runs)} runs of {manifest.motor.name}")
    for model in args.model or tuple(fit_models()):
        for trained, held in SPLITS:
            wall0, cpu0 = time.perf_counter(), time.process_time()
            result = fit(select_gains(manifest, trained), model=model, evals=args.evals, seed=args.seed,
                         start=STARTS[model], fit_kp_scale=args.fit_kp_scale or model != "dc_motor")
            wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
            train = evaluate(select_gains(manifest, trained), result.params)
            test = evaluate(select_gains(manifest, held), result.params)
            label = f"{model} kp {_gains(trained)} -> {_gains(held)}"
            print(f"{label}: held-out MAE {test.mae_deg:.2f} deg (train {train.mae_deg:.2f}); {result.evals} "
                  f"evaluations, CPU {cpu:.1f} s, wall {wall:.1f} s; at bounds: {result.at_bounds or 'none'}")
            print("   per run: " + ", ".join(f"{r.file.removesuffix('.csv')} {r.mae_deg:.2f}" for r in test.runs))
            print("   parameters: " + ", ".join(
                f"{name} {getattr(result.params, name):.4g} +-{u.relative:.0%}"
                for name, u in result.uncertainty.items()))
            tag = f"{model}{'_gain' if args.fit_kp_scale else ''}_kp{_gains(trained)}"
            if args.plot is not None:
                plot_tracking(select_gains(manifest, held), test, args.plot / tag)
            if args.save is not None:
                save_params(args.save / f"{tag}.json", manifest.motor.name, result.params, result.fitted,
                            {"manifest": str(args.manifest), "kp": list(trained), "seed": args.seed,
                             "evals": result.evals, "model": model, "held_out_mae_deg": test.mae_deg,
                             "uncertainty": {k: u.relative for k, u in result.uncertainty.items()}})


if __name__ == "__main__":
    main()
