"""The estimators and loops `WalkZMPPolicy` closes around the ZMP generator, one small class each, state public.

Frames: the torso-heading frame is the world frame rotated by the torso's yaw (x forward, y left, z up); leg
kinematics (`LegIK`) are in the torso frame. Each class is updated once per control tick by the policy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toddlerbot.locomotion.leg_ik import LegIK


@dataclass(frozen=True)
class VelocityTracking:
    """Closed-loop planar velocity tracking: the base velocity is estimated by leg odometry (the planned stance
    feet assumed fixed on the floor, their position from the measured leg angles and the IMU orientation),
    averaged over the last gait cycle, and a PI law on the error (commanded minus estimated, torso-heading frame)
    corrects the (vx, vy) command given to the generator. The y gains default to 0: the odometry's vy is biased by
    the gait's lateral sway and a sideways loop made sideways walking worse (docs/simulation.md). The integral is
    kept across command changes (the bias it learns is roughly the same for every command)."""

    kp: tuple[float, float] = (0.25, 0.0)
    """(x, y) m/s of command correction per m/s of velocity error. Half the earlier 0.5 (and ki 1 instead of 2):
    the correction jumps at a step's start, and the larger jump at the loop's first step was followed by a foot
    yaw slip that felled 1 in 12 perturbed 0.15 m/s walks (0 of 32 with these gains; docs/simulation.md)."""
    ki: tuple[float, float] = (1.0, 0.0)
    """(x, y) m/s of command correction per m of integrated velocity error (1/s)."""
    limit: tuple[float, float] = (0.06, 0.03)
    """(x, y) bound on the correction, m/s (the integral stops growing there: anti-windup)."""
    settle_steps: int = 2
    """Steps the (clipped) command must have stayed the same (and the walk have run) before the loop acts: the
    gait-cycle average lags a velocity change, and integrating that lag winds the correction up."""


@dataclass(frozen=True)
class FootJoint:
    """One joint per leg (left, right) that turns the foot about a torso axis."""

    index: np.ndarray
    """(2,) indices into the robot's joint vector."""
    sign: np.ndarray
    """(2,) +1 or -1: the joint angle's sign that turns the foot about the +axis (mirrored joints differ)."""

    @classmethod
    def find(cls, ik: LegIK, joint_names: list[str], suffix: str, axis: int) -> FootJoint:
        """The joint whose name ends with ``suffix`` in each leg chain; ``axis`` 0 = torso x (roll), 1 = y (pitch)."""
        chains = ik.chains.joint_names
        axes = ik.joint_axes()
        in_chain = [next(i for i, j in enumerate(chain) if j.endswith(suffix)) for chain in chains]
        return cls(np.array([joint_names.index(chains[leg][i]) for leg, i in enumerate(in_chain)]),
                   np.sign([axes[leg, i, axis] for leg, i in enumerate(in_chain)]))


