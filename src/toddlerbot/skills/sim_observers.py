"""What `sim_run` watches while a chain runs in its scene, as run observers: how firmly each hand holds its bar
through the chain's last skill (`GripObserver`), and the side-by-side video of the scene and the head camera
(`ChainVideo`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from toddlerbot.runtime.runner import RunObserver, Step
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.skills.runner import ChainRunner
from toddlerbot.tasks.probe import SceneProbe

VIDEO_CAMERA = "perspective"
"""The tracking camera: a chain that walks leaves the fixed workspace camera's view."""
VIDEO_FPS = 25


@dataclass
class GripMargin:
    """How firmly one hand held a bar through the chain's last skill."""

    min_force_n: float = float("inf")
    """The weaker finger pad's normal force, its minimum over the skill, N (0: a pad let go)."""
    slide_m: float = 0.0
    """Farthest the bar's axis moved along the fingers from `start_m`, m."""
    to_end_m: float = float("inf")
    """Least distance from the grasp point to the nearer end of the bar's straight part, m (the pads reach
    `scenes.PAD_HALF_SIZE[0]` either side of it)."""
    start_m: float | None = None
    """Where the bar's axis was along the fingers (grasp-site y) when the skill last began, m; None until
    measured."""

    def update(self, probe: SceneProbe, side: str, bar: str) -> None:
        self.min_force_n = min(self.min_force_n, float(probe.pad_forces(side, bar).min()))
        in_hand = probe.bar_in_hand(side, bar)
        self.start_m = in_hand.offset[1] if self.start_m is None else self.start_m
        self.slide_m = max(self.slide_m, abs(in_hand.offset[1] - self.start_m))
        self.to_end_m = min(self.to_end_m, in_hand.to_end)


class GripObserver(RunObserver):
    """Measures each (hand, bar) of `bars` after every step the chain's last skill drove (a slide from where the bar
    was each time the skill began: after a re-grasp, from the new grasp)."""

    def __init__(self, chain: ChainRunner, probe: SceneProbe, bars: list[tuple[str, str]]) -> None:
        self.chain, self.probe, self.bars = chain, probe, bars
        self.grip = {side: GripMargin() for side, _ in bars}
        self._measuring = False

    def on_step(self, step: Step) -> None:
        measuring = self.chain.status.skill == self.chain.chain.skills[-1].name
        for side, bar in self.bars if measuring else ():
            if not self._measuring:
                self.grip[side].start_m = None
            self.grip[side].update(self.probe, side, bar)
        self._measuring = measuring


class ChainVideo(RunObserver):
    """An MP4 at `VIDEO_FPS` of the scene (`VIDEO_CAMERA`) beside the head camera's policy image; `close` moves
    it into place, `abort` drops it."""

    def __init__(self, robot: MuJoCoRobot, path: str | Path, head_image: Callable[[], np.ndarray]) -> None:
        from toddlerbot.tasks.video import SideBySideVideo

        self.video = SideBySideVideo(SimpleNamespace(model=robot.model, robot=robot), path, VIDEO_FPS,
                                     camera=VIDEO_CAMERA)
        self.head_image = head_image
        self.every = max(1, round(1.0 / (VIDEO_FPS * robot.control_dt)))

    def on_step(self, step: Step) -> None:
        if step.index % self.every == 0:
            self.video.add(self.head_image())

    def close(self) -> None:
        self.video.close()

    def abort(self) -> None:
        self.video.abort()
