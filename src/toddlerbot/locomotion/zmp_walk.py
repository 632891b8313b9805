"""ZMP walking pattern generator: velocity command -> footsteps -> CoM (preview control) -> leg joint angles.

`ZMPWalk` is deterministic and uses numpy, scipy and MuJoCo's kinematics only. Two ways to use it:

* online (a walking policy): ``state = walk.start(command)``, then every tick
  ``state, ref = walk.step(state, command)``; the command may change at any tick;
* offline (reference motions for RL): ``walk.trajectory(command_or_schedule, duration)`` returns every tick's
  reference stacked into arrays, and ``walk.reference(command, t)`` is the reference at time t of a walk that
  started from the home pose at t = 0 under a constant command (cached per command).

Timeline (ticks of ``WalkConfig.dt``): a standing start of ``start_time``, then steps of half a cycle each. Step
k begins with double support (the ZMP moves from footstep S_{k-1} to S_k) and continues in single support on
S_k while the other foot swings from S_{k-1} to S_{k+1}. Footstep S_{k+1} is fixed when step k begins; later
footsteps (used only by the preview) follow the current command.

Frames: the walk frame (see `footsteps`); foot positions are the foot-centre sites (z = 0 on the floor);
joint angles are output joints (``TransmissionMap.joint_names``) in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.locomotion.footsteps import LEFT, RIGHT, advance, foot_pose, stance_side
from toddlerbot.locomotion.leg_ik import LegIK
from toddlerbot.locomotion.preview import preview_gains, preview_step
from toddlerbot.locomotion.swing import swing_pose
from toddlerbot.robot.description import RobotDescription


@dataclass(frozen=True)
class WalkReference:
    """The walking reference at one tick (walk frame; see the module docstring)."""

    time: float
    """s since the start of the walk."""
    phase: float
    """Gait phase in [0, 1): 0 at the start of a step on the first stance foot; 0 while standing at the start."""
    command: np.ndarray
    """(3,) the command in effect (vx m/s, vy m/s, yaw rate rad/s), after clipping to the limits."""
    joint_pos: np.ndarray
    """(n_joints,) output-joint targets, rad, in TransmissionMap.joint_names order (non-leg joints at home)."""
    com_pos: np.ndarray
    """(3,) planned CoM position, m."""
    com_vel: np.ndarray
    """(3,) planned CoM velocity, m/s."""
    zmp_ref: np.ndarray
    """(2,) ZMP reference from the footsteps, m."""
    zmp: np.ndarray
    """(2,) ZMP of the planned cart-table motion, m."""
    foot_pos: np.ndarray
    """(2, 3) left/right foot-centre positions, m."""
    foot_yaw: np.ndarray
    """(2,) left/right foot yaw, rad."""
    torso_pos: np.ndarray
    """(3,) torso (base body) position, m."""
    torso_yaw: float
    """rad."""
    contact: np.ndarray
    """(2,) planned left/right foot contact (True = on the floor)."""


@dataclass(frozen=True)
class WalkTrajectory:
    """`WalkReference` fields stacked over ticks (first axis = tick)."""

    time: np.ndarray
    phase: np.ndarray
    command: np.ndarray
    joint_pos: np.ndarray
    com_pos: np.ndarray
    com_vel: np.ndarray
    zmp_ref: np.ndarray
    zmp: np.ndarray
    foot_pos: np.ndarray
    foot_yaw: np.ndarray
    torso_pos: np.ndarray
    torso_yaw: np.ndarray
    contact: np.ndarray

    @classmethod
    def stack(cls, refs: list[WalkReference]) -> WalkTrajectory:
        return cls(**{f.name: np.array([getattr(r, f.name) for r in refs]) for f in fields(WalkReference)})

    def at(self, tick: int) -> WalkReference:
        values = {f.name: getattr(self, f.name)[tick] for f in fields(self)}
        values["time"], values["phase"], values["torso_yaw"] = (
            float(values["time"]), float(values["phase"]), float(values["torso_yaw"]))
        return WalkReference(**values)


@dataclass
class WalkState:
    """Everything the generator carries from one tick to the next (copy it to branch a walk)."""

    tick: int
    cart: np.ndarray
    """(3, 2) CoM position, velocity, acceleration along x and y."""
    zmp_error_sum: np.ndarray
    walk_poses: list[np.ndarray]
    """Fixed walk-frame poses P_0 .. P_{k+1}."""
    first_stance: int
    leg_q: np.ndarray
    """(2, 6) last leg solution (IK warm start)."""
    start_feet: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((2, 3)))
    """(2, 3) the feet's floor poses (x, y, yaw) at the start."""
    step_offsets: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    """(3, 2) walk-frame xy shifts of footsteps S_{k-1}, S_k and S_{k+1} from the plan (feedback inputs,
    `ZMPWalk.adjust_swing`; zero offline), m. The feet go to the shifted footsteps; the ZMP reference, and so the
    CoM plan, keep the planned ones. When a shifted foot lands, `follow` of its shift moves the walk pose P_k
    itself (the footsteps after it follow from there) and the rest stays on that footstep alone."""
    follow: float = 1.0
    """Fraction of a landed foot's shift taken into the walk poses (1: walk on from where the foot landed; 0:
    return to the planned path with the next step)."""


