"""Zero-point calibration (appendix section 8.7): per-robot motor zero offsets, measured with the jigs in place.

With a group's 3D-printed jigs clicked in, every joint of that group sits at its zero position, so the raw
reading of each motor (pulses) *is* its zero offset: ``q_motor = (reading - offset - turns * 4096) * 2*pi/4096``.
Offsets live in a per-robot YAML file, never in the spec:

    robot: toddlerbot-07          # which physical robot
    spec: toddlerbot_v1           # spec name (with variant, e.g. toddlerbot_v1+gripper)
    offsets: {neck_yaw_drive: 2051, ...}   # pulses, one per motor
    groups: {neck: '2025-06-01T10:00:00', ...}   # when each group was calibrated

Calibration groups follow the jigs (orange arm, yellow neck, red hip, beige ankle) and are defined on the
spec's motor groups: arm = the spec's ``arm`` and ``gripper`` motors, neck = ``neck``, hip = ``waist`` and the
``leg`` motors of the hip joints, ankle = the remaining ``leg`` motors (knee and ankle).
"""

from __future__ import annotations

import datetime as _dt
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text
from toddlerbot.hardware.control_table import PULSES_PER_REV, RAD_PER_PULSE
from toddlerbot.hardware.driver import DynamixelBus
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import MotorSpec
from toddlerbot.yaml_input import read_yaml

GROUPS = ("arm", "neck", "hip", "ankle")
SAMPLES = 5
"""Readings averaged per motor."""
MAX_SPREAD_PULSES = 4
"""Largest spread of a motor's readings (about 0.35 deg): more means the joint is not held by its jig."""
MAX_SPEED = 0.05
"""Largest speed while calibrating, rad/s."""
MAX_FILE_BYTES = 1_000_000
"""Largest calibration file read, bytes (a real one is about 2 kB)."""
MAX_CHANGE_RAD = np.deg2rad(20.0)
"""Largest change from a good existing offset before the new value is called implausible (a re-seated horn
or jig moves the zero by a few degrees; a jig left out moves it by tens of degrees)."""


class CalibrationError(ToddlerbotError):
    pass


def spec_label(description: RobotDescription) -> str:
    """The spec name a calibration file records, with the variant: ``toddlerbot_v1+gripper``."""
    spec = description.spec
    return spec.name if spec.variant is None else f"{spec.name}+{spec.variant}"


def group_of(motor: MotorSpec) -> str:
    """Calibration group (jig) of a motor, from its spec group and joint name."""
    if motor.group in ("arm", "gripper"):
        return "arm"
    if motor.group == "neck":
        return "neck"
    if motor.group == "waist" or (motor.group == "leg" and "hip" in motor.joint):
        return "hip"
    if motor.group == "leg":
        return "ankle"
    raise CalibrationError(f"motor {motor.id} ({motor.joint}): spec group {motor.group!r} has no calibration jig")


def group_motors(description: RobotDescription, group: str) -> list[MotorSpec]:
    if group not in GROUPS:
        raise CalibrationError(f"unknown calibration group {group!r}; expected one of {', '.join(GROUPS)}")
    return [m for m in description.motors if group_of(m) == group]


@dataclass
class Calibration:
    robot: str
    spec: str
    offsets: dict[str, int] = field(default_factory=dict)
    """Motor name -> reading at the zero position, pulses."""
    groups: dict[str, str] = field(default_factory=dict)

    def offsets_for(self, description: RobotDescription, source: str = "calibration") -> np.ndarray:
        """Offsets (pulses) in motor-id order; raises unless the file is complete and made for this robot."""
        if self.spec != spec_label(description):
            raise CalibrationError(
                f"{source}: made for spec {self.spec!r} (robot {self.robot!r}), "
                f"but this robot uses {spec_label(description)!r}"
            )
        unknown = sorted(set(self.offsets) - set(description.motor_names))
        if unknown:
            raise CalibrationError(f"{source}: offsets: unknown motor {unknown[0]!r} (not a motor of {self.spec})")
        missing = [m.joint for m in description.motors if m.joint not in self.offsets]
        if missing:
            groups = sorted({group_of(m) for m in description.motors if m.joint in missing})
            raise CalibrationError(
                f"{source}: no zero offset for {', '.join(missing)}; run `toddlerbot hw calibrate` for group(s) "
                f"{', '.join(groups)}"
            )
        return np.array([self.offsets[m.joint] for m in description.motors], dtype=np.int64)


