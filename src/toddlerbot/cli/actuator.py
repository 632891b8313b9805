"""`toddlerbot actuator ...`: the motor catalogue's actuator-model parameters and their torque-speed envelope."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.envelope_plot import plot_torque_envelope
from toddlerbot.actuation.params_file import load_params
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_file
from toddlerbot.files import json_text

app = typer.Typer(help="Actuator model: parameters per motor model and the torque-speed plot.", no_args_is_help=True)

MotorOption = Annotated[str, typer.Option("--motor", help="Catalogue name or alias, e.g. XC330.")]
ParamsOption = Annotated[
    Path | None, typer.Option("--params", help="params.json from `toddlerbot sysid fit` (overrides --motor).")
]


def _params(motor: str, params_path: Path | None):
    if params_path is not None:
        return load_params(params_path)
    model = default_catalogue()[motor]
    return model.name, model.actuator


@app.command()
def plot(
    output: Annotated[Path, typer.Option("-o", "--output", help="Image to write (.png, .svg, .pdf).")],
    motor: MotorOption = "XC330",
    params_path: ParamsOption = None,
) -> None:
    """Plot the torque limit versus joint speed (appendix Figure 12) for one motor model."""
    output_file(output, "--output", [params_path])
    name, params = _params(motor, params_path)
    plot_torque_envelope(params, name, output)
    console.print(f"wrote {output} ({name})")


@app.command()
def show(
    motor: MotorOption = "XC330",
    params_path: ParamsOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
) -> None:
    """Print the actuator-model parameters of a motor model (appendix Table 3, or a fitted params.json)."""
    name, params = _params(motor, params_path)
    values = dataclasses.asdict(params)
    if as_json:
        typer.echo(json_text({"motor": name, "actuator": values}, indent=2))
        return
    table = Table(title=name)
    table.add_column("parameter")
    table.add_column("value", justify="right")
    for key, value in values.items():
        table.add_row(key, f"{value:g}")
    console.print(table)
