"""Table 4 as data: the controller mapping file and the pure function from controller state to commands.

`TeleopCommand` is what an operator asks for in one control step, whatever the input device: a walking command
for the walking policy, rates for torso height, waist and neck, whether Menu was just pressed, and which skill
buttons are held. `command_from_gamepad` and `command_from_keys` produce it from raw device state and the
mapping (`load_mapping`; the packaged default is ``teleop_mapping.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from toddlerbot.errors import ToddlerbotError, quoted
from toddlerbot.yaml_input import read_yaml

DEFAULT_MAPPING = Path(__file__).with_name("teleop_mapping.yaml")
MAX_MAPPING_BYTES = 100_000
"""Size cap of a controller mapping file, bytes (the packaged one is about 2 kB)."""
SKILLS = ("skill_l1", "skill_r1", "skill_l2", "skill_r2")
KEY_ACTIONS = (
    "walk_forward", "walk_backward", "walk_left", "walk_right", "turn_left", "turn_right", "stand_up", "squat_down",
    "lean_left", "lean_right", "twist_left", "twist_right", "neck_up", "neck_down", "neck_left", "neck_right",
    "menu", *SKILLS,
)


class MappingError(ToddlerbotError):
    """A controller mapping file is malformed."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class AxisMap(_Strict):
    axis: int = Field(ge=0)
    scale: float
    """Command at full deflection (m/s, rad/s); the sign picks the direction."""
    dead_zone: float | None = Field(default=None, ge=0, lt=1)


class TriggerMap(_Strict):
    axis: int = Field(ge=0)
    threshold: float = Field(gt=-1, lt=1)


class DpadMap(_Strict):
    hat: int = Field(ge=0)
    waist_roll_rate: float = Field(gt=0)
    waist_yaw_rate: float = Field(gt=0)


class AxesMap(_Strict):
    walk_x: AxisMap
    walk_y: AxisMap
    turn: AxisMap
    squat: AxisMap


class ButtonsMap(_Strict):
    menu: int = Field(ge=0)
    neck_up: int = Field(ge=0)
    neck_down: int = Field(ge=0)
    neck_left: int = Field(ge=0)
    neck_right: int = Field(ge=0)
    skill_l1: int = Field(ge=0)
    skill_r1: int = Field(ge=0)


class TeleopMapping(_Strict):
    dead_zone: float = Field(ge=0, lt=1)
    axes: AxesMap
    buttons: ButtonsMap
    triggers: dict[str, TriggerMap] = Field(default_factory=dict)
    dpad: DpadMap
    neck_rate: float = Field(gt=0)
    keyboard: dict[str, str] = Field(default_factory=dict)


def load_mapping(path: str | Path | None = None) -> TeleopMapping:
    """Read and validate a mapping file (default: the packaged Table 4 mapping)."""
    path = Path(path) if path else DEFAULT_MAPPING
    raw = read_yaml(path, "controller mapping", MappingError, MAX_MAPPING_BYTES)
    try:
        mapping = TeleopMapping.model_validate(raw)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"])
        raise MappingError(f"{path}: {loc}: {err['msg']} (got {quoted(err.get('input'))})") from None
    for trigger in mapping.triggers:
        if trigger not in SKILLS:
            raise MappingError(f"{path}: triggers.{trigger}: expected one of {', '.join(SKILLS)}")
    for key, action in mapping.keyboard.items():
        if action not in KEY_ACTIONS:
            raise MappingError(f"{path}: keyboard.{key}: unknown action {action!r}; expected one of "
                               f"{', '.join(KEY_ACTIONS)}")
    return mapping


@dataclass(frozen=True)
class TeleopCommand:
    walk: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """(vx m/s, vy m/s, yaw rate rad/s) in the robot frame, for the walking policy."""
    squat_rate: float = 0.0
    """Torso height rate, m/s (positive stands up)."""
    waist_rate: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """(roll, yaw) rad/s."""
    neck_rate: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """(pitch, yaw) rad/s; positive pitch looks up, positive yaw looks left."""
    menu_pressed: bool = False
    """Menu went down in this step (an edge, not a level)."""
    skills: frozenset[str] = frozenset()
    """Skill buttons held."""


