"""The ``pick`` task (lift a cube and hold it) on the `Robot` interface; the ``wagon`` task (grasp the wagon handle
with both hands) is the wagon chain's grasp phase, in `toddlerbot.skills.wagon`.

A task owns a `MuJoCoRobot` on a scene model (`toddlerbot.tasks.scenes`), resets it for a seed (cube pose
randomised, arm in its ready pose, neck looking at the table), steps it with the follower's reduced upper-body
gains, tracks success and renders the head-camera image.

The recorded vectors follow `ManipulationSpace`: the follower's arm and gripper motor angles (rad, motor-id
order) are the observation state, and the same motors' commanded targets are the action.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import mujoco
import numpy as np

from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT, Observation, Robot
from toddlerbot.runtime.runner import Step
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig
from toddlerbot.tasks import task_description
from toddlerbot.tasks.base import StartPerturbation, Task, TaskProgress, TaskRobot
from toddlerbot.tasks.camera import HeadCamera
from toddlerbot.tasks.demonstrator import DemoConfig, ScriptedPicker
from toddlerbot.tasks.ik import ArmIK, top_down_rotation
from toddlerbot.tasks.scenes import (
    CUBE_BODY,
    CUBE_GEOM,
    TABLE_GEOM,
    add_pick_scene,
    finger_pads,
    grasp_site,
    place_cube,
    scene_model,
)
from toddlerbot.tasks.space import FOLLOWER_KP_SCALE, ManipulationSpace, follower_gains


@dataclass(frozen=True)
class PickConfig:
    """The ``pick`` task: cube start region, success rule and follower settings (lengths in m, world frame)."""

    arm: str = "right"
    cube_x: tuple[float, float] = (0.10, 0.125)
    """Range of the cube centre's x (forward)."""
    cube_y: tuple[float, float] = (-0.125, -0.085)
    cube_yaw: tuple[float, float] = (-0.6, 0.6)
    """Range of the cube's yaw about z, rad."""
    lift_height: float = 0.03
    """Success: the cube's bottom at least this far above the table top..."""
    hold_seconds: float = 1.0
    """...and held between both fingers, continuously for this long."""
    upper_body_kp_scale: float = FOLLOWER_KP_SCALE
    neck_pitch: float = -1.15
    """Neck pitch drive angle (rad, negative looks down) so the head camera sees the table..."""
    neck_yaw: float = -0.4
    """...and neck yaw drive angle (rad, negative looks right, towards the cube region)."""
    ready_offset: tuple[float, float, float] = (0.0, -0.05, 0.10)
    """Start pose: grasp point at this offset from the cube region's centre on the table top (outside and above,
    so the gripper does not hide the cube from the head camera)."""
    control_dt: float = CONTROL_DT

    def __post_init__(self) -> None:
        if self.arm not in ("left", "right"):
            raise ValueError(f"arm must be 'left' or 'right', got {self.arm!r}")
        for name in ("cube_x", "cube_y", "cube_yaw"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: lower {lo} is greater than upper {hi}")


@dataclass
class SuccessTracker:
    """Counts how long the cube has been lifted and pinched by both fingers without interruption."""

    hold_seconds: float
    held_for: float = 0.0
    """Seconds the current uninterrupted lifted pinch has lasted."""
    succeeded: bool = False
    max_lift: float = 0.0
    """Highest lift seen, m (for failure reports)."""

    def update(self, lifted: float, lift_needed: float, pinched: bool, dt: float) -> bool:
        self.max_lift = max(self.max_lift, lifted)
        self.held_for = self.held_for + dt if lifted >= lift_needed and pinched else 0.0
        self.succeeded = self.succeeded or self.held_for >= self.hold_seconds - 1e-9
        return self.succeeded


class PickTask(Task):
    """Lift a 3 cm cube from the table and hold it between both fingers for 1 s (gripper variant)."""

    name = "pick"
    instruction = "pick up the red cube"
    episode_seconds = 8.0
    """`dp eval`'s default limit per episode, s (simulated)."""
    mounted = True
    add_scene = staticmethod(add_pick_scene)

    def __init__(self, description: RobotDescription | None = None, config: PickConfig | None = None) -> None:
        self.config = config or PickConfig()
        self.description = description = task_description(description)
        self.model = scene_model(description, "pick")
        self.robot = MuJoCoRobot(description, SimConfig(control_dt=self.config.control_dt), model=self.model)
        self.space = ManipulationSpace.of(description)
        self.kp = follower_gains(description, self.config.upper_body_kp_scale)
        m = self.model
        side = self.config.arm
        self._cube = m.body(CUBE_BODY).id
        self._cube_geom = m.geom(CUBE_GEOM).id
        self._fingers = tuple(m.geom(pad).id for pad in finger_pads(side))
        self._table_top = float(self.robot.data.geom(TABLE_GEOM).xpos[2] + m.geom(TABLE_GEOM).size[2])
        self._cube_half = float(m.geom(CUBE_GEOM).size[0])
        names = description.motor_names
        self.gripper_motor = names.index(f"{side}_gripper_drive")
        self.neck_pitch_motor = names.index("neck_pitch_drive")
        self.neck_yaw_motor = names.index("neck_yaw_drive")
        self.camera = HeadCamera(m, self.robot.data, description.handles.head_camera or "head_camera")
        self.tracker = SuccessTracker(self.config.hold_seconds)
        self.seed: int | None = None
        """The seed of the last `reset` (the demonstrator draws its waypoint noise from it)."""

    def progress(self) -> PickProgress:
        """A run observer reporting how the arm did (`sim run --task pick`)."""
        return PickProgress(self)

    def demonstrator(self, config: DemoConfig | None = None) -> ScriptedPicker:
        """The task's scripted demonstrator (`manip demo`)."""
        return ScriptedPicker(self, config)

    def chain_start(self, seed: int, perturbation: StartPerturbation) -> tuple[PickStart, np.ndarray]:
        """The pick task's start, as `dp eval` resets it: the cube placed for the seed, the arm ready (offset by the
        perturbation)."""
        start = self.ready_pose + perturbation.motor_offset(np.random.default_rng(seed), self.description.n_motors)
        return PickStart(self, seed, start), start

    @property
    def arm(self) -> str:
        """The arm that picks: ``left`` or ``right``."""
        return self.config.arm

    @property
    def table_top(self) -> float:
        """Height of the table top, m."""
        return self._table_top

    def gripper_range(self) -> tuple[float, float]:
        """(open, closed) gripper drive angles, rad."""
        lo, hi = self.description.motor_range[self.gripper_motor]
        return float(lo), float(hi)

    @cached_property
    def ready_pose(self) -> np.ndarray:
        """Start pose (motor angles, rad): the home pose with the neck looking at the table and the task's arm
        holding its grasp point at `ready_offset` from the middle of the cube region, fingers down (by IK)."""
        cfg = self.config
        ik = ArmIK(self.description, self.model, cfg.arm, site=grasp_site(cfg.arm))
        centre = np.array([np.mean(cfg.cube_x), np.mean(cfg.cube_y), self.table_top]) + np.array(cfg.ready_offset)
        q = self.home_pose()
        for _ in range(6):
            q, _ = ik.solve(q, centre, top_down_rotation(np.array([0.0, 1.0])), self.model.key("home").qpos)
        return q

    def reset(self, seed: int, start_pose: np.ndarray | None = None) -> Observation:
        """Reset to the home keyframe, place the cube for `seed`, put the robot in `start_pose` (motor angles,
        rad; default: `ready_pose`) and return the first observation."""
        cfg = self.config
        rng = np.random.default_rng(seed)
        self.robot.reset()
        xy = np.array([rng.uniform(*cfg.cube_x), rng.uniform(*cfg.cube_y)])
        place_cube(self.model, self.robot.data, xy, float(rng.uniform(*cfg.cube_yaw)))
        q = self.ready_pose if start_pose is None else np.asarray(start_pose, dtype=float)
        self._set_motor_pos(q)
        self.tracker = SuccessTracker(cfg.hold_seconds)
        self.seed = seed
        return self.robot.observe()

    def home_pose(self) -> np.ndarray:
        q = self.description.home_motor_pos.copy()
        q[self.neck_pitch_motor] = self.config.neck_pitch
        q[self.neck_yaw_motor] = self.config.neck_yaw
        return q

    def step(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
             ) -> Observation:
        """One control step through the `Robot` interface (CommandGuard applies) at the follower gains (or
        `kp`, firmware units; `kd` as `Robot.step` takes it)."""
        obs = self.robot.step(motor_targets, kp=self.kp if kp is None else kp, kd=kd)
        self.tracker.update(self.cube_lift(), self.config.lift_height, self.pinched(), self.robot.control_dt)
        return obs

    def cube_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Cube centre (m) and rotation matrix in the world."""
        d = self.robot.data
        return d.xpos[self._cube].copy(), d.xmat[self._cube].reshape(3, 3).copy()

    def cube_lift(self) -> float:
        """Height of the cube's lowest point above the table top, m (0 when resting on it)."""
        pos, rot = self.cube_pose()
        bottom = pos[2] - self._cube_half * float(np.abs(rot[2]).sum())
        return max(0.0, bottom - self._table_top)

    def grasp_distance(self) -> float:
        """Distance from the task arm's grasp point (between the finger pads) to the cube centre, m."""
        site = self.robot.data.site(grasp_site(self.config.arm)).xpos
        return float(np.linalg.norm(site - self.cube_pose()[0]))

    def pinched(self) -> bool:
        """Do both fingers of the task's gripper touch the cube?"""
        d = self.robot.data
        touching = set()
        for c in d.contact[: d.ncon]:
            pair = (int(c.geom[0]), int(c.geom[1]))
            if self._cube_geom in pair:
                touching.add(pair[0] if pair[1] == self._cube_geom else pair[1])
        return all(f in touching for f in self._fingers)

    @property
    def succeeded(self) -> bool:
        return self.tracker.succeeded


    def _set_motor_pos(self, q_motor: np.ndarray) -> None:
        tmap = self.description.transmission
        d = self.robot.data
        for name, value in tmap.motor_to_model(q_motor).items():
            d.qpos[self.model.joint(name).qposadr[0]] = value
        mujoco.mj_forward(self.model, d)


class PickProgress(TaskProgress):
    """A run observer: how the arm did on the pick task: grasp-point-to-cube distance (start, closest, end), lift,
    and success (`TaskProgress`)."""

    def __init__(self, task: PickTask) -> None:
        super().__init__(task)
        self.task: PickTask = task
        self.start_distance_m = self.end_distance_m = float("nan")
        self.min_distance_m, self.max_lift_m = float("inf"), 0.0

    def on_start(self, robot: Robot, policy: Policy, obs: Observation) -> None:
        self.start_distance_m = self.task.grasp_distance()

    def on_step(self, step: Step) -> None:
        super().on_step(step)
        self.end_distance_m = self.task.grasp_distance()
        self.min_distance_m = min(self.min_distance_m, self.end_distance_m)
        self.max_lift_m = max(self.max_lift_m, self.task.cube_lift())

    def to_dict(self) -> dict:
        return super().to_dict() | {"start_distance_m": self.start_distance_m, "min_distance_m": self.min_distance_m,
                                    "end_distance_m": self.end_distance_m, "max_lift_m": self.max_lift_m}

    def describe(self) -> str:
        return (f"{self.task.name}: grasp point to cube {self.start_distance_m:.3f} m -> {self.end_distance_m:.3f} m "
                f"(closest {self.min_distance_m:.3f} m), cube lifted {1e3 * self.max_lift_m:.0f} mm, "
                f"{'not succeeded' if self.succeeded_at is None else f'succeeded at {self.succeeded_at:.2f} s'}")


class PickStart(TaskRobot):
    """The pick task's robot starting at `start_pose` (the task's ready pose, perhaps perturbed): a chain's start."""

    def __init__(self, task: PickTask, seed: int, start_pose: np.ndarray) -> None:
        super().__init__(task, seed)
        self.start_pose = start_pose

    def reset(self) -> Observation:
        return self.task.reset(self.seed, self.start_pose)
