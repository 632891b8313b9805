"""The MJX walking environment (Brax `Env` interface): velocity commands, ZMP imitation, 50 Hz control.

* Physics: the training variant of the robot's model (`toddlerbot.rl.model.training_model`: MJX timestep
  ``EnvConfig.sim_dt`` = 4 ms, 5 substeps per 20 ms control step, pruned contacts, solver settings) in full
  float32 matmul precision (`toddlerbot.rl.precision`); every substep applies the shared actuator model
  (`toddlerbot.actuation.model.motor_torque` with ``xp=jax.numpy``) as MuJoCo motor torques.
* Actions: 12 numbers, clipped to [-1, 1]; leg motor target = home + ``action_scale`` * action. The other 18
  motors hold their reference (the home pose).
* Episodes: `PPOConfig.episode_length` control steps (the episode wrapper counts them), ended early when the
  torso falls below ``min_torso_height`` or tilts more than ``max_tilt``.
* Observations: ``{"state": actor, "privileged_state": critic}`` (see `toddlerbot.rl.observations`).
* Every reset draws new domain-randomisation parameters, a command, and a push schedule for that env.
"""

from __future__ import annotations

from dataclasses import replace

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax.envs.base import Env, State
from mujoco import mjx

from toddlerbot.actuation.model import ActuatorArrays, motor_torque
from toddlerbot.rl import randomization, rewards
from toddlerbot.rl.config import EnvConfig
from toddlerbot.rl.model import training_model
from toddlerbot.rl.observations import Sensors, actor_frame, add_noise, critic_obs, push_frame
from toddlerbot.rl.precision import use_full_precision
from toddlerbot.rl.reference import ReferenceTable, leg_motor_indices, load_reference
from toddlerbot.robot.description import RobotDescription


def _yaw_quat(yaw: jax.Array) -> jax.Array:
    return jnp.array([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)])


def _yaw(quat: jax.Array) -> jax.Array:
    w, x, y, z = quat
    return jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _rotate_z(v: jax.Array, angle: jax.Array) -> jax.Array:
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


