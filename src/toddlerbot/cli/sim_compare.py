"""`toddlerbot sim compare`: a run log (e.g. from `hw run`) replayed in the simulator, sim versus real."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from toddlerbot.cli.options import MotorParamsOption, RobotOptions
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir
from toddlerbot.files import json_text


def compare_command(
    log: Annotated[Path, typer.Argument(help="Run log (.npz) from `toddlerbot hw run --log` or `sim run --log`.")],
    motor_params: MotorParamsOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="Folder for the logged-vs-simulated plot.")] = None,
    top: Annotated[int, typer.Option("--top", min=1, help="Motors listed (and plotted), largest error first.")] = 10,
) -> None:
    """Replay the log's motor targets and gains from its first state in the simulator; report position and
    velocity errors per motor and overall, and Table 7 tracking errors of both for a walking run."""
    from toddlerbot.runtime.log import RunLog
    from toddlerbot.runtime.sim_compare import plot_comparison, replay_in_sim

    if plot is not None:
        output_dir(plot, "--plot")
    run = RunLog.load(log)
    result = replay_in_sim(run, RobotOptions.of(motor_params=motor_params).description())
    written = plot_comparison(result, plot, top=min(top, 6)) if plot is not None else []
    if as_json:
        typer.echo(json_text(result.to_json(), indent=2))
        return
    table = Table(title=f"{log.name}: simulated vs logged ({len(result.time)} steps, {run.policy})")
    for col in ("motor", "pos MAE (deg)", "pos max (deg)", "vel MAE (rad/s)"):
        table.add_column(col, justify="left" if col == "motor" else "right")
    for e in sorted(result.motors, key=lambda e: -e.position_mae_deg)[:top]:
        table.add_row(e.motor, f"{e.position_mae_deg:.3f}", f"{e.position_max_deg:.3f}", f"{e.velocity_mae:.3f}")
    table.add_row("[bold]all motors[/]", f"[bold]{result.position_mae_deg:.3f}[/]", "",
                  f"[bold]{result.velocity_mae:.3f}[/]")
    console.print(table)
    if not result.gains_logged:
        console.print("note: the log has no motor_kp/kd; the spec's gains were replayed")
    for name, tracking in (("sim", result.sim_tracking), ("real", result.real_tracking)):
        if tracking is not None:
            s = tracking.summary()
            console.print(f"Table 7 tracking ({name}): position {s['position_m']:.3f} m, linear velocity "
                          f"{s['lin_vel_mps']:.3f} m/s, angular velocity {s['ang_vel_radps']:.3f} rad/s")
    if written:
        console.print(f"wrote {written[0]}")
