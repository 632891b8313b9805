"""Rigs a motor is identified on. Angles are motor-shaft angles in rad; torques are about the shaft in N*m.

* ``pendulum``: a point mass ``mass`` (kg) at ``length`` (m) from the shaft; q = 0 hangs straight down, so
  gravity adds -mass * g * length * sin(q).
* ``testbed``: the motor test bed: a known load inertia ``load_inertia`` (kg*m^2) on the shaft and an optional
  constant brake torque ``brake_torque`` (N*m, a powder brake: it opposes the motion like Coulomb friction).
* ``robot_joint``: one motor joint ``joint`` of the fixed-base robot model (the other motors hold the home pose
  with their catalogue parameters); simulated with MuJoCo.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from toddlerbot.errors import quoted
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sysid.errors import SysIDError

GRAVITY = 9.81
"""m/s^2."""


@dataclass(frozen=True)
class PendulumRig:
    mass: float
    length: float
    type: str = "pendulum"

    @property
    def load_inertia(self) -> float:
        """kg*m^2 about the shaft."""
        return self.mass * self.length**2

    @property
    def gravity_gain(self) -> float:
        """Gravity torque is -gravity_gain * sin(q), N*m."""
        return self.mass * GRAVITY * self.length

    @property
    def brake_torque(self) -> float:
        """A pendulum has no brake, N*m."""
        return 0.0


@dataclass(frozen=True)
class TestBedRig:
    load_inertia: float
    brake_torque: float = 0.0
    type: str = "testbed"

    @property
    def gravity_gain(self) -> float:
        """The test-bed shaft is balanced: no gravity torque."""
        return 0.0


@dataclass(frozen=True)
class RobotJointRig:
    joint: str
    """Motor joint of the robot spec, e.g. ``left_elbow_roll``."""
    type: str = "robot_joint"
    description: RobotDescription | None = field(default=None, compare=False, repr=False)
    """The robot the joint belongs to (None: the packaged robot with the catalogue's parameters)."""

    @property
    def robot(self) -> RobotDescription:
        return self.description or _packaged_robot()


@cache
def _packaged_robot() -> RobotDescription:
    return RobotDescription.load()


Rig = PendulumRig | TestBedRig | RobotJointRig
SimpleRig = PendulumRig | TestBedRig

_FIELDS: dict[str, tuple[type, tuple[str, ...], tuple[str, ...]]] = {
    # type -> (class, required number fields, optional number fields)
    "pendulum": (PendulumRig, ("mass", "length"), ()),
    "testbed": (TestBedRig, ("load_inertia",), ("brake_torque",)),
}


def parse_rig(raw: Any, source: str, description: RobotDescription | None = None) -> Rig:
    """A rig from its manifest entry, e.g. ``{"type": "pendulum", "mass": 0.49, "length": 0.1}``;
    ``description``: the robot of a ``robot_joint`` rig (default: the packaged robot)."""
    kinds = ", ".join([*_FIELDS, "robot_joint"])
    if not isinstance(raw, dict) or "type" not in raw:
        raise SysIDError(f"{source}: 'rig' must be a mapping with a 'type' (one of {kinds})")
    kind = raw["type"]
    if kind == "robot_joint":
        joint = raw.get("joint")
        if not isinstance(joint, str) or not joint:
            raise SysIDError(f"{source}: rig 'robot_joint' needs 'joint' (a motor joint name of the robot spec)")
        _no_extra(raw, {"type", "joint"}, source)
        return RobotJointRig(joint=joint, description=description)
    if kind not in _FIELDS:
        raise SysIDError(f"{source}: unknown rig type {kind!r}; expected one of {kinds}")
    cls, required, optional = _FIELDS[kind]
    _no_extra(raw, {"type", *required, *optional}, source)
    values = {}
    for name in (*required, *optional):
        if name not in raw:
            if name in required:
                raise SysIDError(f"{source}: rig {kind!r} is missing {name!r}")
            continue
        value = raw[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise SysIDError(f"{source}: rig field {name!r} must be a finite number >= 0, got {quoted(value)}")
        values[name] = float(value)
    if kind == "testbed" and values["load_inertia"] <= 0:
        raise SysIDError(f"{source}: rig field 'load_inertia' must be > 0 kg*m^2")
    return cls(**values)


def rig_to_dict(rig: Rig) -> dict[str, Any]:
    """The manifest entry of a rig."""
    if isinstance(rig, PendulumRig):
        return {"type": rig.type, "mass": rig.mass, "length": rig.length}
    if isinstance(rig, TestBedRig):
        return {"type": rig.type, "load_inertia": rig.load_inertia, "brake_torque": rig.brake_torque}
    return {"type": rig.type, "joint": rig.joint}


def _no_extra(raw: dict, allowed: set[str], source: str) -> None:
    extra = sorted(set(raw) - allowed)
    if extra:
        raise SysIDError(f"{source}: rig {raw['type']!r} has unknown field(s) {', '.join(extra)}; "
                         f"allowed: {', '.join(sorted(allowed))}")
