"""Plain-data configuration of the walking environment, its rewards, domain randomisation and PPO.

Every number the RL stack uses is defined here once; the exported policy file carries the observation
part of it (`ObsConfig`) so inference builds exactly the observations the policy was trained on.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

from toddlerbot.errors import ToddlerbotError
from toddlerbot.locomotion.config import WALK_REACH, WalkConfig
from toddlerbot.policies.rl_inference import ObsConfig
from toddlerbot.policies.walk_rl import WALK_ENVIRONMENT
from toddlerbot.robot.interface import CONTROL_DT, FALL_TILT_RAD
from toddlerbot.sim.terrain import MIN_START, START, parse_terrain

__all__ = ["ObsConfig"]

@dataclass(frozen=True)
class CommandConfig:
    """Velocity commands (torso yaw frame): vx, vy m/s, yaw rate rad/s, drawn continuously within the ranges.

    The ranges default to the walking policies' reach (`locomotion.config.WALK_REACH`: every grid point, corners
    included, is tabulated by the ZMP generator without leg-IK failures). The reference is tabulated on ``grid``
    points (steps of 0.05 m/s, 0.04 m/s and 0.2 rad/s) and interpolated between them."""

    vx: tuple[float, float] = (WALK_REACH.low[0], WALK_REACH.high[0])
    vy: tuple[float, float] = (WALK_REACH.low[1], WALK_REACH.high[1])
    yaw: tuple[float, float] = (WALK_REACH.low[2], WALK_REACH.high[2])
    grid: tuple[int, int, int] = (6, 5, 5)
    """Tabulated reference points along vx, vy, yaw (each range includes 0 as a grid point when it straddles 0)."""
    stand_prob: float = 0.15
    """Probability that a sampled command is zero (stand still)."""
    turn_prob: float = 0.15
    """Probability that a sampled command is a pure turn in place."""
    axis_prob: float = 0.3
    """Probability that a sampled command walks along one axis only (vx or vy, equally likely); the rest are
    uniform over the whole box."""
    resample_s: float = 5.0
    """Commands are resampled every this many seconds within an episode."""

    def __post_init__(self) -> None:
        if min(self.grid) < 2:
            raise ValueError(f"CommandConfig.grid {self.grid}: the reference interpolates, so >= 2 points per axis")


@dataclass(frozen=True)
class RewardConfig:
    """The reward terms' weights (all >= 0; penalty terms return negative values) and their shape parameters."""

    weights: dict[str, float] | None = None
    """Weight of every reward term of the environment; None: its table's defaults (`rewards.WALK_REWARDS` for
    walking, Table 6). A built environment's configuration holds them resolved, and so does a saved run."""
    tracking_sigma: float = 20.0
    """Sharpness of exp(-sigma * error^2) imitation kernels, 1/(unit^2)."""
    velocity_sigma: float = 100.0
    """Sharpness of the velocity-tracking kernels (the yaw rate's is a quarter of it), which compare the command
    with the averaged velocity, so that a walking-speed bias of a few cm/s costs a noticeable part of the term
    (why: docs/rl.md, "Rewards")."""
    velocity_average_s: float = WalkConfig.cycle_time
    """s; time constant of the exponential average of the torso's velocity that the velocity-tracking terms
    read (one gait cycle damps the in-cycle sway to about a sixth)."""
    path_sigma: float = 200.0
    """Sharpness of the path term's kernel, 1/m^2: a steady drift of 4 cm (a 2 cm/s bias over a 2 s memory)
    costs about a quarter of the term."""
    path_memory_s: float = 2.0
    """s; time constant over which the path error is forgotten (a leaky integral of the velocity error)."""
    leg_pos_sigma: float = 2.0
    air_time_target: float = 0.2
    """s; first-contact air time above this is rewarded (below is penalised)."""
    clearance_target: float = 0.03
    """m; desired swing-foot sole height."""
    feet_distance_range: tuple[float, float] = (0.06, 0.15)
    """m; allowed lateral distance between the feet centres."""
    torso_tilt_limit: float = 0.2
    """rad; torso roll/pitch beyond this are penalised linearly."""


