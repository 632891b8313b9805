"""The walking environment, registered as ``walk`` (`toddlerbot.rl.environments`): velocity commands, ZMP
imitation, 50 Hz control.

* Physics: the training variant of the robot's model (`toddlerbot.rl.model.training_model`: timestep
  ``EnvConfig.sim_dt`` = 4 ms, 5 substeps per 20 ms control step, pruned contacts, solver settings), stepped by a
  backend of `toddlerbot.rl.physics` (MJX, or classic MuJoCo on CPU threads), which applies the shared actuator
  model (`toddlerbot.actuation.model.motor_torque`) every substep. Everything else here is one JAX definition for
  both backends.
* Actions: 12 numbers, clipped to [-1, 1]. Residual (default): leg motor target = the gait reference at the
  command and phase (`toddlerbot.policies.rl_inference.GaitReference`, interpolated) + ``action_scale`` * action,
  so a zero action walks the reference; otherwise home + ``action_scale`` * action. The other 18 motors hold the
  home pose. With ``teacher_gains`` the leg P gains follow walk-zmp's stance/swing schedule.
* Episodes: `PPOConfig.episode_length` control steps (the episode wrapper counts them), ended early when the
  torso falls below ``min_torso_height`` above the ground or tilts more than ``max_tilt`` (`WalkEnv.terminated`).
* Ground: the flat floor, or a terrain (`toddlerbot.sim.terrain`, ``EnvConfig.terrain`` and its seed) in the
  training model; torso and feet heights are then heights above the ground under them (`WalkEnv.height_above_ground`;
  on the flat floor the absolute heights, untouched).
* Rewards: `toddlerbot.rl.rewards.WALK_REWARDS` (Table 6 and the path term, each beside its weight).
* Default training: the CPU recipe (DAgger warm start from walk-zmp, then PPO), the one-GPU configuration, and the
  smoke run (`WalkEnv.recipes`).
* Observations: ``{"state": actor, "privileged_state": critic}`` (see `toddlerbot.rl.observations`).
* Every reset draws new domain-randomisation parameters, a command, and a push schedule for that env; every
  command comes with its upper-body pose and pull on the hands (both zero unless randomised).
"""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property
from pathlib import Path
from types import MappingProxyType

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import State

from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.files import atomic_savez, atomic_write_text
from toddlerbot.policies.rl_inference import GaitReference, leg_gain_scale, mirror_frame, mirror_leg_action
from toddlerbot.policies.walk_rl import default_weights
from toddlerbot.rl import config, randomization, rewards
from toddlerbot.rl.config import EnvConfig, Recipe
from toddlerbot.rl.environment import RLEnvironment, training_description
from toddlerbot.rl.export import write_policy
from toddlerbot.rl.model import training_model
from toddlerbot.rl.observations import Sensors, actor_frame, add_noise, aged_imu, critic_obs, push_frame
from toddlerbot.rl.physics import MODEL_FIELDS, Addresses, Frame
from toddlerbot.rl.precision import use_full_precision
from toddlerbot.rl.reference import leg_motor_indices, load_reference
from toddlerbot.rl.run_files import ACTION_SPACE, REFERENCE_RECORD
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.mirror import Mirror, robot_mirror
from toddlerbot.robot.upper_body import upper_body_mask
from toddlerbot.sim.terrain import Ground


def _yaw_quat(yaw: jax.Array) -> jax.Array:
    return jnp.array([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)])


def _yaw(quat: jax.Array) -> jax.Array:
    w, x, y, z = quat
    return jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _rotate_z(v: jax.Array, angle: jax.Array) -> jax.Array:
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


