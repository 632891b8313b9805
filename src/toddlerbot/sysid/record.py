"""Recording identification runs on a real motor: play excitation profiles through a servo at a fixed rate and
write the CSVs and manifest that ``toddlerbot sysid fit`` reads.

The servo is anything with the `Servo` methods (the CLI adapts the hardware layer's ``DynamixelBus`` to it;
tests use the Protocol 2.0 emulator), so this module needs no serial port. Angles are motor-shaft radians
relative to the zero reading taken at the start with torque off (a pendulum hanging still is q = 0).

Per run: gains set, torque on with the goal at the profile's first value, ``settle`` seconds to get there, then
every 1/rate s the goal is written and position, velocity, estimated torque and supply voltage are read; where
the profile's ``torque_enable`` schedule switches, torque is switched (off: the motor goes passive, e.g. the
``drop`` profile; on again: the goal is written first). Torque is switched off after every run and on any error.
Timestamps are those of the reads (the loop sleeps to the next tick but never catches up by skipping samples).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np

from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.excitation import Excitation
from toddlerbot.sysid.logs import MotorLog, write_log
from toddlerbot.sysid.manifest import write_manifest
from toddlerbot.sysid.rigs import Rig


class Servo(Protocol):
    """One servo as the recorder drives it (angles in rad at the motor shaft, torques in N*m)."""

    def read(self) -> tuple[float, float, float, float]:
        """(position rad, velocity rad/s, estimated torque N*m, supply voltage V)."""

    def set_gains(self, kp: int, kd: int) -> None:
        """Firmware position P and D gains."""

    def set_goal(self, position: float) -> None: ...

    def set_torque(self, on: bool) -> None: ...


def record_run(servo: Servo, ex: Excitation, zero: float, settle: float = 1.0,
               clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep
               ) -> tuple[MotorLog, np.ndarray]:
    """Play one excitation (goal relative to ``zero`` rad); returns the run and the estimated torque (N*m)."""
    n = len(ex.time)
    enable = np.ones(n) if ex.torque_enable is None else np.asarray(ex.torque_enable, dtype=float)
    columns = {name: np.empty(n) for name in ("time", "position", "velocity", "torque", "voltage")}
    servo.set_torque(False)
    servo.set_gains(ex.kp, 0)
    servo.set_goal(zero + float(ex.goal_position[0]))
    servo.set_torque(True)
    sleep(settle)
    on = True
    try:
        t0 = clock()
        for k in range(n):
            delay = t0 + float(ex.time[k] - ex.time[0]) - clock()
            if delay > 0:
                sleep(delay)
            want_on = enable[k] > 0.5
            if want_on:
                servo.set_goal(zero + float(ex.goal_position[k]))
            if want_on != on:
                servo.set_torque(want_on)
                on = want_on
            position, velocity, torque, voltage = servo.read()
            columns["time"][k] = clock() - t0
            columns["position"][k] = position - zero
            columns["velocity"][k], columns["torque"][k], columns["voltage"][k] = velocity, torque, voltage
    finally:
        servo.set_torque(False)
    run = MotorLog(file=Path(f"{ex.name}.csv"), time=columns["time"], goal_position=ex.goal_position,
                 position=columns["position"], kp=float(ex.kp), kd=0.0, velocity=columns["velocity"],
                 torque_enable=enable, voltage=columns["voltage"])
    return run, columns["torque"]


def record(servo: Servo, excitations: list[Excitation], folder: str | Path, motor: str, rig: Rig,
           settle: float = 1.0, progress: Callable[[str], None] | None = None,
           clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep) -> Path:
    """Record every excitation, write one CSV per run and ``manifest.json`` into ``folder``; returns the manifest.

    The zero is the position read with torque off before the first run."""
    if not excitations:
        raise SysIDError("nothing to record: no excitation profiles")
    servo.set_torque(False)
    sleep(settle)
    zero = servo.read()[0]
    folder = Path(folder)
    logs = []
    for ex in excitations:
        if progress is not None:
            progress(ex.name)
        run, torque = record_run(servo, ex, zero, settle, clock, sleep)
        write_log(folder / run.file.name, run.time, run.goal_position, run.position, run.velocity,
                  torque=torque, torque_enable=run.torque_enable, voltage=run.voltage)
        logs.append({"file": run.file.name, "kp": run.kp, "kd": run.kd})
    return write_manifest(folder / "manifest.json", motor, rig, logs)
