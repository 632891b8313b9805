"""`toddlerbot chain run` in simulation: the chain's scene, perturbed by the seed, run to its end; the outcome
is the chain's own success predicates plus what each skill was driven by, the switch times and displacements."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np

from toddlerbot.manipulation.chaining.predicates import MovedParams
from toddlerbot.manipulation.chaining.probe import SceneProbe
from toddlerbot.manipulation.chaining.runner import ChainRunner
from toddlerbot.manipulation.chaining.spec import ChainSpec
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.scenes import scene_model, shift_wagon

WAGON_OFFSET = ((-0.01, 0.01), (-0.03, 0.03))
"""Seeded shift of the wagon from its layout position: (x range, y range), m."""
UNBOUNDED_SKILL_S = 60.0
"""Simulated time allowed to a skill with neither `after` nor `timeout` (a button it will never see in sim)."""
VIDEO_CAMERA = "perspective"
VIDEO_FPS = 25


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
    failure: str | None
    sim_seconds: float
    wall_seconds: float
    extra: dict = field(default_factory=dict)

    def as_json(self) -> dict:
        out = {"chain": self.chain, "seed": self.seed, "success": self.success,
               "switch_time_s": None if self.switch_time_s is None else round(self.switch_time_s, 3)}
        out.update({f"{body}_displacement_m": round(v, 4) for body, v in self.displacement_m.items()})
        first = next(iter(self.driven_by))
        out[f"{first}_by"] = self.driven_by[first]
        out.update(checks=self.checks, driven_by=self.driven_by, failure=self.failure,
                   switches=[{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in self.switches],
                   sim_seconds=round(self.sim_seconds, 3), wall_seconds=round(self.wall_seconds, 2))
        return out


def run_in_sim(chain: ChainSpec, seed: int, video: str | Path | None = None,
               description: RobotDescription | None = None) -> SimChainResult:
    description = description or RobotDescription.load(variant="gripper")
    model = scene_model(description, chain.scene)
    robot = MuJoCoRobot(description, model=model)
    obs = robot.reset()
    if chain.scene == "wagon":
        rng = np.random.default_rng(seed)
        shift_wagon(model, robot.data, np.array([rng.uniform(*WAGON_OFFSET[0]), rng.uniform(*WAGON_OFFSET[1])]))
        mujoco.mj_forward(model, robot.data)
    probe = SceneProbe(model, robot.data)
    camera = _head_camera(robot)
    runner = ChainRunner(chain, robot, model, probe, camera.image)
    recorder = None
    if video is not None:
        from toddlerbot.manipulation.video import SideBySideVideo

        # the tracking camera: a chain that walks leaves the fixed workspace camera's view
        recorder = SideBySideVideo(SimpleNamespace(model=model, robot=robot), video, VIDEO_FPS, camera=VIDEO_CAMERA)
    every = max(1, round(1.0 / (VIDEO_FPS * robot.control_dt)))
    limit = sum(s.until.after or s.timeout or UNBOUNDED_SKILL_S for s in chain.skills) + 1.0
    started = time.perf_counter()
    try:
        runner.start(obs, description.home_motor_pos)
        k = 0
        while obs.time < limit:
            command = runner.step(obs)
            if command is None:
                break
            obs = robot.step(*command)
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
    moved = [p.body for name, p in chain.success if isinstance(p, MovedParams)]
    return SimChainResult(
        chain.name, seed, status.failure is None and all(checks.values()), checks,
        {s.name: skill.by for s, skill in zip(chain.skills, runner.skills)},
        status.switches[0][2] if status.switches else None, status.switches,
        {body: probe.displacement(body) for body in moved}, status.failure, float(obs.time),
        time.perf_counter() - started,
    )


def _head_camera(robot: MuJoCoRobot):
    from toddlerbot.manipulation.camera import HeadCamera

    return HeadCamera(robot.model, robot.data, robot.description.handles.head_camera or "head_camera")