@dataclass
class GamepadState:
    """Raw device state: axes in [-1, 1], buttons 0/1, hats (x, y) in {-1, 0, 1}."""

    axes: list[float]
    buttons: list[int]
    hats: list[tuple[int, int]]


def apply_dead_zone(value: float, dead_zone: float) -> float:
    """0 inside the dead zone, then rescaled so the output still reaches +-1 at full deflection."""
    if abs(value) <= dead_zone:
        return 0.0
    return float(np.sign(value) * (abs(value) - dead_zone) / (1 - dead_zone))


class GamepadMapper:
    """Turns successive `GamepadState`s into `TeleopCommand`s (tracks the Menu button's edge)."""

    def __init__(self, mapping: TeleopMapping) -> None:
        self.mapping = mapping
        self._menu_was_down = False

    def command(self, state: GamepadState) -> TeleopCommand:
        m = self.mapping

        def axis(a: AxisMap) -> float:
            raw = state.axes[a.axis] if a.axis < len(state.axes) else 0.0
            return apply_dead_zone(raw, m.dead_zone if a.dead_zone is None else a.dead_zone) * a.scale

        def button(index: int) -> bool:
            return index < len(state.buttons) and bool(state.buttons[index])

        hat = state.hats[m.dpad.hat] if m.dpad.hat < len(state.hats) else (0, 0)
        b = m.buttons
        menu = button(b.menu)
        pressed, self._menu_was_down = menu and not self._menu_was_down, menu
        skills = {name for name in ("skill_l1", "skill_r1") if button(getattr(b, name))}
        skills |= {name for name, t in m.triggers.items()
                   if t.axis < len(state.axes) and state.axes[t.axis] > t.threshold}
        return TeleopCommand(
            walk=np.array([axis(m.axes.walk_x), axis(m.axes.walk_y), axis(m.axes.turn)]),
            squat_rate=axis(m.axes.squat),
            waist_rate=np.array([hat[1] * m.dpad.waist_roll_rate, -hat[0] * m.dpad.waist_yaw_rate]),
            neck_rate=m.neck_rate * np.array([button(b.neck_up) - button(b.neck_down),
                                              button(b.neck_left) - button(b.neck_right)], dtype=float),
            menu_pressed=pressed,
            skills=frozenset(skills),
        )


class KeyboardMapper:
    """Turns the set of held keys (names as in the mapping) into `TeleopCommand`s with the controller's scales."""

    def __init__(self, mapping: TeleopMapping) -> None:
        self.mapping = mapping
        self._menu_was_down = False

    def command(self, held: set[str]) -> TeleopCommand:
        m = self.mapping
        actions = {m.keyboard[k] for k in held if k in m.keyboard}

        def pair(plus: str, minus: str) -> float:
            return float((plus in actions) - (minus in actions))

        menu = "menu" in actions
        pressed, self._menu_was_down = menu and not self._menu_was_down, menu
        a = m.axes
        return TeleopCommand(
            walk=np.array([pair("walk_forward", "walk_backward") * abs(a.walk_x.scale),
                           pair("walk_left", "walk_right") * abs(a.walk_y.scale),
                           pair("turn_left", "turn_right") * abs(a.turn.scale)]),
            squat_rate=pair("stand_up", "squat_down") * abs(a.squat.scale),
            waist_rate=np.array([pair("lean_left", "lean_right") * m.dpad.waist_roll_rate,
                                 pair("twist_left", "twist_right") * m.dpad.waist_yaw_rate]),
            neck_rate=m.neck_rate * np.array([pair("neck_up", "neck_down"), pair("neck_left", "neck_right")]),
            menu_pressed=pressed,
            skills=frozenset(actions & set(SKILLS)),
        )
