"""The ``wagon`` task: the wagon chain's grasp phase as a task of its own (demonstrations, `dp eval`).

Everything comes from the shipped chain (`chains/wagon.yaml`): its grasp skill's parameters (the scripted
demonstrator, a `Policy`, *is* the chain's `ScriptedGrasp`, and the task steps at that skill's gains), its
``until`` check (success: the chain's ``grasped`` predicate, both grippers commanded closed and pinching the
handle, which is when the chain would switch to its next skill) and its timeout (the episode's limit).

The scene's seeded variation is declared once, in `WagonRanges`, named in `VARIATIONS` (``default``: the wagon's
shift alone, the scene the shipped policy was measured in; ``wide``: also the handle's height, the arms' start pose,
the light level and, for the task's episodes, a share of starts where a chain's re-grasp does: the hands open at the
handle after it slipped), drawn per seed by `draw_scene` alike for `chain run wagon --seed N` and for the task's
episodes (`manip demo`, `dp eval`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.skills.library import GraspParams, ScriptedGrasp, SkillEnv, grasp_gains
from toddlerbot.skills.spec import load_chain
from toddlerbot.tasks import task_description
from toddlerbot.tasks.base import StartPerturbation, Task
from toddlerbot.tasks.camera import HeadCamera
from toddlerbot.tasks.predicates import Context, commanded_closed, holds
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import SIDES, HandleHeight, LightLevel, add_wagon_scene, scene_model, shift_wagon
from toddlerbot.tasks.space import ManipulationSpace

CHAIN = "wagon"
GRASP_SKILL = "grasp"
HOLD_S = 0.6
"""The demonstrations keep the closed grip this long after the closing ramp, so the policy learns to stay closed
(the chain's check fires at the ramp's end, a policy that reopens right after would drop the handle)."""


@dataclass(frozen=True)
class WagonRanges:
    """The wagon scene's seeded variation: a seed draws each value uniformly from its range (`draw_scene`). The
    defaults are the scene the shipped policy and chain were measured in: the wagon's shift alone varies."""

    wagon_x: tuple[float, float] = (-0.01, 0.01)
    """Shift of the wagon from its layout position along x (away from the robot), m."""
    wagon_y: tuple[float, float] = (-0.03, 0.03)
    """... and along y, m."""
    handle_height: tuple[float, float] = (0.0, 0.0)
    """Offset of the handle bar from the layout's height, m. The chain's scripted grasp (fingers 0.5 rad down) has
    little margin beyond ±5 mm: from home it grasps a bar 2 cm lower (6 of 6 seeds) but not 1 cm higher (0 of 6),
    and its retry after a grasp that closed on nothing misses a bar 0.8 and 1.4 cm lower."""
    arm_pose: float = 0.0
    """Each arm motor starts up to this far off the home pose, rad."""
    light: tuple[float, float] = (1.0, 1.0)
    """Scale of the scene's light levels (what the head camera sees)."""
    regrasp_share: float = 0.0
    """Share of the task's episodes (not a chain's runs) that start as a chain's re-grasp does: the hands at the
    handle, open (the recover's back-off), after the handle slipped by `slip_x`, `slip_y`."""
    slip_x: tuple[float, float] = (-0.005, 0.015)
    """How far the handle moved from the open hands' grasp point, along x, m."""
    slip_y: tuple[float, float] = (-0.015, 0.015)
    """... and along y, m."""


VARIATIONS = {
    "default": WagonRanges(),
    "wide": WagonRanges(handle_height=(-0.005, 0.005), arm_pose=0.05, light=(0.6, 1.0), regrasp_share=0.25),
}
"""The wagon scene's named variations (`--task wagon:wide`, `chain run wagon --variation wide`)."""


@dataclass(frozen=True)
class WagonScene:
    """One seed's draw of `WagonRanges`."""

    shift: np.ndarray
    handle_height: float
    arm_offset: np.ndarray
    """Start offset of every motor (non-zero on the arms only), rad."""
    light: float
    regrasp: bool
    slip: np.ndarray


def draw_scene(rng: np.random.Generator, description: RobotDescription, ranges: WagonRanges) -> WagonScene:
    """The seed's scene: the first draws of the seed's generator (a task's reset and a chain's start draw it alike,
    so `manip demo --task wagon` and `chain run wagon` place the wagon alike). Every value is drawn, used or not, so
    that one range's change leaves the others' draws alone."""
    shift = np.array([rng.uniform(*ranges.wagon_x), rng.uniform(*ranges.wagon_y)])
    handle_height = rng.uniform(*ranges.handle_height)
    light = rng.uniform(*ranges.light)
    arms = description.groups["arm"]
    arm_offset = np.zeros(description.n_motors)
    arm_offset[arms] = rng.uniform(-1.0, 1.0, len(arms)) * ranges.arm_pose
    regrasp = rng.uniform() < ranges.regrasp_share
    slip = np.array([rng.uniform(*ranges.slip_x), rng.uniform(*ranges.slip_y)])
    return WagonScene(shift, handle_height, arm_offset, light, regrasp, slip)


