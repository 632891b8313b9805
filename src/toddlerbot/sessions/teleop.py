"""`teleop` as a library call: the robot (simulated in a task's scene, or real), the walking policy, the input
source and the leader link, the teleop session with its chain buttons, and the episode recorder, assembled once;
`TeleopRun.run` runs them in real time (`toddlerbot.teleop.launch.run_teleop`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sessions.robot import open_robot, robot_imu
from toddlerbot.skills.teleop_hook import with_chains
from toddlerbot.tasks.space import ManipulationSpace
from toddlerbot.teleop.launch import (
    TeleopRobot,
    input_source,
    leader_link,
    run_teleop,
    sim_robot,
    walking_policy,
)
from toddlerbot.teleop.recording import EpisodeRecorder
from toddlerbot.teleop.session import TeleopSession


@dataclass
class TeleopRun:
    """What `teleop` runs: the robot, the session (with its chain buttons) driving it, the recorder if any."""

    setup: TeleopRobot
    driver: Policy
    recorder: EpisodeRecorder | None
    simulated: bool

    def run(self, seconds: float = 0.0, viewer: bool = False, log: Callable[[str], None] = print) -> None:
        """Run in real time for `seconds` (0: until Esc or Ctrl-C), with the MuJoCo viewer if asked (sim)."""
        run_teleop(self.setup.robot, self.driver, seconds, [] if self.recorder is None else [self.recorder],
                   viewer and self.simulated, log)

    def write(self, out: Path, log: Callable[[str], None] = print) -> None:
        """Write the recorded episodes as a dataset in `out`."""
        if self.recorder is not None:
            self.recorder.write(out, log)


def teleop_session(description: RobotDescription, backend: str = "sim", input_kind: str = "joystick",
                   task: str = "walk", policy: str = "walk-zmp", mapping: Path | None = None, link: str | None = None,
                   port: str | None = None, calibration: Path | None = None, imu: str = "bno08x", seed: int = 0,
                   chains: list[str] | None = None, record: bool = False,
                   log: Callable[[str], None] = print) -> TeleopRun:
    """The teleoperation of ``description``'s robot: simulated (``backend`` sim, in ``task``'s scene for ``seed``)
    or real (``port``, ``calibration``, ``imu``), walked by ``policy`` from ``input_kind`` (joystick, keyboard,
    leader: the arms follow the leader ``link``), with ``chains`` on their buttons; ``record``: episodes marked with
    Menu are recorded."""
    setup, walker = _real(description, port, calibration, imu, policy) if backend == "real" else \
        _sim(description, task, seed, policy)
    robot = setup.robot
    recorder = EpisodeRecorder(f"teleop {task}", ManipulationSpace.of(robot.description), setup.head_image) \
        if record else None
    session = TeleopSession(robot, input_source(input_kind, mapping, log), walker,
                            leader_link(link, robot) if input_kind == "leader" else None,
                            on_menu=None if recorder is None else recorder.toggle, log=log)
    driver = with_chains(session, chains, task if backend == "sim" else None, setup.head_image, log)
    return TeleopRun(setup, driver, recorder, backend == "sim")


def _sim(description: RobotDescription, task: str, seed: int, policy: str) -> tuple[TeleopRobot, Policy | None]:
    """The task's simulated robot and, where it walks, the walking policy."""
    setup = sim_robot(task, seed, description)
    return setup, walking_policy(policy, setup.robot) if setup.walks else None


def _real(description: RobotDescription, port: str | None, calibration: Path | None, imu: str,
          policy: str) -> tuple[TeleopRobot, Policy]:
    """The real robot (its IMU opened for a policy that balances from it) and the walking policy."""
    if port is None or calibration is None:
        raise ToddlerbotError("--backend real needs --port and --calibration")
    robot = open_robot(description, port, calibration)
    walker = walking_policy(policy, robot)
    robot.imu = robot_imu(imu, port, f"teleop --policy {policy}" if walker.needs_imu else None)
    return TeleopRobot(robot, None, walks=True), walker
