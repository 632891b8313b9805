"""Runs a chain on a `Robot`: the current skill's targets (its `hold` groups kept at the previous skill's last
targets and gains) each control step, switching when its `until` holds and failing when its `timeout` passes."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.skills.library import Skill, SkillEnv, make_skill
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.predicates import Context, check_available, holds
from toddlerbot.tasks.probe import SceneProbe


@dataclass
class ChainStatus:
    skill: str | None = None
    """The skill running now (None once the chain has ended)."""
    switches: list[tuple[str, str, float]] = field(default_factory=list)
    """(from skill, to skill, robot time s) of each switch."""
    failure: str | None = None
    done: bool = False


class ChainRunner:
    """Call `start` with the current observation and targets, then `step` once per control period until
    `status.done`; `step` returns the targets and gains to send (the caller sends them through `Robot.step`)."""

    def __init__(self, chain: ChainSpec, robot: Robot, model: mujoco.MjModel, probe: SceneProbe | None = None,
                 head_image=None) -> None:
        self.chain, self.robot, self.probe = chain, robot, probe
        for s in chain.skills:
            if s.until.predicate is not None:
                check_available(s.until.predicate, probe is None, f"{chain.source}: skill {s.name}: until")
        layout = mujoco.MjData(model)  # the scene as its layout puts it
        layout.qpos[:] = model.key("home").qpos
        mujoco.mj_kinematics(model, layout)
        layout_pos = SceneProbe(model, layout).geom_pos
        if probe is None:
            env = SkillEnv(robot, model, lambda: layout.qpos, None, layout_pos, head_image, simulated=False)
        else:
            env = SkillEnv(robot, model, lambda: probe.data.qpos, probe.geom_pos, layout_pos, head_image,
                           simulated=True)
        self.skills: list[Skill] = [make_skill(s.kind, s.params, env) for s in chain.skills]
        d = robot.description
        self._hold = [np.concatenate([d.groups[g] for g in s.hold]) if s.hold else np.zeros(0, int)
                      for s in chain.skills]
        self.status = ChainStatus()

    def start(self, obs: Observation, targets: np.ndarray, kp: np.ndarray | None = None) -> None:
        if self.probe is not None:
            self.probe.mark()
        self._targets = np.array(targets, dtype=float)
        self._kp = np.array(self.robot.description.default_kp if kp is None else kp, dtype=float)
        self._enter(0, obs)

    def _enter(self, index: int, obs: Observation) -> None:
        self._index, self._since = index, obs.time
        self._held_targets, self._held_kp = self._targets.copy(), self._kp.copy()
        self.status.skill = self.chain.skills[index].name
        self.skills[index].start(obs, self._targets)

    def step(self, obs: Observation, buttons: frozenset[str] = frozenset()) -> tuple[np.ndarray, np.ndarray] | None:
        """Targets and gains for this period, or None once the chain has ended (succeeded or failed)."""
        if self.status.done:
            return None
        while self._switch_due(obs, buttons):
            spec = self.chain.skills[self._index]
            if self._index + 1 == len(self.chain.skills):
                self._end(None)
                return None
            self.status.switches.append((spec.name, self.chain.skills[self._index + 1].name, obs.time))
            self._enter(self._index + 1, obs)
        spec = self.chain.skills[self._index]
        if spec.timeout is not None and obs.time - self._since > spec.timeout + 1e-9:
            self._end(f"skill {spec.name}: its switch condition did not hold within {spec.timeout:g} s")
            return None
        targets, kp = self.skills[self._index].act(obs, obs.time - self._since)
        targets, kp = np.array(targets, dtype=float), np.array(kp, dtype=float)
        hold = self._hold[self._index]
        targets[hold], kp[hold] = self._held_targets[hold], self._held_kp[hold]
        self._targets, self._kp = targets, kp
        return targets, kp

    def _switch_due(self, obs: Observation, buttons: frozenset[str]) -> bool:
        until = self.chain.skills[self._index].until
        if until.after is not None:
            return obs.time - self._since >= until.after - 1e-9
        if until.button is not None:
            return until.button in buttons
        ctx = Context(self.robot, obs, self._targets, self.probe)
        return holds(until.predicate, until.params, ctx)  # type: ignore[arg-type]

    def succeeded(self, obs: Observation) -> dict[str, bool]:
        """Each `success` predicate of the chain, evaluated now."""
        ctx = Context(self.robot, obs, self._targets, self.probe)
        return {name: holds(name, params, ctx) for name, params in self.chain.success}

    def _end(self, failure: str | None) -> None:
        self.status.failure, self.status.done, self.status.skill = failure, True, None
        self.close()

    def close(self) -> None:
        for skill in self.skills:
            skill.close()
