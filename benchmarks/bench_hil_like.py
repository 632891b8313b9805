"""Walking in the simulator under what hardware-in-the-loop adds, one effect at a time.

`hw run` against `hw emulate --hil` differs from the simulator in five measured ways, each reproduced here on
`MuJoCoRobot`: the targets take effect ``late`` ms after the observation (bus read, policy, bus write); each
control period lasts 20 +- ``jitter`` ms (HIL's own: 15.9-24.3 ms, 1st-99th percentile); the IMU reading is
``imu_age`` ms old (on average: 10 ms reports, each 5 ms late); motor angles come in 4,096 ticks per turn; and the
command guard slew-limits targets as on hardware (`robot.safety.SLEW_SPEEDS` x the no-load speed, or
``--slew``). The delays are `toddlerbot.sim.loop_delay.DelayedRobot`'s. Printed: falls and the yaw turned over
seeds with all effects, then with each one left out (the ablation that found the slew limit's part in walk-zmp's
HIL falls; docs/hardware.md), then with the delays scaled (the margin a slower host or the real robot's bus needs).

Run: PYTHONPATH=src python benchmarks/bench_hil_like.py [--policy walk-zmp] [--seeds 5] [--slew 2.0] \
         [--delay-scales 2,3]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time

import numpy as np

from toddlerbot.hardware.control_table import RAD_PER_PULSE
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.robot.safety import SLEW_SPEEDS, slew_step
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS, heading
from toddlerbot.sim.loop_delay import HIL_LOOP_DELAY, DelayedRobot, LoopDelay

EFFECTS = ("late", "jitter", "imu_age", "ticks", "slew")


@dataclasses.dataclass(frozen=True)
class HilEffects:
    late: int = HIL_LOOP_DELAY.target_ms
    """ms (physics steps) the previous targets still act after an observation."""
    jitter: int = HIL_LOOP_DELAY.jitter_ms
    """Each control period lasts 20 +- this many ms, uniformly."""
    imu_age: int = HIL_LOOP_DELAY.imu_ms
    """ms by which the IMU reading precedes the observation."""
    ticks: bool = True
    """Motor angles rounded to the bus's 4,096 ticks per turn."""
    slew: float = SLEW_SPEEDS
    """Slew limit in no-load speeds (0: none)."""

    def scaled(self, factor: float) -> HilEffects:
        """The late targets and the IMU age multiplied by ``factor``."""
        return dataclasses.replace(self, late=round(self.late * factor), imu_age=round(self.imu_age * factor))


class HilLikeRobot(DelayedRobot):
    """The simulated robot as `hw run` sees the HIL emulator's (`HilEffects`): the loop's delays of `DelayedRobot`,
    the bus's rounding of motor angles and the hardware's slew limit."""

    def __init__(self, description: RobotDescription, effects: HilEffects, seed: int) -> None:
        super().__init__(description, LoopDelay(effects.late, effects.imu_age, effects.jitter, seed))
        self.effects = effects
        if effects.slew:
            self.guard = dataclasses.replace(self.guard, max_step=slew_step(description.max_motor_speed,
                                                                            self.control_dt, effects.slew))

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        obs = super()._apply(motor_targets, kp, kd)
        if not self.effects.ticks:
            return obs
        q = np.round(obs.motor_pos / RAD_PER_PULSE) * RAD_PER_PULSE
        return dataclasses.replace(obs, motor_pos=q, joint_pos=self._A @ q)


def walks(description: RobotDescription, policy: str, effects: HilEffects,
          seeds: int) -> list[tuple[float | None, float]]:
    """(fall time in s or None, yaw turned in rad) per seed, over the default tracking schedule."""
    out = []
    for seed in range(seeds):
        robot = HilLikeRobot(description, effects, seed)
        result = run_policy(robot, make_policy(policy, robot), CommandSchedule.parse(DEFAULT_COMMANDS),
                            DEFAULT_SECONDS, stop_on_fall=True)
        yaw = np.unwrap(heading(np.asarray(result.log.base_quat)))
        out.append((float(result.log.time[-1]) if result.fell else None, float(yaw[-1] - yaw[0])))
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--slew", type=float, default=SLEW_SPEEDS)
    parser.add_argument("--delay-scales", default="2,3", help="comma-separated factors on the late targets and the "
                                                              "IMU age, each a row with every effect")
    args = parser.parse_args()
    description = RobotDescription.load()
    print(f"{args.policy}, default schedule ({DEFAULT_SECONDS:.0f} s, {DEFAULT_COMMANDS}), {args.seeds} seeds, slew "
          f"{args.slew} x no-load speed; {platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    every = HilEffects(slew=args.slew)
    off = {"late": 0, "jitter": 0, "imu_age": 0, "ticks": False, "slew": 0.0}
    rows = [("all effects", every),
            *((f"without {name}", dataclasses.replace(every, **{name: off[name]})) for name in EFFECTS),
            *((f"delays x{f:g}", every.scaled(f)) for f in map(float, args.delay_scales.split(",")) if f)]
    for label, effects in rows:
        start = time.perf_counter()
        runs = walks(description, args.policy, effects, args.seeds)
        fell = [f"{t:.1f} s" for t, _ in runs if t is not None]
        yaws = ", ".join(f"{y:.2f}" for _, y in runs)
        print(f"{label:18s} ({effects.late} ms late, IMU {effects.imu_age} ms) falls {len(fell)}/{len(runs)} {fell}, "
              f"yaw turned {yaws} rad ({time.perf_counter() - start:.0f} s wall)", flush=True)


if __name__ == "__main__":
    main()
