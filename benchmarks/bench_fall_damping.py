"""What the motors do while the robot falls, with and without the shared layer's lowered gains (`robot.fall`).

Each trial walks the nominal robot with walk-rl at a seeded command within its reach, kicks it once after 2 s with a
seeded horizontal velocity of 1-2 m/s in a seeded direction, and, once the fall is detected, hands it to a policy
that holds the motors where they are (what a recovery does until the robot lands) for 1.5 s. Over that window it
measures, per trial: the largest motor torque as a fraction of the motor's torque limit (``tau_max``), the largest
motor speed as a fraction of its no-load speed, and the motor-seconds spent at the torque limit. Printed: the mean
and largest over the trials that fell, with the gains lowered (the default) and at full gains, and the machine.

Run: PYTHONPATH=src python benchmarks/bench_fall_damping.py [--trials 20] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np

from toddlerbot.locomotion.config import WALK_REACH
from toddlerbot.policies import make_policy
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.fall import FALL_KP_FRACTION, FallGuard
from toddlerbot.runtime.robustness import DirectedKick
from toddlerbot.runtime.runner import RunObserver, Step, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimulationError

KICK_TIME_S, HOLD_S = 2.0, 1.5


class HoldWhereItIs(Policy):
    """Holds every motor at its angle when the fall was detected; gives up after `HOLD_S`."""

    name = "hold"
    start: float | None = None
    """s when the fall handed it the robot; None before."""

    def reset(self, obs):
        self.start, self.pose = obs.time, obs.motor_pos.copy()

    def act(self, obs, command):
        return Action(self.pose, self.transmission.matrix @ self.pose)

    @property
    def done(self) -> bool:
        return self.robot.observe().time - self.start >= HOLD_S

    @property
    def succeeded(self) -> bool:
        return False


class FallWindow(RunObserver):
    """Peak torque and speed fractions, and motor-seconds at the torque limit, from the fall's detection on."""

    def __init__(self, tau_max: np.ndarray, speed_max: np.ndarray, hold: HoldWhereItIs) -> None:
        self.tau_max, self.speed_max, self.hold = tau_max, speed_max, hold
        self.torque = self.speed = self.at_limit = 0.0

    def on_step(self, step: Step) -> None:
        if self.hold.start is None:
            return
        obs = step.next_obs
        torque = np.abs(obs.motor_torque) / self.tau_max
        self.torque = max(self.torque, float(torque.max()))
        self.speed = max(self.speed, float((np.abs(obs.motor_vel) / self.speed_max).max()))
        self.at_limit += float(np.sum(torque >= 0.99)) * (obs.time - step.obs.time)


def trial(description: RobotDescription, seed: int, kp_fraction: float) -> FallWindow | str | None:
    """The fall's figures, ``"diverged"`` where the simulation did, or None without a fall."""
    rng = np.random.default_rng([seed, 41])
    command = rng.uniform(WALK_REACH.low, WALK_REACH.high)
    speed, direction = rng.uniform(1.0, 2.0), rng.uniform(0.0, 2 * np.pi)
    robot = MuJoCoRobot(description)
    robot.fall_guard = FallGuard(robot.control_dt, kp_fraction)
    hold = HoldWhereItIs(robot)
    tau_max = np.array([p.tau_max for p in description.actuator_params])
    window = FallWindow(tau_max, np.asarray(description.max_motor_speed), hold)
    try:
        result = run_policy(robot, make_policy("walk-rl", robot, synchronous=True), lambda t: command,
                            KICK_TIME_S + 4.0, observers=[DirectedKick(robot, speed, direction, KICK_TIME_S), window],
                            recovery=hold)
    except SimulationError:
        return "diverged"
    return window if result.falls else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    description = RobotDescription.load()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"{args.trials} kicks of 1-2 m/s during walk-rl, seeds {args.seed}-{args.seed + args.trials - 1}")
    for label, fraction in ((f"lowered gains ({FALL_KP_FRACTION:g} x kp)", FALL_KP_FRACTION), ("full gains", 1.0)):
        outcomes = [trial(description, args.seed + k, fraction) for k in range(args.trials)]
        windows = [w for w in outcomes if isinstance(w, FallWindow)]
        torque = np.array([w.torque for w in windows])
        speed = np.array([w.speed for w in windows])
        limit = np.array([w.at_limit for w in windows])
        print(f"{label}: {len(windows)} falls, {outcomes.count('diverged')} simulations diverged; peak torque / "
              f"tau_max mean {torque.mean():.2f}, max {torque.max():.2f}; peak speed / no-load speed mean "
              f"{speed.mean():.2f}, max {speed.max():.2f}; motor-seconds at the torque limit mean {limit.mean():.2f},"
              f" max {limit.max():.2f}", flush=True)


if __name__ == "__main__":
    main()
