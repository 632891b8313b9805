"""Simulation speed on one core: the set-up of a walk-zmp run (robot description, simulator, gait generator: one
spec parse and one compile per model), raw MuJoCo stepping of the floating robot versus our loop (actuator model
every 1 ms physics step, observation assembly, target clamping) holding the home pose, and the full walk-zmp loop.

Run: PYTHONPATH=src python benchmarks/bench_sim.py
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from toddlerbot.policies.walk_zmp import WalkZMPPolicy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

SECONDS = 5.0


def main() -> None:
    start = time.perf_counter()
    robot = MuJoCoRobot(RobotDescription.load())
    policy = WalkZMPPolicy(robot)
    setup = time.perf_counter() - start
    print(f"walk-zmp set-up:            {setup * 1e3:8.0f} ms (description, simulator, gait generator and leg IK)")

    m, d = robot.model, mujoco.MjData(robot.model)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    n = round(SECONDS / m.opt.timestep)
    start = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    raw = time.perf_counter() - start
    print(f"raw mj_step:                {n / raw:8.0f} physics steps/s  real-time factor {SECONDS / raw:5.2f}")

    obs = robot.reset()
    steps = round(SECONDS / robot.control_dt)
    start = time.perf_counter()
    for _ in range(steps):
        robot.step(obs.motor_pos)
    ours = time.perf_counter() - start
    print(f"MuJoCoRobot.step (hold):    {steps / ours:8.0f} control steps/s  real-time factor {SECONDS / ours:5.2f}  "
          f"(overhead vs raw {100 * (ours / raw - 1):.0f}%)")

    start = time.perf_counter()
    run_policy(robot, policy, lambda t: np.array([0.1, 0.0, 0.0]), SECONDS)
    walk = time.perf_counter() - start
    print(f"walk-zmp policy loop:       {steps / walk:8.0f} control steps/s  real-time factor {SECONDS / walk:5.2f}")


if __name__ == "__main__":
    main()
