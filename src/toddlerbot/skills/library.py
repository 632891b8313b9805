"""Skill kinds of a chain. A skill starts from the targets the previous one ended with and, each control step,
returns motor targets and firmware gains (the runner applies `hold` and sends them through `Robot.step`).

* ``scripted_grasp``: both (or one) grippers grasp a bar lying across the robot (the wagon handle): each grasp
  point moves to a pre-grasp point behind the bar, then onto it along the fingers, then the grippers close; DLS IK
  every step, targets leading the IK solution by the gravity sag, a slow integral of the measured error (as the
  pick demonstrator does). In sim the bar's position comes from the scene; on hardware from ``target_pos`` or, by
  default, where the scene's layout puts it.
* ``dp``: a diffusion-policy checkpoint drives the arm and gripper motors (torch is imported only here).
* ``walk``: a registered walking policy (walk-zmp, walk-rl, one's own) with a fixed command.
* ``hold``: every motor keeps the previous skill's last targets.
* ``pose``: the named motors move to their angles (the grippers to a fraction of their range, whole groups to the
  home pose) in ``seconds``, the others keep the previous skill's targets.

A chain file names a kind; `SKILLS` (`toddlerbot.skills`) maps the name to its `SkillKind` (parameters and
constructor), so a skill of your own is a `Skill` subclass registered under a new name (docs/extending.md).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import mujoco
import numpy as np

from toddlerbot.dp import have_torch
from toddlerbot.dp.shipped import check_named_checkpoint
from toddlerbot.errors import ToddlerbotError, quoted
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.tasks.demonstrator import min_jerk
from toddlerbot.tasks.ik import CORRECTION_GAIN, MAX_CORRECTION, ArmIK, GraspPointCorrection
from toddlerbot.tasks.scenes import SIDES, grasp_site, rack_travel

MAX_ARM_KP_SCALE = 3.0
"""Largest arm gain multiple a chain may ask for (walk-zmp's swing leg runs at 3x the spec's gains)."""


BAR_MARGIN = 0.004
"""Kept between an open finger pad and the bar when judging the bar to be between the fingers, m."""


@dataclass(frozen=True)
class GraspParams:
    target: str
    """Geom of the bar to grasp (sim); the bar lies along y, each hand grasps it straight in front of itself."""
    target_pos: tuple[float, float, float] | None = None
    """Hardware: the bar's centre in the world frame of the home pose (x forward, z up from the floor), m."""
    hands: Literal["both", "left", "right"] = "both"
    pitch: float = 0.5
    """Fingers tilted down from horizontal by this much, rad (the arms reach further forward and lower)."""
    depth: float = 0.008
    """Grasp point this far past the bar's axis along the fingers, m (the bar sits nearer the palm)."""
    back: float = 0.05
    """Pre-grasp point this far behind the grasp point along the fingers, m."""
    in_place: bool = False
    """Grasp without backing out first when the bar is already between the open fingers (a re-grasp in the wagon
    task's demonstrations, where backing out drags the bar along). Off in the chain: after the slip test's slip
    neither way re-grasps reliably (in place 2 of seeds 0-7, backing out 1: seed 0, the test's;
    docs/manipulation.md)."""
    grip_fraction: float = 0.85
    """Closed gripper target as a fraction of the drive's range from open."""
    arm_kp_scale: float = 1.0
    """The grasping arms' firmware kp while grasping, as a multiple of the spec's. The targets lead the IK solution
    by the gravity sag at these gains, so a skill after it that holds the arms at the spec's gains (`hold` skills,
    and `hold: [arm]` after one) supports 1/arm_kp_scale of the arms' weight and the rest lies on the bar."""
    approach_s: float = 1.5
    reach_s: float = 1.5
    close_s: float = 0.8
    correction_gain: float = CORRECTION_GAIN
    max_correction: float = MAX_CORRECTION
    checkpoint: str | None = None
    """A diffusion-policy checkpoint that grasps instead of the script: a shipped one's task name (``wagon``) or a
    ``.pt`` file (the script grasps where torch or a head camera is missing, and says so)."""

    def __post_init__(self) -> None:
        if self.checkpoint is not None:
            check_named_checkpoint(self.checkpoint)
        if not 1 <= self.arm_kp_scale <= MAX_ARM_KP_SCALE:
            raise ValueError(f"arm_kp_scale: expected a number in [1, {MAX_ARM_KP_SCALE:g}], got {self.arm_kp_scale}")