class WalkEnv(RLEnvironment):
    """One walking robot; vmap it (the training wrappers do) for many."""

    name = "walk"
    runtime_policy = "walk-rl"
    reward_terms = rewards.WALK_REWARDS
    recipes = MappingProxyType({"cpu": Recipe(config.CPU, config.CPU_IMITATION), "mjx": Recipe(config.FULL),
                                "smoke": Recipe(config.SMOKE, config.SMOKE_IMITATION)})
    step_metrics = ("lin_vel_error", "ang_vel_error")
    """|achieved - commanded| horizontal velocity (m/s, yaw frame) and yaw rate (rad/s), instantaneous (the
    tracking evaluation averages over a gait cycle)."""
    curves = (*RLEnvironment.curves[:2], ("lin_vel_error", "|v_xy - command| (m/s)"),
              ("ang_vel_error", "|yaw rate - command| (rad/s)"), ("fall_rate", "falls per env step"))
    """PPO's return and episode length, its `step_metrics`, and its episode ends, which are falls."""

    @classmethod
    def default_config(cls, smoke: bool = False) -> EnvConfig:
        return config.smoke_env_config() if smoke else EnvConfig()

    def __init__(self, cfg: EnvConfig | None = None, description: RobotDescription | None = None,
                 reference: GaitReference | None = None, gain_scales: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> None:
        """``description``: the robot (by default `training_description`; a given one must be of the same
        variant and carry the same params.json files). ``reference``: an imitation table (default: the ZMP walk).
        ``gain_scales``: (stance (n_motors,), swing (2, n_motors)) factors on the spec's P gains (default, with
        ``cfg.teacher_gains``: walk-zmp's). Every env walks on ``cfg.terrain``, drawn from ``cfg.terrain_seed``."""
        use_full_precision()
        cfg = self.resolved_config(cfg or EnvConfig())
        if description is None:
            description = training_description(cfg)
        elif description.spec.variant != cfg.variant:
            raise ValueError(f"the description's variant {description.spec.variant!r} differs from the config's "
                             f"{cfg.variant!r}")
        elif tuple(description.motor_params_files) != tuple(cfg.motor_params):
            raise ValueError(f"the description's motor params {description.motor_params_files} differ from the "
                             f"config's {cfg.motor_params}")
        self.description = description
        if reference is None:
            reference, self.reference_source = load_reference(description, cfg.command, cfg.ctrl_dt)
        else:
            self.reference_source = "given"
        self.reference = reference
        if cfg.obs.gait_period is None:
            cfg = replace(cfg, obs=replace(cfg.obs, gait_period=reference.period))
        self.cfg = cfg
        """The configuration with the gait period, the backend and the reward weights resolved (save this one)."""
        model = training_model(description, cfg)
        self.mj_model = model
        self.ground = Ground.of(model)
        """The terrain's ground heights, None on the flat floor."""
        self.addresses = Addresses.of(model, description)
        self.physics = self.make_physics(model, self.addresses, cfg)
        self._nominal = {name: jnp.asarray(getattr(model, name)) for name in MODEL_FIELDS}

        self.home_motor_pos = np.asarray(description.home_motor_pos, dtype=np.float32)
        self.leg_index = leg_motor_indices(description)
        self._upper_body = jnp.asarray(upper_body_mask(description))
        self._motor_range = jnp.asarray(description.motor_range, dtype=jnp.float32)
        self.n_motors = description.n_motors
        self.actuators = ActuatorArrays(*(jnp.asarray(a, dtype=jnp.float32) for a in description.actuator_arrays()))
        if gain_scales is None:
            if cfg.teacher_gains:
                from toddlerbot.rl.imitation import teacher_gain_scales

                gain_scales = teacher_gain_scales(description)
            else:
                gain_scales = (np.ones(self.n_motors), np.zeros((2, self.n_motors)))
        self.gain_scales = tuple(np.asarray(g, dtype=np.float32) for g in gain_scales)
        a = self.addresses
        self.floor_geom, self.torso_body, self.foot_sites = a.floor_geom, a.torso_body, a.foot_sites
        # the draw's friction is the ground's: the floor's, and a terrain's too
        self._friction_geoms = a.floor_geom if self.ground is None else np.asarray(a.ground_geoms)
        self.motor_qadr, self.motor_dadr = a.motors.qpos, a.motors.dof

    # Brax Env interface -------------------------------------------------------------------------------------
    @property
    def observation_size(self) -> dict[str, tuple[int, ...]]:
        actor = self.cfg.obs.history * self.frame_size
        state = jax.eval_shape(self.reset, jax.random.PRNGKey(0))
        return {"state": (actor,), "privileged_state": state.obs["privileged_state"].shape}

    @property
    def frame_size(self) -> int:
        return self.cfg.obs.frame_size(self.n_motors, self.action_size)

    @property
    def action_size(self) -> int:
        return len(self.leg_index)

    @cached_property
    def mirror(self) -> Mirror:
        """The robot's left-right mirror (checked when first asked: a variant need not be symmetric)."""
        return robot_mirror(self.description)

    def mirror_actor_obs(self, state: jax.Array) -> jax.Array:
        """Actor observations (the flattened history, on the last axis) of the robot's mirror image."""
        frames = state.reshape((*state.shape[:-1], self.cfg.obs.history, self.frame_size))
        return mirror_frame(frames, self.mirror, self.leg_index, jnp).reshape(state.shape)

    def mirror_action(self, action: jax.Array) -> jax.Array:
        """Leg actions (on the last axis) of the robot's mirror image."""
        return mirror_leg_action(action, self.mirror, self.leg_index, jnp)

    def reset(self, rng: jax.Array) -> State:
        cfg = self.cfg
        rng, k_dr, k_cmd, k_push, k_noise = jax.random.split(rng, 5)
        dr = self.draw_randomization(k_dr)
        frame = self.physics.home_frame
        command = self._sample_command(k_cmd)
        zeros = jnp.zeros(self.action_size)
        info = {
            "rng": rng, "dr": dr, "time": jnp.zeros(()), "step": jnp.zeros((), jnp.int32), "command": command,
            "ref_yaw": _yaw(frame.qpos[3:7]), "last_action": zeros, "last_last_action": zeros,
            "air_time": jnp.zeros(2), "last_contact": jnp.ones(2), "feet_pos": frame.feet_pos,
            "push_timer": randomization.push_interval(k_push, cfg.randomization), "push": jnp.zeros(2),
            "avg_vel": jnp.zeros(3), "path_error": jnp.zeros(2),
            "upper_body": self._upper_body_pose(k_cmd), "hand_force": self._hand_force(k_cmd),
            "history": jnp.zeros((cfg.obs.history, self.frame_size)),
        }
        ref_leg, _ = self.reference_at(command, info["time"])
        obs, info = self._observe(frame, info, k_noise, contact=jnp.ones(2), ref_leg=ref_leg)
        info["history"] = jnp.tile(info["history"][:1], (cfg.obs.history, 1))
        obs["state"] = info["history"].reshape(-1)
        metrics = {name: jnp.zeros(()) for name in (*self.reward_terms, *self.step_metrics)}
        return State(self.physics.home_state, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: State, action: jax.Array) -> State:
        cfg, info = self.cfg, dict(state.info)
        dr = info["dr"]
        k_noise, k_push, k_cmd, k_next = jax.random.split(info["rng"], 4)
        action = jnp.clip(action, -1.0, 1.0)  # the policy's Gaussian is unsquashed
        applied = jnp.where(dr.action_delay > 0, info["last_action"], action)
        targets, kp_scale = self.motor_targets(applied, info["command"], info["time"])
        targets = targets + info["upper_body"]
        actuators = randomization.apply_to_actuators(self.actuators, dr)
        actuators = actuators._replace(kp=actuators.kp * kp_scale)

        data, info = self._push(state.pipeline_state, info, k_push)
        hand_force = _rotate_z(info["hand_force"], _yaw(data.qpos[3:7]))
        data, frame = self.physics.step(data, targets, self.model_fields(dr), actuators, hand_force)
        info["time"] = info["time"] + cfg.ctrl_dt
        info["step"] = info["step"] + 1
        info["ref_yaw"] = info["ref_yaw"] + info["command"][2] * cfg.ctrl_dt

        contact = frame.contact
        first_contact = contact * (1 - info["last_contact"])
        air_time = info["air_time"] + cfg.ctrl_dt
        qpos, qvel = frame.qpos, frame.qvel
        torso_quat = qpos[3:7]
        gravity = -frame.torso_z  # world -z in torso frame
        fallen = self.terminated(frame)
        yaw = _yaw(torso_quat)
        lateral = _rotate_z(frame.feet_pos[0] - frame.feet_pos[1], -yaw)[1]
        ref_leg, ref_contact = self.reference_at(info["command"], info["time"])
        lin_vel = _rotate_z(qvel[0:3], -yaw)
        velocity = jnp.concatenate([lin_vel[:2], qvel[5:6]])
        info["avg_vel"] = info["avg_vel"] + cfg.ctrl_dt / cfg.reward.velocity_average_s * (velocity - info["avg_vel"])
        info["path_error"] = info["path_error"] + cfg.ctrl_dt * (
            lin_vel[:2] - info["command"][:2] - info["path_error"] / cfg.reward.path_memory_s)
        q = rewards.StepQuantities(
            torso_quat=torso_quat, ref_torso_quat=_yaw_quat(info["ref_yaw"]),
            lin_vel=lin_vel, ang_vel=qvel[3:6], avg_vel=info["avg_vel"], path_error=info["path_error"],
            command=info["command"],
            leg_pos=qpos[self.motor_qadr][self.leg_index], ref_leg_pos=ref_leg,
            home_leg_pos=jnp.asarray(self.home_motor_pos[self.leg_index]), contact=contact,
            ref_contact=jnp.round(ref_contact), first_contact=first_contact, air_time=air_time,
            feet_height=self.height_above_ground(frame.feet_pos),
            feet_vel_xy=(frame.feet_pos - info["feet_pos"])[:, :2] / cfg.ctrl_dt,
            feet_up_z=frame.feet_up_z, feet_lateral_distance=lateral,
            roll=jnp.arctan2(gravity[1], -gravity[2]), pitch=jnp.arcsin(jnp.clip(-gravity[0], -1.0, 1.0)),
            self_collision=frame.self_collision, action=action, last_action=info["last_action"],
            last_last_action=info["last_last_action"], motor_torque=frame.torque,
            motor_vel=qvel[self.motor_dadr], alive=1.0 - fallen.astype(jnp.float32),
        )
        reward, terms = self.reward_terms.total(q, cfg.reward, cfg.ctrl_dt)
        reward = jnp.where(jnp.isfinite(reward), reward, 0.0)
        terms["lin_vel_error"] = jnp.linalg.norm(q.lin_vel[:2] - q.command[:2])
        terms["ang_vel_error"] = jnp.abs(q.ang_vel[2] - q.command[2])

        info["air_time"] = air_time * (1 - contact)
        info["last_contact"] = contact
        info["feet_pos"] = frame.feet_pos
        info["last_last_action"] = info["last_action"]
        info["last_action"] = action
        resample = info["step"] % round(cfg.command.resample_s / cfg.ctrl_dt) == 0
        info["command"] = jnp.where(resample, self._sample_command(k_cmd), info["command"])
        info["upper_body"] = jnp.where(resample, self._upper_body_pose(k_cmd), info["upper_body"])
        info["hand_force"] = jnp.where(resample, self._hand_force(k_cmd), info["hand_force"])
        info["rng"] = k_next
        obs, info = self._observe(frame, info, k_noise, contact=contact, ref_leg=ref_leg)
        return state.replace(pipeline_state=data, obs=obs, reward=reward, done=fallen.astype(jnp.float32),
                             metrics={**state.metrics, **terms}, info=info)

    def height_above_ground(self, points: jax.Array) -> jax.Array:
        """Heights (m) of world points (..., 3) above the ground under them; on the flat floor their z itself."""
        if self.ground is None:
            return points[..., 2]
        return points[..., 2] - self.ground.height(points[..., 0], points[..., 1], xp=jnp)

    def terminated(self, frame: Frame) -> jax.Array:
        """A fall: the torso below ``min_torso_height`` above the ground, tilted beyond ``max_tilt``, or its height
        not finite."""
        tilt = jnp.arccos(jnp.clip(frame.torso_z[2], -1.0, 1.0))
        height = self.height_above_ground(frame.qpos[:3])
        return (height < self.cfg.min_torso_height) | (tilt > self.cfg.max_tilt) | ~jnp.isfinite(height)

    @classmethod
    def write_export(cls, out: Path, arrays: dict[str, np.ndarray], cfg: EnvConfig, meta: dict,
                     description: RobotDescription, action_space: dict[str, np.ndarray] | None) -> Path:
        """`rl.export.write_policy`: the gait reference (residual) and the leg gain schedule, the command ranges."""
        return write_policy(out, arrays, cfg, meta, description, action_space)

    @classmethod
    def shipped_export(cls, cfg: EnvConfig) -> Path:
        """``walk_rl.npz``, or ``walk_rl_<variant>.npz`` for a variant (`policies.walk_rl.default_weights`)."""
        return default_weights(cfg.variant)

    def record_action_space(self, run_dir: Path) -> None:
        """The reference's source (`REFERENCE_RECORD`) and its tables with the leg gain schedule (`ACTION_SPACE`)."""
        atomic_write_text(run_dir / REFERENCE_RECORD, self.reference_source + "\n")
        atomic_savez(run_dir / ACTION_SPACE, {**self.reference.arrays(), "kp_stance_scale": self.gain_scales[0],
                                              "kp_swing_scale": self.gain_scales[1]})

    # the policy's action space -------------------------------------------------------------------------------
    def reference_at(self, command: jax.Array, t: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(leg motor angles (12,) rad, stance flags (2,)) of the gait reference at a command and time."""
        return self.reference.at(command, t, jnp)

    def motor_targets(self, action: jax.Array, command: jax.Array, t: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(motor targets (n_motors,) rad, factor on each motor's P gain) of an action in [-1, 1]^12 at a command
        and time: the leg targets are the reference (``residual``) or home plus ``action_scale`` x action."""
        ref_leg, ref_contact = self.reference_at(command, t)
        legs = ref_leg if self.cfg.residual else jnp.asarray(self.home_motor_pos[self.leg_index])
        targets = jnp.asarray(self.home_motor_pos).at[self.leg_index].set(legs + self.cfg.obs.action_scale * action)
        return targets, leg_gain_scale(ref_contact, *self.gain_scales, xp=jnp)

    # helpers -------------------------------------------------------------------------------------------------
    def model_fields(self, dr: randomization.DRParams) -> dict[str, jax.Array]:
        """The env's randomised model parameters (both backends apply them)."""
        return randomization.model_fields(self._nominal, dr, self._friction_geoms, self.torso_body)

    def _sample_command(self, key: jax.Array) -> jax.Array:
        """A random command: stand still, turn in place, walk along one axis, or anywhere in the box."""
        c = self.cfg.command
        k_box, k_kind, k_axis = jax.random.split(key, 3)
        lo, hi = jnp.array([c.vx[0], c.vy[0], c.yaw[0]]), jnp.array([c.vx[1], c.vy[1], c.yaw[1]])
        box = jax.random.uniform(k_box, (3,), minval=lo, maxval=hi)
        u = jax.random.uniform(k_kind)
        axis = jnp.where(jax.random.uniform(k_axis) < 0.5, jnp.array([1.0, 0, 0]), jnp.array([0, 1.0, 0]))
        command = jnp.where(u < c.stand_prob + c.turn_prob + c.axis_prob, box * axis, box)
        command = jnp.where(u < c.stand_prob + c.turn_prob, box * jnp.array([0, 0, 1.0]), command)
        return jnp.where(u < c.stand_prob, jnp.zeros(3), command)

    def _upper_body_pose(self, command_key: jax.Array) -> jax.Array:
        """(n_motors,) offsets from home of a random upper-body pose drawn with each command (zeros unless
        randomised; its key is folded from the command's, so the other draws do not depend on it)."""
        fraction = self.cfg.randomization.upper_body_pose if self.cfg.randomize else 0.0
        return randomization.upper_body_offsets(jax.random.fold_in(command_key, 1), fraction,
                                                jnp.asarray(self.home_motor_pos), self._motor_range, self._upper_body)

    def _hand_force(self, command_key: jax.Array) -> jax.Array:
        """(3,) the pull on each hand, heading frame, drawn with each command (zeros unless randomised)."""
        largest = self.cfg.randomization.hand_force if self.cfg.randomize else 0.0
        return randomization.hand_force(jax.random.fold_in(command_key, 2), largest)

    def _push(self, data, info: dict, key: jax.Array) -> tuple[object, dict]:
        """When the env's push timer runs out, kick the torso horizontally and draw the next interval."""
        info["push"], info["push_timer"] = randomization.push(key, info["push_timer"], self.cfg.randomization,
                                                              self.cfg.randomize, self.cfg.ctrl_dt)
        return data.replace(qvel=data.qvel.at[0:2].add(info["push"])), info

    def _observe(self, frame: Frame, info: dict, key: jax.Array, contact: jax.Array,
                 ref_leg: jax.Array) -> tuple[dict[str, jax.Array], dict]:
        cfg = self.cfg
        sensors = Sensors(motor_pos=frame.qpos[self.motor_qadr], motor_vel=frame.qvel[self.motor_dadr],
                          gyro=frame.gyro, imu_quat=frame.imu_quat)
        # the reset has no earlier reading: there the IMU is fresh
        aged = aged_imu(info.get("sensors", sensors), sensors, info["dr"].imu_age / cfg.ctrl_dt)
        noisy, gravity = add_noise(key, aged, cfg.obs, info["dr"].obs_noise_level)
        home = jnp.asarray(self.home_motor_pos)
        frame_obs = actor_frame(info["time"], info["command"], noisy, gravity, home, info["last_action"], cfg.obs)
        clean = actor_frame(info["time"], info["command"], sensors, -frame.imu_z, home, info["last_action"],
                            cfg.obs)
        info["history"] = push_frame(info["history"], frame_obs)
        info["sensors"] = sensors  # noise-free: what the DAgger teacher reads
        actor = info["history"].reshape(-1)
        yaw = _yaw(frame.qpos[3:7])
        privileged = {
            "lin_vel": _rotate_z(frame.qvel[0:3], -yaw), "contact": contact,
            "leg_error": ref_leg - sensors.motor_pos[self.leg_index], "push": info["push"],
            "air_time": info["air_time"], "torso_height": self.height_above_ground(frame.qpos[:3])[None],
            "floor_friction": info["dr"].floor_friction[None], "avg_vel": info["avg_vel"],
        }
        if cfg.reward.weights.get("path_xy"):  # only then: the critics of runs without the term keep their shape
            privileged["path_error"] = info["path_error"]
        return {"state": actor, "privileged_state": critic_obs(actor, clean, privileged)}, info
