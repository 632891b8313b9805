"""The chain file: YAML, validated into frozen dataclasses with one-line errors naming file, skill and field.

    name: wagon                      # chain name (defaults to the file's stem)
    scene: wagon                     # the task whose scene it runs in (a name of `toddlerbot.tasks.TASKS`)
    button: l2                       # optional: teleop button that runs it (l1, r1, l2, r2)
    success: {moved: {body: wagon, at_least: 0.5}, grasped: {target: wagon_handle}}   # optional, checked at the end
    skills:
      - name: grasp
        kind: scripted_grasp         # scripted_grasp | dp | walk | hold | registered; other keys: its parameters
        target: wagon_handle
        hold: [leg]                  # motor groups kept at the targets the previous skill ended with
        until: {predicate: grasped, target: wagon_handle}   # or {after: SECONDS} or {button: l1}
        timeout: 6                   # optional: fail if `until` has not held after this long, s
        retry: {times: 2, back_off: [release]}   # optional: on the timeout, run `release`, then this skill again
      - name: push
        kind: walk
        until: {after: 8}
        recover:                     # optional: while it runs, `lost` must keep holding; once it has not for `for` s,
          lost: {predicate: holding, hands: both}  # run the back-off skills, then go on from `resume` (this
          for: 0.2                               # skill keeps the time it ran)
          back_off: [stop, release]
          resume: grasp
          times: 2
    recovery:                        # optional: skills run only as a retry's or recover's back-off
      - {name: release, kind: pose, home: [arm, gripper], until: {after: 0.8}}

Each kind's parameters are a dataclass (its `SkillKind` in `skills.SKILLS`); a predicate's are in `predicates`.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from toddlerbot.errors import ToddlerbotError, quoted
from toddlerbot.yaml_input import read_yaml

BUTTONS = ("l1", "r1", "l2", "r2")
MAX_CHAIN_BYTES = 64_000
MAX_RECOVERIES = 10
"""Most retries (or recoveries) one transition may make in a run."""
SHIPPED_DIR = Path(__file__).resolve().parent / "chains"


class ChainFileError(ToddlerbotError):
    """A chain file that cannot be used (one line: file, skill, field, what was expected)."""


@dataclass(frozen=True)
class Switch:
    """When a skill hands over: after a time, when a named predicate holds, or while a button is held."""

    after: float | None = None
    predicate: str | None = None
    params: object | None = None
    """The predicate's parameter dataclass."""
    button: str | None = None


@dataclass(frozen=True)
class Retry:
    """When a skill's `timeout` passes: run the `back_off` skills (of the chain's `recovery`) in order, then the
    skill again, from its start; at most `times` retries in a run, then the chain fails as without one."""

    times: int
    back_off: tuple[str, ...] = ()


@dataclass(frozen=True)
class Recover:
    """While a skill runs, its `lost` predicate must keep holding; once it has not held for `for_s` s: run the
    `back_off` skills in order, then go on from `resume` (the skill itself or one before it); when the chain comes
    back to the interrupted skill, it goes on with the time it had run. At most `times` in a run; a loss after that
    fails the chain."""

    lost: Switch
    for_s: float
    back_off: tuple[str, ...]
    resume: str
    times: int


@dataclass(frozen=True)
class SkillSpec:
    name: str
    kind: str
    params: object
    """The kind's parameter dataclass (`skills.skill_kind(kind).params`)."""
    until: Switch
    hold: tuple[str, ...] = ()
    timeout: float | None = None
    retry: Retry | None = None
    recover: Recover | None = None


