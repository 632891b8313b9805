"""Walking in the simulator under what hardware-in-the-loop adds, one effect at a time.

`hw run` against `hw emulate --hil` differs from the simulator in five measured ways, each reproduced here on
`MuJoCoRobot`: the targets take effect some ms after the observation (bus read, policy, bus write); each
control period lasts 20 +- the jitter (HIL's own: 15.9-24.3 ms, 1st-99th percentile); the IMU reading is
some ms old (on average: 10 ms reports, each 5 ms late); motor angles come in 4,096 ticks per turn; and the
command guard slew-limits targets as on hardware (`robot.safety.SLEW_SPEEDS` x the no-load speed, or
``--slew``). The delays are `toddlerbot.sim.loop_delay.DelayedRobot`'s. Printed: falls, the yaw turned, where
the torso ends (dx, dy in the start heading's frame) and the position error `eval tracking` computes, per seed,
with none of the effects (the simulator), with all of them, then with each one left out (the ablation that found
the slew limit's part in walk-zmp's HIL falls; docs/hardware.md), then with the delays scaled (the margin a slower
host or the real robot's bus needs).

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
from toddlerbot.runtime.summary import RunSummary, summarize
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS
from toddlerbot.sim.loop_delay import HIL_LOOP_DELAY, DelayedRobot, LoopDelay


@dataclasses.dataclass(frozen=True)
class HilEffects:
    delay: LoopDelay = HIL_LOOP_DELAY
    """Late targets, IMU age and period jitter (`DelayedRobot`; the seed is each run's)."""
    ticks: bool = True
    """Motor angles rounded to the bus's 4,096 ticks per turn."""
    slew: float = SLEW_SPEEDS
    """Slew limit in no-load speeds (0: none)."""


class HilLikeRobot(DelayedRobot):
    """The simulated robot as `hw run` sees the HIL emulator's (`HilEffects`): the loop's delays of `DelayedRobot`,
    the bus's rounding of motor angles and the hardware's slew limit."""

    def __init__(self, description: RobotDescription, effects: HilEffects, seed: int) -> None:
        super().__init__(description, dataclasses.replace(effects.delay, seed=seed))
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


def walks(description: RobotDescription, policy: str, effects: HilEffects, seeds: int) -> list[RunSummary]:
    """One run's summary per seed of the period jitter, over the default tracking schedule."""
    out = []
    for seed in range(seeds):
        robot = HilLikeRobot(description, effects, seed)
        result = run_policy(robot, make_policy(policy, robot), CommandSchedule.parse(DEFAULT_COMMANDS),
                            DEFAULT_SECONDS, stop_on_fall=True)
        out.append(summarize(result.log, result.fell, result.fall_time))
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
    without = {"late": {"delay": dataclasses.replace(every.delay, target_ms=0)},
               "jitter": {"delay": dataclasses.replace(every.delay, jitter_ms=0)},
               "imu_age": {"delay": dataclasses.replace(every.delay, imu_ms=0)},
               "ticks": {"ticks": False}, "slew": {"slew": 0.0}}
    rows = [("no effect", HilEffects(delay=LoopDelay(), ticks=False, slew=0.0)), ("all effects", every),
            *((f"without {name}", dataclasses.replace(every, **change)) for name, change in without.items()),
            *((f"delays x{f:g}", dataclasses.replace(every, delay=every.delay.scaled(f)))
              for f in map(float, args.delay_scales.split(",")) if f)]
    for label, effects in rows:
        start = time.perf_counter()
        runs = walks(description, args.policy, effects, args.seeds)
        fell = [f"{run.fall_time_s:.1f} s" for run in runs if run.fell]
        yaws = ", ".join(f"{run.yaw_change_rad:.2f}" for run in runs)
        ends = ", ".join("({:.3f}, {:.3f})".format(*run.displacement_m) for run in runs)
        errors = ", ".join(f"{run.tracking.position_m:.3f}" for run in runs)
        delay = effects.delay
        print(f"{label:18s} ({delay.target_ms} ms late, IMU {delay.imu_ms} ms) falls {len(fell)}/{len(runs)} {fell}, "
              f"yaw turned {yaws} rad, ends at dx, dy {ends} m, position error {errors} m "
              f"({time.perf_counter() - start:.0f} s wall)", flush=True)


if __name__ == "__main__":
    main()