class WagonTask(Task):
    """Grasp the wagon handle with both hands (gripper variant, floating robot standing on the floor)."""

    name = "wagon"
    instruction = "grasp the wagon handle with both hands"
    add_scene = staticmethod(add_wagon_scene)

    variations = tuple(VARIATIONS)

    def __init__(self, description: RobotDescription | None = None, variation: str = "default") -> None:
        self.description = description = task_description(description)
        self.variation, self.ranges = variation, VARIATIONS[variation]
        chain = load_chain(CHAIN, description.groups)
        grasp = next(s for s in chain.skills if s.name == GRASP_SKILL)
        self.grasp_params: GraspParams = grasp.params  # type: ignore[assignment]
        self.check = grasp.until
        """The chain's switch condition after its grasp: ``grasped`` with its parameters."""
        self.episode_seconds = float(grasp.timeout)
        self.model = scene_model(description, chain.scene)
        self.handle_height, self.light = HandleHeight(self.model), LightLevel(self.model)
        self.robot = MuJoCoRobot(description, model=self.model)
        self.space = ManipulationSpace.of(description)
        self.kp = grasp_gains(description, self.grasp_params)
        self.ready_pose = description.home_motor_pos.copy()
        """Start pose: the chain's (home)."""
        self.camera = HeadCamera(self.model, self.robot.data, description.handles.head_camera or "head_camera")
        self.probe = SceneProbe(self.model, self.robot.data)
        self._succeeded = False
        self._scene: WagonScene | None = None
        """The scene of the latest episode (`reset`)."""

    @property
    def succeeded(self) -> bool:
        """The chain's grasp check has held (it latches, as the chain switches on it)."""
        return self._succeeded

    def demonstrator(self) -> ScriptedWagonGrasp:
        """The task's scripted demonstrator (`manip demo --task wagon`)."""
        return ScriptedWagonGrasp(self)

    def teleop_robot(self, seed: int) -> MuJoCoRobot:
        """The robot in the wagon scene at its home pose, the wagon where the layout puts it, default gains: the
        operator walks and grasps as the chain would."""
        return self.robot

    def chain_start(self, seed: int, perturbation: StartPerturbation) -> tuple[WagonStart, np.ndarray]:
        """The robot at home (offset by the seed's arm pose and the perturbation), the wagon shifted for the seed
        (and by the perturbation's shift), the seed's handle height and light; a chain always starts at home."""
        rng = np.random.default_rng(seed)
        scene = draw_scene(rng, self.description, self.ranges)
        self._set_scene(scene)
        offset = scene.arm_offset + perturbation.motor_offset(rng, self.description.n_motors)
        start = WagonStart(self.description, self.model, offset, scene.shift + perturbation.object_shift)
        return start, self.description.home_motor_pos + offset

    def reset(self, seed: int) -> Observation:
        """The seed's scene (`draw_scene`): the robot at home with its arm offsets, or, for a re-grasp start, with
        its open hands at the handle, which then slips; returns the first observation."""
        scene = draw_scene(np.random.default_rng(seed), self.description, self.ranges)
        self._set_scene(scene)
        robot = self.robot
        robot.initial_motor_offset = scene.arm_offset
        robot.reset()
        robot.initial_motor_offset = np.zeros_like(scene.arm_offset)  # applied: the robot's next reset is home
        shift_wagon(self.model, robot.data, scene.shift)
        mujoco.mj_forward(self.model, robot.data)
        if scene.regrasp:
            self._reach_open()
            robot.start_qpos = robot.data.qpos.copy()
            robot.reset()  # at rest, time 0, the hands where the reach left them
            robot.start_qpos = None
            shift_wagon(self.model, robot.data, scene.slip)
            mujoco.mj_forward(self.model, robot.data)
        self._scene = scene
        self.probe.mark()
        self._succeeded = False
        return robot.observe()

    def step(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
             ) -> Observation:
        """One control step at the grasp skill's gains (or `kp`; `kd` as `Robot.step` takes it); success latches
        once the chain's check holds, as the chain ends its grasp phase there."""
        obs = self.robot.step(motor_targets, kp=self.kp if kp is None else kp, kd=kd)
        context = Context(self.robot, obs, np.asarray(motor_targets, dtype=float), self.probe)
        self._succeeded = self._succeeded or holds(self.check.predicate, self.check.params, context)
        return obs

    def failure_kind(self) -> str:
        """The start (home or re-grasp), then each hand: open (not commanded closed as far as the chain's check
        asks), closed off the bar (not both pads on it) or pinching; or that the robot fell."""
        start = "re-grasp" if self._scene is not None and self._scene.regrasp else "home"
        if self.robot.fallen:
            return f"{start} start: fell"
        params = self.check.params
        context = Context(self.robot, self.robot.observe(), self.robot.last_targets, self.probe)
        hands = []
        for side in SIDES:
            closed = commanded_closed(params, context, side)[0]
            state = "pinching" if closed and self.probe.pinching(side, params.target) else (
                "closed off the bar" if closed else "open")
            hands.append(f"{side} {state}")
        return f"{start} start: {', '.join(hands)}"

    def start_targets(self, obs: Observation) -> np.ndarray:
        """Where a grasp starts commanding: the ready pose, the arms where they are."""
        targets = self.ready_pose.copy()
        arms = self.description.groups["arm"]
        targets[arms] = obs.motor_pos[arms]
        return targets

    def scripted_grasp(self, why: str) -> ScriptedGrasp:
        """The chain's scripted grasp in this scene (the handle where the simulation has it), grasping in place
        where the open hands already hold the bar between their fingers (a re-grasp start)."""
        data = self.robot.data
        env = SkillEnv(self.robot, self.model, lambda: data.qpos, self.probe.geom_pos, self.probe.geom_pos,
                       self.head_image, simulated=True)
        return ScriptedGrasp(env, replace(self.grasp_params, in_place=True), why)

    def _set_scene(self, scene: WagonScene) -> None:
        self.handle_height.set(scene.handle_height)
        self.light.set(scene.light)

    def _reach_open(self) -> None:
        """The scripted grasp's approach and reach with the hands open: where a chain's re-grasp starts."""
        p, robot = self.grasp_params, self.robot
        skill = self.scripted_grasp("re-grasp start")
        obs = robot.observe()
        skill.start(obs, self.start_targets(obs))
        for _ in range(round((p.approach_s + p.reach_s) / robot.control_dt)):
            targets, kp = skill.act(obs, obs.time)
            obs = robot.step(targets, kp=kp)


