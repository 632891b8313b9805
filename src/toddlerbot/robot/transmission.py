"""Motor-space <-> joint-space maps generated from the spec's transmissions (plain numpy).

Every ToddlerBot transmission is linear, so the whole robot's map is one matrix:

* joint space: one output coordinate per motor (``neck_yaw``, ``waist_roll``, ``left_knee``, ...), in motor-id
  order of the motor that owns it; direct-drive motors are their own output.
* ``q_joint = A @ q_motor`` for positions and velocities; ``tau_motor = A.T @ tau_joint`` for torques.
* ``model_matrix`` maps motor positions to every MuJoCo joint the transmissions touch (motor joints, outputs,
  linkage rods, mirrored gripper fingers), so a consistent full configuration can be built from motor angles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.spec import (
    BevelDifferential,
    ParallelLinkage,
    RackAndPinion,
    RobotSpec,
    SpurGear,
)


@dataclass(frozen=True)
class TransmissionMap:
    motor_names: tuple[str, ...]
    """Motor joint names in motor-id order."""
    joint_names: tuple[str, ...]
    """Output joint names, same order as the motors that own them."""
    matrix: np.ndarray
    """A: q_joint = A @ q_motor."""
    model_joint_names: tuple[str, ...]
    model_matrix: np.ndarray
    """B: q_model_joint = B @ q_motor for every joint named in model_joint_names."""

    @property
    def inverse(self) -> np.ndarray:
        return np.linalg.inv(self.matrix)

    def motor_to_joint(self, q_motor: np.ndarray) -> np.ndarray:
        """Joint positions (or velocities) from motor positions (or velocities); works on (..., n) arrays."""
        return np.asarray(q_motor) @ self.matrix.T

    def joint_to_motor(self, q_joint: np.ndarray) -> np.ndarray:
        return np.asarray(q_joint) @ self.inverse.T

    def joint_to_motor_torque(self, tau_joint: np.ndarray) -> np.ndarray:
        """Motor torques that produce the given joint torques (virtual work: tau_m = A^T tau_j)."""
        return np.asarray(tau_joint) @ self.matrix

    def motor_to_model(self, q_motor: np.ndarray) -> dict[str, float]:
        values = self.model_matrix @ np.asarray(q_motor, dtype=float)
        return dict(zip(self.model_joint_names, values.tolist()))


def build_transmission_map(spec: RobotSpec) -> TransmissionMap:
    motors = [m.joint for m in spec.motors_by_id]
    index = {name: i for i, name in enumerate(motors)}
    n = len(motors)
    outputs: dict[str, np.ndarray] = {}  # output joint -> row over motors
    model: dict[str, np.ndarray] = {}

    def row(**coefs: float) -> np.ndarray:
        r = np.zeros(n)
        for motor, c in coefs.items():
            r[index[motor]] += c
        return r

    for t in spec.transmissions:
        if isinstance(t, SpurGear):
            outputs[t.driven] = row(**{t.drive: -t.ratio})
        elif isinstance(t, ParallelLinkage):
            outputs[t.driven] = row(**{t.drive: 1.0})
            for pair in t.rods:
                model[pair.rod] = model[pair.bearing] = t.rod_sign * outputs[t.driven]
        elif isinstance(t, BevelDifferential):
            m1, m2 = t.drives
            outputs[t.roll] = row(**{m1: -t.roll_coef, m2: t.roll_coef})
            outputs[t.yaw] = row(**{m1: t.yaw_coef, m2: t.yaw_coef})
        elif isinstance(t, RackAndPinion):
            outputs[t.driven[0]] = row(**{t.drive: -t.pitch_radius})
            for finger in t.driven[1:]:
                model[finger] = outputs[t.driven[0]]
    driven_motors = {m for t in spec.transmissions for m in t.joints if m in index}
    for motor in motors:
        if motor not in driven_motors:
            outputs[motor] = row(**{motor: 1.0})
    # order outputs by the lowest motor id they depend on, so joint i belongs to motor i
    joint_names = sorted(outputs, key=lambda j: (int(np.flatnonzero(outputs[j])[0]), j))
    matrix = np.array([outputs[j] for j in joint_names])
    for motor in motors:
        model[motor] = row(**{motor: 1.0})
    model.update(outputs)
    model_names = tuple(sorted(model))
    return TransmissionMap(
        motor_names=tuple(motors),
        joint_names=tuple(joint_names),
        matrix=matrix,
        model_joint_names=model_names,
        model_matrix=np.array([model[j] for j in model_names]),
    )
