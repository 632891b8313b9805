"""A chain as a `Policy` (`ChainRunner`): each control step the current skill's targets (its `hold` groups kept at
the previous skill's last targets and gains), switching when its `until` holds, failing when its `timeout` passes,
`done` once the last skill's `until` holds or a skill failed. `runtime.run_policy` runs it as any policy (`sim_run`
in a scene, `robot_run` on a robot); teleoperation runs it while its button is held (`teleop_hook`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.skills import skill_kind
from toddlerbot.skills.library import Skill, SkillEnv
from toddlerbot.skills.spec import ChainSpec
from toddlerbot.tasks.predicates import Context, check_available, holds
from toddlerbot.tasks.probe import SceneProbe


@dataclass
class ChainStatus:
    """The chain's phases so far: which skill runs, the switches, how it ended."""

    driven_by: dict[str, str]
    """Skill name -> what drives it (e.g. ``scripted (no checkpoint named)``, ``dp (wagon.pt)``)."""
    skill: str | None = None
    """The skill running now (None once the chain has ended)."""
    switches: list[tuple[str, str, float]] = field(default_factory=list)
    """(from skill, to skill, robot time s) of each switch."""
    failure: str | None = None
    done: bool = False

    def to_dict(self) -> dict:
        return {"skill": self.skill, "done": self.done, "failure": self.failure, "driven_by": self.driven_by,
                "switches": [{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in self.switches]}

    def describe(self) -> str:
        """One line for people."""
        ended = "running " + str(self.skill) if not self.done else "failed: " + self.failure if self.failure else "done"
        switches = ", ".join(f"{a} -> {b} at {t:.2f} s" for a, b, t in self.switches) or "no switch"
        return f"chain {ended}; {switches}"


def time_limit(chain: ChainSpec, unbounded_skill_s: float) -> float:
    """Robot time a run of `chain` may take, s: every skill's ``after`` or ``timeout``, `unbounded_skill_s` for a
    skill with neither (one waiting for a button or a predicate), and a second to spare."""
    return sum(s.until.after or s.timeout or unbounded_skill_s for s in chain.skills) + 1.0


class ChainRunner(Policy):
    """Runs `chain` on `robot`: `model` is the chain's scene (kinematics for the skills' IK), `probe` the simulated
    scene (None on hardware: only predicates with a hardware form switch), `head_image` the head camera (a dp
    skill's input). The chain starts from `start_targets` (default: the robot's last targets, or where it is) and
    switches on the buttons `buttons()` reports held; `seed` seeds its learned skills' sampling noise (see
    `DPParams.seed`)."""

    def __init__(self, chain: ChainSpec, robot: Robot, model: mujoco.MjModel, probe: SceneProbe | None = None,
                 head_image: Callable[[], np.ndarray] | None = None, start_targets: np.ndarray | None = None,
                 buttons: Callable[[], frozenset[str]] = frozenset, seed: int = 0) -> None:
        super().__init__(robot)
        self.name = f"chain:{chain.name}"
        self.chain, self.probe, self.start_targets, self.buttons = chain, probe, start_targets, buttons
        for s in chain.skills:
            if s.until.predicate is not None:
                check_available(s.until.predicate, probe is None, f"{chain.source}: skill {s.name}: until")
        layout = mujoco.MjData(model)  # the scene as its layout puts it
        layout.qpos[:] = model.key("home").qpos
        mujoco.mj_kinematics(model, layout)
        layout_pos = SceneProbe(model, layout).geom_pos
        if probe is None:
            env = SkillEnv(robot, model, lambda: layout.qpos, None, layout_pos, head_image, simulated=False, seed=seed)
        else:
            env = SkillEnv(robot, model, lambda: probe.data.qpos, probe.geom_pos, layout_pos, head_image,
                           simulated=True, seed=seed)
        self.skills: list[Skill] = [skill_kind(s.kind)(env, s.params) for s in chain.skills]
        d = robot.description
        self._hold = [np.concatenate([d.groups[g] for g in s.hold]) if s.hold else np.zeros(0, int)
                      for s in chain.skills]
        self._status = self._fresh_status()
        self._index: int | None = None
        self._advanced_at: float | None = None

    def _fresh_status(self) -> ChainStatus:
        return ChainStatus({s.name: skill.by for s, skill in zip(self.chain.skills, self.skills)})

    @property
    def status(self) -> ChainStatus:
        return self._status

    def reset(self, obs: Observation) -> None:
        last = self.robot.last_targets
        self.start(obs, self.start_targets if self.start_targets is not None else
                   obs.motor_pos if last is None else last)

    def start(self, obs: Observation, targets: np.ndarray, kp: np.ndarray | None = None) -> None:
        """Begin the first skill from `targets` (rad) and gains `kp` (default: the spec's)."""
        if self.probe is not None:
            self.probe.mark()
        self._status = self._fresh_status()
        self._targets = np.array(targets, dtype=float)
        self._kp = np.array(self.robot.description.default_kp if kp is None else kp, dtype=float)
        self._advanced_at = None
        self._enter(0, obs)

    def _enter(self, index: int, obs: Observation) -> None:
        self._index, self._since = index, obs.time
        self._held_targets, self._held_kp = self._targets.copy(), self._kp.copy()
        self._status.skill = self.chain.skills[index].name
        self.skills[index].start(obs, self._targets)

    def advance(self, obs: Observation) -> bool:
        """Make the switches due at `obs` (once per observation: the buttons are read once); False once the chain
        has ended (its last skill's `until` held, or a skill's `timeout` passed)."""
        if self._status.done or self._index is None:
            return not self._status.done
        if obs.time == self._advanced_at:
            return True
        self._advanced_at = obs.time
        buttons = self.buttons()
        while self._switch_due(obs, buttons):
            spec = self.chain.skills[self._index]
            if self._index + 1 == len(self.chain.skills):
                self._end(None)
                return False
            self._status.switches.append((spec.name, self.chain.skills[self._index + 1].name, obs.time))
            self._enter(self._index + 1, obs)
        spec = self.chain.skills[self._index]
        if spec.timeout is not None and obs.time - self._since > spec.timeout + 1e-9:
            self._end(f"skill {spec.name}: its switch condition did not hold within {spec.timeout:g} s")
            return False
        return True

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        """The current skill's targets (the velocity `command` is ignored: a walk skill has its own); once the
        chain has ended, the last targets held."""
        if self.advance(obs):
            assert self._index is not None
            targets, kp = self.skills[self._index].act(obs, obs.time - self._since)
            targets, kp = np.array(targets, dtype=float), np.array(kp, dtype=float)
            hold = self._hold[self._index]
            targets[hold], kp[hold] = self._held_targets[hold], self._held_kp[hold]
            self._targets, self._kp = targets, kp
        return Action(self._targets.copy(), self.transmission.motor_to_joint(self._targets), self._kp.copy())

    @property
    def done(self) -> bool:
        """The chain has ended, judged on the robot's latest observation (`Robot.observe`, as `Robot.fallen` is),
        so a run stops on the step whose outcome ended it."""
        return not self.advance(self.robot.observe())

    def _switch_due(self, obs: Observation, buttons: frozenset[str]) -> bool:
        until = self.chain.skills[self._index].until  # type: ignore[index]
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

    def skill_status(self) -> dict[str, dict]:
        """Skill name -> its policy's status (a dp skill's inference statistics), for the skills that report one."""
        return {s.name: skill.status.to_dict() for s, skill in zip(self.chain.skills, self.skills)
                if skill.status is not None}

    def _end(self, failure: str | None) -> None:
        self._status.failure, self._status.done, self._status.skill = failure, True, None
        self.close()

    def close(self) -> None:
        for skill in self.skills:
            skill.close()
