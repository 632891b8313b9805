"""`toddlerbot chain run` in simulation: the chain's scene, perturbed by the seed (the wagon shifted; in the pick
scene the pick task's start for the seed, as `dp eval` resets it), the chain run by `runtime.run_policy` to its end;
the outcome is the chain's own success predicates plus what each skill was driven by, the switch times,
displacements and lifts, how firmly each hand held its bar through the last skill (the margin of a `grasped`
success) and each dp skill's policy status."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.runtime.runner import RunObserver, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.skills.runner import ChainRunner, time_limit
from toddlerbot.skills.sim_observers import ChainVideo, GripMargin, GripObserver
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.pick import PickTask, TaskRobot
from toddlerbot.tasks.predicates import GraspedParams, LiftedParams, MovedParams
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import SIDES, scene_model, shift_wagon

WAGON_OFFSET = ((-0.01, 0.01), (-0.03, 0.03))
"""Seeded shift of the wagon from its layout position: (x range, y range), m."""
UNBOUNDED_SKILL_S = 60.0
"""Simulated time allowed to a skill with neither `after` nor `timeout` (a button it will never see in sim)."""


def wagon_shift(rng: np.random.Generator) -> np.ndarray:
    """The seed's shift of the wagon (x, y), m: the first draws of the seed's generator (the wagon task draws it
    the same way, so `manip demo --task wagon` and `chain run wagon` place the wagon alike for a seed)."""
    return np.array([rng.uniform(*WAGON_OFFSET[0]), rng.uniform(*WAGON_OFFSET[1])])


@dataclass(frozen=True)
class StartPerturbation:
    """Beyond the seed's wagon shift: how far the start state is off the layout, to measure a chain's margin."""

    pose_offset: float = 0.0
    """Each motor starts up to this far off the home pose (uniform, drawn from the seed), rad."""
    wagon_shift: tuple[float, float] = (0.0, 0.0)
    """Added to the seed's wagon shift (x, y), m."""


