"""A chain on any `Robot` in real time (the real robot): no scene probe, so only predicates with a hardware form,
``after`` and buttons switch; the robot is closed (torque off) however the run ends."""

from __future__ import annotations

import time
from collections.abc import Callable

from toddlerbot.robot.interface import Robot
from toddlerbot.skills.runner import ChainRunner, ChainStatus
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.scenes import scene_model


def run_on_robot(chain: ChainSpec, robot: Robot, buttons: Callable[[], frozenset[str]] = frozenset,
                 on_switch: Callable[[str], None] = lambda _: None) -> ChainStatus:
    """Reset, run the chain to its end at the control rate, close the robot; `buttons` gives the held buttons."""
    try:
        runner = ChainRunner(chain, robot, scene_model(robot.description, chain.scene))
        obs = robot.reset()
        runner.start(obs, obs.motor_pos if robot.last_targets is None else robot.last_targets)
        next_tick = time.monotonic()
        reported = 0
        while (command := runner.step(obs, buttons())) is not None:
            obs = robot.step(*command)
            for a, b, t in runner.status.switches[reported:]:
                on_switch(f"{a} -> {b} at {t:.2f} s")
            reported = len(runner.status.switches)
            next_tick += robot.control_dt
            time.sleep(max(0.0, next_tick - time.monotonic()))
        return runner.status
    finally:
        robot.close()
