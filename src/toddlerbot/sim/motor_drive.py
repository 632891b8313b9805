"""`MotorDrive`: the actuator model as every physics substep evaluates it, plus what the servo firmware adds.

The torque is `toddlerbot.actuation.model.motor_torque` itself (the one implementation, which the MJX training
environment evaluates in JAX), followed by the firmware's per-motor torque enable and torque limit
(`firmware_torque`). With numba (`toddlerbot.sim.native`) it is compiled into the substep loop and evaluated
motor by motor; without, the same functions run on arrays. A drive keeps each robot's parameters as one
contiguous (fields, n_motors) table, ready for the compiled loop.
"""

from __future__ import annotations

import numpy as np

from toddlerbot.actuation import model as actuator_model
from toddlerbot.actuation.model import ActuatorArrays, friction_excess, has_friction_excess, motor_torque
from toddlerbot.sim.native import HAVE_NUMBA, compilable, compile_now, compiled

for _function in (actuator_model.acceleration_limit, actuator_model.pd_torque, actuator_model.drive_bounds,
                  actuator_model.limit_torque, actuator_model.pwm_shape, motor_torque, friction_excess):
    compilable(_function)


def _unpacking(fields: tuple[str, ...]):
    """`parameters_of` written out for `fields`: compiled code cannot splat an array into a NamedTuple, so the
    function that indexes each row is generated from the one list of the torque law's coefficients."""
    rows = ", ".join(f"columns[{i}]" for i in range(len(fields)))
    namespace = {"ActuatorArrays": ActuatorArrays}
    exec(compile(f"def parameters_of(columns):\n    return ActuatorArrays({rows})\n", f"<{__name__}>", "exec"),
         namespace)
    unpack = namespace["parameters_of"]
    unpack.__doc__ = ("`ActuatorArrays` from one robot's (fields, n_motors) parameter array (arrays), or one motor's "
                      "(fields,) column (floats), in field order.")
    return unpack


parameters_of = compilable(_unpacking(ActuatorArrays._fields))


@compilable
def firmware_torque(targets, q, q_dot, p: ActuatorArrays, torque_on, limit):
    """The actuator model's torque (N*m), zero where the torque is off, then clamped to +-limit (inf: none);
    elementwise, for arrays or for one motor's floats."""
    return np.clip(np.where(torque_on, motor_torque(targets, q, q_dot, p), 0.0), -limit, limit)


if HAVE_NUMBA:
    @compiled
    def drive_torque(targets: np.ndarray, q: np.ndarray, q_dot: np.ndarray, table: np.ndarray,
                     torque_on: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """`firmware_torque` for one robot's motors ((n_motors,) rad, rad/s; parameters `MotorDrive.table`),
        N*m: compiled, motor by motor."""
        tau = np.empty(len(targets))
        for j in range(len(targets)):
            tau[j] = firmware_torque(targets[j], q[j], q_dot[j], parameters_of(table[:, j]), torque_on[j],
                                     limit[j])
        return tau
else:
    def drive_torque(targets: np.ndarray, q: np.ndarray, q_dot: np.ndarray, table: np.ndarray,
                     torque_on: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """`firmware_torque` for one robot's motors ((n_motors,) rad, rad/s; parameters `MotorDrive.table`),
        N*m: interpreted, as arrays."""
        return firmware_torque(targets, q, q_dot, parameters_of(table), torque_on, limit)


class MotorDrive:
    """The torque each motor applies for given targets and state, for one set of actuator parameters.

    ``params``: (n_motors,) arrays shared by a batch of robots, or (batch, n_motors) rows, one per robot (the RL
    environment's randomised motors). ``torque_on``: per motor, False where the motor's torque is disabled (it
    applies no torque; default: all on). ``torque_limit``: per motor |torque| bound after the actuator model, N*m
    (the firmware's goal current in current-based position mode; default: none)."""

    def __init__(self, params: ActuatorArrays, torque_on: np.ndarray | None = None,
                 torque_limit: np.ndarray | None = None) -> None:
        if torque_limit is not None and not np.all(np.asarray(torque_limit) >= 0):
            raise ValueError(f"torque_limit must be >= 0 N*m (inf: none), got {np.min(torque_limit)}")
        self.params = params
        self.per_robot = any(np.ndim(x) > 1 for x in params)
        """Whether the parameters are rows, one per robot of a batch, rather than one set shared by the batch."""
        self.has_friction_excess = has_friction_excess(params)
        """Whether the load-dependent friction budget (`friction_excess`) is more than zero for some motor."""
        shape = np.broadcast_shapes(*(np.shape(x) for x in params))
        n = shape[-1]
        stacked = np.stack([np.broadcast_to(np.asarray(x, dtype=float), shape) for x in params]).reshape(len(params),
                                                                                                        -1, n)
        self._tables = np.ascontiguousarray(stacked.transpose(1, 0, 2))  # (robots, fields, motors)
        self.torque_on = np.ones(n, dtype=bool) if torque_on is None else np.broadcast_to(torque_on, n).astype(bool)
        self.limit = np.full(n, np.inf) if torque_limit is None else np.broadcast_to(
            np.asarray(torque_limit, dtype=float), n).copy()

    @property
    def tables(self) -> np.ndarray:
        """Every robot's parameters, (robots, fields, n_motors) (one row when they are shared, `per_robot` False)."""
        return self._tables

    def table(self, i: int) -> np.ndarray:
        """Robot ``i``'s parameters as one contiguous (fields, n_motors) array, in `ActuatorArrays` order."""
        return self._tables[i if self.per_robot else 0]

    def compile(self) -> None:
        """Compile the torque for these parameters now, not in the first call (`toddlerbot.sim.native.compile_now`)."""
        zeros = np.zeros(len(self.limit))
        compile_now(drive_torque, zeros, zeros, zeros, self.table(0), self.torque_on, self.limit)

    def torque(self, targets: np.ndarray, q: np.ndarray, q_dot: np.ndarray) -> np.ndarray:
        """Motor torques, N*m, for motor targets and angles (rad) and speeds (rad/s): (n_motors,) or
        (batch, n_motors) arrays."""
        targets, q, q_dot = (np.asarray(x, dtype=float) for x in (targets, q, q_dot))
        if targets.ndim == 1 and not self.per_robot:
            return drive_torque(targets, q, q_dot, self.table(0), self.torque_on, self.limit)
        targets, q, q_dot = np.broadcast_arrays(np.atleast_2d(targets), np.atleast_2d(q), np.atleast_2d(q_dot))
        return np.stack([drive_torque(np.ascontiguousarray(t), np.ascontiguousarray(a), np.ascontiguousarray(v),
                                      self.table(i), self.torque_on, self.limit)
                         for i, (t, a, v) in enumerate(zip(targets, q, q_dot, strict=True))])
