"""The motion behind the emulated motors' registers.

* `SimplePlant`: every motor is an independent inertia driven by the actuator model
  (`toddlerbot.actuation.model.motor_torque`) with the gains in its control table (via `actuator_arrays`).
* `HilPlant` (hardware in the loop): the MuJoCo model of the whole floating robot on the floor (or on a seeded
  terrain, `toddlerbot.sim.terrain`), stepped through
  the simulator's actuated plant (`toddlerbot.sim.actuated.step_actuated`: the actuator model every 1 ms physics
  step, with each motor's torque enable and current limit), paced to wall-clock time in a background thread. It
  has `GroundTruth` (the torso's true pose), which the emulator reports.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from functools import lru_cache

import mujoco
import numpy as np

from toddlerbot.actuation.model import ActuatorArrays, actuator_arrays
from toddlerbot.hardware.control_table import (
    MODE_CURRENT_BASED_POSITION,
    pulses_to_rad,
    rad_s_to_velocity,
    rad_to_pulses,
    torque_to_load,
    traits,
)
from toddlerbot.hardware.emulated_motor import EmulatedMotor
from toddlerbot.hardware.hil_kicks import Kick
from toddlerbot.hardware.imu import ImuReading
from toddlerbot.hardware.imu_stream import Pose
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import FALL_TILT_RAD
from toddlerbot.sim.actuated import MotorAddresses, compile_substeps, step_one_robot
from toddlerbot.sim.ground_truth import FALL_HEIGHT_FRACTION, TorsoGroundTruth, TorsoTruth
from toddlerbot.sim.motor_drive import MotorDrive
from toddlerbot.sim.terrain import TerrainSpec, terrain_model

LOAD_INERTIA = 0.002
"""Load inertia added to the armature of each motor in `SimplePlant`, kg*m^2."""
MAX_LAG = 0.05
"""Largest lag (s) of the hardware-in-the-loop simulation behind wall-clock time; beyond it, time is dropped
(reported by `HilPlant.realtime_factor`)."""
REST_SPEED = 1e-3
"""Largest joint or base speed (rad/s, m/s) at which an unpowered robot counts as at rest."""
SETTLE_S = 2.0
"""Simulated seconds after which an unpowered robot counts as settled even if contacts still jitter."""
IDLE_POLL_S = 0.02
"""How often a paused simulation (robot unpowered and at rest) checks whether torque came on, s."""


class SimplePlant:
    """Independent motors: inertia (armature + LOAD_INERTIA), the actuator model, MuJoCo-like passive terms."""

    def __init__(self, motors: list[EmulatedMotor]) -> None:
        self.motors = motors
        params = [m.model.actuator for m in motors]
        self.params = params
        self.inertia = np.array([a.armature + LOAD_INERTIA for a in params])
        self.damping = np.array([a.damping for a in params])
        self.friction = np.array([a.frictionloss for a in params])
        self.q = np.zeros(len(motors))
        self.qd = np.zeros(len(motors))
        self.tau = np.zeros(len(motors))
        self.dt = 0.001
        commands(motors, params).drive().compile()  # now, not in the first update
        self._last = time.perf_counter()

    def start(self, lock: threading.Lock) -> None:
        self._last = time.perf_counter()

    def stop(self) -> None:
        pass

    def update(self) -> None:
        """Advance to the present wall-clock time (called under the bus lock before each instruction).

        At most 4 semi-implicit Euler steps per call (each <= 5 ms, stable for these gains and inertias);
        time beyond that is dropped, so an idle bus never delays an answer."""
        now = time.perf_counter()
        elapsed, self._last = now - self._last, now
        steps = min(int(elapsed / self.dt), 4)
        if steps:
            dt = min(elapsed / steps, 0.005)
            cmd = commands(self.motors, self.params)
            drive = cmd.drive()
            for _ in range(steps):
                tau = drive.torque(cmd.q_target, self.q, self.qd)
                passive = self.damping * self.qd + self.friction * np.tanh(self.qd / 0.01)
                self.qd += dt * (tau - passive) / self.inertia
                self.q += dt * self.qd
                self.tau = tau
        else:
            self._last -= elapsed
        publish(self.motors, self.q, self.qd, self.tau)


@dataclass
class Commands:
    torque_on: np.ndarray
    q_target: np.ndarray
    arrays: ActuatorArrays
    tau_limit: np.ndarray

    def drive(self) -> MotorDrive:
        """The actuator model with these gains, each motor's torque enable and its current limit."""
        return MotorDrive(self.arrays, self.torque_on, self.tau_limit)


