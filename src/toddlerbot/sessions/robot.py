"""`hw run` as a library call: the real robot on its port with its calibration, the policy, the IMU and motion
capture, assembled once and closed however the run ends; `RobotSession.run` runs the policy with torque on
(`toddlerbot.runtime.hardware_run.drive`: torque off on every exit path, the steps of a run that stops early kept).

    with robot_session(description, "/dev/ttyUSB0", Path("robot.yaml"), "walk-zmp", "0:0.1,0,0", 10) as session:
        result = session.run()
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.imu import Imu
from toddlerbot.hardware.imu_kinds import open_imu
from toddlerbot.hardware.imu_stream import open_mocap
from toddlerbot.hardware.real_robot import RealRobot, TrackedRealRobot
from toddlerbot.policies import check_policy_options, make_policy
from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.hardware_run import drive
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import RunResult
from toddlerbot.sessions.recovery import recovery_policy

DEFAULT_BAUD = 2_000_000
"""The Dynamixel bus rate the robot runs at (appendix 8.5: 2 Mbaud)."""
DEFAULT_LATENCY_MS = 16.0
"""The USB-serial latency timer assumed, ms (the FTDI default): status packets are awaited 2 x this + 2 ms."""


@dataclass
class RobotSession:
    """What `hw run` runs: the robot, the policy, commands and duration, and what to close after."""

    robot: RealRobot
    policy: Policy
    commands: CommandSchedule
    seconds: float
    resources: ExitStack
    recovery: Policy | None = None
    """The policy a fall hands the robot to (``on_fall="get-up"``); None: a fall ends the run with torque off."""

    def run(self, log_path: Path | None = None,
            keep_partial: Callable[[RunLog], object] = lambda _: None) -> RunResult:
        """The run with torque on; a run that stops early hands its steps to `keep_partial` (when a log was asked
        for, or always when the bus or a motor failed) and re-raises."""
        return drive(self.robot, self.policy, self.commands, self.seconds, log_path, keep_partial, self.recovery)

    def close(self) -> None:
        """Close the policy (a dp policy's worker and camera), the IMU and motion capture."""
        self.resources.close()

    def __enter__(self) -> RobotSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def robot_imu(kind: str, port: str, balancing: str | None) -> Imu:
    """The IMU of a robot on ``port`` (`toddlerbot.hardware.imu_kinds`); ``balancing`` names what balances from it
    (a walking policy, a chain with a walk), which ``none`` is refused for (one line)."""
    if kind == "none" and balancing is not None:
        raise ToddlerbotError(f"{balancing} balances from the IMU: --imu none would run it blind (it falls within "
                              "seconds); use --imu bno08x or --imu emulator")
    return open_imu(kind, port)


def open_robot(description: RobotDescription, port: str, calibration: Path, control_dt: float = CONTROL_DT,
               baud: int = DEFAULT_BAUD, latency_ms: float = DEFAULT_LATENCY_MS, tracked: bool = False) -> RealRobot:
    """The robot on ``port`` with the zero offsets of ``calibration``; ``tracked``: watched by motion capture
    (`TrackedRealRobot`, its capture opened by `robot_session`). The bus opens when the run starts."""
    return (TrackedRealRobot if tracked else RealRobot)(
        description, port, load_calibration(calibration, description), control_dt=control_dt, baudrate=baud,
        calibration_source=str(calibration), latency_ms=latency_ms)


def robot_session(description: RobotDescription, port: str, calibration: Path, policy: str = "stand",
                  commands: str | CommandSchedule = "0:0,0,0", seconds: float = 5.0, control_dt: float = CONTROL_DT,
                  baud: int = DEFAULT_BAUD, latency_ms: float = DEFAULT_LATENCY_MS, imu: str = "bno08x",
                  mocap: str = "none", on_fall: str = "stop", **policy_options: object) -> RobotSession:
    """`hw run`'s robot and policy: ``policy`` (its ``policy_options``: weights, motion, checkpoint, camera, ...;
    bad ones fail before the bus opens) on the robot at ``port``, with its IMU (``imu``: bno08x, emulator, none)
    and motion capture (``mocap``: none or emulator), following ``commands`` for ``seconds``; ``on_fall``: what a
    fall does (`toddlerbot.sessions.recovery`; ``get-up`` needs the IMU)."""
    robot = open_robot(description, port, calibration, control_dt, baud, latency_ms, tracked=mocap != "none")
    resources = ExitStack()
    try:
        check_policy_options(policy, **policy_options)
        pol = make_policy(policy, robot, **policy_options)
        resources.callback(pol.close)
        recovery = recovery_policy(on_fall, robot)  # closed by the run loop, as the run's policy is
        balancing = f"policy {pol.name}" if pol.needs_imu else "--on-fall get-up" if recovery else None
        robot.imu = robot_imu(imu, port, balancing)
        resources.callback(robot.imu.close)
        capture = open_mocap(mocap, port)
        if capture is not None:
            robot.mocap = capture  # type: ignore[attr-defined]
            resources.callback(capture.close)
    except BaseException:
        resources.close()
        raise
    schedule = CommandSchedule.parse(commands) if isinstance(commands, str) else commands
    return RobotSession(robot, pol, schedule, seconds, resources, recovery)


def chain_on_robot(chain, description: RobotDescription, port: str, calibration: Path, imu: str = "bno08x",
                   on_switch: Callable[[str], None] = lambda _: None):
    """Run a skill chain (`toddlerbot.skills.spec.ChainSpec`) on the robot at ``port`` to its end; its IMU is
    refused as none when the chain walks. Returns the chain's status (switches, failure)."""
    from toddlerbot.skills.robot_run import needs_imu, run_on_robot

    robot = open_robot(description, port, calibration)
    robot.imu = robot_imu(imu, port, f"chain {chain.name} (it walks)" if needs_imu(chain) else None)
    return run_on_robot(chain, robot, on_switch=on_switch)