class ZMPWalk:
    """The ZMP walking pattern generator of one robot (its description: leg kinematics, home pose, joint order)."""

    def __init__(self, description: RobotDescription, config: WalkConfig | None = None) -> None:
        self.config = config or WalkConfig()
        self.description = description
        self.ik = LegIK(description)
        self.joint_names = description.joint_names
        self.home_joint_pos = description.home_joint_pos
        self._leg_index = np.array([[self.joint_names.index(j) for j in leg] for leg in self.ik.chains.joint_names])
        feet = self.ik.home_foot_pos
        self._mid = feet[:, :2].mean(axis=0)
        """Torso-frame xy of the walk-frame origin at the home pose."""
        self.torso_height = float(-feet[:, 2].mean())
        self.com_offset = self.ik.home_com.copy()
        """CoM in the torso frame, m (home pose; the generator keeps it fixed)."""
        self.com_height = self.torso_height + float(self.com_offset[2])
        self.stance_width = self.config.stance_width or float(feet[0, 1] - feet[1, 1])
        self.gains = preview_gains(
            self.config.dt, self.com_height, self.config.preview_ticks, self.config.zmp_weight, self.config.jerk_weight
        )
        self._limits = np.array([self.config.max_vx, self.config.max_vy, self.config.max_yaw_rate])
        self._cache: dict[tuple[float, float, float], list[WalkReference]] = {}

    # -- public API -------------------------------------------------------------------------------------------
    @property
    def leg_index(self) -> np.ndarray:
        """(2, n_leg_joints) joint-vector indices of the left and right leg chains (`LegIK` chain order)."""
        return self._leg_index

    def clip_command(self, command: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(command, dtype=float).reshape(3), -self._limits, self._limits)

    def start(self, command: np.ndarray | None = None) -> WalkState:
        """The state at t = 0: home pose, both feet down; the first swing foot is the one the command leads with."""
        cmd = self.clip_command(np.zeros(3) if command is None else command)
        first_stance = RIGHT if cmd[1] > 0 else LEFT
        feet = np.array([[*(self.ik.home_foot_pos[s, :2] - self._mid), 0.0] for s in (LEFT, RIGHT)])
        com = self.com_offset[:2] - self._mid
        cart = np.zeros((3, 2))
        cart[0] = com
        return WalkState(tick=0, cart=cart, zmp_error_sum=np.zeros(2), walk_poses=[np.zeros(3)],
                         first_stance=first_stance, leg_q=self.ik.home_q.copy(), start_feet=feet)

    def step(
        self, state: WalkState, command: np.ndarray, torso_tilt: np.ndarray | None = None
    ) -> tuple[WalkState, WalkReference]:
        """The reference at ``state.tick`` under ``command`` and the state of the next tick (state is not modified).

        ``torso_tilt``: optional (2, 3, 3) rotations, per leg, of the torso relative to its planned upright
        orientation (a feedback input: the measured tilt, scaled); the leg IK then places each foot where the plan
        wants it in the world although the torso is tilted. None (offline use) means upright."""
        cfg = self.config
        cmd = self.clip_command(command)
        tick = state.tick
        poses = list(state.walk_poses)
        k = self._step_index(tick)
        offsets = state.step_offsets
        if k >= 0 and (tick - cfg.start_ticks) % cfg.step_ticks == 0 and len(poses) < k + 2:
            if offsets.any():  # a new step: S_k, shifted, has landed
                landed = offsets[2]
                if landed.any() and state.follow > 0:
                    poses[k] = poses[k] + np.array([*(state.follow * landed), 0.0])
                offsets = np.array([offsets[1], (1.0 - state.follow) * landed, np.zeros(2)])
            poses.append(advance(poses[-1], cmd, cfg.step_ticks * cfg.dt))  # fix S_{k+1}
        footsteps = self._footsteps(state, poses, cmd, k + 2 + cfg.preview_ticks // cfg.step_ticks + 2)
        zmp_future = self._zmp_refs(state, footsteps, np.arange(tick, tick + cfg.preview_ticks + 1))
        cart, err_sum, zmp = preview_step(self.gains, state.cart, state.zmp_error_sum, zmp_future)
        foot_floor, lift, contact = self._feet(state, footsteps, tick, offsets)
        ref, leg_q = self._pose(tick, cmd, state, foot_floor, lift, contact, state.cart, zmp, zmp_future[0], torso_tilt)
        next_state = WalkState(tick=tick + 1, cart=cart, zmp_error_sum=err_sum, walk_poses=poses,
                               first_stance=state.first_stance, leg_q=leg_q, start_feet=state.start_feet,
                               step_offsets=offsets, follow=state.follow)
        return next_state, ref

    def trajectory(self, commands, duration: float) -> WalkTrajectory:
        """Every tick's reference over ``duration`` s from the home pose. ``commands`` is a constant (3,) command
        or a callable t -> (3,) command (e.g. `toddlerbot.runtime.commands.CommandSchedule`)."""
        command_at = commands if callable(commands) else (lambda t: commands)
        n = round(duration / self.config.dt)
        state = self.start(command_at(0.0))
        refs = []
        for i in range(n):
            state, ref = self.step(state, command_at(i * self.config.dt))
            refs.append(ref)
        return WalkTrajectory.stack(refs)

    def reference(self, command, t: float) -> WalkReference:
        """Reference at time t (s) of a walk from the home pose under a constant command (cached)."""
        cmd = self.clip_command(command)
        key = (float(cmd[0]), float(cmd[1]), float(cmd[2]))
        refs = self._cache.setdefault(key, [])
        tick = int(np.floor(t / self.config.dt + 1e-9))
        if tick < 0:
            raise ValueError(f"t must be >= 0 s, got {t}")
        state = getattr(self, "_cache_states", {}).get(key) or self.start(cmd)
        while len(refs) <= tick:
            state, ref = self.step(state, cmd)
            refs.append(ref)
        self.__dict__.setdefault("_cache_states", {})[key] = state
        return refs[tick]

    def adjust_swing(self, state: WalkState, offset: np.ndarray, follow: float = 1.0) -> WalkState:
        """The state with the swinging foot's target S_{k+1} shifted by ``offset`` (walk-frame xy, m) from the
        plan (replaces any earlier shift of the same step), ``follow`` of it to be taken into the walk poses when
        the foot lands (`WalkState.step_offsets`)."""
        offsets = state.step_offsets.copy()
        offsets[2] = np.asarray(offset, dtype=float).reshape(2)
        return replace(state, step_offsets=offsets, follow=float(follow))

    def swing_leg(self, state: WalkState) -> tuple[int | None, int]:
        """(the leg that swings, or is about to swing, in the step at ``state.tick``; ticks from then to its
        planned touchdown). (None, 0) while standing at the start."""
        cfg = self.config
        k = self._step_index(state.tick)
        if k < 0:
            return None, 0
        into_step = state.tick - cfg.start_ticks - k * cfg.step_ticks
        return 1 - stance_side(k, state.first_stance), cfg.step_ticks - into_step

    # -- internals --------------------------------------------------------------------------------------------
    def _step_index(self, tick: int) -> int:
        cfg = self.config
        return -1 if tick < cfg.start_ticks else (tick - cfg.start_ticks) // cfg.step_ticks

    def _footsteps(self, state: WalkState, poses: list[np.ndarray], cmd: np.ndarray, n: int) -> dict[int, np.ndarray]:
        """Floor poses (x, y, yaw) of footsteps S_-1 .. S_n."""
        step_time = self.config.step_ticks * self.config.dt
        poses = list(poses)
        while len(poses) <= n:
            poses.append(advance(poses[-1], cmd, step_time))
        first = state.first_stance
        steps = {-1: state.start_feet[1 - first], 0: state.start_feet[first]}
        for j in range(1, n + 1):
            steps[j] = foot_pose(poses[j], stance_side(j, first), self.stance_width)
        return steps

    def _zmp_refs(self, state: WalkState, steps: dict[int, np.ndarray], ticks: np.ndarray) -> np.ndarray:
        """(len(ticks), 2) ZMP reference: the start midpoint while standing, then on footstep S_k, moving linearly
        from S_{k-1} (the start midpoint for k = 0) during step k's double support."""
        cfg = self.config
        start = state.start_feet[:, :2].mean(axis=0)
        n = max(steps) + 1
        targets = np.array([start] + [steps[j][:2] for j in range(n)])  # row 0: start midpoint; row j + 1: S_j
        k = np.where(ticks < cfg.start_ticks, -1, (ticks - cfg.start_ticks) // cfg.step_ticks)
        tau = ticks - cfg.start_ticks - k * cfg.step_ticks
        prev = np.where((k <= 0)[:, None], start, targets[np.maximum(k, 0)])
        target = targets[k + 1]
        blend = np.where(k < 0, 1.0, np.minimum((tau + 1) / cfg.double_support_ticks, 1.0))[:, None]
        return prev + blend * (target - prev)

    def _feet(self, state: WalkState, steps: dict[int, np.ndarray], tick: int, offsets: np.ndarray):
        """Foot floor poses (2, 3: x, y, yaw), lifts (2,) and contact flags (2,) at a tick; footsteps S_{k-1},
        S_k and S_{k+1} shifted by the rows of ``offsets`` (walk frame, m)."""
        cfg = self.config
        k = self._step_index(tick)
        first = state.first_stance
        if k < 0:
            return state.start_feet.copy(), np.zeros(2), np.ones(2, dtype=bool)
        stance = stance_side(k, first)
        swing = 1 - stance
        feet, lift, contact = np.zeros((2, 3)), np.zeros(2), np.ones(2, dtype=bool)
        previous, current, end = steps[k - 1], steps[k], steps[k + 1]
        if offsets.any():
            previous, current, end = (step + np.array([*offset, 0.0])
                                      for step, offset in zip((previous, current, end), offsets, strict=True))
        feet[stance] = current
        tau = tick - cfg.start_ticks - k * cfg.step_ticks
        ss = tau - cfg.double_support_ticks + 1
        if ss <= 0:
            feet[swing] = previous
        else:
            s = ss / (cfg.step_ticks - cfg.double_support_ticks)
            pos, yaw = swing_pose(previous, end, s, cfg.step_height)
            feet[swing] = (pos[0], pos[1], yaw)
            lift[swing] = pos[2]
            contact[swing] = s >= 1.0
        return feet, lift, contact

    def _pose(
        self, tick, cmd, state, feet, lift, contact, cart, zmp, zmp_ref, torso_tilt
    ) -> tuple[WalkReference, np.ndarray]:
        cfg = self.config
        yaw_l, yaw_r = feet[LEFT, 2], feet[RIGHT, 2]
        torso_yaw = yaw_r + 0.5 * ((yaw_l - yaw_r + np.pi) % (2 * np.pi) - np.pi)
        c, s = np.cos(torso_yaw), np.sin(torso_yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        com = np.array([cart[0, 0], cart[0, 1], self.com_height])
        foot_world = np.column_stack([feet[:, :2], lift])
        foot_rot = np.empty((2, 3, 3))
        for leg in (LEFT, RIGHT):
            d = feet[leg, 2] - torso_yaw
            cd, sd = np.cos(d), np.sin(d)
            foot_rot[leg] = np.array([[cd, -sd, 0.0], [sd, cd, 0.0], [0.0, 0.0, 1.0]]) @ self.ik.home_foot_rot[leg]
        # the torso sits where the CoM offset puts it below the cart; with leg_mass_correction the offset is the
        # whole robot's CoM at the legs' angles (moving swing leg included), so torso placement and IK alternate
        leg_q = state.leg_q
        com_offset = self.ik.com(leg_q) if cfg.leg_mass_correction else self.com_offset
        for _ in range(cfg.com_iterations if cfg.leg_mass_correction else 1):
            torso = com - rot @ com_offset
            foot_torso = (foot_world - torso) @ rot  # rot.T @ (p - torso) for each row
            leg_rot = foot_rot.copy()
            if torso_tilt is not None:
                # the torso is rotated by tilt (in the yaw-aligned frame) about its origin: express targets in it
                for leg in (LEFT, RIGHT):
                    foot_torso[leg] = torso_tilt[leg].T @ foot_torso[leg]
                    leg_rot[leg] = torso_tilt[leg].T @ foot_rot[leg]
            leg_q = self.ik.solve(foot_torso, leg_rot, leg_q)
            if cfg.leg_mass_correction:
                com_offset = self.ik.com(leg_q)
        joint_pos = self.home_joint_pos.copy()
        joint_pos[self._leg_index] = leg_q
        k_tick = tick - cfg.start_ticks
        phase = 0.0 if k_tick < 0 else (k_tick % (2 * cfg.step_ticks)) / (2 * cfg.step_ticks)
        ref = WalkReference(
            time=tick * cfg.dt, phase=phase, command=cmd, joint_pos=joint_pos, com_pos=com,
            com_vel=np.array([cart[1, 0], cart[1, 1], 0.0]), zmp_ref=zmp_ref, zmp=zmp,
            foot_pos=foot_world, foot_yaw=feet[:, 2].copy(), torso_pos=torso, torso_yaw=float(torso_yaw),
            contact=contact,
        )
        return ref, leg_q
