"""The real robot behind the `Robot` interface: Dynamixel bus + zero-point calibration + IMU.

Motor angles are ``q = (reading - offset - turns * 4096) * 2*pi/4096``: `offset` from the per-robot calibration
file, `turns` chosen once at start-up so that each motor lies within half a turn of the middle of its joint range
(the multi-turn count is lost at every power-up). Policies command motor angles (rad) and firmware gains, as
in the simulator; the spec's transmission map gives the joint-space view.

Before torque is enabled, every motor's calibrated angle must lie within its joint range widened by
`startup_margin` (a wrong calibration offset or a robot assembled off by a turn is caught while the motors are
still limp); otherwise `StartupCheckError` names the motors and torque stays off.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from toddlerbot.hardware.calibration import Calibration
from toddlerbot.hardware.control_table import PULSES_PER_REV, pulses_to_rad, rad_to_pulses
from toddlerbot.hardware.driver import (
    DEFAULT_BAUDRATE,
    DEFAULT_RETRIES,
    DynamixelBus,
    HardwareError,
    MotorState,
    motors_of,
)
from toddlerbot.hardware.imu import Imu, StaticImu
from toddlerbot.hardware.imu_stream import Pose, StreamMocap
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT, GroundTruth, Observation, Robot, tilt
from toddlerbot.robot.safety import slew_step

STARTUP_MARGIN = 0.25
"""How far (rad) outside its joint range a limp motor may read at start-up before the calibration or the
robot's pose is called implausible (a joint resting on its hard stop sits a little past the spec's range)."""


class StartupCheckError(HardwareError):
    """At start-up a motor read an angle far outside its joint range: torque was not enabled."""


class RealRobot(Robot):
    """ToddlerBot on its Dynamixel bus. Use as a context manager: torque is disabled on exit, errors and Ctrl-C."""

    def __init__(
        self,
        description: RobotDescription,
        port: str,
        calibration: Calibration,
        control_dt: float = CONTROL_DT,
        baudrate: int = DEFAULT_BAUDRATE,
        imu: Imu | None = None,
        reset_duration: float = 2.0,
        calibration_source: str = "calibration",
        retries: int = DEFAULT_RETRIES,
        startup_margin: float = STARTUP_MARGIN,
        latency_ms: float | None = None,
    ) -> None:
        super().__init__(description, control_dt, max_step=slew_step(description.max_motor_speed, control_dt))
        self.offsets = calibration.offsets_for(description, calibration_source)
        self.calibration_source = calibration_source
        self.bus = DynamixelBus(port, motors_of(description), baudrate=baudrate, retries=retries,
                                latency_ms=latency_ms)
        self.startup_margin = startup_margin
        self.imu = imu or StaticImu()
        self.reset_duration = reset_duration
        self.turns = np.zeros(len(self.offsets), dtype=np.int64)
        self.lower, self.upper = description.motor_range.T
        self.range_mid = np.where(np.isfinite(self.lower + self.upper), (self.lower + self.upper) / 2, 0.0)
        self._gains: tuple[np.ndarray, np.ndarray] | None = None
        self._t0 = 0.0
        self._deadline = 0.0
        self._last: Observation | None = None

    # ---- conversions -----------------------------------------------------------------------------------
    def resolve_turns(self, pulses: np.ndarray) -> None:
        """Choose each motor's whole turns so that its angle lies within half a turn of its range's middle."""
        raw = pulses_to_rad(pulses - self.offsets)
        self.turns = np.rint((raw - self.range_mid) / (2 * np.pi)).astype(np.int64)

    def _angles(self, pulses: np.ndarray) -> np.ndarray:
        """Calibrated motor angles (rad) from raw readings (pulses)."""
        return pulses_to_rad(pulses - self.offsets - self.turns * PULSES_PER_REV)

    def _pulses(self, angles: np.ndarray) -> np.ndarray:
        """Raw goal positions (pulses) from motor angles (rad)."""
        return rad_to_pulses(angles) + self.offsets + self.turns * PULSES_PER_REV

    def _observation(self, state: MotorState) -> Observation:
        q = self._angles(state.position)
        imu = self.imu.read()
        tm = self.transmission
        return Observation(
            time=time.perf_counter() - self._t0, motor_pos=q, motor_vel=state.velocity, motor_torque=state.torque,
            joint_pos=tm.motor_to_joint(q), joint_vel=tm.motor_to_joint(state.velocity), imu_quat=imu.quat,
            imu_ang_vel=imu.ang_vel, imu_lin_acc=imu.lin_acc, foot_contact=np.zeros(2, dtype=bool),
        )

    # ---- Robot -----------------------------------------------------------------------------------------
    def reset(self) -> Observation:
        """Open, check and configure the bus, enable torque where the motors are, then move to the home pose
        over `reset_duration` seconds."""
        bus = self.bus
        if not bus.is_open:
            bus.open()
        try:
            bus.scan()
            bus.configure()
            bus.check_voltage()
            state = bus.read_state()
            self.resolve_turns(state.position)
            self.check_startup_pose(self._angles(state.position))
            bus.enable_torque(state.position)
            self._gains = (self.default_kp.copy(), self.default_kd.copy())
            self.fall_guard.reset()
            self._t0 = self._deadline = time.perf_counter()
            start, home = self._angles(state.position), self.description.home_motor_pos
            self.last_targets = start
            steps = max(1, round(self.reset_duration / self.control_dt))
            obs = None
            for k in range(1, steps + 1):
                obs = self.step(start + (home - start) * k / steps)
        except BaseException:
            bus.close()
            raise
        self._t0 = time.perf_counter()
        self._last = dataclasses.replace(obs, time=0.0)  # time counts from the end of the reset
        return self._last

    def check_startup_pose(self, angles: np.ndarray) -> None:
        """Refuse (`StartupCheckError`) if any motor angle (rad) lies beyond its range +- `startup_margin`."""
        low, high = self.lower - self.startup_margin, self.upper + self.startup_margin
        bad = np.flatnonzero((angles < low) | (angles > high))
        if bad.size:
            worst = ", ".join(
                f"{self.motor_names[i]} reads {angles[i]:+.2f} rad, range [{self.lower[i]:+.2f}, {self.upper[i]:+.2f}]"
                for i in bad[:3]
            )
            raise StartupCheckError(
                f"start-up check failed, torque stays off: {bad.size} motor(s) outside their range +-"
                f"{self.startup_margin:g} rad ({worst}{' ...' if bad.size > 3 else ''}); "
                f"check {self.calibration_source} and the robot's pose"
            )

    def observe(self) -> Observation:
        if self._last is None:
            raise RuntimeError("call reset() first")
        return self._last

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        bus = self.bus
        try:
            if kp is not None or kd is not None:
                new = (self.default_kp if kp is None else np.asarray(kp),
                       self.default_kd if kd is None else np.asarray(kd))
                if self._gains is None or not all(np.array_equal(a, b) for a, b in zip(new, self._gains, strict=True)):
                    bus.write_gains(*new)
                    self._gains = (new[0].copy(), new[1].copy())
            bus.write_goal_positions(self._pulses(motor_targets))
            self._deadline += self.control_dt
            delay = self._deadline - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:
                self._deadline = time.perf_counter()  # overran: do not try to catch up
            self._last = self._observation(bus.read_state())
        except BaseException:
            bus.close()
            raise
        return self._last

    def close(self) -> None:
        self.bus.close()
        self.imu.close()


class TrackedRealRobot(RealRobot, GroundTruth):
    """A `RealRobot` watched by motion capture (`mocap`, set before the run: `StreamMocap` of the HIL emulator): the
    runner logs the torso pose it reports as ground truth, so the run's tracking errors are computed as in the
    simulator. The pose is the one reported when the observation was taken, as the simulator's is its last
    observation's: read when the runner asked for it, after the policy had computed (walk-rl: a median 0.6 ms, up to
    12 ms on a loaded 2-core VM), it was that much newer than the logged IMU reading. Falls are still the IMU's
    (`Robot.fallen`): motion capture only watches."""

    mocap: StreamMocap
    _pose: Pose | None = None

    def _observation(self, state: MotorState) -> Observation:
        obs = super()._observation(state)
        self._pose = self.mocap.read()
        return obs

    @property
    def base_pos(self) -> np.ndarray:
        return self._observed_pose().pos

    @property
    def base_quat(self) -> np.ndarray:
        return self._observed_pose().quat

    def _observed_pose(self) -> Pose:
        if self._pose is None:
            raise RuntimeError("call reset() first")
        return self._pose

    def torso_height(self) -> float:
        return float(self.base_pos[2])

    def torso_uprightness(self) -> float:
        return float(np.cos(tilt(self.base_quat)))
