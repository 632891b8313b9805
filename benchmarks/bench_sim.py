"""Simulation speed on one core: the set-up of a walk-zmp run (robot description, simulator, gait generator: one
spec parse and one compile per model), our actuated step (`MuJoCoRobot.step` holding the home pose: the actuator
model every 1 ms physics step, observation assembly, target clamping) against raw ``mj_step`` of the same motion,
and the full walk-zmp loop.

The raw loop replays the motor torques that the actuated run applied, recorded once through MuJoCo's control
callback, from the same start state: the same physics bit for bit (checked), so the ratio of the two is what the
actuator model and our bookkeeping add. Both loops are timed in CPU time of this thread (`time.thread_time`: time
the OS gives other jobs does not count), alternate for ``ROUNDS`` rounds, and each keeps its fastest round; the
real-time factors are CPU-time ones too. The set-up and the walk-zmp loop are timed by the wall clock.

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

SECONDS = 2.0
"""Simulated time per round of each stepping loop."""
ROUNDS = 7


def record_torques(robot: MuJoCoRobot, hold: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The actuator torques (ctrl) of every physics step of ``steps`` control steps holding ``hold``, and the final
    qpos."""
    torques: list[np.ndarray] = []
    robot.reset()
    mujoco.set_mjcb_control(lambda m, d: torques.append(d.ctrl.copy()))
    try:
        for _ in range(steps):
            robot.step(hold)
    finally:
        mujoco.set_mjcb_control(None)
    return np.array(torques), robot.data.qpos.copy()


def time_raw(robot: MuJoCoRobot, torques: np.ndarray) -> tuple[float, np.ndarray]:
    """Wall time of raw ``mj_step`` replaying ``torques`` from the robot's reset state, and the final qpos."""
    robot.reset()
    m, d = robot.model, mujoco.MjData(robot.model)
    mujoco.mj_copyData(d, m, robot.data)
    ctrl, step = d.ctrl, mujoco.mj_step
    start = time.thread_time()
    for u in torques:
        ctrl[:] = u
        step(m, d)
    return time.thread_time() - start, d.qpos.copy()


def time_actuated(robot: MuJoCoRobot, hold: np.ndarray, steps: int) -> float:
    robot.reset()
    start = time.thread_time()
    for _ in range(steps):
        robot.step(hold)
    return time.thread_time() - start


def main() -> None:
    start = time.perf_counter()
    robot = MuJoCoRobot(RobotDescription.load())
    policy = WalkZMPPolicy(robot)
    setup = time.perf_counter() - start
    print(f"walk-zmp set-up:            {setup * 1e3:8.0f} ms (description, simulator, gait generator and leg IK)")

    hold = robot.reset().motor_pos
    steps = round(SECONDS / robot.control_dt)
    torques, final = record_torques(robot, hold, steps)
    raw, ours = np.inf, np.inf
    for _ in range(ROUNDS):
        elapsed, replayed = time_raw(robot, torques)
        if not np.array_equal(replayed, final):
            raise RuntimeError("the raw replay left the actuated run's trajectory: the comparison would be unfair")
        raw, ours = min(raw, elapsed), min(ours, time_actuated(robot, hold, steps))
    print(f"raw mj_step (same motion):  {len(torques) / raw:8.0f} physics steps/s  "
          f"real-time factor {SECONDS / raw:5.2f}")
    print(f"MuJoCoRobot.step (hold):    {steps / ours:8.0f} control steps/s  real-time factor {SECONDS / ours:5.2f}")
    print(f"actuated / raw time:        {ours / raw:8.3f}  (overhead {100 * (ours / raw - 1):.1f}%, "
          f"{(ours - raw) / len(torques) * 1e6:.1f} us per physics step; fastest of {ROUNDS} alternating rounds)")

    walk_steps = round(5.0 / robot.control_dt)
    start = time.perf_counter()
    run_policy(robot, policy, lambda t: np.array([0.1, 0.0, 0.0]), 5.0)
    walk = time.perf_counter() - start
    print(f"walk-zmp policy loop:       {walk_steps / walk:8.0f} control steps/s  real-time factor {5.0 / walk:5.2f}")


if __name__ == "__main__":
    main()
