"""A chain on any `Robot` in real time (the real robot), run by `runtime.run_policy` with a `WallClock`: no scene
probe, so only predicates with a hardware form, ``after`` and buttons switch; a fall stops it (a failure); the robot
is closed (torque off) however the run ends."""

from __future__ import annotations

from collections.abc import Callable

from toddlerbot.robot.interface import Robot
from toddlerbot.runtime.runner import RunObserver, Step, WallClock, run_policy
from toddlerbot.skills import skill_kind
from toddlerbot.skills.runner import ChainRunner, ChainStatus, time_limit
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.scenes import scene_model

BUTTON_WAIT_S = 3600.0
"""Longest a skill waiting for a button (or a predicate) without a timeout may run on a robot, s."""


def needs_imu(chain: ChainSpec) -> bool:
    """Does a skill of `chain` balance from the IMU (a walk)?"""
    return any(skill_kind(s.kind).needs_imu for s in chain.skills + chain.recovery)


class SwitchReporter(RunObserver):
    """Says each switch, retry and recover of the chain as it happens (``grasp -> wait at 0.90 s``, ``recover push
    at 7.52 s, on from grasp``)."""

    def __init__(self, chain: ChainRunner, say: Callable[[str], None]) -> None:
        self.chain, self.say, self.reported, self.recoveries = chain, say, 0, 0

    def on_step(self, step: Step) -> None:
        status = self.chain.status
        for r in status.recoveries[self.recoveries:]:
            self.say(f"{r.kind} {r.skill} at {r.time_s:.2f} s, on from {r.resume}")
        for a, b, t in status.switches[self.reported:]:
            self.say(f"{a} -> {b} at {t:.2f} s")
        self.reported, self.recoveries = len(status.switches), len(status.recoveries)


def run_on_robot(chain: ChainSpec, robot: Robot, buttons: Callable[[], frozenset[str]] = frozenset,
                 on_switch: Callable[[str], None] = lambda _: None) -> ChainStatus:
    """Reset, run the chain to its end at the control rate, close the robot; `buttons` gives the held buttons."""
    try:
        runner = ChainRunner(chain, robot, scene_model(robot.description, chain.scene), buttons=buttons)
        result = run_policy(robot, runner, seconds=time_limit(chain, BUTTON_WAIT_S), clock=WallClock(),
                            observers=[SwitchReporter(runner, on_switch)])
        status = runner.status
        if result.fell:
            status.failure = f"the robot fell at {result.fall_time:.2f} s (skill {status.skill})"
        elif not status.done:
            status.failure = "did not end in time"
        return status
    finally:
        robot.close()
