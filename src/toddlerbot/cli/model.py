"""`toddlerbot model ...`: build the MuJoCo model from the robot spec and describe it."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Annotated, Literal

import typer
from rich.table import Table

from toddlerbot.cli.options import MotorParamsOption, RobotOptions, SpecOption, VariantOption
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_file
from toddlerbot.files import atomic_write_text, json_text
from toddlerbot.robot.builder import Base

app = typer.Typer(help="Build and inspect the MuJoCo model generated from the robot spec.", no_args_is_help=True)

BaseOption = Annotated[Base | None, typer.Option(
    "--base", help="floating (a free joint) or fixed (the torso welded in place); default: the variant's, else "
                   "floating.")]


def _load(robot: RobotOptions, base: Base | None):
    """The description, the base to build on and how to name both in a message."""
    description, variant_base = robot.load()
    base = base or variant_base
    return description, base, ", ".join(dict.fromkeys(n for n in (robot.variant, base) if n))


@app.command()
def build(
    output: Annotated[Path, typer.Option("-o", "--output", help="MJCF file to write.")],
    variant: VariantOption = None,
    base: BaseOption = None,
    scene: Annotated[bool, typer.Option("--scene", help="Add a floor, lights and cameras.")] = False,
    spec_path: SpecOption = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Write the MJCF of the robot (deterministic: same spec, same bytes)."""
    robot = RobotOptions.of(spec_path, variant, motor_params)
    output_file(output, "--output", robot.files)
    description, base, label = _load(robot, base)
    mjspec = description.mjspec(base, scene)  # compiled: a model MuJoCo cannot compile is never written
    atomic_write_text(output, mjspec.to_xml())
    console.print(f"wrote {output} ({description.spec.name}, {label}{', scene' if scene else ''})")


@app.command()
def info(
    variant: VariantOption = None,
    base: BaseOption = None,
    spec_path: SpecOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
    motor_params: MotorParamsOption = None,
) -> None:
    """Print counts, total mass, standing height and the motor table (tau_max from the fitted motors if given)."""
    from toddlerbot.robot.summary import summarize_model

    description, base, label = _load(RobotOptions.of(spec_path, variant, motor_params), base)
    summary = summarize_model(description, description.model(base, scene=False))
    if as_json:
        typer.echo(json_text(asdict(summary), indent=2))
        return
    _print_summary(summary, label)


def _print_summary(summary, label: str) -> None:
    console.print(f"[bold]{summary.name}[/] ({label})")
    console.print(
        f"bodies {summary.bodies}  joints {summary.joints}  nq {summary.nq}  nv {summary.nv}  "
        f"actuators {summary.actuators}  equalities {summary.equalities}  tendons {summary.tendons}  "
        f"geoms {summary.geoms}"
    )
    console.print(f"total mass {summary.total_mass_kg:.3f} kg   standing height {summary.standing_height_m:.3f} m   "
                  f"torso height at home {summary.torso_height_m:.4f} m")
    table = Table("id", "motor", "model", "joint", "group", "kp", "kd", "range (rad)", "tau_max (N*m)")
    for m in summary.motors:
        table.add_row(str(m.id), m.motor, m.model, m.joint, m.group, str(m.kp), str(m.kd),
                      f"[{m.range[0]:+.3f}, {m.range[1]:+.3f}]", f"{m.tau_max:.2f}")
    console.print(table)


@app.command()
def render(
    output: Annotated[Path, typer.Option("-o", "--output", help="PNG file to write.")],
    variant: VariantOption = None,
    base: BaseOption = None,
    camera: Annotated[list[str] | None, typer.Option(
        "--camera", help="Scene camera (repeatable; side by side): perspective, side, front, top.")] = None,
    shapes: Annotated[Literal["visual", "collision"], typer.Option(
        "--shapes", help="visual (motor housings, printed shells: what a person sees) or collision (the "
        "primitives the physics and the head camera see).")] = "visual",
    width: Annotated[int, typer.Option("--width", min=16, max=1280, help="Pixels per camera view.")] = 480,
    height: Annotated[int, typer.Option("--height", min=16, max=720, help="Pixels.")] = 480,
    spec_path: SpecOption = None,
) -> None:
    """Render the robot standing at its home pose to a PNG (needs OSMesa or EGL, as `sim run --video`)."""
    import mujoco

    from toddlerbot.sim.render import render_views, write_png

    output_file(output, "--output", [spec_path])
    description, base, label = _load(RobotOptions.of(spec_path, variant), base)
    model = description.model(base, scene=True)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    image = render_views(model, data, camera or ["perspective", "front"], width, height, shapes == "visual")
    write_png(output, image)
    console.print(f"wrote {output} ({label}, {shapes} shapes, {image.shape[1]}x{image.shape[0]})")
