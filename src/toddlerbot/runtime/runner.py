"""The one run loop: a policy drives a robot at its control rate; observers see every step.

Everything that drives a robot — a walking policy, a motion replay, a scripted demonstrator, a skill chain, a
diffusion policy, a teleop session — is a `Policy` run by `run_policy`. What a caller wants around the loop (the
run log, a recorded episode, a success check, a video, a viewer, a progress bar, velocity kicks) is a
`RunObserver`; how the loop keeps time is a `Clock`: `SimulatedClock` steps as fast as it can, `WallClock`
locks each step to wall-clock time (sleeping off the rest of the control period; a real robot's backend blocks
on its bus instead).

The run stops when the requested time has elapsed, when the policy is done, when an observer asks to stop (a
success check), or when the robot falls (`Robot.fallen`: the IMU tilt, or the simulator's ground truth) unless
``stop_on_fall`` is False. Given a ``recovery`` policy (`get-up`), a fall hands the robot to it instead: once it
reports success the run's policy starts again from where the robot stands and the schedule goes on; a recovery
that gives up ends the run as a fall. The torso's true pose is logged for robots with `GroundTruth` and NaN for the
others.

A command the robot's guard refuses (`UnsafeCommandError`) or a policy that raises stops the run at once: the
error propagates (a policy's own exception wrapped in `PolicyError`, which names the policy and the time) and
the caller's ``with robot:`` turns torque off. The policy is closed on every exit path (`Policy.close`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import GroundTruth, Observation, Robot
from toddlerbot.runtime.log import LogRecorder, RunLog

NAN3, NAN4 = np.full(3, np.nan), np.full(4, np.nan)


class PolicyError(ToddlerbotError):
    """The policy raised while computing an action; the run stopped before sending it."""


@dataclass(frozen=True)
class RunResult:
    log: RunLog | None
    """One row per step; None for a run that kept no log (``record_log=False``)."""
    fell: bool
    fall_time: float | None
    """s since reset when the fall was detected."""
    completed: bool
    """True when the run ended without a fall (time elapsed, policy done or an observer's stop)."""
    stopped_by: str | None = None
    """Why the run ended early: ``fall``, ``policy`` (done) or an observer's class name; None when time ran out."""
    falls: int = 0
    """Falls detected, recovered ones included."""
    recoveries: int = 0
    """Falls the recovery policy got the robot up from."""


@dataclass(frozen=True)
class Step:
    """One control step as observers see it."""

    index: int
    obs: Observation
    """What the policy saw."""
    command: np.ndarray
    """The velocity command it followed (clamped to its reach)."""
    action: Action
    next_obs: Observation
    """The robot after the step."""
    kp: np.ndarray
    """Firmware gains in effect during the step (as sent: a falling robot's lowered ones, `robot.fall`)."""
    kd: np.ndarray
    base_pos: np.ndarray
    """Torso position in the world before the step (ground truth; NaN without it)."""
    base_quat: np.ndarray
    compute_time: float
    """s spent in the policy and the backend's step."""
    step_period: float
    """s of wall time from this step's start to the next's (the clock's wait included)."""
    recovering: bool | None = None
    """True for a step the recovery policy drove, False for the run's policy; None in a run without a recovery."""


class RunObserver:
    """Something that watches a run: override what you need."""

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        """Called once, after the reset, before the first step."""

    def on_step(self, step: Step) -> None:
        """Called after every step."""

    @property
    def stop_requested(self) -> bool:
        """True to end the run after the current step (e.g. a success check that has seen success)."""
        return False


class Clock:
    """How the loop keeps time between steps."""

    def start(self) -> None:
        """Called once before the first step."""

    def wait(self, period: float) -> None:
        """Called after each step with the control period, s."""


class SimulatedClock(Clock):
    """No waiting: simulated time advances as fast as the computer steps."""


class WallClock(Clock):
    """Each step locked to wall-clock time: sleeps off the rest of the control period (deadlines accumulate, so a
    late step is caught up by the next ones rather than drifting)."""

    def start(self) -> None:
        self._deadline = time.perf_counter()

    def wait(self, period: float) -> None:
        self._deadline += period
        time.sleep(max(0.0, self._deadline - time.perf_counter()))


class RunLogObserver(RunObserver):
    """Records the run log (one row per step; `runtime.log`). Give one to `run_policy` to keep the steps of a run
    that stops on an exception; given the log's file (`path`), it writes the rows to disk in chunks while the run
    goes on (`LogRecorder`)."""

    def __init__(self, path: Path | None = None) -> None:
        self.recorder = LogRecorder(path)

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self.recorder.start(robot.motor_names, robot.joint_names, robot.control_dt, policy.name)

    def on_step(self, step: Step) -> None:
        obs, action = step.obs, step.action
        self.recorder.append(
            time=obs.time, command=step.command, motor_pos=obs.motor_pos, motor_vel=obs.motor_vel,
            motor_torque=obs.motor_torque, joint_pos=obs.joint_pos, joint_vel=obs.joint_vel,
            motor_target=action.motor_targets, joint_target=action.joint_targets, imu_quat=obs.imu_quat,
            imu_ang_vel=obs.imu_ang_vel, imu_lin_acc=obs.imu_lin_acc, foot_contact=obs.foot_contact,
            base_pos=step.base_pos, base_quat=step.base_quat, compute_time=step.compute_time,
            step_period=step.step_period, motor_kp=step.kp, motor_kd=step.kd,
            **({} if step.recovering is None else {"recovering": step.recovering}),
        )

    def finish(self, robot: Robot, policy: Policy) -> RunLog:
        return self.recorder.finish(robot.motor_names, robot.joint_names, robot.control_dt, policy.name)


def _still(_: float) -> np.ndarray:
    return np.zeros(3)


def run_policy(
    robot: Robot,
    policy: Policy,
    commands: Callable[[float], np.ndarray] = _still,
    seconds: float = 10.0,
    clock: Clock | None = None,
    observers: Sequence[RunObserver] = (),
    stop_on_fall: bool = True,
    log: RunLogObserver | None = None,
    record_log: bool = True,
    recovery: Policy | None = None,
) -> RunResult:
    """Run ``policy`` on ``robot`` for ``seconds`` (or until the policy is done, an observer stops the run or the
    robot falls), following the velocity ``commands`` (a function of time; none: stand still). Steps are logged
    into ``log`` (a new one if None), unless ``record_log`` is False (hours of teleoperation at 50 Hz would fill
    the memory with rows nobody reads). ``recovery``: the policy a fall hands the robot to (module docstring)."""
    log = (RunLogObserver() if log is None else log) if record_log else None
    clock = SimulatedClock() if clock is None else clock
    watchers = (*observers,) if log is None else (log, *observers)
    try:
        obs = robot.reset()
        policy.reset(obs)
        for observer in watchers:
            observer.on_start(robot, policy, obs)
        loop = _Loop(robot, policy, recovery, commands, clock, watchers, stop_on_fall)
        stopped_by = loop.run(obs, round(seconds / robot.control_dt))
    finally:
        policy.close()
        if recovery is not None:
            recovery.close()
    fell = loop.fall_time is not None
    return RunResult(log=None if log is None else log.finish(robot, policy), fell=fell, fall_time=loop.fall_time,
                     completed=not fell, stopped_by=stopped_by, falls=loop.falls, recoveries=loop.recoveries)


class _Loop:
    """The steps of one run: the run's policy, or the recovery policy from a fall until it is done."""

    def __init__(self, robot: Robot, policy: Policy, recovery: Policy | None,
                 commands: Callable[[float], np.ndarray], clock: Clock, watchers: Sequence[RunObserver],
                 stop_on_fall: bool) -> None:
        self.robot, self.policy, self.recovery = robot, policy, recovery
        self.commands, self.clock, self.watchers, self.stop_on_fall = commands, clock, watchers, stop_on_fall
        self.fall_time: float | None = None
        """s since reset when the last fall not recovered from was detected; None without one."""
        self.falls = self.recoveries = 0
        self._was_fallen = False

    def run(self, obs: Observation, n_steps: int) -> str | None:
        """Step until time runs out (None) or a reason to stop: ``fall``, ``policy`` or an observer's name."""
        robot = self.robot
        truth = robot if isinstance(robot, GroundTruth) else None
        kp, kd = robot.default_kp, robot.default_kd  # gains stay in effect until a policy sends others
        active = self.policy
        self.clock.start()
        for index in range(n_steps):
            start = time.perf_counter()
            command = active.within_reach(self.commands(obs.time))  # logged as the policy follows it
            action = _act(active, obs, command)
            base_pos = truth.base_pos if truth is not None else NAN3
            base_quat = truth.base_quat if truth is not None else NAN4
            next_obs = robot.step(action.motor_targets, action.kp, action.kd)
            sent_kp, sent_kd = robot.last_gains
            kp = kp if sent_kp is None else sent_kp
            kd = kd if sent_kd is None else sent_kd
            compute = time.perf_counter() - start
            self.clock.wait(robot.control_dt)
            step = Step(index, obs, command, action, next_obs, kp, kd, base_pos, base_quat, compute,
                        time.perf_counter() - start, None if self.recovery is None else active is self.recovery)
            for observer in self.watchers:
                observer.on_step(step)
            obs = next_obs
            if active is self.recovery:
                if active.done and not active.succeeded:
                    return "fall"
                if active.done:
                    self.recoveries += 1
                    self.fall_time, self._was_fallen = None, False
                    active = self.policy
                    active.reset(obs)
            elif self._fell(robot.fallen, obs.time):
                if self.recovery is not None:
                    active = self.recovery
                    active.reset(obs)
                elif self.stop_on_fall:
                    return "fall"
            if active is self.policy and active.done:
                return "policy"
            for observer in self.watchers:
                if observer.stop_requested:
                    return type(observer).__name__
        return None

    def _fell(self, fallen: bool, t: float) -> bool:
        """Whether the robot is down; a fall is counted (and timed) when it goes down."""
        if fallen and not self._was_fallen:
            self.falls += 1
            self.fall_time = t
        self._was_fallen = fallen
        return fallen


def _act(policy: Policy, obs: Observation, command: np.ndarray) -> Action:
    try:
        return policy.act(obs, command)
    except ToddlerbotError:
        raise
    except Exception as exc:  # a policy bug must stop the robot with a clear message, not a traceback
        raise PolicyError(f"policy {policy.name} failed at t={obs.time:.3f} s: {type(exc).__name__}: {exc}") from exc
