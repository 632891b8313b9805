"""Replay logged goal positions through the actuator model and a rig, for many candidate parameter sets at once.

Pendulum and test-bed rigs are one-degree-of-freedom and integrated here in numpy, vectorised over
(candidates x runs), with the same time step and the same passive terms as the MuJoCo model:

* the motor torque comes from `toddlerbot.actuation.model.motor_torque` (Eq. 8-10), recomputed every step from
  the goal position held since the last log sample (zero-order hold, as the firmware receives it);
* the armature adds to the rig's load inertia;
* damping is integrated implicitly, as MuJoCo's ``implicitfast`` integrator does;
* friction loss (plus a test-bed brake torque) is exact time-stepped Coulomb friction: in each step it removes up
  to ``dt * frictionloss / inertia`` of speed and never reverses it, so the shaft sticks while the net torque is
  below the friction loss. MuJoCo treats frictionloss as a (soft) constraint with the same stick/slip behaviour;
  its constraint softness makes the two differ slightly at the stick/slip transitions.

Single joints of the fixed-base robot are simulated with MuJoCo itself (`toddlerbot.sysid.robot_joint`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.actuation.model import ActuatorArrays, motor_torque
from toddlerbot.sysid.logs import MotorLog
from toddlerbot.sysid.rigs import Rig, RobotJointRig, SimpleRig
from toddlerbot.sysid.robot_joint import simulate_robot_joint

DT = 0.001
"""Simulation step, s (the robot model's MuJoCo timestep)."""


@dataclass(frozen=True)
class RunBatch:
    """Logs resampled onto a common simulation step grid (shorter runs padded with their last goal)."""

    runs: tuple[MotorLog, ...]
    dt: float
    goal: np.ndarray
    """(n_steps, R) goal position held at each step, rad."""
    q0: np.ndarray
    """(R,) logged initial position, rad."""
    v0: np.ndarray
    """(R,) logged initial velocity, rad/s (0 without a velocity column)."""
    kp: np.ndarray
    """(R,) firmware P gains."""
    kd: np.ndarray
    """(R,) firmware D gains."""
    sample_step: np.ndarray
    """(N,) simulation step of every log sample of every run, concatenated run after run."""
    sample_run: np.ndarray
    """(N,) run index of every sample."""
    measured: np.ndarray
    """(N,) measured positions, rad."""

    @classmethod
    def from_runs(cls, runs: tuple[MotorLog, ...] | list[MotorLog], dt: float = DT) -> RunBatch:
        runs = tuple(runs)
        n_steps = round(max(r.duration for r in runs) / dt) + 1
        goal = np.empty((n_steps, len(runs)))
        steps, run_ids = [], []
        t = np.arange(n_steps) * dt
        for i, run in enumerate(runs):
            rel = run.time - run.time[0]
            held = np.searchsorted(rel, t + 1e-9, side="right") - 1
            goal[:, i] = run.goal_position[np.clip(held, 0, len(rel) - 1)]
            steps.append(np.round(rel / dt).astype(int))
            run_ids.append(np.full(len(rel), i))
        return cls(
            runs=runs, dt=dt, goal=goal,
            q0=np.array([r.position[0] for r in runs]), v0=np.array([r.initial_velocity for r in runs]),
            kp=np.array([r.kp for r in runs]), kd=np.array([r.kd for r in runs]),
            sample_step=np.concatenate(steps), sample_run=np.concatenate(run_ids),
            measured=np.concatenate([r.position for r in runs]),
        )

    def split(self, values: np.ndarray) -> list[np.ndarray]:
        """(..., N) concatenated samples -> one (..., n_i) array per run."""
        bounds = np.cumsum([len(r.time) for r in self.runs])[:-1]
        return np.split(values, bounds, axis=-1)


def simulate_simple_rig(batch: RunBatch, rig: SimpleRig, fields: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated positions (P, N) at every log sample, for P candidates (``fields``: ActuatorParams field name ->
    (P,) array, see `toddlerbot.sysid.params.from_unit`)."""
    col = {k: np.asarray(v, dtype=float)[:, None] for k, v in fields.items()}
    n_cand, n_runs = len(fields["damping"]), len(batch.runs)
    p = ActuatorArrays(
        kp=batch.kp[None, :] / col["kp_scale"], kd=batch.kd[None, :] / col["kp_scale"], kd_min=col["kd_min"],
        tau_max=col["tau_max"], q_dot_tau_max=col["q_dot_tau_max"], q_dot_max=col["q_dot_max"],
        tau_q_dot_max=col["tau_q_dot_max"], tau_brake=col["tau_brake"],
    )
    dt = batch.dt
    inertia = col["armature"] + rig.load_inertia
    implicit = inertia + dt * col["damping"]
    friction_dv = dt * (col["frictionloss"] + rig.brake_torque) / implicit
    gravity = rig.gravity_gain
    q = np.broadcast_to(batch.q0, (n_cand, n_runs)).copy()
    v = np.broadcast_to(batch.v0, (n_cand, n_runs)).copy()
    record = np.empty((len(batch.goal), n_cand, n_runs))
    for k, goal in enumerate(batch.goal):
        record[k] = q
        tau = motor_torque(goal, q, v, p)
        if gravity:
            tau = tau - gravity * np.sin(q)
        v_free = (inertia * v + dt * tau) / implicit
        v = np.sign(v_free) * np.maximum(np.abs(v_free) - friction_dv, 0.0)
        q = q + dt * v
    return record[batch.sample_step, :, batch.sample_run].T


def simulate(batch: RunBatch, rig: Rig, fields: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated positions (P, N) at every log sample for P candidate parameter sets, on any rig."""
    if isinstance(rig, RobotJointRig):
        return simulate_robot_joint(batch, rig, fields)
    return simulate_simple_rig(batch, rig, fields)
