"""`sim run` as a library call: the simulated robot (in a task's scene if asked), the policy, the watchers (the
task's progress, a video, the viewer) and the clock, assembled once; `SimSession.run` runs them through the one run
loop (`toddlerbot.runtime.runner.run_policy`).

    session = sim_session("walk-zmp", commands="0:0.1,0,0", seconds=10)
    result = session.run()
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import accepts_option, make_policy
from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_HZ, Robot
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.observers import VideoObserver, ViewerObserver
from toddlerbot.runtime.runner import (
    Clock,
    RunLogObserver,
    RunObserver,
    RunResult,
    SimulatedClock,
    WallClock,
    run_policy,
)
from toddlerbot.sessions.recovery import recovery_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig
from toddlerbot.sim.terrain import TerrainSpec, parse_terrain, terrain_model


@dataclass
class SimSession:
    """What `sim run` runs: robot, policy, commands, duration, clock and watchers."""

    robot: Robot
    policy: Policy
    commands: Callable[[float], np.ndarray]
    seconds: float
    clock: Clock
    scene: RunObserver | None = None
    """The task's progress report (`--task`), None without a task."""
    video: VideoObserver | None = None
    """The recording of a camera, when a video or snapshot was asked for and a renderer is available."""
    render_skipped: str | None = None
    """Why a video or snapshot asked for cannot be made (no renderer), None otherwise."""
    viewer: ViewerObserver | None = None
    watchers: list[RunObserver] = field(default_factory=list)
    recovery: Policy | None = None
    """The policy a fall hands the robot to (``on_fall="get-up"``); None: a fall ends the run."""

    def run(self, *more: RunObserver, log_path: Path | None = None) -> RunResult:
        """The run, with the session's watchers and `more` (e.g. a progress bar); the viewer is closed after it.
        `log_path`: the file the log will be saved to, where its rows go in chunks while the run goes on."""
        try:
            return run_policy(self.robot, self.policy, self.commands, self.seconds, clock=self.clock,
                              observers=[*self.watchers, *more], log=RunLogObserver(log_path),
                              recovery=self.recovery)
        finally:
            if self.viewer is not None:
                self.viewer.close()

    def write_video(self, video: Path | None, snapshot: Path | None) -> list[Path]:
        """Write the recording asked for; returns the files written (none when rendering was skipped)."""
        return self.video.write(video, snapshot) if self.video is not None else []


def sim_session(policy: str = "walk-zmp", commands: str | CommandSchedule | None = None, seconds: float = 10.0,
                description: RobotDescription | None = None, control_hz: float = CONTROL_HZ,
                realtime: bool = False, task: str | None = None, seed: int = 0, camera: str | None = None,
                viewer: bool = False, on_fall: str = "stop", terrain: str | TerrainSpec | None = None,
                terrain_seed: int = 0, **policy_options: object) -> SimSession:
    """`sim run`'s robot and policy: ``policy`` (a registered name, its ``policy_options``: weights, motion, ...)
    on ``description`` (default: the packaged robot, floating) at ``control_hz``, following ``commands`` (a
    schedule's text, a schedule, or None: the policy's demo command) for ``seconds``; ``task``: in that registered
    task's scene, reset for ``seed``; ``camera``: record it (a video or snapshot, `SimSession.write_video`);
    ``viewer``: show the MuJoCo viewer (implies real time); ``realtime``: keep wall-clock time; ``on_fall``: what a
    fall does (`toddlerbot.sessions.recovery`); ``terrain``: the ground (``NAME[:KEY=VALUE,...]`` or a parsed
    `TerrainSpec`, `toddlerbot.sim.terrain`; None: the flat floor) drawn from ``terrain_seed``."""
    description = description or RobotDescription.load()
    realtime = realtime or viewer
    options = {"synchronous": not realtime, **policy_options}  # inference inline unless the loop keeps real time
    if isinstance(terrain, str):
        terrain = parse_terrain(terrain)
    robot, pol, scene = _robot_and_policy(description, policy, task, seed, 1.0 / control_hz, options,
                                          (terrain, terrain_seed))
    schedule = CommandSchedule.parse(commands) if isinstance(commands, str) else commands
    session = SimSession(robot, pol, schedule or (lambda _t: np.array(pol.demo_command, dtype=float)), seconds,
                         WallClock() if realtime else SimulatedClock(), scene, recovery=recovery_policy(on_fall, robot))
    if camera is not None:
        from toddlerbot.sim.render import RenderError

        try:
            session.video = VideoObserver(robot, camera)  # type: ignore[arg-type]
        except RenderError as exc:
            session.render_skipped = str(exc)
    if viewer:
        session.viewer = _viewer(robot)
    session.watchers = [w for w in (scene, session.video, session.viewer) if w is not None]
    return session


def _robot_and_policy(description: RobotDescription, policy: str, task: str | None, seed: int, control_dt: float,
                      options: dict, ground: tuple[TerrainSpec | None, int]
                      ) -> tuple[Robot, Policy, RunObserver | None]:
    """(robot, policy, task progress observer or None). The robot stands on ``ground`` (terrain, seed). In a task's
    scene the robot is the task's, reset for ``seed``, and a policy that takes a camera sees the task's head
    camera."""
    terrain, terrain_seed = ground
    if task is None:
        robot = MuJoCoRobot(description, SimConfig(control_dt=control_dt),
                            model=terrain_model(description, terrain, terrain_seed))
        return robot, make_policy(policy, robot, **options), None
    if terrain is not None and not terrain.is_flat:
        raise ToddlerbotError(f"--terrain {terrain}: a task's scene has its own floor; drop --terrain or --task")
    from toddlerbot.robot.interface import CONTROL_DT
    from toddlerbot.tasks import make_task
    from toddlerbot.tasks.base import TaskRobot

    if abs(control_dt - CONTROL_DT) > 1e-12:
        raise ToddlerbotError(f"--task runs at the task's {1 / CONTROL_DT:g} Hz control rate; drop --control-hz")
    the_task = make_task(task, description)
    robot = TaskRobot(the_task, seed)
    camera = {"camera": the_task.head_image} if accepts_option(policy, "camera") else {}
    return robot, make_policy(policy, robot, **options, **camera, task=task), the_task.progress()


def _viewer(robot: Robot) -> ViewerObserver:
    from toddlerbot.sim.render import has_display

    if not has_display():
        raise ToddlerbotError("--viewer needs a display (DISPLAY or WAYLAND_DISPLAY); use --video instead")
    return ViewerObserver(robot)  # type: ignore[arg-type]
