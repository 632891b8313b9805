"""Replay logged goal positions through the actuator model and a rig, for many candidate parameter sets at once.

Pendulum and test-bed rigs are one-degree-of-freedom and integrated here in numpy, vectorised over
(candidates x runs), with the same time step and the same passive terms as the MuJoCo model:

* the motor torque comes from `toddlerbot.actuation.model.motor_torque` (either model), recomputed every step from
  the goal position held since the last log sample (zero-order hold, as the firmware receives it), at the run's
  supply voltage (`toddlerbot.actuation.model.at_voltage`); while the log says torque was off the motor applies
  none (its H-bridge is open: no PD torque, no back-EMF braking);
* the armature adds to the rig's load inertia;
* damping is integrated implicitly, as MuJoCo's ``implicitfast`` integrator does;
* Coulomb friction is a budget: friction loss (plus a test-bed brake torque) plus
  `toddlerbot.actuation.model.friction_excess` of the step's speed and motor torque. Each step it removes up to
  ``dt * budget / inertia`` of speed and never reverses it, so the shaft sticks while the net torque is below the
  budget. MuJoCo treats frictionloss as a (soft) constraint with the same stick/slip behaviour (the simulators set
  it to the same budget every step); its softness makes the two differ slightly at the stick/slip transitions.

Single joints of the fixed-base robot are simulated with MuJoCo itself (`toddlerbot.sysid.robot_joint`).
"""

from __future__ import annotations

import numpy as np

from toddlerbot.actuation.model import at_voltage, friction_excess, has_friction_excess, motor_torque
from toddlerbot.sysid.batch import DT, Replay, RunBatch
from toddlerbot.sysid.params import Candidates
from toddlerbot.sysid.rigs import Rig, RobotJointRig, SimpleRig
from toddlerbot.sysid.robot_joint import simulate_robot_joint

__all__ = ["DT", "Replay", "RunBatch", "simulate", "simulate_simple_rig"]


def simulate_simple_rig(batch: RunBatch, rig: SimpleRig, candidates: Candidates, full: bool = False) -> Replay:
    """Replay every run for every candidate on a pendulum or test bed; ``full``: also velocity and torque."""
    n_cand, n_runs = len(candidates), len(batch.runs)
    p = at_voltage(candidates.arrays(batch.kp, batch.kd), batch.voltage_ratio[None, :])
    col = {k: np.asarray(candidates.fields[k], dtype=float)[:, None] for k in ("damping", "armature", "frictionloss")}
    always_on = bool(batch.torque_on.all())
    load_dependent = has_friction_excess(p)
    dt = batch.dt
    inertia = col["armature"] + rig.load_inertia
    implicit = inertia + dt * col["damping"]
    base_friction = col["frictionloss"] + rig.brake_torque
    friction_dv = dt * base_friction / implicit
    gravity = rig.gravity_gain
    q = np.broadcast_to(batch.q0, (n_cand, n_runs)).copy()
    v = np.broadcast_to(batch.v0, (n_cand, n_runs)).copy()
    shape = (len(batch.goal), n_cand, n_runs)
    record_q = np.empty(shape)
    record_v, record_tau = (np.empty(shape), np.empty(shape)) if full else (None, None)
    for k, goal in enumerate(batch.goal):
        record_q[k] = q
        tau = motor_torque(goal, q, v, p)
        if not always_on:
            tau = np.where(batch.torque_on[k], tau, 0.0)
        if full:
            record_v[k], record_tau[k] = v, tau
        if load_dependent:
            friction_dv = dt * (base_friction + friction_excess(v, tau, p)) / implicit
        net = tau - gravity * np.sin(q) if gravity else tau
        v_free = (inertia * v + dt * net) / implicit
        v = np.sign(v_free) * np.maximum(np.abs(v_free) - friction_dv, 0.0)
        q = q + dt * v
    at_samples = lambda r: None if r is None else r[batch.sample_step, :, batch.sample_run].T  # noqa: E731
    return Replay(at_samples(record_q), at_samples(record_v), at_samples(record_tau))


def simulate(batch: RunBatch, rig: Rig, candidates: Candidates, full: bool = False) -> Replay:
    """Replay every run for every candidate on any rig; ``full``: also velocity and torque."""
    if isinstance(rig, RobotJointRig):
        return simulate_robot_joint(batch, rig, candidates, full)
    return simulate_simple_rig(batch, rig, candidates, full)