MAX_PUSH_VELOCITY = 3.0
"""m/s; fastest training kick: ten times the robustness benchmark's 0.3 m/s, and faster than the 1-2 m/s kicks that
knock the robot over."""
MAX_PUSH_INTERVAL_S = 600.0
"""s; longest time between training pushes (an episode is 20 s: anything longer means no push)."""
MAX_HAND_FORCE_N = 30.0
"""N; largest training pull on the hands: about the 3.4 kg robot's weight (33 N), beyond which it is lifted off
its feet rather than walking with a load (the shipped gripper policy trains with 1.5 N)."""
MAX_SOLVER_ITERATIONS = 100
"""Most Newton and line-search iterations of the training model (MuJoCo's own default is 100; the recipe's 4/8)."""
MAX_NUM_ENVS = 65_536
"""Most parallel environments: 8 times the one-GPU configuration's 8,192."""
MAX_TIMESTEPS = 2**31 - 1
"""Most PPO env steps of a run: its step counter is a 32-bit integer (JAX's default); 7 times Table 5's 3e8."""
MAX_IMITATION_ITERATIONS = 1000
"""Most DAgger iterations of a warm start (the CPU recipe makes 12)."""
MAX_LOSS_WEIGHT = 10_000.0
"""Largest weight of a reward term or of the mirror loss: 20 times the largest of appendix Table 6 (500)."""
MAX_DESIRED_KL = 1.0
"""Largest KL target of the adaptive step size: beyond it PPO's clipping, not the KL, bounds every update."""


