"""Reference data shipped with the design metrics (YAML files beside this module, each citing its sources)."""

from __future__ import annotations

from functools import cache
from importlib import resources

import yaml

_DATA = resources.files("toddlerbot.design") / "data"


@cache
def load(name: str) -> dict:
    """Parsed contents of data/<name>.yaml."""
    return yaml.safe_load((_DATA / f"{name}.yaml").read_text())
