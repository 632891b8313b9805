"""`toddlerbot design report`: power factor, torque requirement, weight and power budget, range of motion."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from toddlerbot.cli.options import MotorParamsOption, RobotOptions, SpecOption, VariantOption, within
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir
from toddlerbot.design.budget import PowerInputs
from toddlerbot.design.report import HEIGHT_RANGE_M, MASS_RANGE_KG, DesignReport, design_report
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text

app = typer.Typer(help="Design metrics of the appendix (sections 8.2, 8.4-8.6).", no_args_is_help=True)


@app.command()
def report(
    height: Annotated[float | None, typer.Option("--height", help="What-if height, m (default: the model's).")] = None,
    mass: Annotated[float | None, typer.Option("--mass", help="What-if mass, kg (default: the spec's).")] = None,
    plot: Annotated[Path | None, typer.Option("--plot", help="Directory to write the figures (PNG) to.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print machine-readable JSON only.")] = False,
    variant: VariantOption = None,
    duty_cycle: Annotated[float, typer.Option(help="Motor duty cycle while walking.")] = PowerInputs.duty_cycle,
    battery_ah: Annotated[float, typer.Option(help="Battery capacity, Ah.")] = PowerInputs.battery_capacity_ah,
    spec_path: SpecOption = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Print the design report (and optionally write its figures)."""
    for name, value, (low, high), unit in (("--height", height, HEIGHT_RANGE_M, "m"),
                                           ("--mass", mass, MASS_RANGE_KG, "kg")):
        if value is not None:
            within(value, name, low, high, unit)
    if plot is not None:
        output_dir(plot, "--plot")
    description = RobotOptions.of(spec_path, variant, motor_params).description()
    try:
        power = PowerInputs(duty_cycle=duty_cycle, battery_capacity_ah=battery_ah)
    except ValueError as exc:
        raise ToddlerbotError(str(exc)) from None
    result = design_report(description, height, mass, power_inputs=power)
    if plot is not None:
        from toddlerbot.design.plots import write_plots

        paths = write_plots(result, plot)
    if as_json:
        typer.echo(json_text(result.to_json(), indent=2))
        return
    _print(result)
    if plot is not None:
        console.print("figures: " + ", ".join(str(p) for p in paths))


def _print(r: DesignReport) -> None:
    pf = r.power_factor
    console.rule(f"[bold]{r.robot}[/]  h = {r.height_m:.3f} m, m = {r.mass_kg:.3f} kg, {r.active_dof} active DoF")
    console.print(f"Power factor (Eq. 4): total {pf.total:.2f} = upper {pf.upper:.2f} + lower {pf.lower:.2f}"
                  f"   (Σ stall torque {pf.sum_torque_nm:.1f} N·m)")
    table = Table("humanoid", "h (m)", "m (kg)", "active DoF", "Σ peak torque (N·m)", "power factor", "source",
                  title="Comparison (public specifications)")
    table.add_row(r.robot, f"{r.height_m:.2f}", f"{r.mass_kg:.2f}", str(r.active_dof), f"{pf.sum_torque_nm:.1f}",
                  f"{pf.total:.2f}", "this spec + motor catalogue")
    for h in r.humanoids:
        table.add_row(h.name + (" (est.)" if h.estimated else ""), f"{h.height_m:.2f}", f"{h.mass_kg:.1f}",
                      str(h.active_dof), f"{h.sum_peak_torque_nm:.0f}", f"{h.power_factor:.2f}", h.source[:60])
    console.print(table)
    table = Table("joint", "required (N·m)", "stall at joint (N·m)", "ok", title="Torque requirement (Eq. 5)")
    for c in r.joint_checks:
        table.add_row(c.joint, f"{c.required_nm:.2f}", f"{c.available_nm:.2f}",
                      "yes" if c.sufficient else "[bold red]NO[/]")
    console.print(table)
    w = r.weight
    console.print(f"Weight estimate: {w.motors} motors → {w.estimate_kg:.3f} kg vs spec {w.spec_mass_kg:.3f} kg "
                  f"({100 * w.error_fraction:+.1f} %); catalogue motor mass {w.catalogue_motor_mass_kg:.3f} kg")
    p = r.power
    console.print(f"Power budget: electronics {p.electronics_w:.0f} W + motors {p.motors_w:.1f} W = {p.total_w:.1f} W;"
                  f" battery {p.battery_wh:.0f} Wh → {p.runtime_h:.2f} h; {p.battery_wh_for_target:.0f} Wh needed "
                  f"for the target run time; peak {p.peak_power_w:.0f} W")
    table = Table("joint", "robot (deg)", "span", "human", "human (deg)", "span", title="Range of motion (Fig. 6)")
    for row in r.range_of_motion:
        human = f"[{row.human_deg[0]:.0f}, {row.human_deg[1]:.0f}]" if row.human_deg else "-"
        table.add_row(row.joint, f"[{row.robot_deg[0]:.0f}, {row.robot_deg[1]:.0f}]", f"{row.robot_span_deg:.0f}",
                      row.human_joint or "-", human, f"{row.human_span_deg:.0f}" if row.human_span_deg else "-")
    console.print(table)
