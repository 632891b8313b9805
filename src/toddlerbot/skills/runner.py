"""A chain as a `Policy` (`ChainRunner`): each control step the current skill's targets (its `hold` groups kept at
the previous skill's last targets and gains), switching when its `until` holds, failing when its `timeout` passes
(or retrying it after a back-off, where it declares a `retry`), recovering when its `recover` condition is lost (a
back-off, then on from a skill it names), `done` once the last skill's `until` holds or a skill failed.
`runtime.run_policy` runs it as any policy (`sim_run` in a scene, `robot_run` on a robot); teleoperation runs it
while its button is held (`teleop_hook`)."""

from __future__ import annotations

import typing
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.skills import skill_kind
from toddlerbot.skills.library import Skill, SkillEnv
from toddlerbot.skills.spec import ChainSpec, Recover, SkillSpec
from toddlerbot.tasks.predicates import Context, check_available, holds
from toddlerbot.tasks.probe import SceneProbe


@dataclass(frozen=True)
class Recovery:
    """One retry or recover the chain made."""

    kind: str
    """``retry`` (the skill's timeout passed) or ``recover`` (its ``lost`` predicate stopped holding)."""
    skill: str
    """The skill that timed out or lost its condition."""
    resume: str
    """The skill the chain went on from after the back-off."""
    time_s: float
    """Robot time it began, s."""

    def to_dict(self) -> dict:
        return {"kind": self.kind, "skill": self.skill, "resume": self.resume, "time_s": round(self.time_s, 3)}


@dataclass
class ChainStatus:
    """The chain's phases so far: which skill runs, the switches, the retries and recoveries, how it ended."""

    driven_by: dict[str, str]
    """Skill name -> what drives it (e.g. ``scripted (no checkpoint named)``, ``dp (wagon.pt)``)."""
    skill: str | None = None
    """The skill running now (None once the chain has ended)."""
    switches: list[tuple[str, str, float]] = field(default_factory=list)
    """(from skill, to skill, robot time s) of each switch."""
    recoveries: list[Recovery] = field(default_factory=list)
    failure: str | None = None
    done: bool = False

    def to_dict(self) -> dict:
        return {"skill": self.skill, "done": self.done, "failure": self.failure, "driven_by": self.driven_by,
                "switches": [{"from": a, "to": b, "time_s": round(t, 3)} for a, b, t in self.switches],
                "recoveries": [r.to_dict() for r in self.recoveries]}

    def describe(self) -> str:
        """One line for people."""
        ended = "running " + str(self.skill) if not self.done else "failed: " + self.failure if self.failure else "done"
        switches = ", ".join(f"{a} -> {b} at {t:.2f} s" for a, b, t in self.switches) or "no switch"
        recoveries = "".join(f"; {r.kind} {r.skill} at {r.time_s:.2f} s" for r in self.recoveries)
        return f"chain {ended}; {switches}{recoveries}"


