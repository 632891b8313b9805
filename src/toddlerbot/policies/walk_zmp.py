"""`walk-zmp`: the ZMP pattern generator's leg targets plus feedback from the IMU.

The generator stays a pure function of its command and time; all feedback lives here (gains in
`AttitudeFeedback`):

* attitude: the torso's pitch and roll error (IMU orientation versus upright) and their rates shift the ankle
  pitch/roll (and optionally hip roll) of the legs, turning the feet against the tilt (an ankle strategy);
* heading hold: the commanded yaw rate is integrated into a desired heading; the yaw-rate command given to the
  generator is corrected by the heading error from the IMU (foot slip otherwise turns the robot slowly);
* capture-point (DCM) feedback: the CoM relative to the feet in contact is estimated from the measured leg
  joint angles (leg forward kinematics and whole-robot CoM of `LegIK`) and the IMU tilt, compared with the same
  quantity of the planned leg angles, and the error plus its rate / omega shifts the ankle pitch/roll;
* stance hip lift and a stiffer swing leg (`swing_kp_scale`) so that the swing foot leaves and reaches the floor
  closer to the plan;
* velocity tracking (`VelocityTracking`): the base's forward velocity, estimated by leg odometry (stance-foot
  kinematics and the IMU) over a gait cycle, is driven to the command by a PI correction of the generator's
  command (removes the systematic stride errors that foot slip and stance-leg compliance cause).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.locomotion.preview import GRAVITY
from toddlerbot.locomotion.zmp_walk import WalkReference, ZMPWalk
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot


@dataclass(frozen=True)
class AttitudeFeedback:
    """Feedback gains. Joint offsets rotate the foot relative to the torso about the torso's y (pitch terms) or x
    (roll terms) axis, in the same sense for both legs whatever the joints' mirroring (signs from the model)."""

    ankle_pitch: float = 1.0
    """rad of ankle pitch per rad of torso pitch."""
    ankle_pitch_rate: float = 0.0
    """rad of ankle pitch per rad/s of torso pitch rate (IMU gyro)."""
    ankle_roll: float = 0.0
    """rad of ankle roll per rad of torso roll."""
    ankle_roll_rate: float = 0.0
    """rad of ankle roll per rad/s of torso roll rate."""
    hip_roll: float = 0.0
    """rad of hip roll per rad of torso roll."""
    swing_tilt: float = 0.0
    """Fraction of the measured torso tilt the swing leg's IK compensates (places the foot in the world frame)."""
    stance_tilt: float = 0.0
    """Fraction of the measured torso tilt the stance leg's IK compensates."""
    heading: float = 1.5
    """Heading hold: rad/s of yaw-rate command per rad of heading error (the commanded yaw rate integrated from
    the start minus the IMU yaw change)."""
    heading_integral: float = 0.0
    """rad/s of yaw-rate command per rad*s of integrated heading error (removes a steady yaw slip)."""
    dcm_ankle_x: float = 3.0
    """rad of ankle pitch per m of forward DCM error (measured minus planned capture point, relative to the feet in
    contact, torso-heading frame): the feet push the ZMP towards the error (ankle strategy)."""
    dcm_ankle_y: float = 1.5
    """rad of ankle roll per m of sideways DCM error."""
    dcm_velocity_filter: float = 0.5
    """Low-pass weight of the newest sample in the CoM-velocity estimate (1 = raw finite difference)."""
    stance_hip_roll: float = 0.03
    """rad of stance-leg hip roll in single support that lifts the swing side of the pelvis (compensates the
    stance hip's sag under the robot's weight, which otherwise makes the swing foot drag)."""


@dataclass(frozen=True)
class VelocityTracking:
    """Closed-loop planar velocity tracking: the base velocity is estimated by leg odometry (the planned stance
    feet assumed fixed on the floor, their position from the measured leg angles and the IMU orientation),
    averaged over the last gait cycle, and a PI law on the error (commanded minus estimated, torso-heading frame)
    corrects the (vx, vy) command given to the generator. The y gains default to 0: the odometry's vy is biased by
    the gait's lateral sway and a sideways loop made sideways walking worse (docs/simulation.md). The integral is
    kept across command changes (the bias it learns is roughly the same for every command)."""

    kp: tuple[float, float] = (0.5, 0.0)
    """(x, y) m/s of command correction per m/s of velocity error."""
    ki: tuple[float, float] = (2.0, 0.0)
    """(x, y) m/s of command correction per m of integrated velocity error (1/s)."""
    limit: tuple[float, float] = (0.06, 0.03)
    """(x, y) bound on the correction, m/s (the integral stops growing there: anti-windup)."""
    settle_steps: int = 2
    """Steps the (clipped) command must have stayed the same (and the walk have run) before the loop acts: the
    gait-cycle average lags a velocity change, and integrating that lag winds the correction up."""


def tilt(quat: np.ndarray) -> tuple[float, float]:
    """(roll, pitch) of a w, x, y, z quaternion, rad (ZYX Euler angles)."""
    w, x, y, z = quat
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return float(roll), float(pitch)


