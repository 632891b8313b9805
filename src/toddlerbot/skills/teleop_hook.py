"""Chains on the teleop controller's skill buttons: `ChainButtons`, a `Policy` around a `TeleopSession`. Holding a
chain's button (L1/R1/L2/R2, bound by the chain file's ``button``) starts the chain from the current teleop targets
and lets it drive the robot; releasing the button, or the chain ending, hands control back to teleoperation (a new
press starts the chain again from the beginning)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation
from toddlerbot.skills.runner import ChainRunner
from toddlerbot.skills.spec import BUTTONS, SHIPPED_DIR, ChainSpec, load_chain
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.teleop.session import TeleopSession


class ChainButtons(Policy):
    """`session`'s targets, except while a bound button is held: then its chain's (`model`: the chain's scene,
    `probe` the simulated one or None on hardware, `head_image` a dp skill's camera)."""

    def __init__(self, session: TeleopSession, chains: Iterable[ChainSpec], model: mujoco.MjModel,
                 probe: SceneProbe | None = None, head_image: Callable[[], np.ndarray] | None = None,
                 log: Callable[[str], None] = print) -> None:
        super().__init__(session.robot)
        self.name = session.name
        self.session, self.model, self.probe, self.head_image, self.log = session, model, probe, head_image, log
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
        """The chain started by the button held now (None while teleoperating)."""
        self._button: str | None = None
        self._held: frozenset[str] = frozenset()

    def reset(self, obs: Observation) -> None:
        self.session.reset(obs)
        self._stop_chain()
        self._button = None

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        action = self.session.act(obs, command)
        skills = self.session.last_command.skills
        self._held = frozenset(b for b in BUTTONS if f"skill_{b}" in skills)
        button = next((b for b in BUTTONS if b in self._held and b in self.bound), None)
        pressed_anew, self._button = button != self._button, button
        if button is None:
            self._stop_chain()  # released: teleop's targets again
            return action
        if pressed_anew:
            self._start_chain(self.bound[button], obs, action.motor_targets)
        runner = self.runner
        if runner is None or runner.status.done:
            return action
        if not runner.advance(obs):
            status = runner.status
            self.log(f"chain {runner.chain.name}: " + (f"failed: {status.failure}" if status.failure
                                                       else "done; back to teleoperation"))
            return action
        return runner.act(obs, command)

    def _start_chain(self, chain: ChainSpec, obs: Observation, targets: np.ndarray) -> None:
        self._stop_chain()
        try:  # e.g. a dp skill without torch or without a camera: say so, keep teleoperating
            self.runner = ChainRunner(chain, self.robot, self.model, self.probe, self.head_image,
                                      buttons=lambda: self._held)
        except ToddlerbotError as exc:
            self.runner = None
            self.log(f"chain {chain.name}: cannot start: {exc}")
            return
        self.runner.start(obs, targets)
        self.log(f"chain {chain.name}: started ({chain.button})")

    def _stop_chain(self) -> None:
        if self.runner is not None:
            self.runner.close()
            self.runner = None

    @property
    def done(self) -> bool:
        return self.session.done

    def close(self) -> None:
        self._stop_chain()
        self.session.close()


def teleop_chains(names: list[str] | None, groups: tuple[str, ...], sim_scene: str | None) -> list[ChainSpec]:
    """The chains `names` (shipped names or files), or by default in sim the shipped chains of `sim_scene` (the
    teleop task) that name a button; none by default on hardware (`sim_scene` None)."""
    if names is not None:
        return [load_chain(name, groups) for name in names]
    if sim_scene is None:
        return []
    shipped = [load_chain(path, groups) for path in sorted(SHIPPED_DIR.glob("*.yaml"))]
    return [c for c in shipped if c.scene == sim_scene and c.button is not None]


def with_chains(session: TeleopSession, names: list[str] | None, sim_scene: str | None,
                head_image: Callable[[], np.ndarray] | None = None, log: Callable[[str], None] = print) -> Policy:
    """`session` with the chains of `teleop_chains` on their buttons (said in `log`); the session itself when there
    are none. In sim the chains sense the simulated scene; on hardware they plan in their scene's layout."""
    robot = session.robot
    chains = teleop_chains(names, tuple(robot.description.groups), sim_scene)
    if not chains:
        return session
    if sim_scene is None:
        from toddlerbot.tasks.scenes import scene_model

        policy = ChainButtons(session, chains, scene_model(robot.description, chains[0].scene), None, head_image, log)
    else:
        model, data = robot.model, robot.data  # type: ignore[attr-defined]
        policy = ChainButtons(session, chains, model, SceneProbe(model, data), head_image, log)
    for button, chain in policy.bound.items():
        log(f"hold {button.upper()} to run chain {chain.name}")
    return policy