@dataclass(frozen=True)
class ChainSpec:
    name: str
    source: str
    """Where it was read from (for messages)."""
    scene: str
    skills: tuple[SkillSpec, ...]
    button: str | None = None
    success: tuple[tuple[str, object], ...] = ()
    """(predicate name, its parameters) that must all hold when the chain ends."""
    recovery: tuple[SkillSpec, ...] = ()
    """Skills run only as the back-off of a skill's `retry` or `recover`."""

    def skill(self, name: str) -> SkillSpec:
        """The skill or recovery skill called `name`."""
        return next(s for s in self.skills + self.recovery if s.name == name)

    def with_scripted_grasps(self) -> ChainSpec:
        """The same chain with every ``scripted_grasp`` skill driven by its script, whatever checkpoint it names."""
        def scripted(specs: tuple[SkillSpec, ...]) -> tuple[SkillSpec, ...]:
            return tuple(dataclasses.replace(s, params=dataclasses.replace(s.params, checkpoint=None))  # type: ignore
                         if s.kind == "scripted_grasp" else s for s in specs)
        return dataclasses.replace(self, skills=scripted(self.skills), recovery=scripted(self.recovery))


def chain_path(name_or_path: str | Path) -> Path:
    """A shipped chain by name (``wagon``) or a chain file path."""
    shipped = SHIPPED_DIR / f"{name_or_path}.yaml"
    if shipped.is_file():
        return shipped
    path = Path(name_or_path)
    if not path.is_file():
        names = ", ".join(sorted(p.stem for p in SHIPPED_DIR.glob("*.yaml")))
        raise ChainFileError(f"{name_or_path}: no such chain file and no shipped chain of that name ({names})")
    return path


def load_chain(name_or_path: str | Path, groups: typing.Collection[str]) -> ChainSpec:
    """Read and validate a chain; `groups` are the motor groups `hold` may name (the description's)."""
    from toddlerbot.tasks import TASKS
    from toddlerbot.tasks.predicates import PREDICATES

    path = chain_path(name_or_path)
    doc = read_yaml(path, "chain file", ChainFileError, MAX_CHAIN_BYTES)
    src = str(path)
    top = _mapping(doc, src, "the file")
    _only(top, ("name", "scene", "button", "success", "skills", "recovery"), src, "the file")
    scene = _choice(top.get("scene"), TASKS.names(), src, "scene")
    button = None if top.get("button") is None else _choice(top["button"], BUTTONS, src, "button")
    raw_skills = top.get("skills")
    if not isinstance(raw_skills, list) or not raw_skills:
        raise ChainFileError(f"{src}: skills: expected a non-empty list of skills, got {quoted(raw_skills)}")
    raw_recovery = top.get("recovery", [])
    if not isinstance(raw_recovery, list):
        raise ChainFileError(f"{src}: recovery: expected a list of skills, got {quoted(raw_recovery)}")
    names: list[str] = []
    recovery = tuple(_skill(raw, src, "recovery skill", i, names, groups, PREDICATES)
                     for i, raw in enumerate(raw_recovery))
    recovery_names = tuple(names)
    skills = [_skill(raw, src, "skill", i, names, groups, PREDICATES) for i, raw in enumerate(raw_skills)]
    for i, (raw, spec) in enumerate(zip(raw_skills, skills)):
        where = f"{src}: skill {spec.name}"
        retry = None if raw.get("retry") is None else _retry(raw["retry"], spec, recovery_names, where)
        recover = None if raw.get("recover") is None else _recover(
            raw["recover"], [s.name for s in skills[: i + 1]], recovery_names, where, PREDICATES)
        skills[i] = dataclasses.replace(spec, retry=retry, recover=recover)
    success = []
    for pred, raw in _mapping(top.get("success", {}), src, "success").items():
        where = f"{src}: success: {pred}"
        _choice(pred, tuple(PREDICATES), f"{src}: success", "predicate")
        success.append((pred, build_params(PREDICATES[pred].params, _mapping(raw, where, "parameters"), where)))
    return ChainSpec(str(top.get("name", path.stem)), src, scene, tuple(skills), button, tuple(success), recovery)