def yaw(quat: np.ndarray) -> float:
    """Heading (rad) of a w, x, y, z quaternion (ZYX Euler angles)."""
    w, x, y, z = quat
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def rotation_rp(roll: float, pitch: float) -> np.ndarray:
    """Rotation matrix of pitch about y after roll about x (R = Ry(pitch) @ Rx(roll))."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return ry @ rx


class WalkZMPPolicy(Policy):
    name = "walk-zmp"

    def __init__(
        self,
        robot: Robot,
        config: WalkConfig | None = None,
        feedback: AttitudeFeedback | None = None,
        leg_kp_scale: float = 2.0,
        swing_kp_scale: float = 3.0,
        velocity: VelocityTracking | None = None,
    ) -> None:
        super().__init__(robot)
        names = list(robot.joint_names)
        self.walk = ZMPWalk(robot.description, config or WalkConfig(dt=robot.control_dt))
        if abs(self.walk.config.dt - robot.control_dt) > 1e-12:
            raise ValueError(f"walk dt {self.walk.config.dt} s must equal the control period {robot.control_dt} s")
        chains = self.walk.ik.chains.joint_names
        legs = np.zeros(len(robot.motor_names), dtype=bool)
        legs[robot.description.groups["leg"]] = True
        self.kp = np.where(legs, robot.default_kp * leg_kp_scale, robot.default_kp)
        """Firmware P gains: the leg motors stiffened by leg_kp_scale (the spec's gains let the stance leg sag
        enough for the swing foot to scuff the floor; x3 over-stiffens it and the feet land short). The swing leg
        gets swing_kp_scale while it swings (lift-off and touch-down closer to the plan)."""
        matrix = robot.transmission.matrix
        sides = np.array([np.abs(matrix[[names.index(j) for j in chain]]).sum(axis=0) > 0 for chain in chains]) & legs
        self.swing_kp = np.where(sides, robot.default_kp * swing_kp_scale, 0.0)
        """(2, n_motors) firmware P gains of each leg's motors (those driving its IK chain) while that leg swings
        (0 elsewhere)."""
        self.feedback = feedback or AttitudeFeedback()
        self.velocity = velocity or VelocityTracking()
        axes = self.walk.ik.joint_axes()

        def joint(suffix: str, axis: int) -> tuple[np.ndarray, np.ndarray]:
            """Joint-vector indices of one joint per leg and the sign turning the foot about +axis."""
            legs = [next(i for i, j in enumerate(chain) if j.endswith(suffix)) for chain in chains]
            return (np.array([names.index(chains[leg][i]) for leg, i in enumerate(legs)]),
                    np.sign([axes[leg, i, axis] for leg, i in enumerate(legs)]))

        self._ankle_pitch, self._ankle_pitch_sign = joint("ankle_pitch", 1)
        self._ankle_roll, self._ankle_roll_sign = joint("ankle_roll", 0)
        self._hip_roll, self._hip_roll_sign = joint("hip_roll", 0)
        self._leg = np.array([[names.index(j) for j in chain] for chain in chains])
        self._omega = float(np.sqrt(GRAVITY / self.walk.com_height))
        self.last_reference: WalkReference | None = None

    def reset(self, obs: Observation) -> None:
        self._state = None
        self._planned_contact = np.ones(2, dtype=bool)
        self._heading_error = 0.0
        self._heading_error_sum = 0.0
        self._last_yaw = yaw(obs.imu_quat)
        self._com_error = None
        self._com_error_vel = np.zeros(2)
        self.dcm_error = np.zeros(2)
        self._odometry = None
        self._odometry_steps: list[np.ndarray] = []
        self.velocity_estimate = np.zeros(2)
        self._velocity_error_sum = np.zeros(2)
        self._correction = np.zeros(2)
        self._steady_command = None
        self._steady_since = 0

    def _estimate_velocity(self, obs: Observation, roll: float, pitch: float) -> np.ndarray:
        """Base planar velocity (2,), m/s, torso-heading frame, from leg odometry averaged over the last gait
        cycle: the torso moves opposite to the planned stance feet's position relative to it (measured leg
        angles, IMU orientation); ticks where the stance changes are left out."""
        ref = self.last_reference
        if ref is None:
            return self.velocity_estimate
        feet, _ = self.walk.ik.forward(obs.joint_pos[self._leg])
        heading = yaw(obs.imu_quat)
        c, s = np.cos(heading), np.sin(heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ rotation_rp(roll, pitch)
        legs = tuple(np.flatnonzero(ref.contact))
        torso = -np.mean([rot @ feet[leg] for leg in legs], axis=0)[:2]  # world-aligned, relative to the stance
        if self._odometry is not None and self._odometry[0] == legs:
            step = torso - self._odometry[1]
            self._odometry_steps.append(np.array([c * step[0] + s * step[1], -s * step[0] + c * step[1]]))
            self._odometry_steps = self._odometry_steps[-self.walk.config.step_ticks * 2:]
        self._odometry = (legs, torso)
        if self._odometry_steps:
            n = len(self._odometry_steps)
            self.velocity_estimate = np.sum(self._odometry_steps, axis=0) / (n * self.control_dt)
        return self.velocity_estimate

    def _measure_dcm_error(self, obs: Observation, roll: float, pitch: float) -> np.ndarray:
        """DCM error (2,), m: measured minus planned CoM relative to the planned-contact feet (torso yaw frame),
        plus its rate / omega. The measured CoM comes from the leg joint angles and the IMU tilt."""
        ref = self.last_reference
        if ref is None:
            return np.zeros(2)
        ik = self.walk.ik
        q_meas = obs.joint_pos[self._leg]
        q_plan = ref.joint_pos[self._leg]
        feet_m, _ = ik.forward(q_meas)
        com_m = ik.com(q_meas)
        feet_p, _ = ik.forward(q_plan)
        com_p = ik.com(q_plan)
        rot = rotation_rp(roll, pitch)
        legs = np.flatnonzero(ref.contact)
        err = np.mean([rot @ (com_m - feet_m[leg]) - (com_p - feet_p[leg]) for leg in legs], axis=0)[:2]
        key = tuple(legs)
        if self._com_error is not None and self._com_error[0] == key:
            a = self.feedback.dcm_velocity_filter
            self._com_error_vel = (1 - a) * self._com_error_vel + a * (err - self._com_error[1]) / self.control_dt
        self._com_error = (key, err)
        return err + self._com_error_vel / self._omega

    def _velocity_correction(self, obs: Observation, command: np.ndarray, roll: float, pitch: float) -> np.ndarray:
        """(vx, vy) correction of the generator's command, m/s: PI on the commanded minus the leg-odometry velocity,
        once the command has been steady for `settle_steps` steps. It changes only when a step starts (the
        generator fixes each footstep then; a correction changing every tick would move the previewed footsteps,
        and the CoM plan with them, during a step)."""
        vt, cfg = self.velocity, self.walk.config
        velocity = self._estimate_velocity(obs, roll, pitch)
        clipped = self.walk.clip_command(command)
        if not np.array_equal(clipped, self._steady_command):
            self._steady_command, self._steady_since = clipped, self._state.tick
        tick = self._state.tick
        if tick - max(self._steady_since, cfg.start_ticks) < vt.settle_steps * cfg.step_ticks:
            return self._correction
        ki, limit = np.asarray(vt.ki), np.asarray(vt.limit)
        error = clipped[:2] - velocity
        bound = limit / np.maximum(ki, 1e-9)
        self._velocity_error_sum = np.clip(self._velocity_error_sum + error * self.control_dt, -bound, bound)
        if (tick - cfg.start_ticks) % cfg.step_ticks == 0:
            self._correction = np.clip(np.asarray(vt.kp) * error + ki * self._velocity_error_sum, -limit, limit)
        return self._correction

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        fb = self.feedback
        command = np.asarray(command, dtype=float)
        if self._state is None:
            self._state = self.walk.start(command)
        roll, pitch = tilt(obs.imu_quat)
        heading = yaw(obs.imu_quat)
        self._heading_error -= (heading - self._last_yaw + np.pi) % (2 * np.pi) - np.pi
        self._last_yaw = heading
        self._heading_error_sum += self._heading_error * self.control_dt
        correction = self._velocity_correction(obs, command, roll, pitch)
        walk_command = command + np.array(
            [*correction, fb.heading * self._heading_error + fb.heading_integral * self._heading_error_sum])
        self.dcm_error = dcm = self._measure_dcm_error(obs, roll, pitch)
        contact = self._planned_contact
        gains = np.where(contact, fb.stance_tilt, fb.swing_tilt)
        tilts = np.array([rotation_rp(g * roll, g * pitch) for g in gains])
        self._state, ref = self.walk.step(self._state, walk_command, tilts)
        self._heading_error += self.walk.clip_command(command)[2] * self.control_dt
        self._planned_contact = ref.contact
        self.last_reference = ref
        q = ref.joint_pos.copy()
        roll_rate, pitch_rate = obs.imu_ang_vel[0], obs.imu_ang_vel[1]
        q[self._ankle_pitch] += (fb.ankle_pitch * pitch + fb.ankle_pitch_rate * pitch_rate) * self._ankle_pitch_sign
        q[self._ankle_roll] += (fb.ankle_roll * roll + fb.ankle_roll_rate * roll_rate) * self._ankle_roll_sign
        q[self._hip_roll] += fb.hip_roll * roll * self._hip_roll_sign
        q[self._ankle_pitch] += fb.dcm_ankle_x * dcm[0] * self._ankle_pitch_sign
        q[self._ankle_roll] -= fb.dcm_ankle_y * dcm[1] * self._ankle_roll_sign
        swing = ~ref.contact
        if not swing.all() and swing.any():
            stance = int(np.flatnonzero(ref.contact)[0])
            q[self._hip_roll[stance]] += fb.stance_hip_roll * (1 - 2 * stance) * self._hip_roll_sign[stance]
        kp = self.kp.copy()
        for leg in np.flatnonzero(swing):
            kp = np.where(self.swing_kp[leg] > 0, self.swing_kp[leg], kp)
        action = self.joint_action(q)
        return Action(action.motor_targets, action.joint_targets, kp=kp)