@dataclass(frozen=True)
class RandomizationConfig:
    """Domain randomisation ranges (uniform); scales multiply the model's nominal value."""

    floor_friction: tuple[float, float] = (0.4, 1.0)
    damping_scale: tuple[float, float] = (0.8, 1.2)
    armature_scale: tuple[float, float] = (0.8, 1.2)
    frictionloss_scale: tuple[float, float] = (0.8, 1.2)
    mass_scale: tuple[float, float] = (0.9, 1.1)
    torso_added_mass: tuple[float, float] = (-0.05, 0.2)
    """kg added to the torso."""
    kp_scale: tuple[float, float] = (0.9, 1.1)
    kd_scale: tuple[float, float] = (0.9, 1.1)
    tau_max_scale: tuple[float, float] = (0.9, 1.1)
    q_dot_max_scale: tuple[float, float] = (0.9, 1.1)
    obs_noise_level: tuple[float, float] = (0.0, 1.5)
    """Factor on the observation noise widths of `ObsConfig`, per episode; from 0 so that noise-free sensors
    (the simulator) are within the training range (a cloned policy trained on 0.5-1.5 fell on clean inputs)."""
    action_delay_prob: float = 0.5
    """Probability that an episode applies each action one control step late."""
    imu_age_s: tuple[float, float] = (0.0, 0.0)
    """s; age of the IMU reading (gyro, gravity direction) the actor sees, per episode uniform in this band, at most
    one control period: the reading is interpolated between the previous control step's and this one's. A real
    BNO08x report is some ms old when the policy reads it (hardware-in-the-loop: 10 ms on average,
    `toddlerbot.sim.loop_delay.HIL_LOOP_DELAY`), and a policy trained on fresh readings tracks worse with it
    (docs/hardware.md). (0, 0): fresh, as before."""
    push_interval_s: tuple[float, float] = (2.0, 5.0)
    """s; time from one push to the next, uniform in this band (the first push too, from the reset)."""
    push_velocity: float = 0.3
    """m/s; largest horizontal velocity kick of a push."""
    push_velocity_min: float = 0.0
    """m/s; smallest kick of a push: each push's speed is uniform between this and `push_velocity`, so a band
    near the largest trains recovery from the pushes a robustness test gives (0: uniform from nothing)."""
    upper_body_pose: float = 0.0
    """Upper-body poses (arms, grippers, neck): at every reset and command resample each such motor's target is
    drawn uniformly between home and this fraction of the way to either joint limit (0: held at home), so the
    policy learns to walk with the arms holding a handle, carrying or waving."""
    hand_force: float = 0.0
    """N; largest pull on the hands (a wagon's handle, a carried load): at every reset and command resample a
    force is drawn whose horizontal part (in the robot's heading frame, turning with it) has a random direction
    and a length up to this, and whose vertical part lies within half of it either way; each hand feels it until
    the next command (0: none)."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.upper_body_pose <= 1.0:
            raise ValueError(f"upper_body_pose {self.upper_body_pose}: expected a fraction of the range in [0, 1]")
        if not 0.0 <= self.push_velocity_min <= self.push_velocity <= MAX_PUSH_VELOCITY:
            raise ValueError(f"push velocities {self.push_velocity_min}..{self.push_velocity}: expected "
                             f"0 <= smallest <= largest <= {MAX_PUSH_VELOCITY:g} m/s")
        if not 0.0 < self.push_interval_s[0] <= self.push_interval_s[1] <= MAX_PUSH_INTERVAL_S:
            raise ValueError(f"push interval {self.push_interval_s[0]}..{self.push_interval_s[1]}: expected "
                             f"0 < shortest <= longest <= {MAX_PUSH_INTERVAL_S:g} s")
        if not 0.0 <= self.hand_force <= MAX_HAND_FORCE_N:
            raise ValueError(f"hand_force {self.hand_force}: expected a force in [0, {MAX_HAND_FORCE_N:g}] N")
        if not 0.0 <= self.imu_age_s[0] <= self.imu_age_s[1] < float("inf"):
            raise ValueError(f"IMU age {self.imu_age_s[0]}..{self.imu_age_s[1]}: expected 0 <= youngest <= oldest, s")


CONTACT_SETS = ("feet_hands", "all")
JACOBIANS = ("dense", "sparse")
PHYSICS_BACKENDS = ("cpu", "mjx")


DEFAULT_ENVIRONMENT = WALK_ENVIRONMENT
"""What `rl train` trains without ``--env``, and what a run saved before environments had names trained."""


@dataclass(frozen=True)
class EnvConfig:
    """An environment's configuration: the robot, its physics, observations, commands, rewards and randomisation.
    An environment whose configuration needs more subclasses this (`RLEnvironment.config_class`)."""

    environment: str = DEFAULT_ENVIRONMENT
    """The registered environment it configures (`toddlerbot.rl.environments`; `rl train --env`)."""
    ctrl_dt: float = CONTROL_DT
    """Control period, s."""
    sim_dt: float = 0.004
    """MJX physics timestep, s (ctrl_dt / sim_dt substeps)."""
    solver_iterations: int = 4
    solver_ls_iterations: int = 8
    contacts: str = "feet_hands"
    """Collisions the training model keeps: ``feet_hands`` (feet and hands against the floor, the foot-foot pair)
    or ``all`` (every robot collision geom against the floor and the spec's self-collision pairs)."""
    linkage_loops: bool = False
    """Keep the parallel linkages' weld loops (the simulator's model); False couples their joints directly
    (`toddlerbot.rl.model`)."""
    jacobian: str = "dense"
    """Constraint Jacobian layout of the training model: ``dense`` or ``sparse``."""
    backend: str = "auto"
    """Physics backend (`toddlerbot.rl.physics`): ``cpu`` (classic MuJoCo on threads), ``mjx``, or ``auto`` (mjx
    when JAX has a GPU, else cpu); a saved configuration holds the resolved name."""
    cpu_threads: int = 0
    """Threads of the CPU backend (0: one per CPU core)."""
    residual: bool = True
    """Leg motor target = gait reference (interpolated at the command and phase) + ``obs.action_scale`` x action;
    False: home pose + ``obs.action_scale`` x action (upstream ToddlerBot)."""
    teacher_gains: bool = True
    """The leg motors' P gains follow walk-zmp's schedule (stance and swing-leg factors on the spec's gains, from
    the reference's stance flags); False keeps the spec's gains."""
    motor_params: tuple[str, ...] = ()
    """Fitted actuator parameter files (sysID ``params.json``) the robot is built with; domain randomisation
    scales around them."""
    variant: str | None = None
    """Spec variant the robot is built with (e.g. ``gripper``, 32 motors); its exported policy drives only it."""
    min_torso_height: float = 0.2
    """m; the episode ends (fall) when the torso origin drops below this..."""
    max_tilt: float = FALL_TILT_RAD
    """...or the torso tilts more than this, rad."""
    obs: ObsConfig = field(default_factory=ObsConfig)
    command: CommandConfig = field(default_factory=CommandConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    randomization: RandomizationConfig = field(default_factory=RandomizationConfig)
    randomize: bool = True
    terrain: str = "flat"
    """The ground every env walks on (`toddlerbot.sim.terrain`, ``NAME[:KEY=VALUE,...]``), drawn from
    ``terrain_seed``; `rl train --resume --terrain` starts a next stage on other ground (a curriculum)."""
    terrain_seed: int = 0
    terrain_start: float = START
    """Half-width of the flat square the envs start on, m (the simulator's and the benchmarks' `START`): a smaller
    one makes every episode walk onto the ground within its first steps (docs/rl.md "Walking on terrain")."""

    def __post_init__(self) -> None:
        try:
            parse_terrain(self.terrain, "terrain")
        except ToddlerbotError as exc:
            raise ValueError(str(exc)) from None
        if not MIN_START <= self.terrain_start <= START:
            raise ValueError(f"terrain start {self.terrain_start} m: expected a half-width of {MIN_START}-{START} m")
        if not (1 <= self.solver_iterations <= MAX_SOLVER_ITERATIONS
                and 1 <= self.solver_ls_iterations <= MAX_SOLVER_ITERATIONS):
            raise ValueError(f"solver iterations {self.solver_iterations}/{self.solver_ls_iterations}: expected "
                             f"1-{MAX_SOLVER_ITERATIONS}")
        if self.contacts not in CONTACT_SETS:
            raise ValueError(f"contacts {self.contacts!r}: expected one of {', '.join(CONTACT_SETS)}")
        if self.backend not in ("auto", *PHYSICS_BACKENDS):
            raise ValueError(f"backend {self.backend!r}: expected auto or one of {', '.join(PHYSICS_BACKENDS)}")
        if self.jacobian not in JACOBIANS:
            raise ValueError(f"jacobian {self.jacobian!r}: expected one of {', '.join(JACOBIANS)}")
        if self.randomization.imu_age_s[1] > self.ctrl_dt:
            raise ValueError(f"IMU age up to {self.randomization.imu_age_s[1]} s: expected at most the control period "
                             f"{self.ctrl_dt} s")

    @property
    def n_substeps(self) -> int:
        n = round(self.ctrl_dt / self.sim_dt)
        if abs(n * self.sim_dt - self.ctrl_dt) > 1e-9:
            raise ValueError(f"ctrl_dt {self.ctrl_dt} is not a multiple of sim_dt {self.sim_dt}")
        return n


@dataclass(frozen=True)
class PPOConfig:
    """Brax PPO hyperparameters. The defaults are the one-GPU run meant to walk within 10 minutes: Table 5's
    networks, unroll, minibatch size, epochs per batch, discount, entropy and clipping, but 8,192 environments
    (32 minibatches of 256 envs = one 20-step rollout of every env per update), a KL-adaptive learning rate
    and a Gaussian with a global std starting at 0.5 (ToddlerBot 2.0), 100 M steps (stop earlier with
    ``--minutes``) and no separate evaluation (the training episodes are the measure)."""

    num_timesteps: int = 100_000_000
    num_envs: int = 8192
    episode_length: int = 1000
    unroll_length: int = 20
    batch_size: int = 256
    num_minibatches: int = 32
    num_updates_per_batch: int = 4
    discounting: float = 0.97
    learning_rate: float = 3e-4
    """Initial Adam step size; with ``desired_kl`` set it is then adapted after every minibatch."""
    desired_kl: float | None = 0.01
    """Adaptive learning rate: divided by ``lr_factor`` when the minibatch's KL(behaviour || current policy)
    exceeds twice this, multiplied by it below half of it (RSL-RL's rule). None keeps the rate fixed."""
    lr_factor: float = 1.5
    lr_bounds: tuple[float, float] = (1e-5, 1e-2)
    init_std: float = 0.5
    """Initial standard deviation of the state-independent Gaussian policy (unsquashed; the env clips actions
    to [-1, 1])."""
    init_action_scale: float = 1.0
    """Factor on the fresh actor's output layer (`train.scaled_action_head`): below 1 its first mean actions are
    near zero (a residual policy trained without a warm start starts on its reference)."""
    entropy_cost: float = 5e-4
    clipping_epsilon: float = 0.2
    policy_hidden: tuple[int, ...] = (512, 256, 128)
    value_hidden: tuple[int, ...] = (512, 256, 128)
    gae_lambda: float = 0.95
    max_grad_norm: float = 1.0
    reward_scaling: float = 1.0
    normalize_observations: bool = True
    num_evals: int = 100
    """Evaluations (and checkpoints) spread over the run."""
    num_eval_envs: int = 0
    """Envs of the deterministic evaluation after every epoch; 0 skips it (saves one compilation)."""
    eval_episode_length: int = 1000
    seed: int = 0
    mirror_loss: float = 0.0
    """Weight of the mirror-symmetry loss added to PPO's (`toddlerbot.rl.train.PPO.asymmetry`: the policy's mean
    action against the mirror image of its action on the mirrored observation); 0 trains without it."""

    def __post_init__(self) -> None:
        if not 1 <= self.num_timesteps <= MAX_TIMESTEPS:
            raise ValueError(f"{self.num_timesteps} env steps: expected 1-{MAX_TIMESTEPS:,} (a 32-bit step counter)")
        if not 1 <= self.num_envs <= MAX_NUM_ENVS:
            raise ValueError(f"{self.num_envs} envs: expected 1-{MAX_NUM_ENVS:,}")
        if self.desired_kl is not None and not 0 < self.desired_kl <= MAX_DESIRED_KL:
            raise ValueError(f"desired KL {self.desired_kl}: expected 0 < KL <= {MAX_DESIRED_KL:g}")
        if not 0 <= self.mirror_loss <= MAX_LOSS_WEIGHT:
            raise ValueError(f"mirror_loss {self.mirror_loss}: expected a weight in [0, {MAX_LOSS_WEIGHT:g}]")
        if (self.batch_size * self.num_minibatches) % self.num_envs:
            raise ValueError(f"batch_size * num_minibatches ({self.batch_size * self.num_minibatches}) must be a "
                             f"multiple of num_envs ({self.num_envs})")

    @property
    def env_steps_per_update(self) -> int:
        return self.batch_size * self.num_minibatches * self.unroll_length


@dataclass(frozen=True)
class ImitationConfig:
    """Warm start before PPO (`toddlerbot.rl.imitation`): DAgger with walk-zmp as the teacher, behaviour cloning of
    the actor on the aggregated labels, and a value function fitted to the visited states' returns."""

    iterations: int = 0
    """DAgger iterations (0: no warm start)."""
    teacher_iterations: int = 1
    """The first iterations step the env with the teacher's actions; later ones with the student's."""
    num_envs: int = 64
    steps: int = 250
    """Control steps of every env per iteration (episodes continue across iterations)."""
    bc_steps: int = 1000
    """Adam steps on the aggregated data after each iteration (actor, then critic)."""
    batch_size: int = 512
    learning_rate: float = 1e-3
    policy: str | None = None
    """An exported walk policy (``.npz``) to start from instead of DAgger (`rl train --init-policy`,
    `toddlerbot.rl.policy_start`): its actor and observation normaliser as they are, and a critic fitted to the
    returns it earns in this run's environment over ``iterations`` rollouts."""

    def __post_init__(self) -> None:
        if min(self.num_envs, self.steps, self.bc_steps, self.batch_size) < 1 or \
                not 0 <= self.iterations <= MAX_IMITATION_ITERATIONS:
            raise ValueError(f"ImitationConfig: iterations 0-{MAX_IMITATION_ITERATIONS} and positive envs, steps, "
                             "bc_steps, batch_size")


def with_num_envs(cfg: PPOConfig, num_envs: int) -> PPOConfig:
    """``cfg`` with ``num_envs`` environments and the same number of rollouts of every env per update (the batch
    scaled with the envs, the minibatches kept)."""
    rollouts = cfg.batch_size * cfg.num_minibatches // cfg.num_envs
    step = cfg.num_minibatches // math.gcd(cfg.num_minibatches, rollouts)
    if num_envs < 1 or num_envs % step:
        raise ValueError(f"{num_envs} envs: expected a positive multiple of {step} ({rollouts} rollout(s) of every "
                         f"env per update in {cfg.num_minibatches} minibatches)")
    return replace(cfg, num_envs=num_envs, batch_size=num_envs * rollouts // cfg.num_minibatches)


@dataclass(frozen=True)
class Recipe:
    """An environment's default training settings on one physics backend."""

    ppo: PPOConfig
    imitation: ImitationConfig = field(default_factory=ImitationConfig)
    """Its warm start (none by default)."""


FULL = PPOConfig()
CPU = PPOConfig(
    num_timesteps=20_000_000, num_envs=256, batch_size=64, num_minibatches=4, num_updates_per_batch=4,
    policy_hidden=(256, 128, 64), value_hidden=(256, 128, 64), init_std=0.1, num_evals=400,
)
"""The CPU recipe's PPO (docs/rl.md, "Training on a CPU"): 256 environments, one 20-step rollout of each per
update (5,120 env steps), 4 minibatches, networks a quarter of Table 5's cost, and a narrower exploration noise
around the warm-started policy; ~10 updates per epoch (stop it with ``--minutes``)."""
CPU_IMITATION = ImitationConfig(iterations=8, num_envs=64, steps=250, bc_steps=1000)
"""The CPU recipe's warm start: 8 DAgger iterations of 64 envs x 5 s (the first driven by walk-zmp): 128,000
labels, walk-zmp costing about 5 ms of one core per label."""
SMOKE = PPOConfig(
    num_timesteps=2 * 4 * 2 * 5, num_envs=4, episode_length=40, unroll_length=5, batch_size=4, num_minibatches=2,
    num_updates_per_batch=1, policy_hidden=(32, 32), value_hidden=(32, 32), num_evals=2, num_eval_envs=0,
)
"""Tiny run for CPU tests: 2 epochs of one update (4 envs x 2 minibatches x 5 steps), no separate evaluation."""
SMOKE_IMITATION = ImitationConfig(iterations=1, num_envs=4, steps=5, bc_steps=5, batch_size=8)
"""Tiny warm start of the smoke run: one teacher-driven DAgger iteration of 4 envs x 5 steps."""

SMOKE_XLA_FLAGS = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"
"""XLA flags of `--smoke` runs: unoptimised CPU code compiles several times faster; the few steps it then runs
are slow, which a smoke run does not mind. Never use them for real training."""


def smoke_env_config() -> EnvConfig:
    """The environment of the smoke run: a 3-frame history and a 3 x 2 x 2 command grid (quick to tabulate)."""
    return EnvConfig(obs=replace(ObsConfig(), history=3),
                     command=replace(CommandConfig(), grid=(3, 2, 2)))


def to_dict(cfg: object) -> dict:
    return asdict(cfg)  # type: ignore[arg-type]
