"""``toddlerbot eval``: evaluate walking policies in the CPU simulator."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import (
    AsymmetricOption,
    MotorParamsOption,
    RobotOptions,
    StepInPlaceOption,
    TerrainOption,
    TerrainSeedOption,
    WeightsOption,
    duration,
    stand_option,
    symmetric_option,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_file
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text
from toddlerbot.policies import policy_names
from toddlerbot.sim.terrain import TerrainSpec, parse_terrain

app = typer.Typer(help="Evaluate policies in simulation, or logged runs (appendix Table 7).", no_args_is_help=True)

LogOption = Annotated[Path | None, typer.Option(
    help="A run log (hw run --log, sim run --log): the errors of that run, from its ground-truth pose or from "
         "--mocap; nothing is simulated.")]
MocapOption = Annotated[Path | None, typer.Option(
    help="The motion capture of the --log run as CSV: header time,x,y,z,qw,qx,qy,qz (s, m, unit quaternion; world "
         "z up), aligned to the log on its IMU gyro (docs/hardware.md, \"Table 7 on the real robot\").")]


@app.command()
def tracking(
    policy: Annotated[str, typer.Option(
        help="A walking policy, one that follows velocity commands: walk-rl, walk-zmp or a registered one "
             "(stand, replay and dp are refused).")] = "walk-rl",
    commands: Annotated[str | None, typer.Option(
        help="Command schedule in the runtime syntax, e.g. '0:0.1,0,0; 5:0,0,0.3' (default: the documented "
             "evaluation schedule).")] = None,
    seconds: Annotated[float | None, typer.Option(help="Duration, s (default 26 s, or 5 s past the last command "
                                                         "of --commands).")] = None,
    weights: WeightsOption = None,
    plot: Annotated[Path | None, typer.Option(help="Where to save the commanded-vs-achieved velocity plot.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the metrics as JSON only.")] = False,
    motor_params: MotorParamsOption = None,
    asymmetric: AsymmetricOption = False,
    step_in_place: StepInPlaceOption = False,
    log: LogOption = None,
    mocap: MocapOption = None,
    terrain: TerrainOption = None,
    terrain_seed: TerrainSeedOption = 0,
) -> None:
    """Drive a walking policy through velocity commands and report position/velocity tracking errors and falls
    (exit code 1 if the robot fell); with --log, the same errors of a logged run."""
    if log is None and mocap is None:
        ground = None if terrain is None else parse_terrain(terrain)
        options = {**symmetric_option(policy, asymmetric), **stand_option(policy, step_in_place)}
        result, title, truth = _simulated(policy, commands, seconds, weights, plot, motor_params, options,
                                          as_json, ground, terrain_seed)
    else:
        simulation = {"--commands": commands, "--seconds": seconds, "--weights": weights,
                      "--motor-params": motor_params, "--asymmetric": asymmetric or None, "--terrain": terrain,
                      "--step-in-place": step_in_place or None}
        given = [name for name, value in simulation.items() if value is not None]
        result, title, truth = _logged(log, mocap, plot, given)
    summary = result.summary() | truth
    _show(result, summary, title, plot, as_json)
    if summary["falls"]:
        raise typer.Exit(1)


def _show(result, summary: dict, title: str, plot: Path | None, as_json: bool) -> None:
    """The tracking plot (with ``plot``), then the summary as JSON or for people."""
    from toddlerbot.runtime.tracking import plot_velocity_tracking

    if plot is not None:
        plot_velocity_tracking(result, title, plot)
    if as_json:
        print(json_text(summary))
    else:
        _print(title, summary, plot)


def _simulated(policy: str, commands: str | None, seconds: float | None, weights: Path | None, plot: Path | None,
               motor_params: list[Path] | None, options: dict, quiet: bool, terrain: TerrainSpec | None,
               terrain_seed: int):
    """The policy's tracking in the simulator (on ``terrain`` drawn from ``terrain_seed``; ``options`` for its
    factory), its title, and no ground-truth figures (the simulator's)."""
    from toddlerbot.runtime.tracking import evaluate_policy

    if policy not in policy_names():
        raise ToddlerbotError(f"--policy: unknown policy {policy!r}; expected one of {', '.join(policy_names())}")
    schedule_text, seconds = _schedule(commands, seconds)
    robot = RobotOptions.of(motor_params=motor_params)
    if plot is not None:
        output_file(plot, "--plot", [weights, *robot.files])
    description = robot.description()
    with console.status(f"simulating {policy} for {seconds:.0f} s", spinner="dots") if not quiet else _null():
        result = evaluate_policy(description, policy, schedule_text, seconds, weights, terrain, terrain_seed,
                                 **options)
    return result, policy if terrain is None else f"{policy} on {terrain} (seed {terrain_seed})", {}


def _logged(log: Path | None, mocap: Path | None, plot: Path | None, simulation_options: list[str]):
    """The logged run's tracking from its ground truth or the capture, its title, and where the ground truth came
    from (the capture's alignment)."""
    from toddlerbot.runtime.log import RunLog
    from toddlerbot.runtime.mocap import log_tracking, read_capture

    if log is None:
        raise ToddlerbotError("--mocap needs --log RUN.npz: the run log of the run the capture watched")
    if simulation_options:
        raise ToddlerbotError(f"--log scores a logged run; {', '.join(simulation_options)} set up a simulated one: "
                              "give one or the other")
    if plot is not None:
        output_file(plot, "--plot", [log, mocap])
    run = RunLog.load(log)
    result, alignment = log_tracking(run, str(log), None if mocap is None else read_capture(mocap))
    truth = {"ground_truth": str(mocap or log)} | ({} if alignment is None else {
        "mocap_offset_s": alignment.offset_s, "mocap_correlation": alignment.correlation})
    return result, f"{run.policy} ({log.name})", truth


def _schedule(commands: str | None, seconds: float | None) -> tuple[str, float]:
    """The schedule to walk (default: the evaluation schedule) and its duration (default: 26 s, or 5 s past the
    last of --commands), checked."""
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS

    if seconds is None:
        seconds = DEFAULT_SECONDS if commands is None else CommandSchedule.parse(commands, "--commands").times[-1] + 5
    duration(seconds, "--seconds")
    return commands or DEFAULT_COMMANDS, seconds


def _print(title: str, summary: dict, plot: Path | None) -> None:
    from toddlerbot.runtime.tracking import TABLE7_SIM

    simulated = "ground_truth" not in summary
    truth = "" if simulated else f"; ground truth {summary['ground_truth']}" + (
        f", offset {summary['mocap_offset_s']:+.3f} s, correlation {summary['mocap_correlation']:.2f}"
        if "mocap_offset_s" in summary else "")
    console.print(f"[bold]{title}[/]: position {summary['position_m']:.3f} m, linear velocity "
                  f"{summary['lin_vel_mps']:.3f} m/s, angular velocity {summary['ang_vel_radps']:.3f} rad/s, "
                  f"falls {summary['falls']} ({summary['duration_s']:.1f} s {'simulated' if simulated else 'logged'}"
                  f"{truth})", highlight=False)
    console.print("appendix Table 7 (simulation): {:.3f} m, {:.3f} m/s, {:.3f} rad/s".format(*TABLE7_SIM))
    if plot is not None:
        console.print(f"plot: {plot}")


class _null:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None
