"""RL environments found by name (`rl train --env NAME`): each one registration of an
`toddlerbot.rl.environment.RLEnvironment` subclass carrying its bundle. Listing the names imports no JAX; the class
is imported when a run builds it. Installed packages add environments through the entry-point group
``toddlerbot.environments``; a script calls `ENVIRONMENTS.register`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from toddlerbot.errors import ToddlerbotError
from toddlerbot.registry import Registry

if TYPE_CHECKING:
    from toddlerbot.rl.environment import RLEnvironment

ENVIRONMENTS = Registry("environment", entry_point_group="toddlerbot.environments")
ENVIRONMENTS.register("walk", "toddlerbot.rl.walk_env:WalkEnv")
ENVIRONMENTS.register("track", "toddlerbot.rl.track_env:TrackEnv")


def environment_class(name: str) -> type[RLEnvironment]:
    """The environment registered as `name` (one line naming the registered ones otherwise), which must call
    itself by that name (the name its runs record)."""
    cls = ENVIRONMENTS.get(name)
    if getattr(cls, "name", None) != name:
        raise ToddlerbotError(f"environment {name!r}: its class {cls.__qualname__} is named "
                              f"{getattr(cls, 'name', None)!r}; expected {name!r}")
    return cls