def _skill(raw: object, src: str, what: str, i: int, names: list[str], groups: typing.Collection[str],
           predicates: Mapping) -> SkillSpec:
    """One skill (`what`: ``skill`` or ``recovery skill``), its name added to `names`; `retry` and `recover` are
    read later, for the skills only."""
    from toddlerbot.skills import SKILLS, skill_kind

    raw = _mapping(raw, src, f"{what} {i + 1}")
    name = raw.get("name")
    if not isinstance(name, str) or not name:
        raise ChainFileError(f"{src}: {what} {i + 1}: name: expected a non-empty string, got {quoted(name)}")
    if name in names:
        raise ChainFileError(f"{src}: {what} {name}: name: used twice")
    names.append(name)
    where = f"{src}: {what} {name}"
    if what == "recovery skill":
        for key in ("retry", "recover"):
            if key in raw:
                raise ChainFileError(f"{where}: {key}: only the chain's skills retry or recover, not a recovery skill")
    kind = _choice(raw.get("kind"), SKILLS.names(), where, "kind")
    hold = raw.get("hold", [])
    if not isinstance(hold, list) or any(g not in groups for g in hold):
        raise ChainFileError(f"{where}: hold: expected a list of motor groups from {', '.join(groups)}, "
                             f"got {quoted(hold)}")
    timeout = raw.get("timeout")
    if timeout is not None:
        timeout = _positive(timeout, where, "timeout")
    until = _switch(raw.get("until"), where, predicates)
    params = build_params(skill_kind(kind).params, {k: v for k, v in raw.items() if k not in
                                                    ("name", "kind", "hold", "timeout", "until", "retry", "recover")},
                          where)
    return SkillSpec(name, kind, params, until, tuple(hold), timeout)


def _retry(raw: object, spec: SkillSpec, recovery: tuple[str, ...], where: str) -> Retry:
    raw = _mapping(raw, where, "retry")
    _only(raw, ("times", "back_off"), where, "retry")
    if spec.timeout is None:
        raise ChainFileError(f"{where}: retry: a retry follows the skill's timeout, and it has none")
    return Retry(_times(raw.get("times"), where, "retry.times"), _back_off(raw.get("back_off", []), recovery, where,
                                                                        "retry.back_off"))


def _recover(raw: object, resumable: list[str], recovery: tuple[str, ...], where: str, predicates: Mapping
             ) -> Recover:
    raw = _mapping(raw, where, "recover")
    _only(raw, ("lost", "for", "back_off", "resume", "times"), where, "recover")
    lost = _mapping(raw.get("lost"), where, "recover.lost")
    if "predicate" not in lost:
        raise ChainFileError(f"{where}: recover.lost: expected {{predicate: NAME, ...parameters}}, got {quoted(lost)}")
    lost_for = _typed(raw.get("for", 0.0), float, where, "recover.for")
    if not 0 <= lost_for <= 60:  # type: ignore[operator]
        raise ChainFileError(f"{where}: recover.for: expected seconds in [0, 60], got {quoted(raw['for'])}")
    return Recover(_switch(lost, where, predicates, "recover.lost"), lost_for,  # type: ignore[arg-type]
                   _back_off(raw.get("back_off", []), recovery, where, "recover.back_off"),
                   _choice(raw.get("resume"), tuple(resumable), where, "recover.resume"),
                   _times(raw.get("times"), where, "recover.times"))


