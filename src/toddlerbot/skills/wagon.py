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
from toddlerbot.skills.sim_run import wagon_shift
from toddlerbot.skills.spec import load_chain
from toddlerbot.tasks.base import Task
from toddlerbot.tasks.camera import HeadCamera
from toddlerbot.tasks.predicates import Context, holds
from toddlerbot.tasks.probe import SceneProbe
from toddlerbot.tasks.scenes import scene_model, shift_wagon
from toddlerbot.tasks.space import ManipulationSpace

CHAIN = "wagon"
GRASP_SKILL = "grasp"
HOLD_S = 0.6
"""The demonstrations keep the closed grip this long after the closing ramp, so the policy learns to stay closed
(the chain's check fires at the ramp's end, a policy that reopens right after would drop the handle)."""


class WagonTask(Task):
    """Grasp the wagon handle with both hands (gripper variant, floating robot standing on the floor)."""

    name = "wagon"
    instruction = "grasp the wagon handle with both hands"

    def __init__(self, description: RobotDescription | None = None) -> None:
        description = description or RobotDescription.load(variant="gripper")
        if description.spec.variant != "gripper":
            description = description.with_variant("gripper")
        self.description = description
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
