"""`RunBatch`: a manifest's runs resampled onto the simulation step grid, as the replay simulators consume them;
`Replay`: what they return."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from toddlerbot.sysid.logs import MotorLog

DT = 0.001
"""Simulation step, s (the robot model's MuJoCo timestep)."""


def _held(run: MotorLog, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``values`` logged at the run's samples, held from one sample to the next, at times ``t`` from its start."""
    rel = run.time - run.time[0]
    index = np.searchsorted(rel, t + 1e-9, side="right") - 1
    return values[np.clip(index, 0, len(rel) - 1)]


def supply_voltage(run: MotorLog) -> float:
    """A run's supply, V: the median of its logged voltage. Dynamixel servos read their input under PWM load; on
    the XL330-M288 pendulum logs the reading swings between 5.8 and 9.1 V around a median of 7.30 V in every run,
    uncorrelated with the PWM duty (|r| <= 0.10), and replaying with it sample by sample, or smoothed over 0.1 s,
    predicted the other gain worse (2.4 and 2.1 deg MAE) than the constant median (1.6 deg)."""
    return float(np.median(run.voltage))


@dataclass(frozen=True)
class RunBatch:
    """Logs resampled onto a common simulation step grid (shorter runs padded with their last sample)."""

    runs: tuple[MotorLog, ...]
    dt: float
    goal: np.ndarray
    """(n_steps, R) goal position held at each step, rad."""
    torque_on: np.ndarray
    """(n_steps, R) bool: the motor is powered (False: torque off, passive)."""
    voltage_ratio: np.ndarray
    """(R,) supply voltage / the motor's rated voltage: each run's median logged voltage (a servo's reading swings
    +-1 V around its supply from sample to sample, see `supply_voltage`)."""
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
    measured_velocity: np.ndarray | None
    """(N,) measured velocities, rad/s, where every run logged them (else None)."""

    @classmethod
    def from_runs(cls, runs: tuple[MotorLog, ...] | list[MotorLog], dt: float = DT,
                  rated_voltage: float | None = None) -> RunBatch:
        """``rated_voltage``: the motor's (V); each run's supply (`supply_voltage`) is taken relative to it (None:
        ignore logged voltages)."""
        runs = tuple(runs)
        n_steps = round(max(r.duration for r in runs) / dt) + 1
        t = np.arange(n_steps) * dt
        goal, torque_on = np.empty((n_steps, len(runs))), np.empty((n_steps, len(runs)))
        ratio = np.ones(len(runs))
        steps, run_ids = [], []
        for i, run in enumerate(runs):
            goal[:, i] = _held(run, run.goal_position, t)
            torque_on[:, i] = 1.0 if run.torque_enable is None else _held(run, run.torque_enable, t)
            if run.voltage is not None and rated_voltage is not None:
                ratio[i] = supply_voltage(run) / rated_voltage
            steps.append(np.round((run.time - run.time[0]) / dt).astype(int))
            run_ids.append(np.full(len(run.time), i))
        return cls(
            runs=runs, dt=dt, goal=goal, torque_on=torque_on > 0.5, voltage_ratio=ratio,
            q0=np.array([r.position[0] for r in runs]), v0=np.array([r.initial_velocity for r in runs]),
            kp=np.array([r.kp for r in runs]), kd=np.array([r.kd for r in runs]),
            sample_step=np.concatenate(steps), sample_run=np.concatenate(run_ids),
            measured=np.concatenate([r.position for r in runs]),
            measured_velocity=None if any(r.velocity is None for r in runs)
            else np.concatenate([r.velocity for r in runs]),
        )

    def split(self, values: np.ndarray) -> list[np.ndarray]:
        """(..., N) concatenated samples -> one (..., n_i) array per run."""
        bounds = np.cumsum([len(r.time) for r in self.runs])[:-1]
        return np.split(values, bounds, axis=-1)


class Replay(NamedTuple):
    """Simulated runs at every log sample, each (P, N) for P candidates (velocity and torque only when asked)."""

    position: np.ndarray
    """rad."""
    velocity: np.ndarray | None = None
    """rad/s."""
    torque: np.ndarray | None = None
    """Motor torque (the actuator model's output, 0 while torque is off), N*m."""
