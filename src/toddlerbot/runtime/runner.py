"""The runner: policy <-> robot at a fixed control rate, every step logged.

``realtime=True`` locks each step to wall-clock time (sleeping off the remainder of the control period; a real
robot's backend blocks on its bus instead). The run stops early when the policy is done, or when the robot falls
(`Robot.fallen`: the IMU tilt, or the simulator's ground truth) unless ``stop_on_fall`` is False. The torso's
true pose is logged for robots with `GroundTruth` (simulators) and NaN for the others.

A command the robot's guard refuses (`UnsafeCommandError`) or a policy that raises stops the run at once: the
error propagates (a policy's own exception wrapped in `PolicyError`, which names the policy and the time) and
the caller's ``with robot:`` turns torque off.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import GroundTruth, Observation, Robot
from toddlerbot.runtime.log import LogRecorder, RunLog

NAN3, NAN4 = np.full(3, np.nan), np.full(4, np.nan)


class PolicyError(ToddlerbotError):
    """The policy raised while computing an action; the run stopped before sending it."""


@dataclass(frozen=True)
class RunResult:
    log: RunLog
    fell: bool
    fall_time: float | None
    """s since reset when the fall was detected."""
    completed: bool
    """True when the policy finished (a motion replay) or the requested duration elapsed without a fall."""


def run_policy(
    robot: Robot,
    policy: Policy,
    commands: Callable[[float], np.ndarray],
    seconds: float,
    realtime: bool = False,
    stop_on_fall: bool = True,
    on_step: Callable[[Observation], None] | None = None,
    recorder: LogRecorder | None = None,
) -> RunResult:
    """Run ``policy`` on ``robot`` for ``seconds`` (or until the policy is done / the robot falls). Steps are logged
    into ``recorder`` (a new one if None): give one to keep the steps of a run that stops on an exception."""
    recorder = LogRecorder() if recorder is None else recorder
    obs = robot.reset()
    policy.reset(obs)
    n_steps = round(seconds / robot.control_dt)
    fall_time = None
    truth = robot if isinstance(robot, GroundTruth) else None
    next_deadline = time.perf_counter()
    kp, kd = robot.default_kp, robot.default_kd  # gains stay in effect until a policy sends others
    for _ in range(n_steps):
        start = time.perf_counter()
        command = policy.within_reach(commands(obs.time))  # logged as the policy follows it
        try:
            action = policy.act(obs, command)
        except ToddlerbotError:
            raise
        except Exception as exc:  # a policy bug must stop the robot with a clear message, not a traceback
            raise PolicyError(f"policy {policy.name} failed at t={obs.time:.3f} s: {type(exc).__name__}: {exc}"
                              ) from exc
        base_pos = truth.base_pos if truth is not None else NAN3
        base_quat = truth.base_quat if truth is not None else NAN4
        new_obs = robot.step(action.motor_targets, action.kp, action.kd)
        kp = kp if action.kp is None else action.kp
        kd = kd if action.kd is None else action.kd
        compute = time.perf_counter() - start
        if realtime:
            next_deadline += robot.control_dt
            time.sleep(max(0.0, next_deadline - time.perf_counter()))
        recorder.append(
            time=obs.time, command=command, motor_pos=obs.motor_pos, motor_vel=obs.motor_vel,
            motor_torque=obs.motor_torque, joint_pos=obs.joint_pos, joint_vel=obs.joint_vel,
            motor_target=action.motor_targets, joint_target=action.joint_targets, imu_quat=obs.imu_quat,
            imu_ang_vel=obs.imu_ang_vel, imu_lin_acc=obs.imu_lin_acc, foot_contact=obs.foot_contact,
            base_pos=base_pos, base_quat=base_quat, compute_time=compute,
            step_period=time.perf_counter() - start, motor_kp=kp, motor_kd=kd,
        )
        obs = new_obs
        if on_step is not None:
            on_step(obs)
        if robot.fallen:
            fall_time = obs.time
            if stop_on_fall:
                break
        if policy.done:
            break
    log = recorder.finish(robot.motor_names, robot.joint_names, robot.control_dt, policy.name)
    fell = fall_time is not None
    return RunResult(log=log, fell=fell, fall_time=fall_time, completed=not fell)
