"""Manifests (JSON or YAML) describing a set of runs on one motor and rig, e.g.

``{"motor": "XC330", "rig": {"type": "pendulum", "mass": 0.49, "length": 0.1},
"logs": [{"file": "run1.csv", "kp": 400, "kd": 0}]}``

``kp``/``kd`` are the Dynamixel firmware gains of each run (``kd`` defaults to 0); log paths are relative to the
manifest's folder.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from toddlerbot.actuation.catalogue import Catalogue, MotorModel, default_catalogue
from toddlerbot.errors import SpecError
from toddlerbot.files import atomic_write_text
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.logs import MotorLog, read_log
from toddlerbot.sysid.rigs import Rig, RobotJointRig, parse_rig, rig_to_dict
from toddlerbot.sysid.robot_joint import rig_motor


@dataclass(frozen=True)
class Manifest:
    path: Path
    motor: MotorModel
    rig: Rig
    runs: tuple[MotorLog, ...]


def load_manifest(path: str | Path, catalogue: Catalogue | None = None) -> Manifest:
    """Read a manifest and every log it names; raise `SysIDError` naming the file and the problem."""
    path = Path(path)
    catalogue = catalogue or default_catalogue()
    try:
        text = path.read_text()
    except OSError as exc:
        raise SysIDError(f"{path}: cannot read manifest ({exc.strerror or exc})") from None
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
    rig = parse_rig(raw["rig"], str(path))
    if isinstance(rig, RobotJointRig) and rig_motor(rig).name != motor.name:
        raise SysIDError(f"{path}: robot joint {rig.joint!r} is driven by a {rig_motor(rig).name}, "
                         f"but the manifest's motor is {motor.name}")
    if not isinstance(raw["logs"], list) or not raw["logs"]:
        raise SysIDError(f"{path}: 'logs' must be a non-empty list of {{file, kp, kd}}")
    runs = []
    for i, entry in enumerate(raw["logs"]):
        if not isinstance(entry, dict) or "file" not in entry or "kp" not in entry:
            raise SysIDError(f"{path}: logs[{i}] must be a mapping with 'file' and 'kp' (and optional 'kd')")
        log_path = path.parent / str(entry["file"])
        if not log_path.is_file():
            raise SysIDError(f"{path}: logs[{i}] names {entry['file']!r}, but {log_path} does not exist")
        try:
            kp, kd = float(entry["kp"]), float(entry.get("kd", 0))
        except (TypeError, ValueError):
            raise SysIDError(f"{path}: logs[{i}]: kp/kd must be numbers, got {entry.get('kp')!r}, "
                             f"{entry.get('kd')!r}") from None
        runs.append(read_log(log_path, kp, kd))
    return Manifest(path=path, motor=motor, rig=rig, runs=tuple(runs))


def write_manifest(path: str | Path, motor: str, rig: Rig, logs: list[dict[str, Any]]) -> Path:
    """Write a JSON manifest atomically; ``logs`` entries are ``{"file", "kp", "kd"}`` relative to its folder."""
    body = {"motor": motor, "rig": rig_to_dict(rig), "logs": logs}
    return atomic_write_text(path, json.dumps(body, indent=2) + "\n")
