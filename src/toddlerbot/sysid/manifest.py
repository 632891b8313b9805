"""Manifests (JSON or YAML) describing a set of runs on one motor and rig, e.g.

``{"motor": "XC330", "rig": {"type": "pendulum", "mass": 0.49, "length": 0.1},
"logs": [{"file": "run1.csv", "kp": 400, "kd": 0}]}``

``kp``/``kd`` are the Dynamixel firmware gains of each run (``kd`` defaults to 0); log paths are relative to the
manifest's folder and must stay inside it (a path escaping it is refused without reading the file). An optional
``voltage`` (V, top level or per log) is the supply voltage of runs whose CSV has no ``voltage`` column; without
either, runs are taken at the motor's rated voltage.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from toddlerbot.actuation.catalogue import MotorModel, default_catalogue
from toddlerbot.errors import SpecError, quoted
from toddlerbot.files import atomic_write_text
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.logs import VOLTAGE_RANGE_V, MotorLog, read_log
from toddlerbot.sysid.rigs import Rig, RobotJointRig, parse_rig, rig_to_dict
from toddlerbot.sysid.robot_joint import rig_motor
from toddlerbot.yaml_input import read_text

MAX_MANIFEST_BYTES = 1_000_000
"""Largest manifest, bytes (a manifest of a thousand logs is about 60 kB)."""


@dataclass(frozen=True)
class Manifest:
    path: Path
    motor: MotorModel
    rig: Rig
    runs: tuple[MotorLog, ...]


def load_manifest(path: str | Path, description: RobotDescription | None = None) -> Manifest:
    """Read a manifest and every log it names; raise `SysIDError` naming the file and the problem.
    ``description``: the robot whose motor catalogue names the motor (and of a ``robot_joint`` rig); default: the
    packaged robot with the catalogue's parameters."""
    path = Path(path)
    catalogue = description.catalogue if description is not None else default_catalogue()
    text = read_text(path, "manifest", SysIDError, MAX_MANIFEST_BYTES)
    try:
        raw: Any = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        raise SysIDError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'YAML'}: {exc}") from None
    if not isinstance(raw, dict):
        raise SysIDError(f"{path}: expected a mapping with keys motor, rig, logs")
    missing = [k for k in ("motor", "rig", "logs") if k not in raw]
    if missing:
        raise SysIDError(f"{path}: missing key(s) {', '.join(missing)}")
    try:
        motor = catalogue[str(raw["motor"])]
    except SpecError:
        raise SysIDError(f"{path}: unknown motor model {raw['motor']!r}; expected one of "
                         f"{', '.join(sorted(catalogue.models))} (or an alias)") from None
    rig = parse_rig(raw["rig"], str(path), description)
    if isinstance(rig, RobotJointRig) and rig_motor(rig).name != motor.name:
        raise SysIDError(f"{path}: robot joint {rig.joint!r} is driven by a {rig_motor(rig).name}, "
                         f"but the manifest's motor is {motor.name}")
    if not isinstance(raw["logs"], list) or not raw["logs"]:
        raise SysIDError(f"{path}: 'logs' must be a non-empty list of {{file, kp, kd}}")
    default_voltage = _voltage(raw.get("voltage"), path, "voltage")
    runs: list[MotorLog] = []
    listed: dict[Path, int] = {}
    folder = path.parent.resolve()
    for i, entry in enumerate(raw["logs"]):
        if not isinstance(entry, dict) or "file" not in entry or "kp" not in entry:
            raise SysIDError(f"{path}: logs[{i}] must be a mapping with 'file' and 'kp' (and optional 'kd')")
        log_path = path.parent / str(entry["file"])
        if not log_path.resolve().is_relative_to(folder):
            raise SysIDError(f"{path}: logs[{i}] names {str(entry['file'])[:200]!r}, which is outside the "
                             f"manifest's folder {path.parent}; logs must sit in that folder or below it")
        if not log_path.is_file():
            raise SysIDError(f"{path}: logs[{i}] names {quoted(entry['file'])}, but {log_path} does not exist")
        first = listed.setdefault(log_path.resolve(), i)
        if first != i:  # one run counted twice (e.g. at two gains) would bias the fit and hide its error
            raise SysIDError(f"{path}: logs[{i}] names {quoted(entry['file'])}, which logs[{first}] already names; "
                             "each log may be listed once")
        try:
            kp, kd = float(entry["kp"]), float(entry.get("kd", 0))
        except (TypeError, ValueError):
            raise SysIDError(f"{path}: logs[{i}]: kp/kd must be numbers, got {quoted(entry.get('kp'))}, "
                             f"{quoted(entry.get('kd'))}") from None
        run = read_log(log_path, kp, kd)
        voltage = _voltage(entry.get("voltage"), path, f"logs[{i}].voltage") or default_voltage
        if run.voltage is None and voltage is not None:
            run = dataclasses.replace(run, voltage=np.full(len(run.time), voltage))
        runs.append(run)
    return Manifest(path=path, motor=motor, rig=rig, runs=tuple(runs))


def select_gains(manifest: Manifest, kp: Iterable[float]) -> Manifest:
    """The manifest with only its runs at the firmware P gains ``kp`` (to fit on one gain and evaluate on another);
    raise `SysIDError` naming the gains it has when one asked for is missing."""
    wanted = {float(k) for k in kp}
    present = sorted({run.kp for run in manifest.runs})
    missing = sorted(wanted - set(present))
    if missing:
        raise SysIDError(f"{manifest.path}: no runs at kp {', '.join(f'{k:g}' for k in missing)}; its runs have kp "
                         f"{', '.join(f'{k:g}' for k in present)}")
    return dataclasses.replace(manifest, runs=tuple(run for run in manifest.runs if run.kp in wanted))


def _voltage(value: Any, path: Path, key: str) -> float | None:
    if value is None:
        return None
    lo, hi = VOLTAGE_RANGE_V
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or \
            not lo < value <= hi:
        raise SysIDError(f"{path}: {key} must be a supply voltage > {lo:g} and <= {hi:g} V, got {quoted(value)}")
    return float(value)


def write_manifest(path: str | Path, motor: str, rig: Rig, logs: list[dict[str, Any]],
                   voltage: float | None = None) -> Path:
    """Write a JSON manifest atomically; ``logs`` entries are ``{"file", "kp", "kd"}`` relative to its folder;
    ``voltage``: supply voltage of runs without a voltage column, V."""
    body: dict[str, Any] = {"motor": motor, "rig": rig_to_dict(rig), "logs": logs}
    if voltage is not None:
        body["voltage"] = voltage
    return atomic_write_text(path, json.dumps(body, indent=2) + "\n")
