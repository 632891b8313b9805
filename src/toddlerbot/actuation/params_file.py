"""Reading fitted actuator parameters (``params.json``, written by ``toddlerbot sysid fit``) into a catalogue.

A ``params.json`` holds ``{"motor": <catalogue name>, "actuator": {"model": name, fields of that model},
"fitted": [names], "fit": {...provenance...}}`` (no ``model``: the appendix's). Fields it leaves out keep the
catalogue's value when the catalogue has the same model for the motor; a file with another model gives them all.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from toddlerbot.actuation.catalogue import Catalogue, default_catalogue, motor_params, params_dict
from toddlerbot.actuation.motor_models import DEFAULT_MOTOR_MODEL
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.errors import ParamsError, SpecError
from toddlerbot.yaml_input import read_text

MAX_PARAMS_BYTES = 1 << 20
"""A params.json is a few hundred bytes; anything over 1 MiB is not one."""


def load_params(path: str | Path, catalogue: Catalogue | None = None) -> tuple[str, MotorParams]:
    """(catalogue motor name, parameters) of a params.json; raise `ParamsError` naming the file."""
    path = Path(path)
    catalogue = catalogue or default_catalogue()
    raw = _read(path)
    try:
        name = catalogue[str(raw["motor"])].name
    except SpecError:
        raise ParamsError(f"{path}: unknown motor model {raw['motor']!r}") from None
    fields = raw["actuator"]
    base = catalogue[name].actuator
    # a partial file of the model the catalogue has for the motor keeps the catalogue's other fields
    kept = params_dict(base) if fields.get("model", DEFAULT_MOTOR_MODEL) == base.model else {}
    try:
        params = motor_params({**kept, **fields}, "actuator")
    except (TypeError, ValueError) as exc:
        raise ParamsError(f"{path}: {exc} (motor {name})") from None
    return name, params


def relative_errors(path: str | Path) -> dict[str, float]:
    """Each fitted parameter's relative standard error, as `sysid fit` records it in the file's ``fit``
    (``{}`` for a file without them)."""
    raw = _read(Path(path))
    try:
        return {name: float(entry["relative"])
                for name, entry in raw.get("fit", {}).get("uncertainty", {}).items()}
    except (AttributeError, KeyError, TypeError, ValueError):
        raise ParamsError(f"{path}: fit.uncertainty: expected {{name: {{'relative': number, ...}}}}") from None


def _read(path: Path) -> dict:
    text = read_text(path, "params.json", ParamsError, MAX_PARAMS_BYTES, "UTF-8 JSON")
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParamsError(f"{path}: not valid JSON: {exc}") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("actuator"), dict) or "motor" not in raw:
        raise ParamsError(f"{path}: expected {{'motor': name, 'actuator': {{...}}}}")
    return raw


def catalogue_with_params(paths: Iterable[str | Path], catalogue: Catalogue | None = None) -> Catalogue:
    """The motor catalogue with each params.json applied to its motor model (later files win)."""
    catalogue = catalogue or default_catalogue()
    for path in paths:
        name, params = load_params(path, catalogue)
        catalogue = catalogue.with_actuator(name, params)
    return catalogue
