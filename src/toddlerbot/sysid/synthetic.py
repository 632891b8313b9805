"""Synthetic logs: replay excitation profiles through the simulated rig with known parameters and add
measurement noise (used by tests, the benchmark and ``toddlerbot sysid excite --simulate``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams
from toddlerbot.sysid.excitation import Excitation
from toddlerbot.sysid.logs import RunLog, write_log
from toddlerbot.sysid.manifest import write_manifest
from toddlerbot.sysid.rigs import Rig
from toddlerbot.sysid.simulate import DT, RunBatch, simulate


def synthesize(excitations: list[Excitation], rig: Rig, params: ActuatorParams, noise_std: float = 0.0,
               seed: int = 0, q0: float | None = None, dt: float = DT, voltage: float | None = None,
               rated_voltage: float | None = None) -> list[RunLog]:
    """Runs with simulated positions (rad) plus Gaussian noise of std ``noise_std`` rad; ``voltage``: the supply
    (V, logged in every sample) relative to the motor's ``rated_voltage``."""
    runs = [RunLog(file=Path(f"{e.name}.csv"), time=e.time, goal_position=e.goal_position,
                   position=np.full_like(e.time, e.goal_position[0] if q0 is None else q0), kp=e.kp, kd=0.0,
                   torque_enable=e.torque_enable, voltage=None if voltage is None else np.full_like(e.time, voltage))
            for e in excitations]
    batch = RunBatch.from_runs(runs, dt, rated_voltage)
    fields = {k: np.array([float(v)]) for k, v in dataclasses.asdict(params).items()}
    clean = batch.split(simulate(batch, rig, fields)[0])
    rng = np.random.default_rng(seed)
    return [dataclasses.replace(r, position=q + rng.normal(0.0, noise_std, q.shape))
            for r, q in zip(runs, clean, strict=True)]


def write_runs(folder: str | Path, motor: str, rig: Rig, runs: list[RunLog], with_position: bool = True) -> Path:
    """Write one CSV per run and ``manifest.json`` into ``folder``; returns the manifest path."""
    folder = Path(folder)
    for run in runs:
        write_log(folder / run.file.name, run.time, run.goal_position, run.position if with_position else None,
                  torque_enable=run.torque_enable, voltage=run.voltage if with_position else None)
    logs = [{"file": run.file.name, "kp": run.kp, "kd": run.kd} for run in runs]
    return write_manifest(folder / "manifest.json", motor, rig, logs)
