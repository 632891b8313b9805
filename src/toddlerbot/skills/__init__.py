"""Declared skill chains: an ordered list of skills read from a YAML file, each run until its switch
condition holds, on any `Robot` (sim or real) — see `spec` (file format), `predicates`, `library` (the skills),
`runner` (the chain as a `Policy`).

The skill kinds a chain file may name are found in `SKILLS`, imported on first use: the built-in ones below,
those of installed packages (entry-point group ``toddlerbot.skills``) and those added with `register_skill`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from toddlerbot.registry import Registry

if TYPE_CHECKING:
    from toddlerbot.skills.library import SkillKind

SKILLS = Registry("skill", entry_point_group="toddlerbot.skills")
"""Skill kind -> its `SkillKind` (parameter dataclass and constructor)."""
for _kind, _target in (("scripted_grasp", "SCRIPTED_GRASP"), ("dp", "DP"), ("walk", "WALK"), ("hold", "HOLD"),
                       ("pose", "POSE")):
    SKILLS.register(_kind, f"toddlerbot.skills.library:{_target}")


def register_skill(name: str, kind: SkillKind | str) -> None:
    """Offer a skill kind to chain files as ``kind: name``: a `SkillKind` or ``"module:attribute"`` naming one
    (imported when a chain first uses it). A name already registered is refused."""
    SKILLS.register(name, kind)


def skill_kind(name: str) -> SkillKind:
    """The kind registered as `name` (one line naming the kinds when there is none)."""
    return SKILLS.get(name)  # type: ignore[return-value]
