"""From `rl train` options to what `rl.train.train` runs: a resumed run as it started, or a new run's recipe (by
physics backend, or another run's warm start) with the options' overrides, every option checked before anything
compiles. Importing it starts no JAX (`is_smoke_run` is asked before the XLA flags are set)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text
from toddlerbot.rl import config
from toddlerbot.rl.environments import environment_class
from toddlerbot.rl.run_files import CONFIG, SMOKE_MARKER

if TYPE_CHECKING:
    from toddlerbot.rl.train import WarmStartSource

"""File in a `--smoke` run: a resumed smoke run sets the smoke XLA flags again."""


@dataclass(frozen=True)
class TrainRequest:
    """The `rl train` options that choose the configuration (None: the recipe's value)."""

    smoke: bool = False
    timesteps: int | None = None
    num_envs: int | None = None
    seed: int = 0
    solver_iterations: int | None = None
    ls_iterations: int | None = None
    backend: str = "auto"
    imitation_iterations: int | None = None
    motor_params: tuple[Path, ...] = ()
    warm_start: Path | None = None
    variant: str | None = None
    upper_body_pose: float | None = None
    hand_force: float | None = None
    push_velocity: tuple[float, float] | None = None
    push_interval: tuple[float, float] | None = None
    imu_age: tuple[float, float] | None = None
    mirror_loss: float | None = None
    reward_weights: tuple[str, ...] = ()
    """``NAME=WEIGHT`` overrides of `RewardConfig.weights`."""
    environment: str | None = None
    """The registered environment to train (`toddlerbot.rl.environments`; None: `config.DEFAULT_ENVIRONMENT`)."""
    motion: str | None = None
    """The motion a tracking environment tracks (a built-in name or a motion file; ``track`` needs one, the others
    take none)."""
    terrain: str | None = None
    """The ground to train on (`toddlerbot.sim.terrain`; None: the recipe's, the flat floor)."""
    terrain_seed: int | None = None
    init_policy: Path | None = None
    """An exported walk policy to continue training from (`toddlerbot.rl.policy_start`)."""
    desired_kl: float | None = None
    """`PPOConfig.desired_kl`, the KL the adaptive step size aims at (None: the recipe's)."""
    terrain_start: float | None = None
    """Half-width of the flat start square in training, m (None: the configuration's)."""


@dataclass(frozen=True)
class TrainPlan:
    """Arguments of `rl.train.train` (configurations None: a resumed run reads its own)."""

    run_dir: Path
    resume: bool
    env: config.EnvConfig | None = None
    ppo: config.PPOConfig | None = None
    imitation: config.ImitationConfig | None = None


def is_smoke_run(run_dir: Path) -> bool:
    return (run_dir / SMOKE_MARKER).is_file()


KEPT_ON_RESUME = {"motor_params": "--motor-params", "solver_iterations": "--solver-iterations",
                  "ls_iterations": "--ls-iterations", "backend": "--backend",
                  "imitation_iterations": "--imitation-iterations", "warm_start": "--warm-start",
                  "variant": "--variant", "upper_body_pose": "--upper-body-pose", "hand_force": "--hand-force",
                  "num_envs": "--num-envs", "mirror_loss": "--mirror-loss", "reward_weights": "--reward-weight",
                  "environment": "--env", "motion": "--motion", "init_policy": "--init-policy"}
"""`TrainRequest` fields a resume refuses to change (given other than their defaults), and their options."""


STAGE_OPTIONS = {"push_velocity": "--push-velocity", "push_interval": "--push-interval", "imu_age": "--imu-age",
                 "terrain": "--terrain", "terrain_seed": "--terrain-seed", "terrain_start": "--terrain-start",
                 "desired_kl": "--desired-kl"}
"""`TrainRequest` fields of the randomisation, the ground and PPO's step-size target that a resume may change: each
starts a next stage (as a new step budget, ``--timesteps``, does)."""


def resume_plan(run_dir: Path, request: TrainRequest, write: bool = True) -> TrainPlan:
    """Continue the run in `run_dir` from its last checkpoint. `STAGE_OPTIONS` and `--timesteps` start its next
    stage (a curriculum: say harder or more frequent pushes from here on); options that would change anything else
    are refused. ``write`` False: the options are checked, the run's configuration is left to process 0 of a run of
    several processes (`toddlerbot.rl.distributed`)."""
    if not (run_dir / CONFIG).is_file():
        raise ToddlerbotError(f"{run_dir}: no training run to resume (config.json missing)")
    changed = [option for field, option in KEPT_ON_RESUME.items()
               if getattr(request, field) != getattr(TrainRequest(), field)]
    if changed:
        raise ToddlerbotError(f"{'/'.join(changed)}: a resumed run keeps the settings it started "
                              f"with (only {', '.join(STAGE_OPTIONS.values())} and --timesteps start a next stage)")
    if request.timesteps is not None or any(getattr(request, field) is not None for field in STAGE_OPTIONS):
        _next_stage(run_dir, request, write)
    return TrainPlan(run_dir, resume=True)


def _next_stage(run_dir: Path, request: TrainRequest, write: bool) -> None:
    """config.json takes the new `STAGE_OPTIONS` and step budget (checked first), and its `stages` list the stage
    that starts at the last checkpoint, so that an export knows which pushes and ground trained which
    checkpoint."""
    from toddlerbot.rl import train

    env_cfg, ppo_cfg = train.load_config(run_dir)
    paths = train.checkpoint_paths(run_dir)
    start = train.checkpoint_env_steps(paths[-1]) if paths else 0
    stage_request = TrainRequest(**{field: getattr(request, field) for field in STAGE_OPTIONS})
    env_cfg = _ground(_robot_variant(env_cfg, stage_request), stage_request)
    ppo_cfg = _ppo_overrides(ppo_cfg, TrainRequest(timesteps=request.timesteps, desired_kl=request.desired_kl))
    if ppo_cfg.num_timesteps <= start:
        raise ToddlerbotError(f"--timesteps {ppo_cfg.num_timesteps}: the run is already at {start} PPO env steps; "
                              "expected more")
    if not write:
        return
    earlier = [stage for stage in train.training_stages(run_dir) if stage["from_env_steps"] < start]
    train.save_config(run_dir, env_cfg, ppo_cfg, train.load_imitation_config(run_dir),
                      [*earlier, train.training_stage(start, env_cfg, ppo_cfg)])


def new_run_plan(run_dir: Path, request: TrainRequest, write: bool = True) -> TrainPlan:
    """A new run in `run_dir` of the requested environment: its recipe on the resolved backend (e.g. the CPU
    recipe, the one-GPU configuration or the smoke run), or the `--warm-start` run's environment, networks and warm
    start (copied into `run_dir`), then the overrides. ``write`` False: nothing is written into `run_dir` (the
    processes of a run but process 0, `toddlerbot.rl.distributed`)."""
    from toddlerbot.rl.environment import resolve_backend
    from toddlerbot.rl.train import adopt_warm_start

    name = request.environment or config.DEFAULT_ENVIRONMENT
    env_class = environment_class(name)
    backend = resolve_backend(request.backend)
    source = _warm_start_source(request)
    if source and source.env.environment != name:
        raise ToddlerbotError(f"--warm-start {source.run_dir}: a run of environment {source.env.environment!r}; "
                              f"expected {name!r}")
    recipe = env_class.recipe(backend, request.smoke)
    ppo_cfg, imitation_cfg = replace(recipe.ppo, seed=request.seed), recipe.imitation
    base = source.env if source else env_class.default_config(request.smoke)
    if source:
        ppo_cfg, imitation_cfg = source.policy_of(ppo_cfg), source.imitation
    if request.init_policy is not None:
        base, ppo_cfg, imitation_cfg = _init_policy(request, name, base, ppo_cfg, imitation_cfg)
    env_cfg = _motion(_environment(base, backend, request), request)
    if request.imitation_iterations is not None:
        try:
            imitation_cfg = replace(imitation_cfg, iterations=request.imitation_iterations)
        except ValueError as exc:
            raise ToddlerbotError(f"--imitation-iterations {request.imitation_iterations}: {exc}") from None
    ppo_cfg = _ppo_overrides(ppo_cfg, request)
    if source and write:
        adopt_warm_start(source.run_dir, run_dir)
    if request.smoke and write:
        run_dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(run_dir / SMOKE_MARKER, "this run uses the --smoke configuration\n")
    return TrainPlan(run_dir, False, env_cfg, ppo_cfg, imitation_cfg)


def _init_policy(request: TrainRequest, environment: str, env_cfg: config.EnvConfig, ppo_cfg: config.PPOConfig,
                 imitation_cfg: config.ImitationConfig):
    """The configurations of a run that continues ``--init-policy``'s export: the export's settings on the recipe's,
    and a warm start made from it (`toddlerbot.rl.policy_start`)."""
    from toddlerbot.rl.policy_start import exported_env_config, exported_policy, exported_ppo_config

    if request.warm_start is not None or request.variant is not None or request.motor_params:
        raise ToddlerbotError("--init-policy: the exported policy fixes the robot and its start; --warm-start, "
                              "--variant and --motor-params are refused with it")
    exported = exported_policy(request.init_policy, environment)
    return (exported_env_config(exported, env_cfg), exported_ppo_config(exported, ppo_cfg),
            replace(imitation_cfg, policy=str(exported.path.resolve()), iterations=max(1, imitation_cfg.iterations)))


def _warm_start_source(request: TrainRequest) -> WarmStartSource | None:
    from toddlerbot.rl.train import warm_start_source

    if request.warm_start is None:
        return None
    if request.motor_params or request.imitation_iterations is not None or request.variant is not None \
            or request.upper_body_pose is not None or request.reward_weights or request.motion is not None:
        raise ToddlerbotError("--warm-start: the source run's warm start fixes its --motor-params, "
                              "--imitation-iterations, --variant, --upper-body-pose, --reward-weight and --motion "
                              "(its critic learned the source's rewards)")
    return warm_start_source(request.warm_start)


def _environment(env_cfg: config.EnvConfig, backend: str, request: TrainRequest) -> config.EnvConfig:
    try:
        env_cfg = replace(
            env_cfg, backend=backend,
            solver_iterations=env_cfg.solver_iterations if request.solver_iterations is None
            else request.solver_iterations,
            solver_ls_iterations=env_cfg.solver_ls_iterations if request.ls_iterations is None
            else request.ls_iterations)
    except ValueError as exc:
        raise ToddlerbotError(f"--solver-iterations/--ls-iterations: {exc}") from exc
    defaults = environment_class(env_cfg.environment).reward_terms.weights(env_cfg.reward.weights)
    env_cfg = replace(_ground(_robot_variant(env_cfg, request), request),
                      reward=replace(env_cfg.reward, weights=reward_weights(defaults, request)))
    if not request.motor_params:
        return env_cfg
    from toddlerbot.actuation.params_file import catalogue_with_params

    catalogue_with_params(request.motor_params)  # bad files fail here, before anything compiles
    return replace(env_cfg, motor_params=tuple(str(p) for p in request.motor_params))


def _motion(env_cfg: config.EnvConfig, request: TrainRequest) -> config.EnvConfig:
    """The request's ``--motion`` in a configuration with a ``motion`` field (required there unless the
    configuration has one, refused by the others), loaded now so that a bad one fails before anything compiles; a
    motion file is recorded by its absolute path (a resume may start elsewhere)."""
    from toddlerbot.policies.motions import MotionError, builtin_motions, load_motion, motion_path

    tracks = "motion" in {f.name for f in dataclasses.fields(env_cfg)}
    if request.motion is None:
        if tracks and not env_cfg.motion:
            raise ToddlerbotError(f"--env {env_cfg.environment}: needs --motion NAME_OR_FILE (built-in: "
                                  f"{', '.join(builtin_motions())}; or a motion file)")
        return env_cfg
    if not tracks:
        raise ToddlerbotError(f"--motion {request.motion}: the {env_cfg.environment!r} environment tracks no motion")
    from toddlerbot.rl.environment import training_description

    try:
        load_motion(request.motion, training_description(env_cfg))
    except MotionError as exc:
        raise ToddlerbotError(f"--motion: {exc}") from None
    builtin = request.motion in builtin_motions()
    return replace(env_cfg, motion=request.motion if builtin else str(motion_path(request.motion).resolve()))


def _robot_variant(env_cfg: config.EnvConfig, request: TrainRequest) -> config.EnvConfig:
    """The request's spec variant (checked against the spec now) and its randomisation overrides: upper-body pose,
    hand pull, push band, push interval and IMU age (the pull, the pushes and the age also on top of a warm start's
    environment: they change only what PPO trains with)."""
    if request.variant is not None:
        from toddlerbot.robot.description import RobotDescription

        RobotDescription.load(variant=request.variant)  # an unknown variant fails here, naming the known ones
        env_cfg = replace(env_cfg, variant=request.variant)
    smallest, largest = request.push_velocity or (None, None)
    overrides = {"--upper-body-pose": {"upper_body_pose": request.upper_body_pose},
                 "--hand-force": {"hand_force": request.hand_force},
                 "--push-velocity": {"push_velocity_min": smallest, "push_velocity": largest},
                 "--push-interval": {"push_interval_s": request.push_interval},
                 "--imu-age": {"imu_age_s": request.imu_age}}
    for option, fields in overrides.items():
        if any(value is None for value in fields.values()):
            continue
        try:
            env_cfg = replace(env_cfg, randomization=replace(env_cfg.randomization, **fields))
        except ValueError as exc:
            raise ToddlerbotError(f"{option}: {exc}") from exc
    return env_cfg


def _ground(env_cfg: config.EnvConfig, request: TrainRequest) -> config.EnvConfig:
    """The request's terrain and terrain seed (checked now) on ``env_cfg``."""
    from toddlerbot.sim.terrain import parse_terrain

    if request.terrain is not None:
        env_cfg = replace(env_cfg, terrain=str(parse_terrain(request.terrain)))
    if request.terrain_seed is not None:
        env_cfg = replace(env_cfg, terrain_seed=request.terrain_seed)
    if request.terrain_start is not None:
        try:
            env_cfg = replace(env_cfg, terrain_start=request.terrain_start)
        except ValueError as exc:
            raise ToddlerbotError(f"--terrain-start: {exc}") from None
    return env_cfg


def reward_weights(weights: dict[str, float], request: TrainRequest) -> dict[str, float]:
    """`weights` with the request's ``NAME=WEIGHT`` overrides (each checked: a known term, a finite weight >= 0)."""
    weights = dict(weights)
    for item in request.reward_weights:
        name, _, text = item.partition("=")
        try:
            value = float(text)
        except ValueError:
            value = math.nan  # not a number: refused below with the finite-weight message
        if name not in weights:
            raise ToddlerbotError(f"--reward-weight {item}: unknown reward term {name!r}; expected one of "
                                  f"{', '.join(sorted(weights))}")
        if not 0 <= value <= config.MAX_LOSS_WEIGHT:  # False for NaN
            raise ToddlerbotError(f"--reward-weight {item}: expected NAME=WEIGHT with a weight in "
                                  f"[0, {config.MAX_LOSS_WEIGHT:g}]")
        weights[name] = value
    return weights


def _ppo_overrides(ppo_cfg: config.PPOConfig, request: TrainRequest) -> config.PPOConfig:
    overrides = (("--timesteps", request.timesteps, lambda cfg, v: replace(cfg, num_timesteps=v)),
                 ("--num-envs", request.num_envs, config.with_num_envs),
                 ("--mirror-loss", request.mirror_loss, lambda cfg, v: replace(cfg, mirror_loss=v)),
                 ("--desired-kl", request.desired_kl, lambda cfg, v: replace(cfg, desired_kl=v)))
    for option, value, apply in overrides:
        if value is None:
            continue
        try:
            ppo_cfg = apply(ppo_cfg, value)
        except ValueError as exc:
            raise ToddlerbotError(f"{option}: {exc}") from exc
    return ppo_cfg
