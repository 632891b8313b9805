"""A progress bar over the steps of a run (`rich`), as a run observer."""

from __future__ import annotations

from rich.progress import Progress

from toddlerbot.cli.output import console
from toddlerbot.runtime.runner import RunObserver, Step


class RunProgress(RunObserver):
    """A transient progress bar advanced once per control step; use as a context manager around the run."""

    def __init__(self, description: str, total_steps: int) -> None:
        self.progress = Progress(console=console, transient=True)
        self.task = self.progress.add_task(description, total=total_steps)

    def __enter__(self) -> RunProgress:
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        self.progress.stop()

    def on_step(self, step: Step) -> None:
        self.progress.advance(self.task)
