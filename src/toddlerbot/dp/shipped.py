"""Where the shipped diffusion-policy checkpoints live (``{task}.pt`` beside this module), named once for `dp eval`,
`dp live` and the chain's grasp skill; needs no torch, so a chain can ask without the ``[dp]`` extra."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.errors import ToddlerbotError

SHIPPED_DIR = Path(__file__).parent / "checkpoints"


class NoShippedCheckpointError(ToddlerbotError):
    """No checkpoint given and none shipped for the task."""


def is_shipped(task: str) -> bool:
    return (SHIPPED_DIR / f"{task}.pt").is_file()


def shipped_checkpoint(task: str) -> Path:
    """The checkpoint shipped for ``task``; a one-line error when there is none (none is shipped untrained)."""
    path = SHIPPED_DIR / f"{task}.pt"
    if not path.is_file():
        raise NoShippedCheckpointError(
            f"no --checkpoint given and no trained checkpoint is shipped for task {task!r} (looked for {path}); "
            "train one with `toddlerbot dp train DATASET -o RUN` and pass --checkpoint RUN/checkpoint.pt")
    return path