def time_limit(chain: ChainSpec, unbounded_skill_s: float) -> float:
    """Robot time a run of `chain` may take, s: every skill's ``after`` or ``timeout``, `unbounded_skill_s` for a
    skill with neither (one waiting for a button or a predicate), as often as its retries and recoveries may run it,
    and a second to spare."""
    def length(names: typing.Iterable[str]) -> float:
        return sum((s.until.after or s.timeout or unbounded_skill_s) for s in map(chain.skill, names))

    order = [s.name for s in chain.skills]
    total = length(order) + 1.0
    for i, s in enumerate(chain.skills):
        if s.retry is not None:
            total += s.retry.times * length((*s.retry.back_off, s.name))
        if s.recover is not None:
            again = (*s.recover.back_off, *order[order.index(s.recover.resume): i])
            total += s.recover.times * (s.recover.for_s + length(again))
    return total


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
        specs = chain.skills + chain.recovery
        for s in specs:
            for field_name, switch in (("until", s.until), ("recover.lost", s.recover and s.recover.lost)):
                if switch and switch.predicate is not None:
                    check_available(switch.predicate, probe is None, f"{chain.source}: skill {s.name}: {field_name}")
        layout = mujoco.MjData(model)  # the scene as its layout puts it
        layout.qpos[:] = model.key("home").qpos
        mujoco.mj_kinematics(model, layout)
        layout_pos = SceneProbe(model, layout).geom_pos
        if probe is None:
            env = SkillEnv(robot, model, lambda: layout.qpos, None, layout_pos, head_image, simulated=False, seed=seed)
        else:
            env = SkillEnv(robot, model, lambda: probe.data.qpos, probe.geom_pos, layout_pos, head_image,
                           simulated=True, seed=seed)
        self._built: dict[str, Skill] = {s.name: skill_kind(s.kind)(env, s.params) for s in specs}
        self.skills: list[Skill] = [self._built[s.name] for s in chain.skills]
        """The chain's skills in order (its recovery skills are run only as back-offs)."""
        d = robot.description
        self._hold = {s.name: np.concatenate([d.groups[g] for g in s.hold]) if s.hold else np.zeros(0, int)
                      for s in specs}
        self._order = [s.name for s in chain.skills]
        self._status = self._fresh_status()
        self._current: SkillSpec | None = None
        self._advanced_at: float | None = None

    def _fresh_status(self) -> ChainStatus:
        return ChainStatus({name: skill.by for name, skill in self._built.items()})

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
        self._queue: list[str] = []
        """Skills to run next, before the chain's order goes on (a back-off, then where it resumes)."""
        self._credit: dict[str, float] = {}
        """Skill -> the time it had run when a recover interrupted it (it goes on from there)."""
        self._used: dict[tuple[str, str], int] = {}
        """(retry or recover, skill) -> how many the run has made."""
        self._enter(self._order[0], obs)

    def _enter(self, name: str, obs: Observation) -> None:
        spec = self.chain.skill(name)
        self._current, self._since = spec, obs.time - self._credit.pop(name, 0.0)
        self._lost_since: float | None = None
        self._held_targets, self._held_kp = self._targets.copy(), self._kp.copy()
        self._status.skill = name
        self._built[name].start(obs, self._targets)

    def _switch(self, name: str, obs: Observation) -> None:
        self._status.switches.append((self._current.name, name, obs.time))  # type: ignore[union-attr]
        self._enter(name, obs)

    def advance(self, obs: Observation) -> bool:
        """Make the switches due at `obs` (once per observation: the buttons are read once); False once the chain
        has ended (its last skill's `until` held, a skill's `timeout` passed with no retry left, or its `recover`
        condition was lost with no recovery left)."""
        if self._status.done or self._current is None:
            return not self._status.done
        if obs.time == self._advanced_at:
            return True
        self._advanced_at = obs.time
        buttons = self.buttons()
        while self._switch_due(obs, buttons):
            if self._queue:
                self._switch(self._queue.pop(0), obs)
                continue
            i = self._order.index(self._current.name)  # a recovery skill always has a queue to go on with
            if i + 1 == len(self._order):
                self._end(None)
                return False
            self._switch(self._order[i + 1], obs)
        spec = self._current
        if spec.timeout is not None and obs.time - self._since > spec.timeout + 1e-9:
            if spec.retry is None or not self._begin("retry", spec.retry.times, spec.retry.back_off, spec.name, obs):
                self._end(f"skill {spec.name}: its switch condition did not hold within {spec.timeout:g} s"
                          + (f" ({spec.retry.times} retries made)" if spec.retry is not None else ""))
                return False
        elif spec.recover is not None and self._lost(spec.recover, obs):
            r = spec.recover
            self._credit[spec.name] = obs.time - self._since
            if not self._begin("recover", r.times, r.back_off, r.resume, obs):
                self._end(f"skill {spec.name}: {r.lost.predicate} lost again after {r.times} recoveries")
                return False
        return True

    def _begin(self, kind: str, times: int, back_off: tuple[str, ...], resume: str, obs: Observation) -> bool:
        """Start a retry or recover of the current skill: its back-off, then `resume`; False when the run has made
        `times` already."""
        key = (kind, self._current.name)  # type: ignore[union-attr]
        if self._used.get(key, 0) >= times:
            return False
        self._used[key] = self._used.get(key, 0) + 1
        self._status.recoveries.append(Recovery(kind, key[1], resume, obs.time))
        self._queue = [*back_off, resume]
        self._switch(self._queue.pop(0), obs)
        return True

    def _lost(self, recover: Recover, obs: Observation) -> bool:
        """Has `recover.lost` not held for `recover.for_s` s?"""
        ctx = Context(self.robot, obs, self._targets, self.probe)
        if holds(recover.lost.predicate, recover.lost.params, ctx):  # type: ignore[arg-type]
            self._lost_since = None
            return False
        if self._lost_since is None:
            self._lost_since = obs.time
        return obs.time - self._lost_since >= recover.for_s - 1e-9

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        """The current skill's targets (the velocity `command` is ignored: a walk skill has its own); once the
        chain has ended, the last targets held."""
        if self.advance(obs):
            assert self._current is not None
            name = self._current.name
            targets, kp = self._built[name].act(obs, obs.time - self._since)
            targets, kp = np.array(targets, dtype=float), np.array(kp, dtype=float)
            hold = self._hold[name]
            targets[hold], kp[hold] = self._held_targets[hold], self._held_kp[hold]
            self._targets, self._kp = targets, kp
        return Action(self._targets.copy(), self.transmission.motor_to_joint(self._targets), self._kp.copy())

    @property
    def done(self) -> bool:
        """The chain has ended, judged on the robot's latest observation (`Robot.observe`, as `Robot.fallen` is),
        so a run stops on the step whose outcome ended it."""
        return not self.advance(self.robot.observe())

    def _switch_due(self, obs: Observation, buttons: frozenset[str]) -> bool:
        until = self._current.until  # type: ignore[union-attr]
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
        return {name: skill.status.to_dict() for name, skill in self._built.items() if skill.status is not None}

    def _end(self, failure: str | None) -> None:
        self._status.failure, self._status.done, self._status.skill = failure, True, None
        self.close()

    def close(self) -> None:
        for skill in self._built.values():
            skill.close()