def commands(motors: list[EmulatedMotor], params: list) -> Commands:
    """Targets (rad, motor angle) and gains from the control tables."""
    goal = np.array([m.get("goal_position") - m.mounting_offset - m.turn_offset - m.get("homing_offset")
                     for m in motors])
    kp = tuple(m.get("position_p_gain") for m in motors)
    kd = tuple(m.get("position_d_gain") for m in motors)
    tau_limit = np.full(len(motors), np.inf)
    for i, m in enumerate(motors):
        t = traits(m.model)
        if m.get("operating_mode") == MODE_CURRENT_BASED_POSITION:
            tau_limit[i] = abs(m.get("goal_current")) * t.current_unit_a * t.torque_per_amp
    return Commands(
        torque_on=np.array([m.torque_on for m in motors]), q_target=pulses_to_rad(goal),
        arrays=_arrays(tuple(params), kp, kd), tau_limit=tau_limit,
    )


@lru_cache(maxsize=8)
def _arrays(params: tuple, kp: tuple, kd: tuple) -> ActuatorArrays:
    return actuator_arrays(params, kp, kd)


def publish(motors: list[EmulatedMotor], q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> None:
    """Write present position/velocity/current into the control tables."""
    pulses = rad_to_pulses(q)
    vel = rad_s_to_velocity(qd)
    tick = int(time.perf_counter() * 1000) % 32768
    for i, m in enumerate(motors):
        m.set("present_position", int(pulses[i]) + m.mounting_offset + m.turn_offset + m.get("homing_offset"))
        m.set("present_velocity", int(vel[i]))
        m.set("present_current", torque_to_load(float(tau[i]), m.model))
        m.set("realtime_tick", tick)
        m.set("moving", int(abs(qd[i]) > 0.02))


class HilPlant(TorsoGroundTruth):
    """The whole robot in MuJoCo (floating base, on the floor or on ``terrain`` drawn from ``terrain_seed``), motors
    driven by the actuator model every physics step.

    The simulation holds still (robot hanging on its stand) until the first motor's torque is enabled, then
    runs in real time in a background thread; `realtime_factor` reports how well it kept up. Once every motor
    is unpowered and the robot has come to rest, the simulation pauses (no CPU) until torque comes back.
    The model and the actuator parameters come from the description, so fitted params.json files apply.
    """

    def __init__(self, motors: list[EmulatedMotor], description: RobotDescription, kicks: tuple[Kick, ...] = (),
                 terrain: TerrainSpec | None = None, terrain_seed: int = 0) -> None:
        self.motors = motors
        self.ground = "flat" if terrain is None else f"{terrain} (seed {terrain_seed})"
        """The ground the robot stands on, as the emulator reports it."""
        self.kicks = list(kicks)
        """Kicks still to come (`toddlerbot.hardware.hil_kicks`), in time order."""
        self.kicked: list[tuple[float, float, float]] = []
        """(powered time s, dvx, dvy m/s in the world) of each kick given."""
        self.powered_time = 0.0
        """Simulated seconds since torque first came on: the kicks' clock."""
        self.retried_steps = 0
        """Physics batches taken again with more solver iterations after they diverged (`step_one_robot`)."""
        self.params = [m.model.actuator for m in motors]
        self.model = terrain_model(description, terrain, terrain_seed)  # the description's own on the flat floor
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key("home").id)
        mujoco.mj_forward(self.model, self.data)
        self._motors = MotorAddresses.of(self.model, [mo.name for mo in motors])
        self.qadr, self.vadr = self._motors.qpos, self._motors.dof
        # compiled now, not in the first physics batch of a wall-clock run
        compile_substeps(self.model, self.data, self._motors, commands(motors, self.params).drive())
        self.torso_truth = TorsoTruth(self.model, self.data, description.handles.torso)
        self.standing_height = self.torso_height()
        """Torso height at the home pose, m: the reference of the fall test."""
        self._imu = [self.model.sensor(name) for name in ("imu_quat", "imu_gyro", "imu_accel")]
        self.sim_time = 0.0
        self.wall_time = 0.0
        self.powered_min_height = np.inf
        """Lowest torso height (m) seen while any motor had torque on."""
        self.powered_min_upright = np.inf
        """Lowest torso uprightness seen while any motor had torque on."""
        self.powered_start: tuple[np.ndarray, float] | None = None
        """Torso (x, y) position, m, and yaw, rad, when a motor's torque first came on."""
        self.powered_end: tuple[np.ndarray, float] | None = None
        """The same at the last step any motor had torque on: with `powered_start`, what motion capture sees."""
        self.powered_turn = 0.0
        """Yaw turned while powered, rad, summed step by step (so turns past half a revolution count whole)."""
        self.imu_sample: tuple[float, ImuReading] = (0.0, self._read_imu())
        """(simulated time, IMU reading) after the latest physics batch (replaced whole: safe to read from
        another thread)."""
        self.pose_sample: tuple[float, Pose] = (0.0, self._read_pose())
        """(simulated time, the torso's world pose) after the latest physics batch: what motion capture sees (replaced
        whole, like `imu_sample`)."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock: threading.Lock | None = None
        self._publish()

    @property
    def realtime_factor(self) -> float:
        return self.sim_time / self.wall_time if self.wall_time > 0 else 1.0

    # -- GroundTruth (read between physics batches; the physics thread replaces the state in place) -----------
    @property
    def fallen(self) -> bool:
        return self.torso_truth.fallen(self.standing_height, FALL_TILT_RAD, FALL_HEIGHT_FRACTION)

    def torso_planar_pose(self) -> tuple[np.ndarray, float]:
        """Torso (x, y) position, m, and heading (yaw of its x axis), rad."""
        return self.torso_truth.planar_pose()

    def powered_motion(self) -> tuple[float, float, float] | None:
        """(dx, dy, yaw change) of the torso between the first and the last powered step (None if never
        powered); the yaw change is unwrapped (summed over the steps)."""
        if self.powered_start is None or self.powered_end is None:
            return None
        (start, _), (end, _) = self.powered_start, self.powered_end
        return float(end[0] - start[0]), float(end[1] - start[1]), self.powered_turn

    def _read_imu(self) -> ImuReading:
        d = self.data.sensordata
        quat, gyro, accel = (d[s.adr[0]:s.adr[0] + s.dim[0]].copy() for s in self._imu)
        return ImuReading(quat=quat, ang_vel=gyro, lin_acc=accel)

    def _read_pose(self) -> Pose:
        return Pose(pos=self.base_pos, quat=self.base_quat)

    def _publish(self) -> None:
        publish(self.motors, self.data.qpos[self.qadr], self.data.qvel[self.vadr],
                self.data.ctrl[self._motors.actuator])

    def start(self, lock: threading.Lock) -> None:
        self._lock = lock
        self._thread = threading.Thread(target=self._run, name="hil-physics", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def update(self) -> None:
        pass  # the physics thread publishes

    def _any_torque(self) -> bool:
        assert self._lock is not None
        with self._lock:
            return any(mo.torque_on for mo in self.motors)

    def _wait_for_torque(self) -> None:
        """Sleep (the world paused) until a motor's torque is enabled or the plant stops."""
        while not self._stop.is_set() and not self._any_torque():
            time.sleep(IDLE_POLL_S)

    def _at_rest(self) -> bool:
        return float(np.abs(self.data.qvel).max(initial=0.0)) < REST_SPEED

    def advance(self, cmd: Commands, n_steps: int) -> None:
        """One batch of ``n_steps`` physics steps holding the control tables' commands ``cmd``, then the powered
        motion's bookkeeping and the IMU sample (the physics thread's work between two reads of the tables)."""
        self.retried_steps += step_one_robot(self.model, self.data, self._motors, cmd.q_target, cmd.drive(), n_steps)[1]
        self.sim_time += n_steps * self.model.opt.timestep
        if self.powered_start is not None or cmd.torque_on.any():
            self.powered_time += n_steps * self.model.opt.timestep
            self._kick()
        if cmd.torque_on.any():
            self.powered_min_height = min(self.powered_min_height, self.torso_height())
            self.powered_min_upright = min(self.powered_min_upright, self.torso_uprightness())
            previous, self.powered_end = self.powered_end, self.torso_planar_pose()
            if self.powered_start is None:
                self.powered_start = self.powered_end
            else:
                self.powered_turn += float((self.powered_end[1] - previous[1] + np.pi) % (2 * np.pi) - np.pi)
        self.imu_sample = (self.sim_time, self._read_imu())
        self.pose_sample = (self.sim_time, self._read_pose())

    def _kick(self) -> None:
        """Give the kicks that are due: a horizontal velocity change of the floating base."""
        while self.kicks and self.kicks[0].time <= self.powered_time + 1e-9:
            kick = self.kicks.pop(0)
            angle = kick.direction + self.torso_planar_pose()[1]
            dv = kick.speed * np.array([np.cos(angle), np.sin(angle)])
            self.data.qvel[0:2] += dv
            self.kicked.append((round(self.powered_time, 3), float(dv[0]), float(dv[1])))

    def _run(self) -> None:
        dt = self.model.opt.timestep
        self._wait_for_torque()
        t0 = time.perf_counter()
        lost = 0.0  # wall-clock time the simulation gave up on (host too slow)
        unpowered_since = None  # sim time at which the last motor lost torque
        while not self._stop.is_set():
            self.wall_time = time.perf_counter() - t0
            behind = self.wall_time - lost - self.sim_time
            if behind > MAX_LAG:  # never run flat out to catch up: the bus must keep answering
                lost += behind - MAX_LAG
            if behind < dt:
                time.sleep(min(dt, 0.002))
                continue
            assert self._lock is not None
            with self._lock:
                cmd = commands(self.motors, self.params)
            self.advance(cmd, min(int(behind / dt), 10))
            with self._lock:
                self._publish()
            if cmd.torque_on.any():
                unpowered_since = None
            else:
                unpowered_since = self.sim_time if unpowered_since is None else unpowered_since
                if self._at_rest() or self.sim_time - unpowered_since > SETTLE_S:
                    paused = time.perf_counter()
                    self._wait_for_torque()
                    t0 += time.perf_counter() - paused  # paused time is neither simulated nor lost
                    unpowered_since = None
            time.sleep(0)  # let the serving thread answer between batches
