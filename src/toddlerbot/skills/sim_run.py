"""`toddlerbot chain run` in simulation: the chain's scene, perturbed by the seed (the wagon shifted; in the pick
scene the pick task's start for the seed, as `dp eval` resets it), run to its end; the outcome is the chain's own
success predicates plus what each skill was driven by, the switch times, displacements and lifts, how firmly each
hand held its bar through the last skill (the margin of a `grasped` success) and each dp skill's policy status."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.skills.runner import ChainRunner
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.predicates import GraspedParams, LiftedParams, MovedParams
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import SIDES, scene_model, shift_wagon

WAGON_OFFSET = ((-0.01, 0.01), (-0.03, 0.03))
"""Seeded shift of the wagon from its layout position: (x range, y range), m."""
UNBOUNDED_SKILL_S = 60.0
"""Simulated time allowed to a skill with neither `after` nor `timeout` (a button it will never see in sim)."""
VIDEO_CAMERA = "perspective"
VIDEO_FPS = 25


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
class GripMargin:
    """How firmly one hand held a bar through the chain's last skill."""

    min_force_n: float = float("inf")
    """The weaker finger pad's normal force, its minimum over the skill, N (0: a pad let go)."""
    slide_m: float = 0.0
    """Farthest the bar's axis moved along the fingers from `start_m`, m."""
    to_end_m: float = float("inf")
    """Least distance from the grasp point to the nearer end of the bar's straight part, m (the pads reach
    `scenes.PAD_HALF_SIZE[0]` either side of it)."""
    start_m: float | None = None
    """Where the bar's axis was along the fingers (grasp-site y) when the skill began, m; None until measured."""

    def update(self, probe: SceneProbe, side: str, bar: str) -> None:
        self.min_force_n = min(self.min_force_n, float(probe.pad_forces(side, bar).min()))
        in_hand = probe.bar_in_hand(side, bar)
        self.start_m = in_hand.offset[1] if self.start_m is None else self.start_m
        self.slide_m = max(self.slide_m, abs(in_hand.offset[1] - self.start_m))
        self.to_end_m = min(self.to_end_m, in_hand.to_end)


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


def run_in_sim(chain: ChainSpec, seed: int, video: str | Path | None = None,
               description: RobotDescription | None = None,
               perturbation: StartPerturbation = StartPerturbation()) -> SimChainResult:
    description = description or RobotDescription.load(variant="gripper")
    rng = np.random.default_rng(seed)
    shift = wagon_shift(rng)
    offset = rng.uniform(-1, 1, len(description.motor_names)) * perturbation.pose_offset
    if chain.scene == "pick":  # the pick task's start, as `dp eval` resets it: cube placed for the seed, arm ready
        from toddlerbot.tasks.pick import PickTask, TaskRobot

        task = PickTask(description)
        robot = TaskRobot(task, seed)
        model, start = task.model, task.ready_pose + offset
        obs = task.reset(seed, start)
    else:
        model = scene_model(description, chain.scene)
        robot = MuJoCoRobot(description, model=model)
        robot.initial_motor_offset = offset
        start = description.home_motor_pos + offset
        obs = robot.reset()
        if chain.scene == "wagon":
            shift_wagon(model, robot.data, shift + perturbation.wagon_shift)
            mujoco.mj_forward(model, robot.data)
    probe = SceneProbe(model, robot.data)
    bars = [(side, p.target) for name, p in chain.success if isinstance(p, GraspedParams) and _is_bar(model, p.target)
            for side in (SIDES if p.hands in ("both", "either") else (p.hands,))]
    grip = {side: GripMargin() for side, _ in bars}
    camera = _head_camera(robot)
    runner = ChainRunner(chain, robot, model, probe, camera.image)
    recorder = None
    if video is not None:
        from toddlerbot.tasks.video import SideBySideVideo

        # the tracking camera: a chain that walks leaves the fixed workspace camera's view
        recorder = SideBySideVideo(SimpleNamespace(model=model, robot=robot), video, VIDEO_FPS, camera=VIDEO_CAMERA)
    every = max(1, round(1.0 / (VIDEO_FPS * robot.control_dt)))
    limit = sum(s.until.after or s.timeout or UNBOUNDED_SKILL_S for s in chain.skills) + 1.0
    started = time.perf_counter()
    try:
        runner.start(obs, start)
        k = 0
        while obs.time < limit:
            command = runner.step(obs)
            if command is None:
                break
            obs = robot.step(*command)
            if runner.status.skill == chain.skills[-1].name:
                for side, bar in bars:
                    grip[side].update(probe, side, bar)
            if recorder is not None and k % every == 0:
                recorder.add(camera.image())
            k += 1
        if not runner.status.done:
            runner.status.failure = f"did not end within {limit:g} s of simulated time"
        checks = runner.succeeded(obs)
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        runner.close()
        camera.close()
    if recorder is not None:
        recorder.close()
    status = runner.status
    dp = {s.name: skill.live.status.to_dict() for s, skill in zip(chain.skills, runner.skills)
          if getattr(skill, "live", None) is not None and skill.live.runner is not None}
    moved = [p.body for name, p in chain.success if isinstance(p, MovedParams)]
    lifted = [p.body for name, p in chain.success if isinstance(p, LiftedParams)]
    return SimChainResult(
        chain.name, seed, status.failure is None and all(checks.values()), checks,
        {s.name: skill.by for s, skill in zip(chain.skills, runner.skills)},
        status.switches[0][2] if status.switches else None, status.switches,
        {body: probe.displacement(body) for body in moved}, {body: probe.rise(body) for body in lifted},
        status.failure, float(obs.time),
        time.perf_counter() - started, grip, {"dp": dp} if dp else {},
    )


def _is_bar(model: mujoco.MjModel, geom: str) -> bool:
    """Is `geom` a bar (capsule or cylinder), whose grip `GripMargin` can measure? (Not the pick task's cube.)"""
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    bars = (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER))
    return i >= 0 and int(model.geom_type[i]) in bars


def _head_camera(robot: MuJoCoRobot):
    from toddlerbot.tasks.camera import HeadCamera

    return HeadCamera(robot.model, robot.data, robot.description.handles.head_camera or "head_camera")
