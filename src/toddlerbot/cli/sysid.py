"""`toddlerbot sysid ...`: motor system identification (appendix sections 8.8-8.9). See docs/sysid.md."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.params_file import load_params
from toddlerbot.cli.options import seed_option, within
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import not_an_input, output_dir, output_file
from toddlerbot.cli.sysid_record import Profile, excitation_runs, profile_names, record_command
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.evaluate import evaluate, plot_tracking
from toddlerbot.sysid.excitation import DEFAULT_KP, DEFAULT_PROFILES, SAMPLE_HZ
from toddlerbot.sysid.fit import DEFAULT_EVALS
from toddlerbot.sysid.fit import fit as run_fit
from toddlerbot.sysid.fit_run import fit_provenance, params_for
from toddlerbot.sysid.logs import read_columns
from toddlerbot.sysid.manifest import Manifest, load_manifest, select_gains
from toddlerbot.sysid.params import DEFAULT_MODEL, fit_models, save_params, search_range, searched_as
from toddlerbot.sysid.rigs import parse_rig
from toddlerbot.sysid.synthetic import synthesize, write_runs
from toddlerbot.sysid.testbed import armature_from_spindown, fit_friction

app = typer.Typer(help="Motor system identification: test-bed analysis, excitation, fit and evaluation.",
                  no_args_is_help=True)
testbed = typer.Typer(help="Motor test-bed analysis (appendix 8.8).", no_args_is_help=True)
app.add_typer(testbed, name="testbed")
app.command("record")(record_command)

ManifestArg = Annotated[Path, typer.Argument(help="Manifest (JSON or YAML) naming the run CSVs, motor and rig.")]
JsonOption = Annotated[bool, typer.Option("--json", help="Machine-readable output.")]
GainsOption = Annotated[list[float] | None, typer.Option(
    "--kp", help="Only the manifest's runs at this firmware P gain (repeatable), e.g. fit on one gain and "
                 "evaluate on another.")]


def _runs(manifest: Path, kp: list[float] | None) -> Manifest:
    m = load_manifest(manifest)
    return select_gains(m, kp) if kp else m


def _fit_model(name: str) -> str:
    """`name` if a registered motor model fits it (models are registered at run time: no fixed choice list)."""
    if name not in fit_models():
        raise typer.BadParameter(f"{name!r} is not one of {', '.join(fit_models())}", param_hint="--model")
    return name


FitModelOption = Annotated[str, typer.Option(
    "--model", callback=_fit_model,
    help="A registered motor model's fit: dc_motor (PWM duty, stall torque, back-EMF, load-dependent friction: the "
         "one that holds across gains on real servos), appendix (the 9 parameters of section 8.9) or extended (plus "
         "stiction, Stribeck velocity and load-dependent friction).")]
FitKpScaleOption = Annotated[bool, typer.Option(
    "--fit-kp-scale", help="Also fit the firmware-to-physical gain conversion (dc_motor: pwm_per_rad; appendix, "
                           "extended: kp_scale).")]
EvalsOption = Annotated[int, typer.Option("--evals", min=4, help="Candidate evaluations (all restarts).")]
PopsizeOption = Annotated[int, typer.Option("--popsize", min=4, help="Candidates per generation of the first CMA-ES "
                                                                     "run (doubled at each IPOP restart).")]
StartOption = Annotated[Path | None, typer.Option("--start", help="params.json to start from (default: catalogue).")]


@app.command("fit")
def fit_command(
    manifest: ManifestArg,
    output: Annotated[Path, typer.Option("-o", "--output", help="params.json to write.")],
    fit_kp_scale: FitKpScaleOption = False,
    model: FitModelOption = DEFAULT_MODEL,
    kp: GainsOption = None,
    seed: Annotated[int, seed_option("CMA-ES seed (>= 1); same seed, same result.", smallest=1)] = 1,
    evals: EvalsOption = DEFAULT_EVALS,
    popsize: PopsizeOption = 32,
    restarts: Annotated[int, typer.Option("--restarts", min=0, help="Most IPOP restarts on stagnation.")] = 4,
    start: StartOption = None,
) -> None:
    """Fit an actuator model to the manifest's runs; prints each parameter's standard error, the parameters left
    at a bound and the ones kept fixed (with the reason)."""
    output_file(output, "--output", [manifest, start])  # an unwritable -o fails now, not after minutes of fitting
    listed = load_manifest(manifest)
    not_an_input(output, "--output", (run.file for run in listed.runs))
    m = select_gains(listed, kp) if kp else listed
    start_params = None if start is None else params_for(start, m, manifest)
    with Progress(TextColumn("fitting"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.description}"),
                  TimeElapsedColumn(), console=console, transient=True) as bar:
        task = bar.add_task("", total=evals)
        result = run_fit(m, fit_kp_scale=fit_kp_scale, model=model, seed=seed, evals=evals, popsize=popsize,
                         restarts=restarts, start=start_params,
                         progress=lambda n, rmse: bar.update(task, completed=n, description=f"RMSE {rmse:.3f} deg"))
    save_params(output, m.motor.name, result.params, result.fitted, fit_provenance(m, manifest, model, seed, result))
    console.print(f"wrote {output}: {m.motor.name} ({model}), RMSE {result.rmse_deg:.3f} deg over {len(m.runs)} runs "
                  f"({result.evals} evaluations, {result.wall_s:.1f} s)")
    _print_fit(result)


def _print_fit(result) -> None:
    """The fitted parameters with their uncertainty, then those at a search bound and those kept fixed."""
    table = Table(title="fitted parameters (standard error: linearised, residual autocorrelation counted)")
    for col in ("parameter", "value", "std error", "relative", "most correlated with"):
        table.add_column(col, justify="left" if col in ("parameter", "most correlated with") else "right")
    for name in result.fitted:
        u = result.uncertainty.get(name)
        other, r = u.strongest_correlation if u else ("", 0.0)
        table.add_row(name, f"{getattr(result.params, name):.4g}", f"{u.std:.2g}" if u else "-",
                      f"{u.relative:.0%}" if u else "-", f"{other} ({r:+.2f})" if u else "")
    console.print(table)
    for name, side in result.at_bounds.items():
        lo, hi, _, unit = search_range(name)
        console.print(f"[yellow]warning:[/] {name} = {getattr(result.params, name):.4g} ended at its {side} search "
                      f"bound ({lo:g} .. {hi:g}{searched_as(name)} {unit}): not identified by these runs")
    for name, reason in result.fixed.items():
        console.print(f"fixed: {name} = {getattr(result.params, name):.4g} ({reason})")


@app.command("eval")
def eval_command(
    manifest: ManifestArg,
    params: Annotated[Path, typer.Argument(help="params.json (from `sysid fit`).")],
    kp: GainsOption = None,
    as_json: JsonOption = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="Folder for per-run plots: measured vs simulated "
                                                             "position and velocity, simulated torque.")] = None,
) -> None:
    """Tracking MAE/RMSE (degrees) of a parameter set per run and overall."""
    if plot is not None:
        output_dir(plot, "--plot", [manifest, params])
    m = _runs(manifest, kp)
    p = params_for(params, m, manifest)
    ev = evaluate(m, p)
    written = plot_tracking(m, ev, plot) if plot is not None else []
    if as_json:
        typer.echo(json.dumps(ev.to_json(), indent=2))
        return
    table = Table(title=f"{m.motor.name} ({p.model}) on {m.rig.type}: tracking error")
    for col in ("run", "kp", "MAE (deg)", "RMSE (deg)"):
        table.add_column(col, justify="left" if col == "run" else "right")
    for r in ev.runs:
        table.add_row(r.file, f"{r.kp:g}", f"{r.mae_deg:.3f}", f"{r.rmse_deg:.3f}")
    table.add_row("[bold]overall[/]", "", f"[bold]{ev.mae_deg:.3f}[/]", f"[bold]{ev.rmse_deg:.3f}[/]")
    console.print(table)
    if written:
        console.print(f"wrote {len(written)} plot(s) to {plot}")


@app.command()
def excite(
    output: Annotated[Path, typer.Option("-o", "--output", help="Folder for the run CSVs and manifest.json.")],
    motor: Annotated[str, typer.Option("--motor", help="Catalogue name or alias.")] = "XC330",
    rig: Annotated[str, typer.Option("--rig", help="Rig as JSON, as in a manifest.")]
    = '{"type": "pendulum", "mass": 0.49, "length": 0.1}',
    profile: Annotated[list[Profile] | None, typer.Option("--profile", help="Repeatable.")] = None,
    kp: Annotated[list[int] | None, typer.Option("--kp", help="Firmware kp values to cycle (repeatable).")] = None,
    seconds: Annotated[float, typer.Option("--duration", help="Seconds per run.")] = 6.0,
    rate: Annotated[float, typer.Option("--rate", help="Sample rate, Hz.")] = SAMPLE_HZ,
    amplitude: Annotated[float, typer.Option("--amplitude", help="Goal amplitude, rad.")] = 0.5,
    center: Annotated[float, typer.Option("--center", help="Goal centre, rad.")] = 0.0,
    simulate: Annotated[bool, typer.Option("--simulate", help="Also simulate the runs (synthetic logs).")] = False,
    params: Annotated[Path | None, typer.Option("--params", help="params.json for --simulate (default: catalogue).")]
    = None,
    noise_deg: Annotated[float, typer.Option("--noise-deg", help="Position noise std for --simulate, deg.")] = 0.1,
    seed: Annotated[int, seed_option("Noise seed for --simulate.")] = 0,
) -> None:
    """Write excitation profiles (one CSV per profile x kp) and a manifest; --simulate fills in positions."""
    output_dir(output, "--output", [params])
    within(noise_deg, "--noise-deg", 0.0, 10.0, "degrees")
    model = default_catalogue()[motor]
    rig_obj = parse_rig(_json_arg(rig, "--rig"), "--rig")
    runs_ex = excitation_runs(profile_names(profile, DEFAULT_PROFILES), tuple(kp or DEFAULT_KP), seconds, rate,
                              amplitude, center)
    p = load_params(params)[1] if params is not None else model.actuator
    import numpy as np

    runs = synthesize(runs_ex, rig_obj, p, np.radians(noise_deg) if simulate else 0.0, seed)
    path = write_runs(output, model.name, rig_obj, runs, with_position=simulate)
    what = "synthetic logs" if simulate else "goal profiles (run them on the motor to fill in `position`)"
    console.print(f"wrote {len(runs)} {what} and {path}")


@testbed.command()
def friction(
    log: Annotated[Path, typer.Argument(help="CSV with columns speed (rad/s) and torque (N*m).")],
    as_json: JsonOption = False,
) -> None:
    """Friction loss and damping from constant-speed back-drive data (linear fit per direction)."""
    data = read_columns(log, ("speed", "torque"))
    result = fit_friction(data["speed"], data["torque"], source=str(log))
    body = {"frictionloss": result.frictionloss, "damping": result.damping,
            "directions": {k: dataclasses.asdict(v) for k, v in result.directions.items()}}
    if as_json:
        typer.echo(json.dumps(body, indent=2))
        return
    console.print(f"frictionloss {result.frictionloss:.4f} N*m   damping {result.damping:.5f} N*m*s/rad")
    for name, line in result.directions.items():
        console.print(f"  {name:8s}: intercept {line.intercept:.4f}  slope {line.slope:.5f}  "
                      f"R^2 {line.r2:.4f}  ({line.samples} samples)")


@testbed.command()
def spindown(
    log: Annotated[Path, typer.Argument(help="CSV with columns time (s) and velocity (rad/s), from power cut.")],
    damping: Annotated[float, typer.Option("--damping", help="Fitted damping, N*m*s/rad.")],
    frictionloss: Annotated[float, typer.Option("--frictionloss", help="Fitted friction loss, N*m.")],
    load_inertia: Annotated[float, typer.Option("--load-inertia", help="Test-bed inertia on the shaft, kg*m^2.")]
    = 0.0,
    as_json: JsonOption = False,
) -> None:
    """Armature from a spin-down: I = 2 E / w0^2, E the energy dissipated until the stop."""
    data = read_columns(log, ("time", "velocity"))
    result = armature_from_spindown(data["time"], data["velocity"], damping, frictionloss, load_inertia,
                                    source=str(log))
    if as_json:
        typer.echo(json.dumps(dataclasses.asdict(result), indent=2))
        return
    console.print(f"w0 {result.omega0:.3f} rad/s  E {result.energy:.5f} J  I {result.inertia:.6f} kg*m^2  "
                  f"armature {result.armature:.6f} kg*m^2  (stopped after {result.stop_time:.2f} s)")


def _json_arg(text: str, option: str) -> object:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise SysIDError(f"{option}: not valid JSON ({exc})") from None
