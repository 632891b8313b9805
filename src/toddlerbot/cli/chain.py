"""`toddlerbot chain run NAME`: a declared skill chain (grasp the wagon handle, then walk pushing it) in sim or on
the real robot."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import (
    ImuOption,
    MotorParamsOption,
    RobotOptions,
    SpecOption,
    VariantOption,
    seed_option,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_file
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text
from toddlerbot.tasks import GRIPPER

app = typer.Typer(help="Skill chains: run a chain file's skills in order (docs/manipulation.md, Skill chaining).")

NameArgument = Annotated[str, typer.Argument(help="Shipped chain (wagon, pick) or a chain file.")]
ChainFileOption = Annotated[Path | None, typer.Option("--chain", help="Chain file to run instead of NAME's.")]
SeedOption = Annotated[int, seed_option(help="Scene seed (sim: shifts the wagon a little; places the pick "
                                                        "task's cube as `dp eval --seed` does).")]
JsonOption = Annotated[bool, typer.Option("--json", help="Print the outcome as JSON.")]
VideoOption = Annotated[Path | None, typer.Option("--video", help="MP4 of the run (sim): scene and head camera.")]
PortOption = Annotated[str | None, typer.Option("--port", help="Serial port: run on the real robot.")]
CalibrationOption = Annotated[Path | None, typer.Option("--calibration", help="Robot calibration YAML (real).")]
ScriptedGraspOption = Annotated[bool, typer.Option(
    "--scripted-grasp", help="Grasp by the chain's script instead of its diffusion policy (wagon: wagon.pt; success "
                             "rates of both in docs/manipulation.md).")]


@app.command()
def run(name: NameArgument, chain_file: ChainFileOption = None, seed: SeedOption = 0, json_output: JsonOption = False,
        video: VideoOption = None, port: PortOption = None, calibration: CalibrationOption = None,
        imu: ImuOption = "bno08x", scripted_grasp: ScriptedGraspOption = False, spec: SpecOption = None,
        variant: VariantOption = GRIPPER, motor_params: MotorParamsOption = None,
        variation: Annotated[str, typer.Option(help="Sim: the scene variation the seed draws from (wagon: default or "
                                                    "wide, docs/manipulation.md).")] = "default") -> None:
    """Run a chain to its end (`--json` says which policy or script drove each skill). Sim: success is the
    chain's success predicates (wagon: moved >= 0.5 m and the handle still held; pick: the cube lifted 3 cm and
    held). With --port and --calibration it runs on the real robot through the same interface. Exit code 1 when the
    chain fails (a predicate, a skill or a switch), 2 on bad input."""
    from toddlerbot.skills.spec import load_chain

    description = RobotOptions.of(spec, variant, motor_params).description()
    chain = load_chain(chain_file or name, tuple(description.groups))
    if scripted_grasp:
        chain = chain.with_scripted_grasps()
    if (port is None) != (calibration is None):
        raise ToddlerbotError("the real robot needs both --port and --calibration")
    if port is not None and variation != "default":
        raise ToddlerbotError(f"--variation {variation!r} draws a simulated scene; the real robot has its own")
    if port is None:
        success, outcome, lines = _run_sim(chain, seed, video, description, variation)
    else:
        success, outcome, lines = _run_real(chain, description, port, calibration, imu, video,  # type: ignore[arg-type]
                                            say=(lambda _: None) if json_output else console.print)
    if json_output:
        console.print_json(json_text(outcome))
    else:
        for line in lines:
            console.print(line)
    if not success:
        raise typer.Exit(1)


def _run_sim(chain, seed: int, video: Path | None, description, variation: str) -> tuple[bool, dict, list[str]]:
    from toddlerbot.skills.sim_run import run_in_sim

    if video is not None:
        output_file(video, "--video")
    result = run_in_sim(chain, seed, video, description, variation=variation)
    return result.success, result.as_json(), result.summary() + ([f"wrote {video}"] if video is not None else [])


def _run_real(chain, description, port: str, calibration: Path, imu: str, video: Path | None,
              say) -> tuple[bool, dict, list[str]]:
    from toddlerbot.sessions.robot import chain_on_robot

    if video is not None:
        raise ToddlerbotError("--video records the simulator; it is not available on the real robot")
    status = chain_on_robot(chain, description, port, calibration, imu, on_switch=say)
    outcome = {"chain": chain.name, "success": status.failure is None, "failure": status.failure,
               "switches": [{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in status.switches],
               "recoveries": [r.to_dict() for r in status.recoveries]}
    line = f"chain {chain.name}: {'ended' if status.failure is None else 'FAILED: ' + status.failure}"
    return status.failure is None, outcome, [line]
