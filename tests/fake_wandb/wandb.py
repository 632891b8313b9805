"""A stand-in for the ``wandb`` package (the real one is large and not part of the test install): it records
every call the W&B sink makes, in ``CALLS`` and, when ``FAKE_WANDB_LOG`` names a file, as JSON lines there (for a
training run in another process; put this folder first on ``PYTHONPATH``)."""

from __future__ import annotations

import json
import os

CALLS: list[tuple[str, dict]] = []


def _record(call: str, /, **kwargs) -> None:
    CALLS.append((call, kwargs))
    path = os.environ.get("FAKE_WANDB_LOG")
    if path:
        with open(path, "a", encoding="utf-8") as f:
            f.write(json.dumps({"call": call, **kwargs}) + "\n")


class Run:
    def define_metric(self, name: str, step_metric: str | None = None) -> None:
        _record("define_metric", name=name, step_metric=step_metric)

    def log(self, data: dict, step: int | None = None, commit: bool | None = None) -> None:
        _record("log", data=dict(data), step=step)

    def finish(self, exit_code: int | None = None, quiet: bool | None = None) -> None:
        _record("finish", exit_code=exit_code)


def init(**kwargs) -> Run:
    _record("init", **kwargs)
    return Run()
