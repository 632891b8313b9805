"""Where the shipped diffusion-policy checkpoints live (``{task}.pt`` beside this module), named once for `dp eval`,
`dp live` and the chain's grasp skill; needs no torch, so a chain can ask without the ``[dp]`` extra."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.errors import ToddlerbotError, quoted

SHIPPED_DIR = Path(__file__).parent / "checkpoints"


class NoShippedCheckpointError(ToddlerbotError):
    """No checkpoint given and none shipped for the task."""


def is_shipped(task: str) -> bool:
    return (SHIPPED_DIR / f"{task}.pt").is_file()


def shipped_tasks() -> list[str]:
    """The tasks a checkpoint is shipped for."""
    return sorted(path.stem for path in SHIPPED_DIR.glob("*.pt"))


def check_named_checkpoint(name: str) -> str:
    """`name` if it is a shipped checkpoint's task or an existing ``.pt`` file; a named checkpoint that cannot be
    loaded is an error, never a quiet fallback (`ValueError`, which a chain file reports with its line)."""
    if name.endswith(".pt"):
        if not Path(name).is_file():
            raise ValueError(f"checkpoint: {quoted(name)} is not a file")
    elif not is_shipped(name):
        raise ValueError(f"checkpoint: no checkpoint is shipped for {quoted(name)}; expected one of "
                         f"{', '.join(shipped_tasks())} or a .pt file")
    return name


def shipped_checkpoint(task: str) -> Path:
    """The checkpoint shipped for ``task``; a one-line error when there is none (none is shipped untrained)."""
    path = SHIPPED_DIR / f"{task}.pt"
    if not path.is_file():
        raise NoShippedCheckpointError(
            f"no --checkpoint given and no trained checkpoint is shipped for task {task!r} (looked for {path}); "
            "train one with `toddlerbot dp train DATASET -o RUN` and pass --checkpoint RUN/checkpoint.pt")
    return path
