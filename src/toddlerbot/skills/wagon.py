"""The ``wagon`` task: the wagon chain's grasp phase as a task of its own (demonstrations, `dp eval`).

Everything comes from the shipped chain (`chains/wagon.yaml`): its grasp skill's parameters (the scripted
demonstrator, a `Policy`, *is* the chain's `ScriptedGrasp`, and the task steps at that skill's gains), its
``until`` check (success: the chain's ``grasped`` predicate, both grippers commanded closed and pinching the
handle, which is when the chain would switch to its next skill) and its timeout (the episode's limit). The robot
starts as the chain does: home pose, wagon shifted by the seed exactly as `chain run wagon --seed N` shifts it.
"""

from __future__ import annotations

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
from toddlerbot.tasks.predicates import Context, holds
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import add_wagon_scene, scene_model, shift_wagon
from toddlerbot.tasks.space import ManipulationSpace

WAGON_OFFSET = ((-0.01, 0.01), (-0.03, 0.03))
"""Seeded shift of the wagon from its layout position: (x range, y range), m."""
CHAIN = "wagon"
GRASP_SKILL = "grasp"
HOLD_S = 0.6
"""The demonstrations keep the closed grip this long after the closing ramp, so the policy learns to stay closed
(the chain's check fires at the ramp's end, a policy that reopens right after would drop the handle)."""


def wagon_shift(rng: np.random.Generator) -> np.ndarray:
    """The seed's shift of the wagon (x, y), m: the first draws of the seed's generator (the task's reset and a
    chain's start draw it alike, so `manip demo --task wagon` and `chain run wagon` place the wagon alike)."""
    return np.array([rng.uniform(*WAGON_OFFSET[0]), rng.uniform(*WAGON_OFFSET[1])])


class WagonTask(Task):
    """Grasp the wagon handle with both hands (gripper variant, floating robot standing on the floor)."""

    name = "wagon"
    instruction = "grasp the wagon handle with both hands"
    add_scene = staticmethod(add_wagon_scene)

    def __init__(self, description: RobotDescription | None = None) -> None:
        self.description = description = task_description(description)
        chain = load_chain(CHAIN, description.groups)
        grasp = next(s for s in chain.skills if s.name == GRASP_SKILL)
        self.grasp_params: GraspParams = grasp.params  # type: ignore[assignment]
        self.check = grasp.until
        """The chain's switch condition after its grasp: ``grasped`` with its parameters."""
        self.episode_seconds = float(grasp.timeout)
        self.model = scene_model(description, chain.scene)
        self.robot = MuJoCoRobot(description, model=self.model)
        self.space = ManipulationSpace.of(description)
        self.kp = grasp_gains(description, self.grasp_params)
        self.ready_pose = description.home_motor_pos.copy()
        """Start pose: the chain's (home)."""
        self.camera = HeadCamera(self.model, self.robot.data, description.handles.head_camera or "head_camera")
        self.probe = SceneProbe(self.model, self.robot.data)
        self._succeeded = False

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
        """The robot at home (offset by the perturbation), the wagon shifted for the seed (and by the
        perturbation's shift)."""
        rng = np.random.default_rng(seed)
        shift = wagon_shift(rng) + perturbation.object_shift
        offset = perturbation.motor_offset(rng, self.description.n_motors)
        return WagonStart(self.description, self.model, offset, shift), self.description.home_motor_pos + offset

    def reset(self, seed: int) -> Observation:
        """Home pose, wagon shifted for `seed`; returns the first observation."""
        self.robot.reset()
        shift_wagon(self.model, self.robot.data, wagon_shift(np.random.default_rng(seed)))
        mujoco.mj_forward(self.model, self.robot.data)
        self.probe.mark()
        self._succeeded = False
        return self.robot.observe()

    def step(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
             ) -> Observation:
        """One control step at the grasp skill's gains (or `kp`; `kd` as `Robot.step` takes it); success latches
        once the chain's check holds, as the chain ends its grasp phase there."""
        obs = self.robot.step(motor_targets, kp=self.kp if kp is None else kp, kd=kd)
        context = Context(self.robot, obs, np.asarray(motor_targets, dtype=float), self.probe)
        self._succeeded = self._succeeded or holds(self.check.predicate, self.check.params, context)
        return obs


class ScriptedWagonGrasp(Policy):
    """Demonstrator: the chain's own scripted grasp (`ScriptedGrasp`, the chain's parameters, the handle where the
    scene has it), then the closed grip held for `HOLD_S`, at the task's gains; done after `duration`."""

    name = "scripted-wagon-grasp"

    def __init__(self, task: WagonTask) -> None:
        super().__init__(task.robot)
        self.task = task
        data = task.robot.data
        env = SkillEnv(task.robot, task.model, lambda: data.qpos, task.probe.geom_pos, task.probe.geom_pos,
                       task.head_image, simulated=True)
        self.skill = ScriptedGrasp(env, task.grasp_params, "wagon demonstration")
        p = task.grasp_params
        self.duration = p.approach_s + p.reach_s + p.close_s + HOLD_S
        self._steps = round(self.duration / self.control_dt)
        self._step = 0
        self._start_time = 0.0

    @property
    def done(self) -> bool:
        return self._step >= self._steps

    def reset(self, task_obs: Observation) -> None:
        """Plan from the handle's position (right after `WagonTask.reset`: the run loop's reset of the task's
        `TaskRobot`); the seed's wagon shift is the episode's only variation."""
        self.skill.start(task_obs, self.task.ready_pose)
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