def load_calibration(
    path: str | Path, description: RobotDescription | None = None, robot: str | None = None
) -> Calibration:
    """Read a calibration file; with `description`/`robot`, refuse a file made for another robot.

    Every offset must be an integer number of pulses in 0..4095 (one turn, as `measure_offsets` writes them):
    anything else (a float, ``true``, a number of radians, a value past one turn) is refused naming the motor."""
    path = Path(path)
    raw = read_yaml(path, "calibration file", CalibrationError, MAX_FILE_BYTES)
    if not isinstance(raw, dict) or not isinstance(raw.get("robot"), str) or not isinstance(raw.get("spec"), str):
        raise CalibrationError(f"{path}: expected a mapping with 'robot', 'spec' and 'offsets'")
    offsets = raw.get("offsets") or {}
    if not isinstance(offsets, dict):
        raise CalibrationError(f"{path}: 'offsets' must map motor names to integer pulses")
    for name, value in offsets.items():
        # bool is an int subclass: `true` must not pass as 1
        if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < PULSES_PER_REV:
            raise CalibrationError(
                f"{path}: offsets.{name} is {value!r}; expected an integer number of pulses in 0..{PULSES_PER_REV - 1}"
            )
    groups = raw.get("groups") or {}
    if not isinstance(groups, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in groups.items()):
        raise CalibrationError(f"{path}: 'groups' must map group names to calibration times (text)")
    cal = Calibration(raw["robot"], raw["spec"], {str(k): v for k, v in offsets.items()}, dict(groups))
    if robot is not None and cal.robot != robot:
        raise CalibrationError(f"{path}: calibration of robot {cal.robot!r}, not of {robot!r}")
    if description is not None:
        cal.offsets_for(description, str(path))
    return cal


def save_calibration(cal: Calibration, path: str | Path) -> None:
    """Write atomically (temporary file + rename): a crash never leaves a half-written file."""
    text = yaml.safe_dump(
        {"robot": cal.robot, "spec": cal.spec, "offsets": dict(cal.offsets), "groups": dict(cal.groups)},
        sort_keys=False,
    )
    atomic_write_text(path, text)


def measure_offsets(bus: DynamixelBus, samples: int = SAMPLES, interval: float = 0.02) -> dict[str, int]:
    """Read the bus's motors (torque off, jigs in place) and return plausible offsets by motor name.

    Checks: every motor answers with its model number, the readings are steady (spread <= MAX_SPREAD_PULSES)
    and the joints are still (|speed| <= MAX_SPEED). Offsets are wrapped into one turn (0..4095)."""
    bus.scan()
    bus.disable_torque()
    readings, speeds = [], []
    for _ in range(samples):
        state = bus.read_state()
        readings.append(state.position)
        speeds.append(np.abs(state.velocity))
        time.sleep(interval)
    readings_arr, speeds_arr = np.array(readings), np.array(speeds)
    problems = []
    for k, m in enumerate(bus.motors):
        spread = int(readings_arr[:, k].max() - readings_arr[:, k].min())
        if spread > MAX_SPREAD_PULSES or speeds_arr[:, k].max() > MAX_SPEED:
            problems.append(
                f"{m.label} is moving (readings spread {spread} pulses, up to {speeds_arr[:, k].max():.2f} rad/s): "
                f"is its jig clicked in?"
            )
    if problems:
        raise CalibrationError("implausible readings, nothing written: " + "; ".join(problems))
    mean = np.rint(readings_arr.mean(axis=0)).astype(np.int64)
    return {m.name: int(v % PULSES_PER_REV) for m, v in zip(bus.motors, mean, strict=True)}


def merge(existing: Calibration | None, robot: str, description: RobotDescription, group: str,
          offsets: dict[str, int], force: bool = False, source: str = "calibration") -> Calibration:
    """The calibration with one group's new offsets; refuses an existing robot/spec mismatch and, unless
    `force`, offsets that moved by more than MAX_CHANGE_RAD from the existing file's."""
    if existing is None:
        cal = Calibration(robot, spec_label(description))
    else:
        if existing.robot != robot or existing.spec != spec_label(description):
            raise CalibrationError(
                f"{source}: belongs to robot {existing.robot!r} (spec {existing.spec!r}), not to robot {robot!r} "
                f"(spec {spec_label(description)!r}); choose another file"
            )
        cal = Calibration(existing.robot, existing.spec, dict(existing.offsets), dict(existing.groups))
    if not force:
        jumps = []
        for name, value in offsets.items():
            if name in cal.offsets:
                diff = (value - cal.offsets[name] + PULSES_PER_REV // 2) % PULSES_PER_REV - PULSES_PER_REV // 2
                if abs(diff) * RAD_PER_PULSE > MAX_CHANGE_RAD:
                    jumps.append(f"{name} moved {np.rad2deg(diff * RAD_PER_PULSE):+.1f} deg")
        if jumps:
            raise CalibrationError(
                f"{source}: refusing to overwrite good offsets with implausible ones ({'; '.join(jumps)}; limit "
                f"{np.rad2deg(MAX_CHANGE_RAD):.0f} deg). Check the {group} jigs, or pass --force after a rebuild"
            )
    cal.offsets.update(offsets)
    cal.groups[group] = _dt.datetime.now().isoformat(timespec="seconds")
    return cal
