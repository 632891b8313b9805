"""`MotorDrive`: the actuator model's torque for fixed parameters, cheap enough to evaluate every physics substep.

`toddlerbot.actuation.model.motor_torque` is written once for numpy and JAX and recomputes every derived constant
on each call; the simulator evaluates it every 1 ms, where those numpy calls cost as much as a third of
``mj_step``. A drive computes the constants once (the same floating-point operations, so its torque equals
`motor_torque` bit for bit), skips the PWM shape and the back-EMF where they are the identity (the appendix's
model), and adds what the hardware's firmware does on top: per-motor torque enable and a torque limit.
"""

from __future__ import annotations

import numpy as np

from toddlerbot.actuation.model import ActuatorArrays, friction_excess, has_friction_excess, pwm_shape


class MotorDrive:
    """The torque each motor applies for given targets and state, for one set of actuator parameters.

    ``torque_on``: per motor, False where the motor's torque is disabled (it applies no torque; default: all on).
    ``torque_limit``: per motor |torque| bound after the actuator model, N*m (the firmware's goal current in
    current-based position mode; default: none). Both broadcast against the targets, like the parameters."""

    def __init__(self, params: ActuatorArrays, torque_on: np.ndarray | None = None,
                 torque_limit: np.ndarray | None = None) -> None:
        if torque_limit is not None and not np.all(np.asarray(torque_limit) >= 0):
            raise ValueError(f"torque_limit must be >= 0 N*m (inf: none), got {np.min(torque_limit)}")
        p = params
        self.params = p
        self._kp, self._damping = p.kp, p.kd_min + p.kd
        self._knee, self._span = p.q_dot_tau_max, p.q_dot_max - p.q_dot_tau_max
        self._tau_max, self._drop, self._brake = p.tau_max, p.tau_q_dot_max - p.tau_max, p.tau_brake
        # the least drive limit at any speed, computed as `torque` computes the limit at the knee speed and at
        # q_dot_max (rounding is monotonic, so every limit in between is at least this): below it nothing clamps
        self._never_clamped = np.minimum(np.minimum(self._tau_max, self._tau_max + self._drop), self._brake)
        self._shaped = bool(np.any(np.asarray(p.pwm_exponent) != 1.0))
        self._back_emf = bool(np.any(np.asarray(p.back_emf_damping)))
        self._off = None if torque_on is None or np.all(torque_on) else ~np.asarray(torque_on, dtype=bool)
        limit = None if torque_limit is None else np.asarray(torque_limit, dtype=float)
        self._limit = None if limit is None else (-limit, limit)
        self._plain = not (self._shaped or self._back_emf or self._off is not None or self._limit is not None)
        self.per_robot = any(np.ndim(x) > 1 for x in p)
        """Whether the parameters are rows, one per robot of a batch (the RL environment's randomised motors),
        rather than one (n_motors,) set shared by the batch."""
        self.has_friction_excess = has_friction_excess(p)
        """Whether the load-dependent friction budget (`friction_excess`) is more than zero for some motor."""

    def torque(self, targets: np.ndarray, q: np.ndarray, q_dot: np.ndarray) -> np.ndarray:
        """Motor torques, N*m, for motor targets and angles (rad) and speeds (rad/s)."""
        tau = self._kp * (targets - q) - self._damping * q_dot
        # the common case holding a pose: no motor at its limit (the ufunc's reduce: ndarray.all's wrapper costs more)
        if np.logical_and.reduce(np.abs(tau) <= self._never_clamped, axis=None):
            return tau if self._plain else self._after_limit(tau, q_dot)
        # the drive limit (Eq. 9-10): tau_max up to the knee speed, then linear to tau_q_dot_max at q_dot_max
        fraction = np.abs(q_dot)
        fraction -= self._knee
        fraction /= self._span
        np.maximum(fraction, 0.0, out=fraction)
        np.minimum(fraction, 1.0, out=fraction)
        accel = self._tau_max + fraction * self._drop
        np.maximum(tau, -np.where(q_dot > 0, self._brake, accel), out=tau)
        np.minimum(tau, np.where(q_dot < 0, self._brake, accel), out=tau)
        return self._after_limit(tau, q_dot)

    def _after_limit(self, tau: np.ndarray, q_dot: np.ndarray) -> np.ndarray:
        """The drive-limited torque shaped by the PWM, less the back-EMF, then the firmware's enable and limit."""
        if self._shaped:
            tau = pwm_shape(tau, self.params)
        if self._back_emf:
            tau = tau - self.params.back_emf_damping * q_dot
        if self._off is not None:
            np.copyto(tau, 0.0, where=self._off)
        if self._limit is not None:
            np.maximum(tau, self._limit[0], out=tau)
            np.minimum(tau, self._limit[1], out=tau)
        return tau

    def friction_excess(self, q_dot: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Coulomb friction on top of the joints' frictionloss for motors applying ``tau``, N*m (see
        `toddlerbot.actuation.model.friction_excess`)."""
        return friction_excess(q_dot, tau, self.params)