@dataclass(frozen=True)
class DPParams:
    checkpoint: str
    """A shipped checkpoint's task name (``pick``) or a checkpoint file."""
    seed: int | None = None
    """Seed of the diffusion noise; None: the run's (`chain run --seed S` in sim; 0 on a robot), so that each
    seeded run is an independent trial, as each episode of `dp eval` is."""
    threads: int = 1
    """torch CPU threads (the process's setting), 1 as in `dp eval`: on a busy 2-core machine two threads made
    one inference 30-50 times slower than one."""

    def __post_init__(self) -> None:
        check_named_checkpoint(self.checkpoint)
        if self.threads < 1:
            raise ValueError(f"threads: expected a positive number of threads, got {self.threads}")


@dataclass(frozen=True)
class WalkParams:
    policy: str = "walk-zmp"
    """A registered policy that follows velocity commands (walk-zmp, walk-rl or one's own)."""
    command: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """(vx m/s, vy m/s, yaw rate rad/s)."""

    def __post_init__(self) -> None:
        from toddlerbot.policies import policy_names

        if self.policy not in policy_names():
            raise ValueError(f"policy: expected a registered policy ({', '.join(policy_names())}), got "
                             f"{quoted(self.policy)}")


@dataclass(frozen=True)
class HoldParams:
    pass


@dataclass(frozen=True)
class PoseParams:
    motors: dict[str, float] = field(default_factory=dict)
    """Motor name -> target angle, rad (the spec's motor angles, as `home_motor_pos`)."""
    grip: float | None = None
    """The grippers (the ``gripper`` group) to this fraction of their range from open (as a grasp's grip_fraction)."""
    home: tuple[str, ...] = ()
    """Motor groups moved to the home pose (e.g. ``[arm, gripper]``: arms back, grippers open)."""
    seconds: float = 0.5
    """Duration of the minimum-jerk move from the previous skill's last targets."""

    def __post_init__(self) -> None:
        if not self.motors and self.grip is None and not self.home:
            raise ValueError("motors, grip, home: expected motor angles (name: rad), a grip fraction or groups to "
                             "move home")
        if self.grip is not None and not 0.0 <= self.grip <= 1.0:
            raise ValueError(f"grip: expected a fraction of the grippers' range in [0, 1], got {self.grip}")
        if not self.seconds > 0:
            raise ValueError(f"seconds: expected a positive duration, got {self.seconds}")


def range_fraction(description: RobotDescription, motors: list[int], fraction: float) -> np.ndarray:
    """The angles `fraction` of the way through each motor's range from its low end (a gripper: from open), rad."""
    lo, hi = description.motor_range[motors].T
    return lo + fraction * (hi - lo)


def grasp_gains(description: RobotDescription, p: GraspParams) -> np.ndarray:
    """Firmware kp while grasping: the spec's, the grasping arms' scaled by `arm_kp_scale` (the wagon task
    demonstrates and evaluates its policy at these gains too)."""
    kp = description.default_kp.copy()
    names = description.motor_names
    for side in SIDES if p.hands == "both" else (p.hands,):
        kp[[i for i in description.groups["arm"] if names[i].startswith(side)]] *= p.arm_kp_scale
    return kp