# The two rotation helpers below stay written out on purpose: scipy's Rotation (as_euler("ZYX"),
# from_euler("YX")) agrees with them to 1e-16, but the walking loop amplifies last-bit differences (a 10 s walk
# at 0.1 m/s ends at 0.946 m instead of 0.937 m, yaw -0.001 instead of -0.021 rad), which would silently move
# every measured walking figure.
def attitude(quat: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of a w, x, y, z quaternion, rad (ZYX Euler angles: yaw about z, then pitch, then roll)."""
    w, x, y, z = quat
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return float(roll), float(pitch), float(yaw)


def tilt_rotation(roll: float, pitch: float) -> np.ndarray:
    """Rotation matrix of pitch about y after roll about x (R = Ry(pitch) @ Rx(roll)), i.e. the torso's tilt."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return ry @ rx


@dataclass
class HeadingHold:
    """Integrates the commanded yaw rate into a desired heading and measures the IMU heading against it."""

    last_yaw: float
    """IMU heading at the previous tick, rad."""
    error: float = 0.0
    """Desired minus measured heading change since reset, rad."""
    error_sum: float = 0.0
    """Time integral of `error`, rad*s."""

    def measure(self, heading: float, dt: float) -> None:
        """Take the IMU heading (rad) of this tick (``dt`` s after the last)."""
        self.error -= (heading - self.last_yaw + np.pi) % (2 * np.pi) - np.pi
        self.last_yaw = heading
        self.error_sum += self.error * dt

    def correction(self, gain: float, integral_gain: float) -> float:
        """Yaw-rate command correction, rad/s (``gain`` 1/s per rad, ``integral_gain`` per rad*s)."""
        return gain * self.error + integral_gain * self.error_sum

    def advance(self, yaw_rate: float, dt: float) -> None:
        """Move the desired heading by the (clipped) commanded yaw rate, rad/s, over ``dt`` s."""
        self.error += yaw_rate * dt


@dataclass
class LegOdometry:
    """Base planar velocity from leg odometry: while the same feet stay planned in contact, the torso moves
    opposite to their position relative to it (measured leg angles, IMU orientation); the per-tick moves are
    averaged over the last ``window`` ticks (a gait cycle). Ticks where the stance changes are left out."""

    ik: LegIK
    leg_index: np.ndarray
    """(2, n_leg_joints) joint-vector indices of each leg's chain."""
    window: int
    """Ticks averaged (two steps: one gait cycle)."""
    dt: float
    """Control period, s."""
    stance: tuple[int, ...] | None = None
    """Legs (0 left, 1 right) planned in contact at the last update."""
    torso: np.ndarray | None = None
    """(2,) torso position relative to the stance feet at the last update, m, world-aligned axes."""
    moves: list[np.ndarray] = field(default_factory=list)
    """Torso moves of the last `window` ticks, m, torso-heading frame."""
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """Estimated (vx, vy), m/s, torso-heading frame."""

    def update(self, joint_pos: np.ndarray, contact: np.ndarray, heading: float, roll: float,
               pitch: float) -> np.ndarray:
        """Take this tick's joint positions, planned contact (2,) and IMU attitude (rad); returns `velocity`."""
        feet, _ = self.ik.forward(joint_pos[self.leg_index])
        c, s = np.cos(heading), np.sin(heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ tilt_rotation(roll, pitch)
        legs = tuple(np.flatnonzero(contact))
        torso = -np.mean([rot @ feet[leg] for leg in legs], axis=0)[:2]
        if self.stance is not None and self.stance == legs:
            move = torso - self.torso
            self.moves.append(np.array([c * move[0] + s * move[1], -s * move[0] + c * move[1]]))
            self.moves = self.moves[-self.window:]
        self.stance, self.torso = legs, torso
        if self.moves:
            self.velocity = np.sum(self.moves, axis=0) / (len(self.moves) * self.dt)
        return self.velocity


@dataclass
class CapturePointEstimator:
    """Capture-point (DCM) error: the measured minus the planned CoM relative to the planned-contact feet (torso
    yaw frame), plus its low-pass-filtered rate / omega. The measured CoM comes from the leg joint angles
    (whole-robot CoM of `LegIK`) and the IMU tilt."""

    ik: LegIK
    leg_index: np.ndarray
    """(2, n_leg_joints) joint-vector indices of each leg's chain."""
    omega: float
    """Natural frequency of the linear inverted pendulum sqrt(g / CoM height), 1/s."""
    rate_filter: float
    """Low-pass weight of the newest sample in the CoM-error rate (1 = raw finite difference)."""
    dt: float
    """Control period, s."""
    stance: tuple[int, ...] | None = None
    """Legs planned in contact at the last update (the rate restarts when they change)."""
    com_error: np.ndarray | None = None
    """(2,) CoM error at the last update, m."""
    com_error_rate: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """(2,) filtered rate of `com_error`, m/s."""
    dcm_error: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """(2,) latest DCM error, m."""
    leg_error: np.ndarray | None = None
    """(2 legs, 2) CoM error relative to each foot at the last update, m (continuous when the stance changes)."""
    leg_error_rate: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    """(2 legs, 2) filtered rate of `leg_error`, m/s."""
    leg_dcm_error: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    """(2 legs, 2) DCM error relative to each foot, m: row ``leg`` is what the step adjustment reads while that
    leg is the step's stance leg (no jump when the other foot lands or lifts off)."""

    def update(self, joint_pos: np.ndarray, planned_joint_pos: np.ndarray, contact: np.ndarray, roll: float,
               pitch: float) -> np.ndarray:
        """Take the measured and planned joint positions, the planned contact (2,) and the IMU tilt (rad);
        returns `dcm_error`."""
        q_meas, q_plan = joint_pos[self.leg_index], planned_joint_pos[self.leg_index]
        feet_m, _ = self.ik.forward(q_meas)
        com_m = self.ik.com(q_meas)
        feet_p, _ = self.ik.forward(q_plan)
        com_p = self.ik.com(q_plan)
        rot = tilt_rotation(roll, pitch)
        per_leg = [rot @ (com_m - feet_m[leg]) - (com_p - feet_p[leg]) for leg in range(2)]
        legs = np.flatnonzero(contact)
        err = np.mean([per_leg[leg] for leg in legs], axis=0)[:2]
        key = tuple(legs)
        a = self.rate_filter
        if self.stance is not None and self.stance == key:
            self.com_error_rate = (1 - a) * self.com_error_rate + a * (err - self.com_error) / self.dt
        self.stance, self.com_error = key, err
        self.dcm_error = err + self.com_error_rate / self.omega
        per_leg = np.array(per_leg)[:, :2]
        if self.leg_error is not None:
            self.leg_error_rate = (1 - a) * self.leg_error_rate + a * (per_leg - self.leg_error) / self.dt
        self.leg_error = per_leg
        self.leg_dcm_error = per_leg + self.leg_error_rate / self.omega
        return self.dcm_error


@dataclass
class VelocityLoop:
    """PI correction of the generator's (vx, vy) command from the commanded minus the estimated velocity, once
    the command has been steady for `VelocityTracking.settle_steps` steps. It changes only when a step starts
    (the generator fixes each footstep then; a correction changing every tick would move the previewed
    footsteps, and the CoM plan with them, during a step)."""

    gains: VelocityTracking
    start_ticks: int
    """Ticks of the generator's standing start."""
    step_ticks: int
    """Ticks per step."""
    dt: float
    """Control period, s."""
    steady_command: np.ndarray | None = None
    """The (clipped) command the loop last saw change to."""
    steady_since: int = 0
    """Tick at which `steady_command` started."""
    error_sum: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """Integrated velocity error, m (bounded so the integral term stays within the limit)."""
    correction: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """Current (vx, vy) correction, m/s."""

    def update(self, tick: int, command: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Take the generator tick, the clipped command (vx, vy, yaw rate) and the estimated velocity (2,), m/s;
        returns `correction`."""
        g = self.gains
        if not np.array_equal(command, self.steady_command):
            self.steady_command, self.steady_since = command, tick
        if tick - max(self.steady_since, self.start_ticks) < g.settle_steps * self.step_ticks:
            return self.correction
        ki, limit = np.asarray(g.ki), np.asarray(g.limit)
        error = command[:2] - velocity
        bound = limit / np.maximum(ki, 1e-9)
        self.error_sum = np.clip(self.error_sum + error * self.dt, -bound, bound)
        if (tick - self.start_ticks) % self.step_ticks == 0:
            self.correction = np.clip(np.asarray(g.kp) * error + ki * self.error_sum, -limit, limit)
        return self.correction


@dataclass
class GaitBaseline:
    """The part of a per-tick (2,) signal that repeats with the gait cycle, learned per tick of the cycle, so that
    what is left is what a push added. On an unpushed walk the DCM error (`CapturePointEstimator`) swings by
    about +-3 cm sideways at the gait frequency (the robot sways less than planned) but repeats from cycle to
    cycle within 0.3-0.9 cm. A tick's first ``warmup`` samples are averaged (the residual is zero meanwhile: the
    first cycles of a walk are learned, not judged); after that each sample moves its tick's value by ``rate``
    x the residual clipped to ``clip``, so a push moves the baseline by at most rate x clip and a new gait
    (another command) is learned in a few cycles."""

    period: int
    """Ticks per gait cycle."""
    rate: float = 0.3
    """Fraction of the (clipped) residual learned per sample."""
    clip: float = 0.02
    """Bound on the residual learned per sample, m."""
    warmup: int = 2
    """Samples of a tick averaged before its residual counts."""
    values: np.ndarray | None = None
    """(period, 2) learned signal per tick of the cycle."""
    samples: np.ndarray | None = None
    """(period,) samples seen per tick of the cycle."""

    def residual(self, tick: int, value: np.ndarray) -> np.ndarray:
        """``value`` at gait ``tick`` minus the learned baseline of that tick (zero while the tick warms up);
        then learns from it."""
        if self.values is None:
            self.values, self.samples = np.zeros((self.period, 2)), np.zeros(self.period, dtype=int)
        i = tick % self.period
        self.samples[i] += 1
        if self.samples[i] <= self.warmup:
            self.values[i] += (value - self.values[i]) / self.samples[i]
            return np.zeros(2)
        out = value - self.values[i]
        self.values[i] += self.rate * np.clip(out, -self.clip, self.clip)
        return out
