"""Checks of CLI option values that typer cannot express, each failing with a one-line `ToddlerbotError`
before any work starts (a run is never started only to fail at its end)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import typer

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import accepts_option, policy_names
from toddlerbot.policies.walk_rl import shipped_names
from toddlerbot.robot.builder import Base
from toddlerbot.robot.description import RobotDescription, load_variant, variant_names
from toddlerbot.robot.interface import CONTROL_HZ
from toddlerbot.sessions.recovery import ON_FALL
from toddlerbot.sim.terrain import terrain_names


def _registered_variant(name: str | None) -> str | None:
    """`name` if the variant registry knows it (plugins register names at run time, so no fixed choice list)."""
    if name is not None and name not in variant_names():
        raise typer.BadParameter(f"{name!r} is not one of {', '.join(variant_names())}", param_hint="--variant")
    return name


SpecOption = Annotated[Path | None, typer.Option("--spec", help="Robot spec YAML (default: packaged ToddlerBot v1).")]
VariantOption = Annotated[str | None, typer.Option(
    "--variant", callback=_registered_variant, autocompletion=variant_names,
    help=f"Registered robot variant: {', '.join(variant_names())} (default: the spec as it is, floating base; the "
         "manipulation commands chain and teleop: gripper).")]
MotorParamsOption = Annotated[list[Path] | None, typer.Option(
    "--motor-params", help="params.json from `toddlerbot sysid fit` (repeatable, one per motor model): the fitted "
                           "actuator parameters replace that motor model's.")]


@dataclass(frozen=True)
class RobotOptions:
    """The robot a command works on, from ``--spec``, ``--variant`` and ``--motor-params``: every command spells
    and reads them the same way, and builds one `RobotDescription` from them."""

    spec: Path | None = None
    variant: str | None = None
    """A name of the variant registry (`robot.description.register_variant`), or None for the spec as it is."""
    motor_params: tuple[Path, ...] = ()

    @classmethod
    def of(cls, spec: Path | None = None, variant: str | None = None,
           motor_params: Sequence[Path] | None = None) -> RobotOptions:
        """From the option values as typer passes them (an absent repeatable option is None)."""
        return cls(spec, variant, tuple(motor_params or ()))

    def load(self) -> tuple[RobotDescription, Base]:
        """The description and the base its variant builds on (floating without a variant)."""
        if self.variant is None:
            return RobotDescription.load(self.spec, motor_params=self.motor_params), "floating"
        return load_variant(self.variant, self.spec, self.motor_params)

    def description(self) -> RobotDescription:
        return self.load()[0]

    @property
    def files(self) -> tuple[Path | None, ...]:
        """The files these options read (the spec and every params.json): inputs no output may overwrite."""
        return (self.spec, *self.motor_params)

MAX_SEED = 2**32 - 1
"""Largest seed a command takes: numpy's generators refuse negative seeds, JAX's keys hold 32 bits."""


def seed_option(help: str, flag: str = "--seed", smallest: int = 0):
    """The typer option of a seed: a whole number in [`smallest`, `MAX_SEED`], refused in one line otherwise."""
    return typer.Option(flag, min=smallest, max=MAX_SEED, help=help)


TerrainOption = Annotated[str | None, typer.Option("--terrain", help=f"The ground: NAME[:KEY=VALUE,...], NAME one "
                                                   f"of {', '.join(terrain_names())}, e.g. rough:height=0.02 or "
                                                   "slope:degrees=-10 (docs/simulation.md, \"Terrain\"). Default: "
                                                   "the flat floor.")]
TerrainSeedOption = Annotated[int, seed_option(help="For --terrain: the seed its ground is drawn from.",
                                               flag="--terrain-seed")]


WeightsOption = Annotated[Path | None, typer.Option(
    "--weights", help="For --policy walk-rl: an exported policy (.npz, or .onnx run by onnxruntime, from `toddlerbot "
    f"rl export`), or one shipped in the package by name: {', '.join(shipped_names())} (default: walk_rl, or the "
    "variant's; docs/rl.md).")]


ControlHzOption = Annotated[float | None, typer.Option(
    "--control-hz", help=f"Control rate, Hz (default {CONTROL_HZ}).")]


MAX_RUN_SECONDS = 3600.0
"""Longest run a command accepts, s: an hour (the battery's run time; a simulated hour logs about 180,000 steps)."""


def check_run_policy(name: str) -> str:
    """`name` if `sim run` and `hw run` accept it, else one line listing what they accept."""
    if name not in policy_names():
        raise ToddlerbotError(f"unknown policy {name!r}; expected one of {', '.join(policy_names())}")
    return name


OnFallOption = Annotated[Literal[ON_FALL], typer.Option(
    "--on-fall", help="What a fall does: stop (the run ends; on the robot torque goes off, exit 1) or get-up (the "
                      "get-up policy stands the robot up, then the run goes on; falls and recoveries are counted).")]
AsymmetricOption = Annotated[bool, typer.Option(
    "--asymmetric", help="For --policy walk-rl: the policy alone, not the mean of it and its mirror image "
                         "(docs/rl.md, \"Mirror symmetry\").")]


def symmetric_option(policy: str, asymmetric: bool) -> dict[str, bool]:
    """The policy option of `--asymmetric` (none when not given); one line for a policy that has no mirror."""
    if not asymmetric:
        return {}
    if not accepts_option(policy, "symmetric"):
        raise ToddlerbotError(f"--asymmetric is not an option of policy {policy!r}")
    return {"symmetric": False}


StepInPlaceOption = Annotated[bool, typer.Option(
    "--step-in-place", help="For --policy walk-rl: step in place at a zero command instead of standing still "
                            "(docs/rl.md, \"Standing still\").")]


def stand_option(policy: str, step_in_place: bool) -> dict[str, bool]:
    """The policy option of `--step-in-place` (none when not given); one line for a policy that has no stance."""
    if not step_in_place:
        return {}
    if not accepts_option(policy, "stand"):
        raise ToddlerbotError(f"--step-in-place is not an option of policy {policy!r}")
    return {"stand": False}


MocapOption = Annotated[str, typer.Option("--mocap", help="Motion capture of the torso's pose, logged as ground truth "
                                          "so that the run's tracking errors are measured as in the simulator: "
                                          "none, or emulator (the true pose of `hw emulate --hil` on --port).")]
ImuOption = Annotated[str, typer.Option("--imu", help="The IMU: bno08x (the robot's, over I2C), emulator (the "
                                        "simulated IMU of `hw emulate --hil` on --port) or none (an upright, still "
                                        "stand-in; walking policies refuse it).")]


def duration(value: float, option: str, max_s: float = MAX_RUN_SECONDS, unit: str = "seconds") -> float:
    """`value` if it is a finite duration in (0, `max_s`] (a run of 1e300 s would never end)."""
    if not (math.isfinite(value) and 0 < value <= max_s):
        raise ToddlerbotError(f"{option} {value:g}: expected a duration in (0, {max_s:g}] {unit}")
    return value


MAX_TRAINING_MINUTES = 7 * 24 * 60.0
"""Longest training budget a command accepts, minutes (a week; a budget must end)."""


def training_budget(minutes: float | None, steps: int | None, step_option: str = "--steps") -> None:
    """Refuse a training budget that would not end or not start: --minutes must be finite in (0, a week], the step
    count >= 1."""
    if minutes is not None:
        duration(minutes, "--minutes", MAX_TRAINING_MINUTES, "minutes")
    if steps is not None and steps < 1:
        raise ToddlerbotError(f"{step_option} {steps}: expected a whole number >= 1")


def within(value: float, option: str, low: float, high: float, unit: str) -> float:
    """`value` if it lies in [`low`, `high`] (plausible physical ranges: NaN and inf never do)."""
    if not low <= value <= high:  # False for NaN
        raise ToddlerbotError(f"{option} {value:g}: expected a number of {unit} in [{low:g}, {high:g}]")
    return value


def positive(value: float, option: str, unit: str) -> float:
    """`value` if it is a finite number > 0 (NaN, inf, 0 and negatives are refused, naming the option)."""
    if not (math.isfinite(value) and value > 0):
        raise ToddlerbotError(f"{option} {value}: expected a finite number of {unit} > 0")
    return value


TensorBoardOption = Annotated[bool, typer.Option(
    "--tensorboard/--no-tensorboard", help="Write the metrics as TensorBoard scalars into RUN/tensorboard/ "
                                           "(tensorboard --logdir RUN).")]
WandbOption = Annotated[bool, typer.Option(
    "--wandb", help="Also log the metrics to Weights & Biases (extra [wandb]; project: WANDB_PROJECT, default "
                    "toddlerbot).")]
WandbModeOption = Annotated[str | None, typer.Option(
    "--wandb-mode", help="online or offline (files in RUN/wandb/ for a later `wandb sync`); default: WANDB_MODE, "
                         "else online.")]


def dashboards(tensorboard: bool, wandb: bool, wandb_mode: str | None):
    """The training's metric sinks (`toddlerbot.metrics.Dashboards`), their packages checked now."""
    from toddlerbot.metrics import Dashboards

    if wandb_mode is not None and not wandb:
        raise ToddlerbotError(f"--wandb-mode {wandb_mode}: W&B logging is off; add --wandb")
    chosen = Dashboards(tensorboard=tensorboard, wandb=wandb, wandb_mode=wandb_mode)
    chosen.check()
    return chosen
