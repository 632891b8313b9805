"""Chains on the teleop controller's skill buttons: a `TeleopSession` skill hook. Holding a chain's button
(L1/R1/L2/R2, bound by the chain file's ``button``) starts the chain from the current teleop targets and lets it
drive the robot; releasing the button, or the chain ending, hands control back to teleoperation (a new press
starts the chain again from the beginning)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.skills.runner import ChainRunner
from toddlerbot.skills.spec import BUTTONS, ChainSpec
from toddlerbot.tasks.probe import SceneProbe


class ChainHook:
    def __init__(self, chains: Iterable[ChainSpec], robot: Robot, model: mujoco.MjModel,
                 probe: SceneProbe | None = None, head_image=None, log: Callable[[str], None] = print) -> None:
        self.robot, self.model, self.probe, self.head_image, self.log = robot, model, probe, head_image, log
        self.bound: dict[str, ChainSpec] = {}
        for chain in chains:
            if chain.button is None:
                raise ToddlerbotError(f"{chain.source}: button: a chain run from teleop needs one of "
                                      f"{', '.join(BUTTONS)}")
            if chain.button in self.bound:
                raise ToddlerbotError(f"{chain.source}: button {chain.button} is already bound to chain "
                                      f"{self.bound[chain.button].name}")
            self.bound[chain.button] = chain
        self.runner: ChainRunner | None = None
        self._button: str | None = None
        self._last_time = -np.inf

    def __call__(self, obs: Observation, skills: frozenset[str],
                 targets: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        held = frozenset(b for b in BUTTONS if f"skill_{b}" in skills)
        button = next((b for b in BUTTONS if b in held and b in self.bound), None)
        # the session calls the hook only while a skill button is held: a gap in time means it was released
        pressed_anew = obs.time - self._last_time > 1.5 * self.robot.control_dt or button != self._button
        self._last_time, self._button = obs.time, button
        if button is None:
            return None
        if pressed_anew:
            if self.runner is not None:
                self.runner.close()
            chain = self.bound[button]
            try:  # e.g. a dp skill without torch or without a camera: say so, keep teleoperating
                self.runner = ChainRunner(chain, self.robot, self.model, self.probe, self.head_image)
            except ToddlerbotError as exc:
                self.runner = None
                self.log(f"chain {chain.name}: cannot start: {exc}")
                return None
            self.runner.start(obs, targets)
            self.log(f"chain {chain.name}: started ({button})")
        if self.runner is None or self.runner.status.done:
            return None
        command = self.runner.step(obs, held)
        if command is None:
            status = self.runner.status
            self.log(f"chain {self.runner.chain.name}: " + (f"failed: {status.failure}" if status.failure
                                                             else "done; back to teleoperation"))
        return command
