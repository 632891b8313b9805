"""Walking in the simulator under what hardware-in-the-loop adds, one effect at a time.

`hw run` against `hw emulate --hil` differs from the simulator in five measured ways, each reproduced here on
`MuJoCoRobot`: the targets take effect ``late`` ms after the observation (bus read, policy, bus write); each
control period lasts 20 +- ``jitter`` ms (HIL's own: 15.9-24.3 ms, 1st-99th percentile); the IMU reading is
``imu_age`` ms old (on average: 10 ms reports, each 5 ms late); motor angles come in 4,096 ticks per turn; and the
command guard slew-limits targets as on hardware (`robot.safety.SLEW_SPEEDS` x the no-load speed, or
``--slew``). Printed: falls over seeds with all effects, then with each one left out (the ablation that found the
slew limit's part in walk-zmp's HIL falls; docs/hardware.md).

Run: PYTHONPATH=src python benchmarks/bench_hil_like.py [--policy walk-zmp] [--seeds 5] [--slew 2.0]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time

import numpy as np

from toddlerbot.hardware.control_table import RAD_PER_PULSE
from toddlerbot.hardware.imu import REPORT_INTERVAL_S
from toddlerbot.hardware.imu_stream import LATENCY_S
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.robot.safety import SLEW_SPEEDS, slew_step
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

EFFECTS = ("late", "jitter", "imu_age", "ticks", "slew")
IMU_AGE_MS = round(1000 * (LATENCY_S + REPORT_INTERVAL_S / 2))
"""Mean age of the emulated IMU's newest report when read: its latency plus half its report interval (10 ms)."""


@dataclasses.dataclass(frozen=True)
class HilEffects:
    late: int = 5
    """ms (physics steps) the previous targets still act after an observation."""
    jitter: int = 4
    """Each control period lasts 20 +- this many ms, uniformly."""
    imu_age: int = IMU_AGE_MS
    """ms by which the IMU reading precedes the observation."""
    ticks: bool = True
    """Motor angles rounded to the bus's 4,096 ticks per turn."""
    slew: float = SLEW_SPEEDS
    """Slew limit in no-load speeds (0: none)."""


class HilLikeRobot(MuJoCoRobot):
    """The simulated robot as `hw run` sees the HIL emulator's (`HilEffects`)."""

    def __init__(self, description: RobotDescription, effects: HilEffects, seed: int) -> None:
        super().__init__(description)
        self.effects, self.rng = effects, np.random.default_rng(seed)
        if effects.slew:
            self.guard = dataclasses.replace(self.guard, max_step=slew_step(description.max_motor_speed,
                                                                            self.control_dt, effects.slew))

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        e = self.effects
        period = self.n_substeps + (int(self.rng.integers(-e.jitter, e.jitter + 1)) if e.jitter else 0)
        if e.late:
            self.advance(e.late)  # the previous targets still act
        self.command(motor_targets, kp, kd)
        self.advance(period - e.late - e.imu_age)
        imu = self.data.sensordata.copy()
        if e.imu_age:
            self.advance(e.imu_age)
        obs = self.observe()
        q = np.round(obs.motor_pos / RAD_PER_PULSE) * RAD_PER_PULSE if e.ticks else obs.motor_pos
        s = self._imu
        return dataclasses.replace(obs, motor_pos=q, joint_pos=self._A @ q, imu_quat=imu[s["imu_quat"]],
                                   imu_ang_vel=imu[s["imu_gyro"]], imu_lin_acc=imu[s["imu_accel"]])


def falls(description: RobotDescription, policy: str, effects: HilEffects, seeds: int) -> list[float | None]:
    """Fall time (s) or None per seed, over the default tracking schedule."""
    out = []
    for seed in range(seeds):
        robot = HilLikeRobot(description, effects, seed)
        result = run_policy(robot, make_policy(policy, robot), CommandSchedule.parse(DEFAULT_COMMANDS),
                            DEFAULT_SECONDS, stop_on_fall=True)
        out.append(float(result.log.time[-1]) if result.fell else None)
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--slew", type=float, default=SLEW_SPEEDS)
    args = parser.parse_args()
    description = RobotDescription.load()
    print(f"{args.policy}, default schedule ({DEFAULT_SECONDS:.0f} s), {args.seeds} seeds, slew {args.slew} x "
          f"no-load speed; {platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    every = HilEffects(slew=args.slew)
    off = {"late": 0, "jitter": 0, "imu_age": 0, "ticks": False, "slew": 0.0}
    for label, effects in [("all effects", every),
                           *((f"without {name}", dataclasses.replace(every, **{name: off[name]})) for name in EFFECTS)]:
        start = time.perf_counter()
        times = falls(description, args.policy, effects, args.seeds)
        fell = [f"{t:.1f} s" for t in times if t is not None]
        print(f"{label:18s} falls {len(fell)}/{len(times)} {fell} ({time.perf_counter() - start:.0f} s wall)",
              flush=True)


if __name__ == "__main__":
    main()