@dataclass
class SimChainResult:
    chain: str
    seed: int
    success: bool
    checks: dict[str, bool]
    """Each success predicate at the end (all true, and no skill failed, is success)."""
    driven_by: dict[str, str]
    """Skill name -> what drove it."""
    switch_time_s: float | None
    """Sim time the first skill handed over (grasp -> next)."""
    switches: list[tuple[str, str, float]]
    displacement_m: dict[str, float]
    """Body -> horizontal displacement since the start, for each `moved` success predicate."""
    lift_m: dict[str, float]
    """Body -> how far it rose since the start, at the end, for each `lifted` success predicate."""
    failure: str | None
    sim_seconds: float
    wall_seconds: float
    grip: dict[str, GripMargin] = field(default_factory=dict)
    """Side -> its grip on the bar of each `grasped` success predicate, over the last skill."""
    extra: dict = field(default_factory=dict)
    """More JSON fields: ``dp``, skill name -> its policy's `LiveStatus` (chunks used, inference time), for each dp
    skill that ran."""

    def as_json(self) -> dict:
        out = {"chain": self.chain, "seed": self.seed, "success": self.success,
               "switch_time_s": None if self.switch_time_s is None else round(self.switch_time_s, 3)}
        out.update({f"{body}_displacement_m": round(v, 4) for body, v in self.displacement_m.items()})
        out.update({f"{body}_lift_m": round(v, 4) for body, v in self.lift_m.items()})
        first = next(iter(self.driven_by))
        out[f"{first}_by"] = self.driven_by[first]
        out.update(checks=self.checks, driven_by=self.driven_by, failure=self.failure,
                   switches=[{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in self.switches],
                   sim_seconds=round(self.sim_seconds, 3), wall_seconds=round(self.wall_seconds, 2),
                   grip={side: {"min_force_n": round(g.min_force_n, 2), "slide_mm": round(1e3 * g.slide_m, 1),
                                "to_end_mm": round(1e3 * g.to_end_m, 1)}
                         for side, g in self.grip.items() if g.start_m is not None})
        out.update(self.extra)
        return out

    def summary(self) -> list[str]:
        """The outcome in a few lines for a person."""
        lines = [f"chain {self.chain} seed {self.seed}: {'success' if self.success else 'FAILED'}"
                 + (f" ({self.failure})" if self.failure else "")]
        lines += [f"  {skill}: {by}" for skill, by in self.driven_by.items()]
        lines += [f"  {a} -> {b} at {t:.2f} s" for a, b, t in self.switches]
        lines += [f"  {body} moved {moved:.3f} m" for body, moved in self.displacement_m.items()]
        lines += [f"  {body} rose {rise:.3f} m" for body, rise in self.lift_m.items()]
        lines.append(f"  checks {self.checks}; {self.sim_seconds:.1f} s simulated in {self.wall_seconds:.1f} s")
        return lines


class SceneRobot(MuJoCoRobot):
    """The chain's scene with the seed's start: every `reset` puts the motors at their offsets and, in the wagon
    scene, the wagon at its shift."""

    def __init__(self, description: RobotDescription, model: mujoco.MjModel, motor_offset: np.ndarray,
                 wagon_shift: np.ndarray | None) -> None:
        self.wagon_shift = wagon_shift  # before the base class's first reset
        super().__init__(description, model=model)
        self.initial_motor_offset = motor_offset

    def reset(self) -> Observation:
        obs = super().reset()  # the robot senses the same wherever the wagon stands
        if self.wagon_shift is not None:
            shift_wagon(self.model, self.data, self.wagon_shift)
            mujoco.mj_forward(self.model, self.data)
        return obs


class PickStart(TaskRobot):
    """The pick task's robot starting at `start_pose` (the task's ready pose, perhaps perturbed)."""

    def __init__(self, task: PickTask, seed: int, start_pose: np.ndarray) -> None:
        super().__init__(task, seed)
        self.start_pose = start_pose

    def reset(self) -> Observation:
        return self.task.reset(self.seed, self.start_pose)


def scene_robot(chain: ChainSpec, seed: int, description: RobotDescription,
                perturbation: StartPerturbation = StartPerturbation()) -> tuple[SceneRobot | PickStart, np.ndarray]:
    """(robot, start targets): the chain's scene robot, which `run_policy`'s reset puts at the seed's start."""
    rng = np.random.default_rng(seed)
    shift = wagon_shift(rng)
    offset = rng.uniform(-1, 1, len(description.motor_names)) * perturbation.pose_offset
    if chain.scene == "pick":  # the pick task's start, as `dp eval` resets it: cube placed for the seed, arm ready
        task = PickTask(description)
        start = task.ready_pose + offset
        return PickStart(task, seed, start), start
    shifted = shift + perturbation.wagon_shift if chain.scene == "wagon" else None
    robot = SceneRobot(description, scene_model(description, chain.scene), offset, shifted)
    return robot, description.home_motor_pos + offset


def run_in_sim(chain: ChainSpec, seed: int, video: str | Path | None = None,
               description: RobotDescription | None = None,
               perturbation: StartPerturbation = StartPerturbation()) -> SimChainResult:
    description = description or RobotDescription.load(variant="gripper")
    robot, start = scene_robot(chain, seed, description, perturbation)
    model = robot.model
    probe = SceneProbe(model, robot.data)
    camera = _head_camera(robot)
    runner = ChainRunner(chain, robot, model, probe, camera.image, start_targets=start, seed=seed)
    grip = GripObserver(runner, probe, _bars(chain, model))
    recorder = None if video is None else ChainVideo(robot, video, camera.image)
    observers: list[RunObserver] = [grip] if recorder is None else [grip, recorder]
    limit = time_limit(chain, UNBOUNDED_SKILL_S)
    started = time.perf_counter()
    try:  # a chain walking into the wagon may fall: `upright` is one of its checks, not a reason to stop
        run_policy(robot, runner, seconds=limit, observers=observers, stop_on_fall=False)
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        camera.close()
    if recorder is not None:
        recorder.close()
    status = runner.status
    if not status.done:
        status.failure = f"did not end within {limit:g} s of simulated time"
    obs = robot.observe()
    checks = runner.succeeded(obs)
    dp = runner.skill_status()
    moved = [p.body for name, p in chain.success if isinstance(p, MovedParams)]
    lifted = [p.body for name, p in chain.success if isinstance(p, LiftedParams)]
    return SimChainResult(
        chain.name, seed, status.failure is None and all(checks.values()), checks, dict(status.driven_by),
        status.switches[0][2] if status.switches else None, status.switches,
        {body: probe.displacement(body) for body in moved}, {body: probe.rise(body) for body in lifted},
        status.failure, float(obs.time), time.perf_counter() - started, grip.grip, {"dp": dp} if dp else {},
    )


def _bars(chain: ChainSpec, model: mujoco.MjModel) -> list[tuple[str, str]]:
    """(hand, bar) of each `grasped` success predicate on a bar."""
    return [(side, p.target) for name, p in chain.success if isinstance(p, GraspedParams) and _is_bar(model, p.target)
            for side in (SIDES if p.hands in ("both", "either") else (p.hands,))]


def _is_bar(model: mujoco.MjModel, geom: str) -> bool:
    """Is `geom` a bar (capsule or cylinder), whose grip `GripMargin` can measure? (Not the pick task's cube.)"""
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    bars = (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER))
    return i >= 0 and int(model.geom_type[i]) in bars


def _head_camera(robot: MuJoCoRobot):
    from toddlerbot.tasks.camera import HeadCamera

    return HeadCamera(robot.model, robot.data, robot.description.handles.head_camera or "head_camera")
