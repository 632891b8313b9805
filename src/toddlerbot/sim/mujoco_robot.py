"""`MuJoCoRobot`: the `Robot` interface on a MuJoCo model of the spec, with the actuator model in the loop.

Every physics substep (the spec's timestep, 1 ms) the actuator model (`toddlerbot.actuation.model.motor_torque`)
turns the latest motor targets and firmware gains into motor torques, which MuJoCo applies through the model's
torque actuators; passive friction, damping and armature come from the joint parameters. One `step` advances
one control period (``control_dt``, 20 ms at 50 Hz).

Safety in the loop:

* targets and gains pass the shared `CommandGuard` of `Robot.step` (finite, clamped to the motor and output
  joint ranges) before the backend applies them;
* non-finite or runaway state raises `SimulationError` naming the simulated time;
* a fall detector (`MuJoCoRobot.fallen`): torso tilted beyond ``fall_tilt_rad`` or its height below
  ``fall_height_fraction`` of the standing height.

The robot has `GroundTruth` (`toddlerbot.sim.ground_truth.TorsoTruth`): the torso's true pose in the world.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT, FALL_TILT_RAD, Observation, Robot
from toddlerbot.sim.actuated import (
    UNSTABLE_SPEED,
    MotorAddresses,
    compile_substeps,
    diverged,
    step_one_robot,
)
from toddlerbot.sim.ground_truth import FALL_HEIGHT_FRACTION, TorsoGroundTruth, TorsoTruth
from toddlerbot.sim.motor_drive import MotorDrive
from toddlerbot.sim.terrain import ground_geoms


class SimulationError(ToddlerbotError):
    """The simulation became numerically unstable (NaN, runaway velocities)."""


@dataclass(frozen=True)
class SimConfig:
    control_dt: float = CONTROL_DT
    """Control period, s."""
    fall_tilt_rad: float = FALL_TILT_RAD
    """Torso tilt from upright (angle between torso z and world z) that counts as a fall."""
    fall_height_fraction: float = FALL_HEIGHT_FRACTION
    """Torso height below this fraction of its standing height counts as a fall."""

    def __post_init__(self) -> None:
        if self.control_dt <= 0:
            raise ValueError(f"control_dt must be > 0 s, got {self.control_dt}")


class MuJoCoRobot(Robot, TorsoGroundTruth):
    """The floating-base robot on a floor, stepped with the actuator model."""

    def __init__(
        self,
        description: RobotDescription | None = None,
        config: SimConfig | None = None,
        model: mujoco.MjModel | None = None,
    ) -> None:
        description = description or RobotDescription.load()
        self.config = config or SimConfig()
        super().__init__(description, self.config.control_dt)
        self.model = model if model is not None else description.model("floating", scene=True)
        self.data = mujoco.MjData(self.model)
        physics_dt = self.model.opt.timestep
        self.n_substeps = round(self.config.control_dt / physics_dt)
        if self.n_substeps < 1 or abs(self.n_substeps * physics_dt - self.config.control_dt) > 1e-9:
            raise ValueError(
                f"control_dt {self.config.control_dt} s must be a multiple of the physics timestep {physics_dt} s"
            )
        m = self.model
        self._motors = MotorAddresses.of(m, self.motor_names)
        self._qadr, self._dadr = self._motors.qpos, self._motors.dof
        self._A = self.transmission.matrix
        self._imu = {name: slice(m.sensor(name).adr[0], m.sensor(name).adr[0] + m.sensor(name).dim[0])
                     for name in ("imu_quat", "imu_gyro", "imu_accel")}
        handles = description.handles
        self._foot_geoms = [m.geom(g).id for g in handles.feet_geoms]
        self._ground = ground_geoms(m)
        self.torso_truth = TorsoTruth(m, self.data, handles.torso)
        self._home_key = m.key("home").id
        self._targets = np.zeros(len(self.motor_names))
        self._torque = np.zeros(len(self.motor_names))
        self.retried_steps = 0
        """Control steps taken again with more solver iterations after they diverged (`step_one_robot`)."""
        self.initial_motor_offset = np.zeros(len(self.motor_names))
        """Motor angles added to the home keyframe at `reset`, rad (a perturbation; zero by default)."""
        self.start_qpos: np.ndarray | None = None
        """Where `reset` puts the robot instead of the home keyframe, at rest (MuJoCo qpos, e.g. lying on the floor
        from `robot.floor_pose.place_on_floor`, where a get-up motion starts); None: the home keyframe."""
        self._gains: tuple[np.ndarray, np.ndarray] | None = None
        self.set_gains(self.default_kp, self.default_kd)
        compile_substeps(self.model, self.data, self._motors, self._drive)  # not in the first (wall-clock) step
        self.reset()
        self.standing_height = self.torso_height()

    # -- Robot interface -------------------------------------------------------------------------------------
    def reset(self) -> Observation:
        mujoco.mj_resetDataKeyframe(self.model, self.data, self._home_key)
        if self.start_qpos is not None:
            self.data.qpos[:] = self.start_qpos
            self.data.qvel[:] = 0.0
        self.data.qpos[self._qadr] += self.initial_motor_offset
        mujoco.mj_forward(self.model, self.data)
        self._targets = self.data.qpos[self._qadr].copy()
        self.last_targets = None
        self._torque[:] = 0.0
        self.set_gains(self.default_kp, self.default_kd)
        return self.observe()

    def observe(self) -> Observation:
        d = self.data
        q, qd = d.qpos[self._qadr].copy(), d.qvel[self._dadr].copy()
        return Observation(
            time=float(d.time),
            motor_pos=q,
            motor_vel=qd,
            motor_torque=self._torque.copy(),
            joint_pos=self._A @ q,
            joint_vel=self._A @ qd,
            imu_quat=d.sensordata[self._imu["imu_quat"]].copy(),
            imu_ang_vel=d.sensordata[self._imu["imu_gyro"]].copy(),
            imu_lin_acc=d.sensordata[self._imu["imu_accel"]].copy(),
            foot_contact=self.foot_contact(),
        )

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        self.command(motor_targets, kp, kd)
        self.advance(self.n_substeps)
        self._check_stable()
        return self.observe()

    def command(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None) -> None:
        """Hold already-checked motor targets (rad) and firmware gains from now on, without stepping (`step` is
        `command` then `advance` by one control period)."""
        if kp is not None or kd is not None:
            self.set_gains(self.default_kp if kp is None else kp, self.default_kd if kd is None else kd)
        self._targets = motor_targets
        if self._drive.params is not self._params:  # parameters replaced from outside (the RL backend test)
            self._drive = MotorDrive(self._params)

    def advance(self, n_substeps: int) -> None:
        """``n_substeps`` physics steps holding the commanded targets (MuJoCo's sensors evaluated in the last:
        the robot owns its model, and only the last substep's are observed)."""
        self._torque, retried = step_one_robot(self.model, self.data, self._motors, self._targets, self._drive,
                                               n_substeps, sensors_last_only=True)
        self.retried_steps += retried

    # -- helpers ---------------------------------------------------------------------------------------------
    def set_gains(self, kp: np.ndarray, kd: np.ndarray) -> None:
        """Firmware gains (Dynamixel units) used by the actuator model from now on."""
        kp, kd = np.array(kp, dtype=float), np.array(kd, dtype=float)
        if self._gains is not None and np.array_equal(kp, self._gains[0]) and np.array_equal(kd, self._gains[1]):
            return  # a policy sending the same gains every step: the drive is a function of them, keep it
        self._gains = (kp, kd)
        self._params = self.description.actuator_arrays(kp, kd)
        self._drive = MotorDrive(self._params)

    def foot_contact(self) -> np.ndarray:
        """(left, right): does each foot's collision geom touch the ground (the floor or a terrain)?"""
        ground = self._ground
        on_ground = {b if a in ground else a for a, b in self.data.contact.geom[: self.data.ncon].tolist()
                     if a in ground or b in ground}  # a few contacts: plain Python beats numpy's set operations
        return np.array([foot in on_ground for foot in self._foot_geoms])

    def push(self, velocity_change: np.ndarray) -> None:
        """Add a horizontal velocity (dvx, dvy), m/s, world frame, to the torso: a kick."""
        self.data.qvel[0:2] += np.asarray(velocity_change, dtype=float)

    # -- GroundTruth -----------------------------------------------------------------------------------------
    @property
    def base_lin_vel(self) -> np.ndarray:
        """Torso linear velocity in the world frame, m/s."""
        return self.data.qvel[0:3].copy()

    @property
    def base_ang_vel(self) -> np.ndarray:
        """Torso angular velocity in the torso frame, rad/s (MuJoCo free-joint convention)."""
        return self.data.qvel[3:6].copy()

    @property
    def fallen(self) -> bool:
        c = self.config
        return self.torso_truth.fallen(self.standing_height, c.fall_tilt_rad, c.fall_height_fraction)

    def _check_stable(self) -> None:
        d = self.data
        if not diverged(d):
            return
        if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:  # MuJoCo then resets the state to qpos0 silently
            raise SimulationError("simulation diverged: MuJoCo found a non-finite or huge acceleration and reset the "
                                  "state")
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            raise SimulationError(f"simulation diverged at t={d.time:.3f} s (non-finite state)")
        speed = np.max(np.abs(d.qvel[6:]))
        if speed > UNSTABLE_SPEED:
            raise SimulationError(
                f"simulation unstable at t={d.time:.3f} s: a joint moves at {speed:.0f} rad/s "
                f"(> {UNSTABLE_SPEED:.0f}); check the gains and targets"
            )