class WalkEnv(Env):
    """One walking robot; vmap it (the training wrappers do) for many."""

    def __init__(self, cfg: EnvConfig | None = None, description: RobotDescription | None = None,
                 reference: ReferenceTable | None = None) -> None:
        """``description``: the robot (by default the packaged spec with ``cfg.motor_params`` applied; a given
        one must carry the same params.json files). ``reference``: an imitation table (default: the ZMP walk)."""
        use_full_precision()
        cfg = cfg or EnvConfig()
        rewards.check_weights(cfg.reward)
        if description is None:
            description = RobotDescription.load(motor_params=cfg.motor_params)
        elif tuple(description.motor_params_files) != tuple(cfg.motor_params):
            raise ValueError(f"the description's motor params {description.motor_params_files} differ from the "
                             f"config's {cfg.motor_params}")
        self.description = description
        if reference is None:
            reference, self.reference_source = load_reference(description, cfg.command)
        else:
            self.reference_source = "given"
        self.reference = reference
        if cfg.obs.gait_period is None:
            cfg = replace(cfg, obs=replace(cfg.obs, gait_period=reference.period))
        self.cfg = cfg
        """The configuration with the gait period resolved (save this one)."""
        model = training_model(description, cfg)
        self.mj_model = model
        self.sys = mjx.put_model(model)
        self._ref_leg = jnp.asarray(reference.leg_motor_pos, dtype=jnp.float32)
        self._ref_contact = jnp.asarray(reference.contact, dtype=jnp.float32)

        joints = model.actuator_trnid[:, 0]
        self.motor_qadr = np.asarray(model.jnt_qposadr[joints])
        self.motor_dadr = np.asarray(model.jnt_dofadr[joints])
        self.home_motor_pos = np.asarray(description.home_motor_pos, dtype=np.float32)
        self.leg_index = leg_motor_indices(description)
        self.n_motors = len(self.motor_qadr)
        self.actuators = ActuatorArrays(*(jnp.asarray(a, dtype=jnp.float32) for a in description.actuator_arrays()))

        handles = description.handles
        self.floor_geom = model.geom("floor").id
        self.foot_geoms = np.array([model.geom(name).id for name in handles.feet_geoms])
        self.foot_sites = np.array([model.site(name).id for name in handles.feet_sites])
        home = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, home, model.key("home").id)
        mujoco.mj_forward(model, home)
        self._home_data = mjx.put_data(model, home)
        """The start state of every episode, computed once with classic MuJoCo (so reset compiles no physics)."""
        up = home.site_xmat[self.foot_sites[0]].reshape(3, 3)[2]  # world-z components of the site's axes
        self._foot_up_axis, self._foot_up_sign = int(np.argmax(np.abs(up))), float(np.sign(up[np.argmax(np.abs(up))]))
        self.torso_body = model.body(handles.torso).id
        self.imu_site = model.site(handles.imu_site).id
        self._quat_adr = model.sensor_adr[model.sensor("imu_quat").id]
        self._gyro_adr = model.sensor_adr[model.sensor("imu_gyro").id]
        self._zero_command_index = jnp.asarray(reference.grid.snap(np.zeros(3)))

    # Brax Env interface -------------------------------------------------------------------------------------
    @property
    def observation_size(self) -> dict[str, tuple[int, ...]]:
        actor = self.cfg.obs.history * self.frame_size
        state = self.reset(jax.random.PRNGKey(0))
        return {"state": (actor,), "privileged_state": state.obs["privileged_state"].shape}

    @property
    def frame_size(self) -> int:
        return self.cfg.obs.frame_size(self.n_motors, self.action_size)

    @property
    def action_size(self) -> int:
        return len(self.leg_index)

    @property
    def backend(self) -> str:
        return "mjx"

    def reset(self, rng: jax.Array) -> State:
        cfg = self.cfg
        rng, k_dr, k_cmd, k_push, k_noise = jax.random.split(rng, 5)
        m = self.sys
        dr = (randomization.sample(k_dr, cfg.randomization, m.nv, m.nbody, self.n_motors) if cfg.randomize
              else randomization.nominal(m.nv, m.nbody, self.n_motors))
        data = self._home_data
        cmd_index = self._sample_command(k_cmd)
        zeros12 = jnp.zeros(self.action_size)
        info = {
            "rng": rng, "dr": dr, "time": jnp.zeros(()), "step": jnp.zeros((), jnp.int32),
            "command": self.reference.grid.command(cmd_index, jnp), "command_index": cmd_index,
            "ref_yaw": _yaw(data.qpos[3:7]), "last_action": zeros12, "last_last_action": zeros12,
            "air_time": jnp.zeros(2), "last_contact": jnp.ones(2), "feet_pos": data.site_xpos[self.foot_sites],
            "push_timer": self._push_interval(k_push), "push": jnp.zeros(2),
            "history": jnp.zeros((cfg.obs.history, self.frame_size)),
        }
        obs, info = self._observe(data, info, k_noise, contact=jnp.ones(2), ref_leg=self._ref_leg_pos(info))
        info["history"] = jnp.tile(info["history"][:1], (cfg.obs.history, 1))
        obs["state"] = info["history"].reshape(-1)
        metrics = {name: jnp.zeros(()) for name in rewards.TERMS}
        return State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: State, action: jax.Array) -> State:
        cfg, info = self.cfg, dict(state.info)
        dr = info["dr"]
        k_noise, k_push, k_cmd, k_next = jax.random.split(info["rng"], 4)
        action = jnp.clip(action, -1.0, 1.0)  # the policy's Gaussian is unsquashed
        applied = jnp.where(dr.action_delay > 0, info["last_action"], action)
        targets = jnp.asarray(self.home_motor_pos).at[self.leg_index].add(cfg.obs.action_scale * applied)

        data, info = self._push(state.pipeline_state, info, k_push)
        data, taus = self.physics_step(data, targets, self._model(dr),
                                       randomization.apply_to_actuators(self.actuators, dr))
        info["time"] = info["time"] + cfg.ctrl_dt
        info["step"] = info["step"] + 1
        info["ref_yaw"] = info["ref_yaw"] + info["command"][2] * cfg.ctrl_dt

        contact, self_collision = self._contacts(data)
        first_contact = contact * (1 - info["last_contact"])
        air_time = info["air_time"] + cfg.ctrl_dt
        torso_quat = data.qpos[3:7]
        gravity = -data.xmat[self.torso_body][2]  # world -z in torso frame
        tilt = jnp.arccos(jnp.clip(-gravity[2], -1.0, 1.0))
        fallen = (data.qpos[2] < cfg.min_torso_height) | (tilt > cfg.max_tilt)
        feet_pos = data.site_xpos[self.foot_sites]
        yaw = _yaw(torso_quat)
        lateral = _rotate_z(feet_pos[0] - feet_pos[1], -yaw)[1]
        ref_leg, ref_contact = self._ref_leg_pos(info), self._ref_contact_flags(info)
        q = rewards.StepQuantities(
            torso_quat=torso_quat, ref_torso_quat=_yaw_quat(info["ref_yaw"]),
            lin_vel=_rotate_z(data.qvel[0:3], -yaw), ang_vel=data.qvel[3:6], command=info["command"],
            leg_pos=data.qpos[self.motor_qadr][self.leg_index], ref_leg_pos=ref_leg,
            home_leg_pos=jnp.asarray(self.home_motor_pos[self.leg_index]), contact=contact,
            ref_contact=ref_contact, first_contact=first_contact, air_time=air_time, feet_height=feet_pos[:, 2],
            feet_vel_xy=(feet_pos - info["feet_pos"])[:, :2] / cfg.ctrl_dt,
            feet_up_z=self._foot_up_sign * data.site_xmat[self.foot_sites][:, 2, self._foot_up_axis],
            feet_lateral_distance=lateral,
            roll=jnp.arctan2(gravity[1], -gravity[2]), pitch=jnp.arcsin(jnp.clip(-gravity[0], -1.0, 1.0)),
            self_collision=self_collision, action=action, last_action=info["last_action"],
            last_last_action=info["last_last_action"], motor_torque=taus[-1],
            motor_vel=data.qvel[self.motor_dadr], alive=1.0 - fallen.astype(jnp.float32),
        )
        reward, terms = rewards.total_reward(q, cfg.reward, cfg.ctrl_dt)

        info["air_time"] = air_time * (1 - contact)
        info["last_contact"] = contact
        info["feet_pos"] = feet_pos
        info["last_last_action"] = info["last_action"]
        info["last_action"] = action
        resample = info["step"] % round(cfg.command.resample_s / cfg.ctrl_dt) == 0
        new_index = jnp.where(resample, self._sample_command(k_cmd), info["command_index"])
        info["command_index"] = new_index
        info["command"] = self.reference.grid.command(new_index, jnp)
        info["rng"] = k_next
        obs, info = self._observe(data, info, k_noise, contact=contact, ref_leg=ref_leg)
        return state.replace(pipeline_state=data, obs=obs, reward=reward, done=fallen.astype(jnp.float32),
                             metrics={**state.metrics, **terms}, info=info)

    def physics_step(self, data: mjx.Data, targets: jax.Array, model: mjx.Model | None = None,
                     actuators: ActuatorArrays | None = None) -> tuple[mjx.Data, jax.Array]:
        """One control period of physics holding motor targets (rad, motor-id order): ``n_substeps`` MJX steps,
        each with the actuator model's torques. Returns the data and the (n_substeps, n_motors) torques, N m.
        ``model`` / ``actuators`` default to the nominal (un-randomised) robot."""
        model = self.sys if model is None else model
        act = self.actuators if actuators is None else actuators

        def substep(d: mjx.Data, _: None) -> tuple[mjx.Data, jax.Array]:
            tau = motor_torque(targets, d.qpos[self.motor_qadr], d.qvel[self.motor_dadr], act, xp=jnp)
            return mjx.step(model, d.replace(ctrl=tau)), tau

        return jax.lax.scan(substep, data, None, length=self.cfg.n_substeps)

    @property
    def home_data(self) -> mjx.Data:
        """The start state of every episode (home keyframe on the floor)."""
        return self._home_data

    # helpers -------------------------------------------------------------------------------------------------
    def _model(self, dr: randomization.DRParams) -> mjx.Model:
        return randomization.apply_to_model(self.sys, dr, self.floor_geom, self.torso_body)

    def _sample_command(self, key: jax.Array) -> jax.Array:
        """Grid indices of a random command: uniform over the grid, or stand still, or turn in place."""
        c = self.cfg.command
        k_idx, k_kind = jax.random.split(key)
        index = jax.random.randint(k_idx, (3,), 0, jnp.asarray(self.reference.grid.shape))
        u = jax.random.uniform(k_kind)
        zero = self._zero_command_index
        turn = zero.at[2].set(index[2])
        index = jnp.where(u < c.stand_prob + c.turn_prob, turn, index)
        return jnp.where(u < c.stand_prob, zero, index)

    def _phase_index(self, t: jax.Array) -> jax.Array:
        return self.reference.phase_index(t, jnp)

    def _ref_leg_pos(self, info: dict) -> jax.Array:
        i = info["command_index"]
        return self._ref_leg[i[0], i[1], i[2], self._phase_index(info["time"])]

    def _ref_contact_flags(self, info: dict) -> jax.Array:
        i = info["command_index"]
        return self._ref_contact[i[0], i[1], i[2], self._phase_index(info["time"])]

    def _contacts(self, data: mjx.Data) -> tuple[jax.Array, jax.Array]:
        """(left/right foot touching the floor as 0/1, number of penetrating robot-robot contacts)."""
        c = data._impl.contact
        g1, g2 = c.geom[:, 0], c.geom[:, 1]
        touching = c.dist < 0.0
        floor = self.floor_geom
        feet = jnp.stack([jnp.any(touching & (((g1 == floor) & (g2 == f)) | ((g2 == floor) & (g1 == f))))
                          for f in self.foot_geoms]).astype(jnp.float32)
        self_collision = jnp.sum(touching & (g1 != floor) & (g2 != floor)).astype(jnp.float32)
        return feet, self_collision

    def _push_interval(self, key: jax.Array) -> jax.Array:
        lo, hi = self.cfg.randomization.push_interval_s
        return jax.random.uniform(key, minval=lo, maxval=hi)

    def _push(self, data: mjx.Data, info: dict, key: jax.Array) -> tuple[mjx.Data, dict]:
        """When the env's push timer runs out, kick the torso horizontally and draw the next interval."""
        k_dir, k_mag, k_next = jax.random.split(key, 3)
        due = (info["push_timer"] <= 0) & self.cfg.randomize
        angle = jax.random.uniform(k_dir, maxval=2 * jnp.pi)
        speed = jax.random.uniform(k_mag, maxval=self.cfg.randomization.push_velocity)
        kick = jnp.where(due, speed, 0.0) * jnp.array([jnp.cos(angle), jnp.sin(angle)])
        info["push"] = kick
        info["push_timer"] = jnp.where(due, self._push_interval(k_next), info["push_timer"] - self.cfg.ctrl_dt)
        return data.replace(qvel=data.qvel.at[0:2].add(kick)), info

    def _observe(self, data: mjx.Data, info: dict, key: jax.Array, contact: jax.Array,
                 ref_leg: jax.Array) -> tuple[dict[str, jax.Array], dict]:
        cfg = self.cfg
        sensors = Sensors(
            motor_pos=data.qpos[self.motor_qadr], motor_vel=data.qvel[self.motor_dadr],
            gyro=data.sensordata[self._gyro_adr:self._gyro_adr + 3],
            imu_quat=data.sensordata[self._quat_adr:self._quat_adr + 4],
        )
        noisy, gravity = add_noise(key, sensors, cfg.obs, info["dr"].obs_noise_level)
        home = jnp.asarray(self.home_motor_pos)
        frame = actor_frame(info["time"], info["command"], noisy, gravity, home, info["last_action"], cfg.obs)
        clean = actor_frame(info["time"], info["command"], sensors, -data.site_xmat[self.imu_site][2], home,
                            info["last_action"], cfg.obs)
        info["history"] = push_frame(info["history"], frame)
        actor = info["history"].reshape(-1)
        yaw = _yaw(data.qpos[3:7])
        privileged = {
            "lin_vel": _rotate_z(data.qvel[0:3], -yaw), "contact": contact,
            "leg_error": ref_leg - sensors.motor_pos[self.leg_index], "push": info["push"],
            "air_time": info["air_time"], "torso_height": data.qpos[2:3],
            "floor_friction": info["dr"].floor_friction[None],
        }
        return {"state": actor, "privileged_state": critic_obs(actor, clean, privileged)}, info
