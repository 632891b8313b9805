"""`walk-zmp`: the ZMP pattern generator's leg targets plus feedback from the IMU.

The generator stays a pure function of its command and time; all feedback lives here (gains in
`AttitudeFeedback`; the estimators and loops are small classes in `toddlerbot.policies.walk_feedback`):

* attitude: the torso's pitch and roll error (IMU orientation versus upright) and their rates shift the ankle
  pitch/roll (and optionally hip roll) of the legs, turning the feet against the tilt (an ankle strategy);
* heading hold (`HeadingHold`): the commanded yaw rate is integrated into a desired heading; the yaw-rate
  command given to the generator is corrected by the heading error from the IMU (foot slip otherwise turns the
  robot slowly);
* capture-point (DCM) feedback (`CapturePointEstimator`): the CoM relative to the feet in contact is estimated
  from the measured leg joint angles (leg forward kinematics and whole-robot CoM of `LegIK`) and the IMU tilt,
  compared with the same quantity of the planned leg angles, and the error plus its rate / omega shifts the
  ankle pitch/roll;
* stepping to catch a push (`toddlerbot.locomotion.capture_step`): the DCM error relative to the step's stance
  foot, less its part that repeats with the gait (`GaitBaseline`), moves the swinging foot's target to where the
  error will have gone at touchdown, within its reach; the walk goes on from where the foot lands, and the step
  hurries when only the other foot can catch the push;
* stance hip lift and a stiffer swing leg (`swing_kp_scale`) so that the swing foot leaves and reaches the floor
  closer to the plan;
* velocity tracking (`VelocityTracking`, `VelocityLoop`): the base's forward velocity, estimated by leg
  odometry (`LegOdometry`: stance-foot kinematics and the IMU) over a gait cycle, is driven to the command by a
  PI correction of the generator's command (removes the systematic stride errors that foot slip and stance-leg
  compliance cause).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.locomotion.capture_step import StepAdjustment, footstep_shift, hurries
from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.locomotion.preview import GRAVITY
from toddlerbot.locomotion.zmp_walk import WalkReference, WalkState, ZMPWalk
from toddlerbot.policies.base import Action, Policy
from toddlerbot.policies.walk_feedback import (
    CapturePointEstimator,
    FootJoint,
    GaitBaseline,
    HeadingHold,
    LegOdometry,
    VelocityLoop,
    VelocityTracking,
    attitude,
    tilt_rotation,
)
from toddlerbot.robot.interface import Observation, Robot


@dataclass(frozen=True)
class AttitudeFeedback:
    """Feedback gains. Joint offsets rotate the foot relative to the torso about the torso's y (pitch terms) or x
    (roll terms) axis, in the same sense for both legs whatever the joints' mirroring (signs from the model)."""

    ankle_pitch: float = 0.7
    """rad of ankle pitch per rad of torso pitch. 1.0 fell under 2 x the loop delays of hardware-in-the-loop, 0.6
    on a perturbed robot without them (`benchmarks/bench_hil_like.py`; docs/hardware.md)."""
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
    dcm_ankle_x: float = 2.0
    """rad of ankle pitch per m of forward DCM error (measured minus planned capture point, relative to the feet in
    contact, torso-heading frame): the feet push the ZMP towards the error (ankle strategy). 3.0 overshot with the
    10-20 ms loop delay of hardware-in-the-loop (`benchmarks/bench_hil_like.py`)."""
    dcm_ankle_y: float = 1.5
    """rad of ankle roll per m of sideways DCM error."""
    dcm_velocity_filter: float = 0.5
    """Low-pass weight of the newest sample in the CoM-velocity estimate (1 = raw finite difference)."""
    stance_hip_roll: float = 0.03
    """rad of stance-leg hip roll in single support that lifts the swing side of the pelvis (compensates the
    stance hip's sag under the robot's weight, which otherwise makes the swing foot drag)."""


