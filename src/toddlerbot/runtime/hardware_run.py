"""A policy on the real robot (or the emulator behind the driver): the one run loop inside the robot's torque
context, keeping the steps of a run that stops early; with a log file, the steps go to disk in chunks while the run
goes on (`toddlerbot.runtime.log.LogRecorder`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from toddlerbot.hardware.driver import HardwareError
from toddlerbot.hardware.real_robot import RealRobot
from toddlerbot.policies.base import Policy
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import RunLogObserver, RunResult, run_policy


def drive(robot: RealRobot, policy: Policy, commands: Callable[[float], np.ndarray], seconds: float,
          log_path: Path | None, keep_partial: Callable[[RunLog], object],
          recovery: Policy | None = None) -> RunResult:
    """Run `policy` with torque on (off again on every exit path). A run that stops early (an error, a stop
    signal) hands the steps so far to `keep_partial` when a log was asked for, or always when the bus or a motor
    failed (the log is then the evidence), and re-raises. Chunks of an unfinished run already at `log_path` are
    refused before torque comes on. The log is joined once torque is off: joining 30 minutes of chunks takes
    seconds, which a walking robot held by motors that get no goals would spend falling over. ``recovery``: the
    policy a fall hands the robot to (`toddlerbot.runtime.runner`); without one a fall ends the run."""
    run_log = RunLogObserver(log_path)
    try:
        with robot:
            result = run_policy(robot, policy, commands, seconds, observers=[run_log], record_log=False,
                                recovery=recovery)
    except BaseException as exc:
        if len(run_log.recorder) and (log_path is not None or isinstance(exc, HardwareError)):
            keep_partial(run_log.finish(robot, policy))
        raise
    return dataclasses.replace(result, log=run_log.finish(robot, policy))
