"""The control loop's delays of a real robot, reproduced on the simulated one.

On hardware a policy's targets act some milliseconds after the observation they answer (bus read, policy, bus
write), its IMU reading is older than its motor angles, and control periods are not exactly equal. The simulator
has none of that: targets act at once and every reading is fresh. `DelayedRobot` adds these delays, at the
physics step's resolution, to `MuJoCoRobot`, so that a controller's margin against them is measured in the
simulator (walk-zmp fell in hardware-in-the-loop where the simulator walked: docs/hardware.md).

    robot = DelayedRobot(description, HIL_LOOP_DELAY.scaled(2))
"""

from __future__ import annotations

import collections
import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig


@dataclass(frozen=True)
class LoopDelay:
    """Delays of one control loop, in physics steps (ms at the spec's 1 ms timestep)."""

    target_ms: int = 0
    """The previous targets still act this long after each observation; then the new ones do."""
    imu_ms: int = 0
    """The IMU reading is this much older than the motor angles it comes with."""
    jitter_ms: int = 0
    """Each control period lasts the nominal one +- this much, uniformly at random."""
    seed: int = 0
    """Seed of the period jitter."""

    def __post_init__(self) -> None:
        for name in ("target_ms", "imu_ms", "jitter_ms"):
            if getattr(self, name) < 0:
                raise ValueError(f"LoopDelay.{name} must be >= 0 ms, got {getattr(self, name)}")

    def scaled(self, factor: float) -> LoopDelay:
        """The target delay and IMU age multiplied by ``factor`` (the jitter kept)."""
        return dataclasses.replace(self, target_ms=round(self.target_ms * factor), imu_ms=round(self.imu_ms * factor))

    def describe(self) -> str:
        return f"targets {self.target_ms} ms late, IMU {self.imu_ms} ms old, periods +-{self.jitter_ms} ms"


HIL_LOOP_DELAY = LoopDelay(target_ms=5, imu_ms=10, jitter_ms=4)
"""The loop of `hw run` against `hw emulate --hil`, measured on the 2-core VM (docs/hardware.md): targets act about
5 ms after the observation, the IMU reading is on average 10 ms old (the emulated BNO08x's 5 ms latency plus half
its 10 ms report interval; `tests/test_loop_delay.py` keeps the two in step), periods last 15.9-24.3 ms (1st-99th
percentile)."""


class DelayedRobot(MuJoCoRobot):
    """`MuJoCoRobot` whose targets act late, whose IMU reading is old and whose control periods jitter
    (`LoopDelay`)."""

    def __init__(self, description: RobotDescription | None, delay: LoopDelay, config: SimConfig | None = None,
                 model: mujoco.MjModel | None = None) -> None:
        self.delay = delay
        self._rng = np.random.default_rng(delay.seed)
        self._sensor_history: collections.deque[np.ndarray] = collections.deque(maxlen=delay.imu_ms + 1)
        super().__init__(description, config, model=model)  # resets, so the history exists first
        if delay.jitter_ms >= self.n_substeps:
            raise ValueError(f"LoopDelay.jitter_ms {delay.jitter_ms} must be < the control period "
                             f"({self.n_substeps} physics steps)")

    def reset(self) -> Observation:
        obs = super().reset()
        self._sensor_history.clear()
        self._sensor_history.append(self.data.sensordata.copy())
        return obs

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        jitter = self.delay.jitter_ms
        period = self.n_substeps + (int(self._rng.integers(-jitter, jitter + 1)) if jitter else 0)
        late = min(self.delay.target_ms, period)
        for step in range(period):
            if step == late:
                self.command(motor_targets, kp, kd)
            self.advance(1)
            self._sensor_history.append(self.data.sensordata.copy())
        if late == period:
            self.command(motor_targets, kp, kd)
        self._check_stable()
        obs = self.observe()
        old = self._sensor_history[0]  # imu_ms steps ago (or the oldest kept, just after a reset)
        return dataclasses.replace(obs, imu_quat=old[self._imu["imu_quat"]].copy(),
                                   imu_ang_vel=old[self._imu["imu_gyro"]].copy(),
                                   imu_lin_acc=old[self._imu["imu_accel"]].copy())
