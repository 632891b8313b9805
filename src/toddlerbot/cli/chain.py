"""`toddlerbot chain run NAME`: a declared skill chain (grasp the wagon handle, then walk pushing it) in sim or on
the real robot."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import ImuOption, open_robot_imu, output_file
from toddlerbot.cli.output import console
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text

app = typer.Typer(help="Skill chains: run a chain file's skills in order (docs/manipulation.md, Skill chaining).")


@app.command()
def run(
    name: Annotated[str, typer.Argument(help="Shipped chain (wagon, pick) or a chain file.")],
    chain_file: Annotated[Path | None, typer.Option("--chain", help="Chain file to run instead of NAME's.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Scene seed (sim: shifts the wagon a little; places the pick "
                                      "task's cube as `dp eval --seed` does).")] = 0,
    json_output: Annotated[bool, typer.Option("--json", help="Print the outcome as JSON.")] = False,
    video: Annotated[Path | None, typer.Option("--video", help="MP4 of the run (sim): scene and head camera.")]
        = None,
    port: Annotated[str | None, typer.Option("--port", help="Serial port: run on the real robot.")] = None,
    calibration: Annotated[Path | None, typer.Option("--calibration", help="Robot calibration YAML (real).")]
        = None,
    imu: ImuOption = "bno08x",
    dp_grasp: Annotated[bool, typer.Option("--dp-grasp", help="Grasp with the scene's shipped diffusion policy "
                                           "(wagon: wagon.pt, 4/10 chain successes measured; the script: 20/20) "
                                           "instead of the script (sim: it needs the head camera).")] = False,
) -> None:
    """Run a chain to its end (`--json` says which policy or script drove each skill). Sim: success is the
    chain's success predicates (wagon: moved >= 0.5 m and the handle still held; pick: the cube lifted 3 cm and
    held). With --port and --calibration it runs on the real robot through the same interface. Exit code 1 when the
    chain fails (a predicate, a skill or a switch), 2 on bad input."""
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.skills.spec import load_chain

    description = RobotDescription.load(variant="gripper")
    chain = load_chain(chain_file or name, tuple(description.groups))
    if dp_grasp:
        chain = chain.with_dp_grasps()
    if (port is None) != (calibration is None):
        raise ToddlerbotError("the real robot needs both --port and --calibration")
    if video is not None and port is None:
        output_file(video, "--video")
    if port is not None:
        _run_real(chain, description, port, calibration, imu, json_output, video)  # type: ignore[arg-type]
        return
    from toddlerbot.skills.sim_run import run_in_sim

    result = run_in_sim(chain, seed, video, description)
    if json_output:
        console.print_json(json_text(result.as_json()))
    else:
        _print(result, seed, video)
    if not result.success:
        raise typer.Exit(1)


def _print(result, seed: int, video: Path | None) -> None:
    console.print(f"chain {result.chain} seed {seed}: {'success' if result.success else 'FAILED'}"
                  + (f" ({result.failure})" if result.failure else ""))
    for skill, by in result.driven_by.items():
        console.print(f"  {skill}: {by}")
    for a, b, t in result.switches:
        console.print(f"  {a} -> {b} at {t:.2f} s")
    for body, moved in result.displacement_m.items():
        console.print(f"  {body} moved {moved:.3f} m")
    for body, rise in result.lift_m.items():
        console.print(f"  {body} rose {rise:.3f} m")
    console.print(f"  checks {result.checks}; {result.sim_seconds:.1f} s simulated in {result.wall_seconds:.1f} s")
    if video is not None:
        console.print(f"wrote {video}")


def _run_real(chain, description, port: str, calibration: Path, imu: str, json_output: bool,
              video: Path | None) -> None:
    from toddlerbot.hardware.calibration import load_calibration
    from toddlerbot.hardware.real_robot import RealRobot
    from toddlerbot.skills.robot_run import run_on_robot

    if video is not None:
        raise ToddlerbotError("--video records the simulator; it is not available on the real robot")
    walks = any(skill.kind == "walk" for skill in chain.skills)
    robot = RealRobot(description, port, load_calibration(calibration, description),
                      imu=open_robot_imu(imu, port, f"chain {chain.name} (it walks)" if walks else None))
    status = run_on_robot(chain, robot, on_switch=lambda line: None if json_output else console.print(line))
    outcome = {"chain": chain.name, "success": status.failure is None, "failure": status.failure,
               "switches": [{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in status.switches]}
    if json_output:
        console.print_json(json_text(outcome))
    else:
        console.print(f"chain {chain.name}: {'ended' if status.failure is None else 'FAILED: ' + status.failure}")
    if status.failure is not None:
        raise typer.Exit(1)
