"""A keyframe motion played on the CPU simulator, perturbed, by open-loop `replay` or by an exported tracking policy
(`track`), judged against the motion's reference (`benchmarks/bench_track_trials.py`, the tests). numpy only.

A trial starts the (perturbed) simulated robot where the motion starts (lying on the floor for a get-up motion,
`robot.floor_pose.place_on_floor`, as training does), plays the motion and the hold after it for as many control
steps as the reference has rows, and compares every step with the reference row of that time (the motion played on
the training model, `rl.motion_reference`). It **completed** when the robot never left the reference by the
tracking environment's termination thresholds (`TrackConfig`: torso orientation, height, horizontal drift) and ends
as the reference ends: standing where it ends upright (torso at least `HEIGHT_FRACTION` of the standing height,
uprightness at least `UPRIGHTNESS`: the get-up benchmark's bar, `policies.get_up_trials`), else with the torso's up
axis within `END_TILT_RAD` of the reference's last (a roll ends lying on the front).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from toddlerbot.policies.base import Policy
from toddlerbot.policies.get_up_trials import HEIGHT_FRACTION, UPRIGHTNESS
from toddlerbot.policies.motions import Motion, full_pose, load_motion
from toddlerbot.policies.replay import ReplayPolicy
from toddlerbot.policies.track import TrackPolicy
from toddlerbot.policies.walk_feedback import attitude
from toddlerbot.rl.model import training_model
from toddlerbot.rl.motion_reference import MotionReference, build_reference
from toddlerbot.rl.track_config import TrackConfig
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.floor_pose import place_on_floor
from toddlerbot.sim.actuated import MotorAddresses
from toddlerbot.sim.perturbation import Perturbation, perturbed_robot

KICK_SPEED = 0.2
"""m/s of the kick condition's one horizontal kick, in a seeded direction at a seeded time during the motion."""


@dataclass(frozen=True)
class Condition:
    name: str
    perturbation: Callable[[RobotDescription, int], Perturbation]
    kick_speed: float = 0.0


CONDITIONS = (
    Condition("nominal", lambda d, s: Perturbation(seed=s)),
    Condition("torso +10%", lambda d, s: Perturbation(seed=s, torso_mass_scale=1.1)),
    Condition("friction 0.5", lambda d, s: Perturbation(seed=s, friction=0.5)),
    Condition("perturbed", lambda d, s: replace(Perturbation.sample(s, d), joint_offset=())),
    Condition(f"kick {KICK_SPEED:g} m/s", lambda d, s: Perturbation(seed=s), KICK_SPEED),
)
"""Nominal; torso 10 % heavier; floor friction 0.5; torso mass +-10 %, friction 0.5-1.0 and every motor parameter
+-10 % drawn from the seed (`Perturbation.sample`, without its joint offsets: the robot starts in the motion's pose);
one kick."""


@dataclass(frozen=True)
class MotionTrial:
    player: str
    condition: str
    seed: int
    completed: bool
    left_at: float | None
    """s when the robot first left the reference (None: it never did)."""
    stood: bool
    motor_rmse: float
    """RMS of the motor angles' error against the reference over the trial, rad."""
    tilt_error: float
    """Mean angle between the torso's up axis and the reference's over the trial, rad: the orientation error
    without the heading, which the policy cannot sense (its IMU reading is the gravity direction and the gyro)."""
    heading_error: float
    """The torso's heading at the end against the reference's (standing), rad, in [-pi, pi]."""


END_TILT_RAD = 0.5
"""How far the torso's up axis may end from the reference's last, rad, for a motion that does not end standing."""


class MotionTrials:
    """The motion's reference (built once) and trials of players on it."""

    def __init__(self, description: RobotDescription, motion: str, cfg: TrackConfig | None = None) -> None:
        """``motion``: a built-in name or a motion file; ``cfg``: the tracking configuration whose reference and
        thresholds judge the trials (default `TrackConfig`'s)."""
        self.description = description
        self.cfg = cfg = replace(cfg or TrackConfig(), motion=motion)
        self.motion: Motion = load_motion(motion, description)
        model = training_model(description, cfg)
        self.reference: MotionReference = build_reference(self.motion, description, model, cfg.ctrl_dt,
                                                          cfg.n_substeps, cfg.hold_s)
        self._ref_motor_pos = self.reference.qpos[:, MotorAddresses.of(model, description.motor_names).qpos]
        self.ends_standing = bool(up_axis(self.reference.torso_quat[-1])[2] >= UPRIGHTNESS)
        """Whether the reference ends upright (then a trial must end standing)."""

    def trial(self, player: str, condition: Condition, seed: int, weights: str | Path | None = None) -> MotionTrial:
        """Play the motion with ``player`` (``replay``, or ``track`` with ``weights``) on the robot perturbed by
        ``condition`` at ``seed``."""
        description, cfg, ref = self.description, self.cfg, self.reference
        robot = perturbed_robot(description, condition.perturbation(description, seed))
        base = self.motion.start_base
        if base is not None:
            robot.start_qpos = place_on_floor(robot.model, mujoco.MjData(robot.model), description.transmission,
                                              full_pose(self.motion, description), base.roll, base.pitch,
                                              base.z).qpos.copy()
        obs = robot.reset()
        policy: Policy = ReplayPolicy(robot, self.motion) if player == "replay" else TrackPolicy(robot, weights)
        policy.reset(obs)
        rng = np.random.default_rng([seed, 3])
        kick_row = round(rng.uniform(0.5, self.motion.duration) / cfg.ctrl_dt)
        kick = condition.kick_speed * np.array([np.cos(angle := rng.uniform(0, 2 * np.pi)), np.sin(angle)])
        squared, tilted, left_at = [], [], None
        for row in range(1, ref.n_steps + 1):
            action = policy.act(obs, np.zeros(3))
            obs = robot.step(action.motor_targets, action.kp, action.kd)
            if row == kick_row and condition.kick_speed > 0:
                robot.push(kick)
            quat = robot.base_quat
            error = 2.0 * np.arccos(np.clip(abs(float(np.dot(quat, ref.torso_quat[row]))), 0.0, 1.0))
            squared.append(np.mean((obs.motor_pos - self._ref_motor_pos[row]) ** 2))
            tilted.append(np.arccos(np.clip(np.dot(up_axis(quat), up_axis(ref.torso_quat[row])), -1.0, 1.0)))
            pos = robot.base_pos
            left = (error > cfg.max_orientation_error or abs(pos[2] - ref.torso_height[row]) > cfg.max_height_error
                    or np.linalg.norm(pos[:2] - ref.qpos[row, 0:2]) > cfg.max_position_error)
            if left and left_at is None:
                left_at = row * cfg.ctrl_dt
        stood = (robot.torso_height() >= HEIGHT_FRACTION * robot.standing_height
                 and robot.torso_uprightness() >= UPRIGHTNESS)
        ended = stood if self.ends_standing else tilted[-1] <= END_TILT_RAD
        heading = attitude(robot.base_quat)[2] - attitude(ref.torso_quat[-1])[2]
        return MotionTrial(player, condition.name, seed, left_at is None and ended, left_at, stood,
                           float(np.sqrt(np.mean(squared))), float(np.mean(tilted)),
                           float(np.angle(np.exp(1j * heading))))


def up_axis(quat: np.ndarray) -> np.ndarray:
    """The torso's z axis in the world frame, of its orientation (w, x, y, z)."""
    w, x, y, z = quat
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])

