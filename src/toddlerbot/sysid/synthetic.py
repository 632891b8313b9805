"""Synthetic logs: replay excitation profiles through the simulated rig with known parameters and add
measurement noise (used by tests, the benchmark and ``toddlerbot sysid excite --simulate``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from toddlerbot.actuation.model import actuator_arrays, at_voltage, motor_torque
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.hardware.control_table import RAD_PER_PULSE
from toddlerbot.sysid.excitation import Excitation
from toddlerbot.sysid.logs import MotorLog, write_log
from toddlerbot.sysid.manifest import write_manifest
from toddlerbot.sysid.params import Candidates
from toddlerbot.sysid.rigs import Rig, SimpleRig
from toddlerbot.sysid.simulate import DT, RunBatch, simulate


def synthesize(excitations: list[Excitation], rig: Rig, params: MotorParams, noise_std: float = 0.0,
               seed: int = 0, q0: float | None = None, dt: float = DT, voltage: float | None = None,
               rated_voltage: float | None = None) -> list[MotorLog]:
    """Runs with simulated positions (rad) plus Gaussian noise of std ``noise_std`` rad; ``voltage``: the supply
    (V, logged in every sample) relative to the motor's ``rated_voltage``."""
    runs = [MotorLog(file=Path(f"{e.name}.csv"), time=e.time, goal_position=e.goal_position,
                   position=np.full_like(e.time, e.goal_position[0] if q0 is None else q0), kp=e.kp, kd=0.0,
                   torque_enable=e.torque_enable, voltage=None if voltage is None else np.full_like(e.time, voltage))
            for e in excitations]
    batch = RunBatch.from_runs(runs, dt, rated_voltage)
    clean = batch.split(simulate(batch, rig, Candidates.of(params)).position[0])
    rng = np.random.default_rng(seed)
    return [dataclasses.replace(r, position=q + rng.normal(0.0, noise_std, q.shape))
            for r, q in zip(runs, clean, strict=True)]


def write_runs(folder: str | Path, motor: str, rig: Rig, runs: list[MotorLog], with_position: bool = True) -> Path:
    """Write one CSV per run and ``manifest.json`` into ``folder``; returns the manifest path."""
    folder = Path(folder)
    for run in runs:
        write_log(folder / run.file.name, run.time, run.goal_position, run.position if with_position else None,
                  torque_enable=run.torque_enable, voltage=run.voltage if with_position else None)
    logs = [{"file": run.file.name, "kp": run.kp, "kd": run.kd} for run in runs]
    return write_manifest(folder / "manifest.json", motor, rig, logs)


def synthesize_richer(excitations: list[Excitation], rig: SimpleRig, params: MotorParams, voltage: float,
                      rated_voltage: float, sag: float = 0.3, noise_std: float = np.radians(0.05), seed: int = 0,
                      latency: float = 0.002, dt: float = 0.00025) -> list[MotorLog]:
    """Pendulum / test-bed runs from a plant RICHER than any model the fit can express, to test the fit against
    model error rather than only noise:

    * the static friction decays exponentially (exp(-|q_dot| / stribeck_velocity)), not as the model's Gaussian;
    * the motor sees its momentary supply, not the run's median the replay assumes;
    * each position is read up to ``latency`` s before its logged timestamp (uniformly at random), as a bus
      read returns a sample taken some time before the host stamps it;
    * the supply sags by ``sag`` V per N*m of motor torque relative to the stall torque (logged, as a servo reports
      its input voltage);
    * positions are read through the 4096-count encoder and Gaussian noise, the plant steps at 0.25 ms.
    """
    n_runs = len(excitations)
    base = actuator_arrays([params] * n_runs, [e.kp for e in excitations], [0.0] * n_runs)
    duration = max(float(e.time[-1] - e.time[0]) for e in excitations)
    n_steps = round(duration / dt) + 1
    t = np.arange(n_steps) * dt
    goal = np.stack([e.goal_position[np.clip(np.searchsorted(e.time - e.time[0], t + 1e-9, "right") - 1, 0, None)]
                     for e in excitations], axis=1)
    on = np.stack([np.ones(n_steps) if e.torque_enable is None else e.torque_enable[
        np.clip(np.searchsorted(e.time - e.time[0], t + 1e-9, "right") - 1, 0, None)] for e in excitations], axis=1)
    inertia = params.armature + rig.load_inertia
    implicit = inertia + dt * params.damping
    q = np.array([e.goal_position[0] for e in excitations])
    v = np.zeros(n_runs)
    tau = np.zeros(n_runs)
    q_rec, volt_rec = np.empty((n_steps, n_runs)), np.empty((n_steps, n_runs))
    for k in range(n_steps):
        volts = voltage - sag * np.abs(tau) / params.tau_max
        p = at_voltage(base, volts / rated_voltage)
        q_rec[k], volt_rec[k] = q, volts
        gravity = rig.gravity_gain * np.sin(q)
        tau = np.where(on[k] > 0.5, motor_torque(goal[k], q, v, p), 0.0)
        budget = (params.frictionloss + p.stiction * np.exp(-np.abs(v) / p.stribeck_velocity)
                  + p.load_friction * np.abs(tau))
        v_free = (inertia * v + dt * (tau - gravity)) / implicit
        v = np.sign(v_free) * np.maximum(np.abs(v_free) - dt * budget / implicit, 0.0)
        q = q + dt * v
    rng = np.random.default_rng(seed)
    runs = []
    for i, e in enumerate(excitations):
        sampled = e.time - e.time[0] - rng.uniform(0.0, latency, len(e.time))
        at = np.clip(np.round(sampled / dt).astype(int), 0, n_steps - 1)
        measured = np.round((q_rec[at, i] + rng.normal(0.0, noise_std, len(at))) / RAD_PER_PULSE) * RAD_PER_PULSE
        runs.append(MotorLog(file=Path(f"{e.name}.csv"), time=e.time, goal_position=e.goal_position, position=measured,
                           kp=float(e.kp), kd=0.0, torque_enable=e.torque_enable,
                           voltage=np.round(volt_rec[at, i], 1)))
    return runs
