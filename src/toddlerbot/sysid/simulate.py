"""Replay logged goal positions through the actuator model and a rig, for many candidate parameter sets at once.

Pendulum and test-bed rigs are one-degree-of-freedom and integrated here in numpy, vectorised over
(candidates x runs), with the same time step and the same passive terms as the MuJoCo model:

* the motor torque comes from `toddlerbot.actuation.model.motor_torque` (Eq. 8-10 and the optional extended
  friction), recomputed every step from the goal position held since the last log sample (zero-order hold, as the
  firmware receives it), at the logged supply voltage (`toddlerbot.actuation.model.at_voltage`); while the log
  says torque was off the motor is passive (`passive_torque`: no PD torque, no kd_min);
* the armature adds to the rig's load inertia;
* damping is integrated implicitly, as MuJoCo's ``implicitfast`` integrator does;
* friction loss (plus a test-bed brake torque) is exact time-stepped Coulomb friction: in each step it removes up
  to ``dt * frictionloss / inertia`` of speed and never reverses it, so the shaft sticks while the net torque is
  below the friction loss. MuJoCo treats frictionloss as a (soft) constraint with the same stick/slip behaviour;
  its constraint softness makes the two differ slightly at the stick/slip transitions.

Single joints of the fixed-base robot are simulated with MuJoCo itself (`toddlerbot.sysid.robot_joint`).
"""

from __future__ import annotations

import numpy as np

from toddlerbot.actuation.model import (
    ActuatorArrays,
    at_voltage,
    limit_torque,
    motor_torque,
    passive_torque,
    pd_torque,
)
from toddlerbot.sysid.batch import DT, RunBatch
from toddlerbot.sysid.rigs import Rig, RobotJointRig, SimpleRig
from toddlerbot.sysid.robot_joint import simulate_robot_joint

__all__ = ["DT", "RunBatch", "simulate", "simulate_simple_rig"]


def simulate_simple_rig(batch: RunBatch, rig: SimpleRig, fields: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated positions (P, N) at every log sample, for P candidates (``fields``: ActuatorParams field name ->
    (P,) array, see `toddlerbot.sysid.params.from_unit`)."""
    col = {k: np.asarray(v, dtype=float)[:, None] for k, v in fields.items()}
    n_cand, n_runs = len(fields["damping"]), len(batch.runs)
    p = ActuatorArrays(
        kp=batch.kp[None, :] / col["kp_scale"], kd=batch.kd[None, :] / col["kp_scale"], kd_min=col["kd_min"],
        tau_max=col["tau_max"], q_dot_tau_max=col["q_dot_tau_max"], q_dot_max=col["q_dot_max"],
        tau_q_dot_max=col["tau_q_dot_max"], tau_brake=col["tau_brake"], stiction=col["stiction"],
        stribeck_velocity=col["stribeck_velocity"], load_friction=col["load_friction"],
    )
    # the logged voltage is held between samples: rescale the parameters only on the steps where it changes
    voltage_changes = np.r_[False, np.any(np.diff(batch.voltage_ratio, axis=0) != 0, axis=1)]
    p_now = at_voltage(p, batch.voltage_ratio[0])
    always_on = bool(batch.torque_on.all())
    # the appendix's model (no extended friction in any candidate): skip computing a friction term that is 0
    appendix_model = not np.any(col["stiction"]) and not np.any(col["load_friction"])
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
        if voltage_changes[k]:
            p_now = at_voltage(p, batch.voltage_ratio[k])
        if appendix_model:
            tau = limit_torque(pd_torque(goal, q, v, p_now), v, p_now)
        else:
            tau = motor_torque(goal, q, v, p_now)
        if not always_on and not batch.torque_on[k].all():
            tau = np.where(batch.torque_on[k], tau, passive_torque(v, p_now))
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