def _times(value: object, where: str, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_RECOVERIES:
        raise ChainFileError(f"{where}: {field}: expected a whole number in [1, {MAX_RECOVERIES}], got {quoted(value)}")
    return value


def _back_off(value: object, recovery: tuple[str, ...], where: str, field: str) -> tuple[str, ...]:
    if not isinstance(value, list) or any(name not in recovery for name in value):
        known = ", ".join(recovery) or "none declared"
        raise ChainFileError(f"{where}: {field}: expected a list of the chain's recovery skills ({known}), "
                             f"got {quoted(value)}")
    return tuple(value)


def _switch(raw: object, where: str, predicates: Mapping, field: str = "until") -> Switch:
    raw = _mapping(raw, where, field)
    keys = [k for k in ("after", "predicate", "button") if k in raw]
    if len(keys) != 1:
        raise ChainFileError(f"{where}: {field}: expected exactly one of after, predicate, button; "
                             f"got {quoted(sorted(raw))}")
    if keys[0] == "after":
        _only(raw, ("after",), where, field)
        return Switch(after=_positive(raw["after"], where, f"{field}.after"))
    if keys[0] == "button":
        _only(raw, ("button",), where, field)
        return Switch(button=_choice(raw["button"], BUTTONS, where, f"{field}.button"))
    name = _choice(raw["predicate"], tuple(predicates), where, f"{field}.predicate")
    params = build_params(predicates[name].params, {k: v for k, v in raw.items() if k != "predicate"},
                          f"{where}: {field}")
    return Switch(predicate=name, params=params)


def build_params(cls: type, raw: Mapping, where: str) -> object:
    """An instance of the parameter dataclass `cls` from `raw`, each value checked against the field's type."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    _only(raw, tuple(fields), where, "parameters")
    values = {}
    for name, value in raw.items():
        values[name] = _typed(value, hints[name], where, name)
    missing = [n for n, f in fields.items() if n not in values and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    if missing:
        raise ChainFileError(f"{where}: {missing[0]}: required")
    try:
        return cls(**values)
    except ValueError as exc:
        raise ChainFileError(f"{where}: {exc}") from None


def _typed(value: object, hint: object, where: str, field: str) -> object:
    """`value` converted to `hint` (float, int, str, bool, a Literal, a fixed tuple of floats, a tuple of any
    length of such, a dict of such, or X | None)."""
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    if value is None and type(None) in options:
        return None
    hint = next(o for o in options if o is not type(None))
    if typing.get_origin(hint) is typing.Literal:
        return _choice(value, typing.get_args(hint), where, field)
    if hint is bool and isinstance(value, bool):
        return value
    if hint is str and isinstance(value, str) and value:
        return value
    if hint in (float, int) and isinstance(value, int | float) and not isinstance(value, bool):
        number = hint(value)
        if number == value and number == number and abs(number) != float("inf"):
            return number
    if typing.get_origin(hint) is dict and isinstance(value, dict):
        key_hint, value_hint = typing.get_args(hint)
        return {_typed(k, key_hint, where, field): _typed(v, value_hint, where, f"{field}.{k}")
                for k, v in value.items()}
    if typing.get_origin(hint) is tuple and isinstance(value, list):
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:  # tuple[X, ...]: a list of any length
            return tuple(_typed(v, args[0], where, f"{field}[{i}]") for i, v in enumerate(value))
        if len(value) == len(args):
            return tuple(_typed(v, float, where, f"{field}[{i}]") for i, v in enumerate(value))
    name = getattr(hint, "__name__", str(hint))
    raise ChainFileError(f"{where}: {field}: expected {name}, got {quoted(value)}")


def _mapping(value: object, where: str, what: str) -> dict:
    if not isinstance(value, dict):
        raise ChainFileError(f"{where}: {what}: expected a mapping, got {quoted(value)}")
    return value


def _only(raw: Mapping, allowed: tuple[str, ...], where: str, what: str) -> None:
    unknown = [k for k in raw if k not in allowed]
    if unknown:
        raise ChainFileError(f"{where}: {what}: unknown field {unknown[0]!r}; expected {', '.join(allowed)}")


def _choice(value: object, allowed: tuple, where: str, field: str) -> str:
    if value not in allowed:
        raise ChainFileError(f"{where}: {field}: expected one of {', '.join(map(str, allowed))}, got {quoted(value)}")
    return value  # type: ignore[return-value]


def _positive(value: object, where: str, field: str) -> float:
    number = _typed(value, float, where, field)
    if not number > 0:  # type: ignore[operator]
        raise ChainFileError(f"{where}: {field}: expected a positive number of seconds, got {quoted(value)}")
    return number  # type: ignore[return-value]
