"""`toddlerbot chain run` in simulation: the chain's scene at its task's start for the seed (the wagon shifted; the
pick task's start as `dp eval` resets it: `Task.chain_start`), the chain run by `runtime.run_policy` to its end;
the outcome is the chain's own success predicates plus what each skill was driven by, the switch times, its
retries and recoveries, displacements and lifts, how firmly each hand held its bar through the last skill (the
margin of a `grasped` success) and each dp skill's policy status."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Robot
from toddlerbot.runtime.runner import RunObserver, run_policy
from toddlerbot.skills.runner import ChainRunner, Recovery, time_limit
from toddlerbot.skills.sim_observers import ChainVideo, GripMargin, GripObserver
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks import make_task, task_description
from toddlerbot.tasks.base import StartPerturbation
from toddlerbot.tasks.predicates import GraspedParams, LiftedParams, MovedParams
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import SIDES

UNBOUNDED_SKILL_S = 60.0
"""Simulated time allowed to a skill with neither `after` nor `timeout` (a button it will never see in sim)."""


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
    """Sim time the first skill first handed over to the second (grasp -> next)."""
    switches: list[tuple[str, str, float]]
    displacement_m: dict[str, float]
    """Body -> horizontal displacement since the start, for each `moved` success predicate."""
    lift_m: dict[str, float]
    """Body -> how far it rose since the start, at the end, for each `lifted` success predicate."""
    failure: str | None
    sim_seconds: float
    wall_seconds: float
    recoveries: list[Recovery] = field(default_factory=list)
    """Each retry and recover the chain made."""
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
                   recoveries=[r.to_dict() for r in self.recoveries],
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
        lines += [f"  {r.kind} {r.skill} at {r.time_s:.2f} s, on from {r.resume}" for r in self.recoveries]
        lines += [f"  {body} moved {moved:.3f} m" for body, moved in self.displacement_m.items()]
        lines += [f"  {body} rose {rise:.3f} m" for body, rise in self.lift_m.items()]
        lines.append(f"  checks {self.checks}; {self.sim_seconds:.1f} s simulated in {self.wall_seconds:.1f} s")
        return lines


def scene_robot(chain: ChainSpec, seed: int, description: RobotDescription,
                perturbation: StartPerturbation = StartPerturbation(), variation: str = "default"
                ) -> tuple[Robot, np.ndarray]:
    """(robot, start targets): the start of the task whose scene the chain names, for the seed (`Task.chain_start`)
    in the task's scene `variation`, which `run_policy`'s reset puts in place."""
    return make_task(chain.scene, description, variation).chain_start(seed, perturbation)


def run_in_sim(chain: ChainSpec, seed: int, video: str | Path | None = None,
               description: RobotDescription | None = None,
               perturbation: StartPerturbation = StartPerturbation(),
               disturbances: Sequence[RunObserver] = (), variation: str = "default") -> SimChainResult:
    """The chain run to its end in its scene (drawn from the scene task's `variation`) for `seed`; `disturbances`
    are more run observers, each told the robot and the chain (`on_start`) and called after every step (a test's
    slip: the handle made slippery)."""
    description = task_description(description)
    robot, start = scene_robot(chain, seed, description, perturbation, variation)
    model = robot.model
    probe = SceneProbe(model, robot.data)
    camera = _head_camera(robot)
    runner = ChainRunner(chain, robot, model, probe, camera.image, start_targets=start, seed=seed)
    grip = GripObserver(runner, probe, _bars(chain, model))
    recorder = None if video is None else ChainVideo(robot, video, camera.image)
    observers: list[RunObserver] = [grip, *disturbances] + ([] if recorder is None else [recorder])
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
    first = [t for a, b, t in status.switches if (a, b) == tuple(s.name for s in chain.skills[:2])]
    return SimChainResult(
        chain.name, seed, status.failure is None and all(checks.values()), checks, dict(status.driven_by),
        first[0] if first else None, status.switches,
        {body: probe.displacement(body) for body in moved}, {body: probe.rise(body) for body in lifted},
        status.failure, float(obs.time), time.perf_counter() - started, list(status.recoveries), grip.grip,
        {"dp": dp} if dp else {},
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


def _head_camera(robot: Robot):
    from toddlerbot.tasks.camera import HeadCamera

    return HeadCamera(robot.model, robot.data, robot.description.handles.head_camera or "head_camera")