@dataclass(frozen=True)
class SkillEnv:
    """What a skill may use: the robot, a kinematic model with the grasp sites, and the base pose to solve IK in."""

    robot: Robot
    model: mujoco.MjModel
    base_qpos: Callable[[], np.ndarray]
    """The model's full qpos for the base and free bodies: the simulated state, or the home keyframe on hardware."""
    target_pos: Callable[[str], np.ndarray] | None
    """World position of a named geom (sim), None on hardware."""
    layout_pos: Callable[[str], np.ndarray]
    """World position of a named geom where the scene's layout puts it (the home keyframe): hardware's default."""
    head_image: Callable[[], np.ndarray] | None
    """The head camera's 96x96 RGB image (sim), None where the `Robot` has no camera."""
    simulated: bool
    """True in sim (time is the simulation's), False on a real robot (the control loop runs in real time)."""
    seed: int = 0
    """The run's seed (the scene's in sim): the default of a learned skill's sampling noise."""


class Skill(ABC):
    """One phase of a chain; the chain (`runner.ChainRunner`, a `Policy`) runs its skills in order."""

    by = ""
    """What drives it, for reports (e.g. ``scripted (no checkpoint for task wagon)``)."""

    @abstractmethod
    def start(self, obs: Observation, targets: np.ndarray) -> None:
        """Begin from `targets` (rad, the last ones commanded)."""

    @abstractmethod
    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        """(motor targets rad, firmware kp) for the next step, `elapsed` s after `start`."""

    @property
    def status(self) -> object | None:
        """What its policy reports (a dp skill's inference statistics), an object with ``to_dict()``; None when it
        has nothing to say."""
        return None

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release threads or files."""


@dataclass(frozen=True)
class SkillKind:
    """A ``kind`` of chain files: the dataclass its parameters fill (each chain-file key a field) and the
    constructor of its skill, ``build(env, params)``."""

    params: type
    build: Callable[[SkillEnv, Any], Skill]
    needs_imu: bool = False
    """True for a skill that balances from the IMU (walking): on hardware its chain is refused without one."""

    def __call__(self, env: SkillEnv, params: object) -> Skill:
        return self.build(env, params)


class ScriptedGrasp(Skill):
    def __init__(self, env: SkillEnv, p: GraspParams, why: str) -> None:
        self.env, self.p, self.by = env, p, f"scripted ({why})"
        d = env.robot.description
        sides = SIDES if p.hands == "both" else (p.hands,)
        self.iks = [ArmIK(d, env.model, side, site=grasp_site(side)) for side in sides]
        self.grippers = [d.motor_names.index(f"{side}_gripper_drive") for side in sides]
        self.kp = grasp_gains(d, p)
        self._stiffness = d.actuator_arrays(self.kp).kp
        if p.in_place:  # how far across the open fingers the bar's axis may be: pad travel - bar radius - margin
            bar = env.model.geom(p.target)
            self._clearance = (min(rack_travel(d, f"{side}_gripper_drive") for side in sides)
                               - bar.size[0] - BAR_MARGIN)

    def _bar(self) -> np.ndarray:
        if self.env.target_pos is not None:  # sim: where the bar is now
            return self.env.target_pos(self.p.target)
        if self.p.target_pos is not None:  # hardware: where the chain file says it is
            return np.array(self.p.target_pos, dtype=float)
        return self.env.layout_pos(self.p.target)

    def start(self, obs: Observation, targets: np.ndarray) -> None:
        p, base, bar = self.p, self.env.base_qpos(), self._bar()
        tilt = np.array([np.cos(p.pitch), 0.0, -np.sin(p.pitch)])
        """Fingertip direction in the world: forward, tilted down by `pitch`."""
        self._plans = []
        for ik in self.iks:
            pos, rot = ik.forward(obs.motor_pos, base)
            wrist = rot.T @ (ik.data.xpos[ik.model.site_bodyid[ik.site]] - pos)
            fingers = -np.sign(wrist[1]) * tilt  # site y runs along the fingers, towards the tips on one side only
            closing = np.array([np.sin(p.pitch), 0.0, np.cos(p.pitch)])
            closing *= np.sign(closing @ rot[:, 2])  # keep the closing axis' sense: no wrist flip
            goal_rot = np.column_stack([np.cross(fingers, closing), fingers, closing])
            goal = np.array([bar[0], pos[1], bar[2]]) + p.depth * tilt
            self._plans.append((pos, goal - p.back * tilt, goal, goal_rot))
        if p.in_place and all(self._between_fingers(start - goal, rot[:, 2]) for start, _, goal, rot in self._plans):
            # the bar is already between the open fingers (a re-grasp): backing out would drag it along
            self._plans = [(start, start, goal, rot) for start, _, goal, rot in self._plans]
            self._skipped = p.approach_s
        else:
            self._skipped = 0.0
        self._q = np.array(targets, dtype=float)
        self._open = self._q[self.grippers].copy()
        self._correction = [GraspPointCorrection(p.correction_gain, p.max_correction) for _ in self.iks]

    def _between_fingers(self, offset: np.ndarray, closing: np.ndarray) -> bool:
        """Whether a grasp point this far (m) from its goal holds the bar between the open fingers: within the
        pre-grasp distance, and across the fingers by less than the open gap leaves around the bar."""
        return bool(np.linalg.norm(offset) < self.p.back and abs(offset @ closing) < self._clearance)

    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        p, base = self.p, self.env.base_qpos()
        q = self._q
        elapsed += self._skipped
        for k, (ik, (start, pregrasp, goal, rot)) in enumerate(zip(self.iks, self._plans)):
            if elapsed < p.approach_s:
                a, b, s = start, pregrasp, min_jerk(elapsed / p.approach_s)
            else:
                a, b, s = pregrasp, goal, min_jerk((elapsed - p.approach_s) / p.reach_s)
            desired = a + (b - a) * s
            measured, _ = ik.forward(obs.motor_pos, base)
            q, _ = ik.solve(q, self._correction[k].target(desired, measured), rot, base)
        self._q = q
        out = q.copy()
        for ik in self.iks:
            out[ik.arm] += ik.gravity_torque(q, base) / self._stiffness[ik.arm]
        closed = range_fraction(self.env.robot.description, self.grippers, p.grip_fraction)
        s = min_jerk((elapsed - p.approach_s - p.reach_s) / p.close_s)
        out[self.grippers] = self._open + s * (closed - self._open)
        return out, self.kp


class DPSkill(Skill):
    """A checkpoint as the runtime runs it (`dp.live.LiveDPPolicy`): its motors found by name, observations at the
    policy rate, the other motors held; inference inline in sim (as `dp eval`), on the worker thread on a real
    robot (the 50 Hz loop must not wait for it)."""

    def __init__(self, env: SkillEnv, p: DPParams, kp: np.ndarray | None = None) -> None:
        from toddlerbot.dp import require_torch
        from toddlerbot.dp.live import load_live_policy
        from toddlerbot.dp.shipped import shipped_checkpoint

        require_torch(p.threads)
        path = Path(p.checkpoint) if p.checkpoint.endswith(".pt") else shipped_checkpoint(p.checkpoint)
        self.live = load_live_policy(env.robot, path, env.head_image, synchronous=env.simulated,
                                     seed=env.seed if p.seed is None else p.seed, kp=kp)
        self.by = f"dp ({path.name})"

    @property
    def status(self) -> object | None:
        return self.live.status if self.live.runner is not None else None

    def start(self, obs: Observation, targets: np.ndarray) -> None:
        self.live.reset(obs)

    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        action = self.live.act(obs, np.zeros(3))
        return action.motor_targets, action.kp

    def close(self) -> None:
        self.live.close()


class WalkSkill(Skill):
    def __init__(self, env: SkillEnv, p: WalkParams) -> None:
        from toddlerbot.policies import make_policy

        self.policy = make_policy(p.policy, env.robot)
        if self.policy.command_reach is None:
            raise ToddlerbotError(f"walk skill: policy {p.policy!r} follows no velocity command (it has no command "
                                  "reach); a walk skill drives a walking policy")
        self.command = np.array(p.command)
        self.kp = env.robot.description.default_kp.copy()
        self.by = p.policy

    def start(self, obs: Observation, targets: np.ndarray) -> None:
        self.policy.reset(obs)

    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        action = self.policy.act(obs, self.command)
        return action.motor_targets, self.kp if action.kp is None else np.asarray(action.kp, dtype=float)


class HoldSkill(Skill):
    by = "hold"

    def __init__(self, env: SkillEnv, p: HoldParams) -> None:
        self.kp = env.robot.description.default_kp.copy()

    def start(self, obs: Observation, targets: np.ndarray) -> None:
        self._targets = np.array(targets, dtype=float)

    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        return self._targets.copy(), self.kp


class PoseSkill(Skill):
    """Moves the named motors to their angles (minimum jerk), the others kept where the previous skill left them:
    e.g. the neck tilted down so that the head camera sees what the next skill grasps."""

    by = "pose"

    def __init__(self, env: SkillEnv, p: PoseParams) -> None:
        d = env.robot.description
        unknown = sorted(set(p.motors) - set(d.motor_names))
        if unknown:
            raise ToddlerbotError(f"pose skill: {', '.join(unknown)}: not motors of {d.spec.name} "
                                  f"(e.g. {', '.join(d.motor_names[:3])})")
        index, goal = [d.motor_names.index(m) for m in p.motors], [float(v) for v in p.motors.values()]
        if p.grip is not None:
            grippers = list(d.groups.get("gripper", ()))
            if not grippers:
                raise ToddlerbotError(f"pose skill: grip: {d.spec.name} has no gripper motors")
            index, goal = index + grippers, goal + list(range_fraction(d, grippers, p.grip))
        for group in p.home:
            if group not in d.groups:
                raise ToddlerbotError(f"pose skill: home: {group!r} is not a motor group of {d.spec.name} "
                                      f"({', '.join(d.groups)})")
            index, goal = index + list(d.groups[group]), goal + list(d.home_motor_pos[d.groups[group]])
        self.index, self.goal = np.array(index), np.array(goal)
        self.seconds = p.seconds
        self.kp = d.default_kp.copy()

    def start(self, obs: Observation, targets: np.ndarray) -> None:
        self._start = np.array(targets, dtype=float)

    def act(self, obs: Observation, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        targets = self._start.copy()
        s = min_jerk(elapsed / self.seconds)
        targets[self.index] += s * (self.goal - self._start[self.index])
        return targets, self.kp


def grasp_skill(env: SkillEnv, p: GraspParams) -> Skill:
    """The diffusion policy ``checkpoint`` names, where a head camera feeds it and torch runs it; else the
    scripted grasp (its report says why)."""
    if p.checkpoint is not None and env.head_image is not None and have_torch():
        # at the scripted grasp's gains: the wagon task demonstrates and trains the policy at them
        return DPSkill(env, DPParams(p.checkpoint), grasp_gains(env.robot.description, p))
    file = p.checkpoint if p.checkpoint is None or p.checkpoint.endswith(".pt") else f"{p.checkpoint}.pt"
    why = ("no checkpoint named" if p.checkpoint is None else f"no head camera for {file}" if env.head_image is None
           else f"no torch for {file}: pip install 'toddlerbot[dp]'")
    return ScriptedGrasp(env, p, why)


SCRIPTED_GRASP = SkillKind(GraspParams, grasp_skill)
DP = SkillKind(DPParams, DPSkill)
WALK = SkillKind(WalkParams, WalkSkill, needs_imu=True)
HOLD = SkillKind(HoldParams, HoldSkill)
POSE = SkillKind(PoseParams, PoseSkill)