class WalkZMPPolicy(Policy):
    """ZMP walking with attitude, heading, capture-point and velocity feedback (module docstring). The feedback
    parts are public attributes: `heading` (`HeadingHold`), `odometry` (`LegOdometry`), `capture_point`
    (`CapturePointEstimator`) and `velocity_loop` (`VelocityLoop`)."""

    name = "walk-zmp"
    needs_imu = True
    demo_command = (0.1, 0.0, 0.0)

    def __init__(
        self,
        robot: Robot,
        config: WalkConfig | None = None,
        feedback: AttitudeFeedback | None = None,
        leg_kp_scale: float = 2.0,
        swing_kp_scale: float = 3.0,
        velocity: VelocityTracking | None = None,
        step_adjustment: StepAdjustment | None = None,
    ) -> None:
        super().__init__(robot)
        names = list(robot.joint_names)
        self.walk = ZMPWalk(robot.description, config or WalkConfig(dt=robot.control_dt))
        self.command_reach = self.walk.config.reach
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
        self.step_adjustment = step_adjustment or StepAdjustment()
        ik = self.walk.ik
        self.ankle_pitch = FootJoint.find(ik, names, "ankle_pitch", 1)
        self.ankle_roll = FootJoint.find(ik, names, "ankle_roll", 0)
        self.hip_roll = FootJoint.find(ik, names, "hip_roll", 0)
        self.leg_index = self.walk.leg_index
        self.omega = float(np.sqrt(GRAVITY / self.walk.com_height))
        """Natural frequency of the walk's linear inverted pendulum, 1/s."""
        self.walk_state: WalkState | None = None
        """The generator's state (None until the first `act` after `reset`)."""
        self.last_reference: WalkReference | None = None
        """The generator's latest output (planned joints, contact, feet)."""

    def reset(self, obs: Observation) -> None:
        """Start a new walk: the generator restarts and every estimator and loop forgets its state."""
        cfg, dt = self.walk.config, self.control_dt
        self.walk_state = None
        self.last_reference = None
        self.heading = HeadingHold(last_yaw=attitude(obs.imu_quat)[2])
        self.odometry = LegOdometry(self.walk.ik, self.leg_index, window=cfg.step_ticks * 2, dt=dt)
        self.capture_point = CapturePointEstimator(self.walk.ik, self.leg_index, self.omega,
                                                   self.feedback.dcm_velocity_filter, dt)
        self.velocity_loop = VelocityLoop(self.velocity, cfg.start_ticks, cfg.step_ticks, dt)
        self.dcm_baseline = GaitBaseline(2 * cfg.step_ticks)
        self.step_index = -1
        """The generator's step that `step_shift` belongs to."""
        self.step_shift = np.zeros(2)
        """Current shift of the swinging foot's target, m, torso-heading frame (`StepAdjustment`)."""

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        fb = self.feedback
        command = self.within_reach(command)
        if self.walk_state is None:
            self.walk_state = self.walk.start(command)
        roll, pitch, heading = attitude(obs.imu_quat)
        self.heading.measure(heading, self.control_dt)
        ref = self.last_reference
        if ref is not None:  # estimators compare the measurement with the plan of the previous tick
            self.odometry.update(obs.joint_pos, ref.contact, heading, roll, pitch)
        correction = self.velocity_loop.update(self.walk_state.tick, self.walk.clip_command(command),
                                               self.odometry.velocity)
        walk_command = command + np.array([*correction, self.heading.correction(fb.heading, fb.heading_integral)])
        dcm = np.zeros(2)
        if ref is not None:
            dcm = self.capture_point.update(obs.joint_pos, ref.joint_pos, ref.contact, roll, pitch)
        ticks = self._catch_step(dcm, ref.torso_yaw) if ref is not None else 1
        contact = ref.contact if ref is not None else np.ones(2, dtype=bool)
        gains = np.where(contact, fb.stance_tilt, fb.swing_tilt)
        tilts = np.array([tilt_rotation(g * roll, g * pitch) for g in gains])
        for _ in range(ticks):
            self.walk_state, ref = self.walk.step(self.walk_state, walk_command, tilts)
        self.heading.advance(self.walk.clip_command(command)[2], self.control_dt)
        self.last_reference = ref
        q = ref.joint_pos.copy()
        roll_rate, pitch_rate = obs.imu_ang_vel[0], obs.imu_ang_vel[1]
        pitch_joint, roll_joint, hip_joint = self.ankle_pitch, self.ankle_roll, self.hip_roll
        q[pitch_joint.index] += (fb.ankle_pitch * pitch + fb.ankle_pitch_rate * pitch_rate) * pitch_joint.sign
        q[roll_joint.index] += (fb.ankle_roll * roll + fb.ankle_roll_rate * roll_rate) * roll_joint.sign
        q[hip_joint.index] += fb.hip_roll * roll * hip_joint.sign
        q[pitch_joint.index] += fb.dcm_ankle_x * dcm[0] * pitch_joint.sign
        q[roll_joint.index] -= fb.dcm_ankle_y * dcm[1] * roll_joint.sign
        swing = ~ref.contact
        if not swing.all() and swing.any():
            stance = int(np.flatnonzero(ref.contact)[0])
            q[hip_joint.index[stance]] += fb.stance_hip_roll * (1 - 2 * stance) * hip_joint.sign[stance]
        kp = self.kp.copy()
        for leg in np.flatnonzero(swing):
            kp = np.where(self.swing_kp[leg] > 0, self.swing_kp[leg], kp)
        action = self.joint_action(q)
        return Action(action.motor_targets, action.joint_targets, kp=kp)

    def _catch_step(self, dcm_error: np.ndarray, plan_yaw: float) -> int:
        """Move the swinging foot's target where the DCM error (its part beyond the gait's periodic swing)
        will have gone at touchdown, and hurry the step when the other foot must catch it
        (`toddlerbot.locomotion.capture_step`); the generator walks on from where the foot lands. Returns the
        generator ticks to advance this control tick."""
        cfg, adj, state = self.walk.config, self.step_adjustment, self.walk_state
        leg, ticks_left = self.walk.swing_leg(state)
        if leg is None:
            return 1
        residual = self.dcm_baseline.residual(state.tick - cfg.start_ticks, self.capture_point.leg_dcm_error[1 - leg])
        tau = cfg.step_ticks - ticks_left
        step = (state.tick - cfg.start_ticks) // cfg.step_ticks
        if step != self.step_index:  # a new step: the generator takes the last step's shift into the plan
            self.step_index, self.step_shift = step, np.zeros(2)
        swing = (tau - cfg.double_support_ticks + 1) / (cfg.step_ticks - cfg.double_support_ticks)
        if swing <= 0:  # double support: a foot has just landed, and the estimate rings with the impact
            return 1
        ticks = adj.hurry_ticks if hurries(residual, leg, adj) else 1
        if swing > adj.hold:
            return ticks
        target = footstep_shift(residual, self.omega, ticks_left * cfg.dt / ticks, leg, adj)
        limit = adj.max_speed * cfg.dt
        self.step_shift = self.step_shift + np.clip(target - self.step_shift, -limit, limit)
        if self.step_shift.any() or state.step_offsets[2].any():
            c, s = np.cos(plan_yaw), np.sin(plan_yaw)
            shift = self.step_shift
            self.walk_state = self.walk.adjust_swing(state, (c * shift[0] - s * shift[1], s * shift[0] + c * shift[1]),
                                                     adj.follow)
        return ticks