class ScriptedWagonGrasp(Policy):
    """Demonstrator: the chain's own scripted grasp (`ScriptedGrasp`, the chain's parameters, the handle where the
    scene has it), then the closed grip held for `HOLD_S`, at the task's gains; done after `duration`."""

    name = "scripted-wagon-grasp"

    def __init__(self, task: WagonTask) -> None:
        super().__init__(task.robot)
        self.task = task
        self.skill = task.scripted_grasp("wagon demonstration")
        p = task.grasp_params
        self.duration = p.approach_s + p.reach_s + p.close_s + HOLD_S
        self._steps = round(self.duration / self.control_dt)
        self._step = 0
        self._start_time = 0.0

    @property
    def done(self) -> bool:
        return self._step >= self._steps

    def reset(self, task_obs: Observation) -> None:
        """Plan from the hands' and the handle's positions (right after `WagonTask.reset`: the run loop's reset of
        the task's `TaskRobot`)."""
        self.skill.start(task_obs, self.task.start_targets(task_obs))
        self._start_time = task_obs.time
        self._step = 0

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        """Motor targets (rad, all motors) for the next control step, at the task's gains."""
        targets, _ = self.skill.act(obs, obs.time - self._start_time)
        self._step += 1
        return Action(targets, self.transmission.motor_to_joint(targets), kp=self.task.kp)


class WagonStart(MuJoCoRobot):
    """The wagon scene with a chain's start: every `reset` puts the motors at their offsets and the wagon at its
    shift."""

    def __init__(self, description: RobotDescription, model: mujoco.MjModel, motor_offset: np.ndarray,
                 wagon_shift: np.ndarray) -> None:
        self.wagon_shift = wagon_shift  # before the base class's first reset
        super().__init__(description, model=model)
        self.initial_motor_offset = motor_offset

    def reset(self) -> Observation:
        obs = super().reset()  # the robot senses the same wherever the wagon stands
        shift_wagon(self.model, self.data, self.wagon_shift)
        mujoco.mj_forward(self.model, self.data)
        return obs
