"""`toddlerbot model ...`: build the MuJoCo model from the robot spec and describe it."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from toddlerbot.cli.options import output_file
from toddlerbot.cli.output import console
from toddlerbot.files import atomic_write_text, json_text
from toddlerbot.robot.description import variant_names

SHAPES = ("visual", "collision")

app = typer.Typer(help="Build and inspect the MuJoCo model generated from the robot spec.", no_args_is_help=True)

SpecOption = Annotated[Path | None, typer.Option("--spec", help="Robot spec YAML (default: packaged ToddlerBot v1).")]
VariantOption = Annotated[str, typer.Option("--variant", help=f"One of: {', '.join(variant_names())}.")]
MotorParamsOption = Annotated[
    list[Path] | None,
    typer.Option("--motor-params", help="params.json from `toddlerbot sysid fit` (repeatable); replaces that motor "
                 "model's actuator parameters."),
]


def _check_variant(variant: str) -> str:
    if variant not in variant_names():
        raise typer.BadParameter(f"{variant!r} is not one of {', '.join(variant_names())}", param_hint="--variant")
    return variant


@app.command()
def build(
    output: Annotated[Path, typer.Option("-o", "--output", help="MJCF file to write.")],
    variant: VariantOption = "floating",
    scene: Annotated[bool, typer.Option("--scene", help="Add a floor, lights and cameras.")] = False,
    spec_path: SpecOption = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Write the MJCF of the robot (deterministic: same spec, same bytes)."""
    from toddlerbot.robot.description import load_variant

    output_file(output, "--output")
    description, base = load_variant(_check_variant(variant), spec_path, motor_params or [])
    mjspec = description.mjspec(base, scene)  # compiled: a model MuJoCo cannot compile is never written
    atomic_write_text(output, mjspec.to_xml())
    console.print(f"wrote {output} ({description.spec.name}, {variant}{', scene' if scene else ''})")


@app.command()
def info(
    variant: VariantOption = "floating",
    spec_path: SpecOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
    motor_params: MotorParamsOption = None,
) -> None:
    """Print counts, total mass, standing height and the motor table (tau_max from the fitted motors if given)."""
    from toddlerbot.robot.description import load_variant
    from toddlerbot.robot.summary import summarize_model

    description, base = load_variant(_check_variant(variant), spec_path, motor_params or [])
    summary = summarize_model(description, description.model(base, scene=False))
    if as_json:
        typer.echo(json_text(asdict(summary), indent=2))
        return
    console.print(f"[bold]{summary.name}[/] ({variant})")
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
    variant: VariantOption = "floating",
    camera: Annotated[list[str] | None, typer.Option(
        "--camera", help="Scene camera (repeatable; side by side): perspective, side, front, top.")] = None,
    shapes: Annotated[str, typer.Option(
        "--shapes", help="visual (motor housings, printed shells: what a person sees) or collision (the "
        "primitives the physics and the head camera see).")] = "visual",
    width: Annotated[int, typer.Option("--width", min=16, max=1280, help="Pixels per camera view.")] = 480,
    height: Annotated[int, typer.Option("--height", min=16, max=720, help="Pixels.")] = 480,
    spec_path: SpecOption = None,
) -> None:
    """Render the robot standing at its home pose to a PNG (needs OSMesa or EGL, as `sim run --video`)."""
    import mujoco

    from toddlerbot.robot.description import load_variant
    from toddlerbot.sim.render import render_views, write_png

    if shapes not in SHAPES:
        raise typer.BadParameter(f"{shapes!r} is not one of {', '.join(SHAPES)}", param_hint="--shapes")
    output_file(output, "--output")
    description, base = load_variant(_check_variant(variant), spec_path, [])
    model = description.model(base, scene=True)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    image = render_views(model, data, camera or ["perspective", "front"], width, height, shapes == "visual")
    write_png(output, image)
    console.print(f"wrote {output} ({variant}, {shapes} shapes, {image.shape[1]}x{image.shape[0]})")
