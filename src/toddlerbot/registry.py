"""Names mapped to factories that are imported only when used: the policies and robot variants the CLI offers.

A factory is a callable or a ``"module:attribute"`` string; a string is imported on the first `get` of its name,
so listing names (the CLI's help) imports nothing. Installed packages add names through an entry-point group
(``[project.entry-points."toddlerbot.policies"]`` in their pyproject.toml), read on the first use of the registry;
scripts call `Registry.register`. A name is registered once: a second registration is an error, never a silent
replacement of a built-in.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

from toddlerbot.errors import ToddlerbotError

Factory = Callable[..., Any]
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""Names are listed comma-separated in errors and help texts and typed as CLI values: no spaces or commas."""
_TARGET = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_][\w.]*")


class Registry:
    """Names of one kind (``policy``, ``variant``) mapped to their factories, in registration order."""

    def __init__(self, kind: str, entry_point_group: str | None = None) -> None:
        self.kind = kind
        self.entry_point_group = entry_point_group
        self._targets: dict[str, str | Factory] = {}
        self._resolved: dict[str, Factory] = {}
        self._plugins_read = entry_point_group is None

    def register(self, name: str, factory: str | Factory | None = None):
        """Register `factory` (a callable or ``"module:attribute"``) as `name`; without `factory`, a decorator
        that registers what it decorates. A name already registered is refused in one line."""
        if factory is None:
            def decorate(target: Factory) -> Factory:
                self.register(name, target)
                return target

            return decorate
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise ToddlerbotError(f"{self.kind} name {name!r}: expected letters, digits, '-', '_' or '.'")
        if isinstance(factory, str):
            if not _TARGET.fullmatch(factory):
                raise ToddlerbotError(f"{self.kind} {name!r}: {factory!r} is not 'module:attribute'")
        elif not callable(factory):
            raise ToddlerbotError(f"{self.kind} {name!r}: expected a callable or 'module:attribute', "
                                  f"got {type(factory).__name__}")
        if name in self._targets:
            raise ToddlerbotError(f"{self.kind} {name!r} is already registered (to {_describe(self._targets[name])})")
        self._targets[name] = factory
        return factory

    def names(self) -> tuple[str, ...]:
        """Every registered name, built-in ones first."""
        self._read_plugins()
        return tuple(self._targets)

    def __contains__(self, name: object) -> bool:
        return name in self.names()

    def get(self, name: str) -> Factory:
        """The factory registered as `name`, imported now if it was given as a string."""
        if name not in self:
            raise ToddlerbotError(f"unknown {self.kind} {name!r}; expected one of {', '.join(self._targets)}")
        if name not in self._resolved:
            self._resolved[name] = self._import(name, self._targets[name])
        return self._resolved[name]

    def _import(self, name: str, target: str | Factory) -> Factory:
        if not isinstance(target, str):
            return target
        module_name, attribute = target.split(":")
        try:
            value: Any = importlib.import_module(module_name)
        except ImportError as exc:
            raise ToddlerbotError(f"{self.kind} {name!r}: cannot import {module_name} ({exc})") from None
        for part in attribute.split("."):
            if not hasattr(value, part):
                raise ToddlerbotError(f"{self.kind} {name!r}: {module_name} has no attribute {attribute!r}")
            value = getattr(value, part)
        if not callable(value):
            raise ToddlerbotError(f"{self.kind} {name!r}: {target} is a {type(value).__name__}, not a callable")
        return value

    def _read_plugins(self) -> None:
        """Register the installed packages' entry points, once; their modules are imported only when used."""
        if self._plugins_read:
            return
        self._plugins_read = True
        for point in entry_points(group=self.entry_point_group):
            if point.name in self._targets:
                package = point.dist.name if point.dist is not None else "an installed package"
                raise ToddlerbotError(f"{self.kind} {point.name!r} from {package} ({point.value}) is already "
                                      f"registered (to {_describe(self._targets[point.name])})")
            self.register(point.name, point.value)


def _describe(target: str | Factory) -> str:
    if isinstance(target, str):
        return target
    return f"{getattr(target, '__module__', '?')}:{getattr(target, '__qualname__', repr(target))}"
