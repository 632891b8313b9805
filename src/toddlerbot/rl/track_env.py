"""The motion-tracking environment, registered as ``track`` (`toddlerbot.rl.environments`): DeepMimic-style
imitation of a keyframe motion (`rl train --env track --motion NAME_OR_FILE`).

* Reference: the motion played open-loop on the training model (`toddlerbot.rl.motion_reference`), built once when
  the env is made; its row ``i`` is the state after ``i`` control steps, its last rows hold the final pose.
* Actions: one residual per motor (all 30), clipped to [-1, 1]: motor target = the reference's target at the current
  row + ``obs.action_scale`` x action, so a zero action plays the motion open-loop. Every motor, not only the ones
  the motion moves: the robot keeps its balance with its legs whatever the motion moves, and one action space serves
  every motion.
* Episodes: start at a random row of the reference, in its exact state (reference-state initialisation); end early
  when the torso turns, sinks or rises, or drifts too far from the reference (`TrackEnv.terminated`). Past the last
  row the reference stays there (the final pose).
* Observations: the actor sees a history of what the robot senses (motor angles relative to home, motor speeds,
  last action, gyro, gravity direction; noisy, the IMU aged, as walking's) and, once, the reference's phase (row /
  last row) and its motor targets `TrackConfig.lookahead` steps ahead (relative to home). The critic also sees the
  noise-free frame and privileged state (torso height, orientation, velocity, its errors against the reference,
  the push, floor friction).
* Rewards: `toddlerbot.rl.track_rewards.TRACK_REWARDS`. Domain randomisation and pushes: walking's
  (`toddlerbot.rl.randomization`), drawn at every reset.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import State

from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_savez, atomic_write_text
from toddlerbot.policies.motions import MAX_MOTION_BYTES, builtin_motions, load_motion, motion_path
from toddlerbot.policies.track import TrackPolicy
from toddlerbot.policies.track_observation import MotionTargets, track_actor_obs, track_frame, track_frame_size
from toddlerbot.policies.walk_rl import SHIPPED_WEIGHTS
from toddlerbot.rl import config, randomization, track_config
from toddlerbot.rl.config import Recipe
from toddlerbot.rl.environment import RLEnvironment, training_description
from toddlerbot.rl.export import robot_arrays
from toddlerbot.rl.model import training_model
from toddlerbot.rl.motion_reference import MotionReference, build_reference, in_torso_frame
from toddlerbot.rl.observations import Sensors, add_noise, aged_imu, critic_obs, push_frame
from toddlerbot.rl.physics import MODEL_FIELDS, Addresses, CPUState, Frame, frames_of
from toddlerbot.rl.precision import use_full_precision
from toddlerbot.rl.run_files import ACTION_SPACE, REFERENCE_RECORD
from toddlerbot.rl.track_config import TRACK, TrackConfig
from toddlerbot.rl.track_rewards import TRACK_REWARDS, TrackQuantities
from toddlerbot.robot.description import RobotDescription
from toddlerbot.yaml_input import read_text


class ReferenceRows(NamedTuple):
    """The reference's tables the env indexes by row, float32 (JAX)."""

    motor_targets: jax.Array
    motor_pos: jax.Array
    motor_vel: jax.Array
    torso_pos: jax.Array
    torso_quat: jax.Array
    end_effectors: jax.Array


def orientation_error(quat: jax.Array, ref_quat: jax.Array) -> jax.Array:
    """rad; the angle of the rotation between two orientations (w, x, y, z)."""
    return 2.0 * jnp.arccos(jnp.clip(jnp.abs(jnp.dot(quat, ref_quat)), 0.0, 1.0))


class TrackEnv(RLEnvironment):
    """One robot tracking one motion; vmap it (the training wrappers do) for many."""

    name = TRACK
    runtime_policy = TrackPolicy.name
    config_class = TrackConfig
    reward_terms = TRACK_REWARDS
    recipes = MappingProxyType({"cpu": Recipe(track_config.CPU), "mjx": Recipe(track_config.FULL),
                                "smoke": Recipe(config.SMOKE)})
    step_metrics = ("motor_pos_error", "orientation_error", "end_effector_error")
    """RMS motor angle error (rad), torso orientation error (rad) and mean end-effector distance (m, torso frame)
    against the reference."""
    curves = (("episode_reward", "episode return"), ("episode_length", "episode length (steps)"),
              ("motor_pos_error", "motor angle error, RMS (rad)"),
              ("orientation_error", "torso orientation error (rad)"), ("fall_rate", "episode ends per env step"))

    @classmethod
    def default_config(cls, smoke: bool = False) -> TrackConfig:
        """Without a motion (`rl train --motion` gives it)."""
        return track_config.SMOKE_TRACK if smoke else TrackConfig()

    def __init__(self, cfg: TrackConfig, reference: MotionReference | None = None) -> None:
        """``reference``: the motion's reference on this configuration's training model (default: built now)."""
        use_full_precision()
        cfg = self.resolved_config(cfg)
        if not cfg.motion:
            raise ToddlerbotError(f"the {TRACK} environment needs a motion (rl train --motion NAME_OR_FILE)")
        self.cfg = cfg
        self.description = description = training_description(cfg)
        self.mj_model = model = training_model(description, cfg)
        if reference is None:
            reference = build_reference(load_motion(cfg.motion, description), description, model, cfg.ctrl_dt,
                                        cfg.n_substeps, cfg.hold_s)
        self.reference = reference
        self.addresses = a = Addresses.of(model, description)
        self.physics = self.make_physics(model, a, cfg)
        self._nominal = {name: jnp.asarray(getattr(model, name)) for name in MODEL_FIELDS}
        self.n_motors = description.n_motors
        self.home_motor_pos = jnp.asarray(description.home_motor_pos, dtype=jnp.float32)
        self.actuators = ActuatorArrays(*(jnp.asarray(x, dtype=jnp.float32) for x in description.actuator_arrays()))
        datas = reference.datas(model)
        self._starts = jax.tree.map(jnp.asarray, CPUState.of_batch(datas))
        """Each row's exact state, where an episode may start."""
        self._start_frames = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32),
                                          frames_of(a, datas, np.zeros((len(datas), self.n_motors))))
        f32 = lambda x: jnp.asarray(x, jnp.float32)  # noqa: E731
        self.rows = ReferenceRows(f32(reference.motor_targets), f32(reference.qpos[:, a.motors.qpos]),
                                  f32(reference.qvel[:, a.motors.dof]), f32(reference.qpos[:, 0:3]),
                                  f32(reference.torso_quat), f32(reference.end_effectors))

    # Brax Env interface -------------------------------------------------------------------------------------
    @property
    def observation_size(self) -> dict[str, tuple[int, ...]]:
        obs = jax.eval_shape(self.reset, jax.random.PRNGKey(0)).obs
        return {key: value.shape for key, value in obs.items()}

    @property
    def action_size(self) -> int:
        return self.n_motors

    @property
    def frame_size(self) -> int:
        """Sensed features per history frame (`track_frame`): motor angles, speeds, last action, gyro, gravity."""
        return track_frame_size(self.n_motors)

    def reset(self, rng: jax.Array) -> State:
        cfg = self.cfg
        rng, k_dr, k_row, k_push, k_noise = jax.random.split(rng, 5)
        dr = self.draw_randomization(k_dr)
        row = jax.random.randint(k_row, (), 0, self.reference.n_steps)
        info = {
            "rng": rng, "dr": dr, "row": row, "last_action": jnp.zeros(self.action_size),
            "push_timer": randomization.push_interval(k_push, cfg.randomization), "push": jnp.zeros(2),
            "history": jnp.zeros((cfg.obs.history, self.frame_size)),
        }
        frame = jax.tree.map(lambda x: x[row], self._start_frames)
        obs, info = self._observe(frame, info, k_noise)
        info["history"] = jnp.tile(info["history"][:1], (cfg.obs.history, 1))
        obs["state"] = self._actor_obs(info)
        metrics = {name: jnp.zeros(()) for name in (*self.reward_terms, *self.step_metrics)}
        start = self.physics.state_of(jax.tree.map(lambda x: x[row], self._starts))
        return State(start, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: State, action: jax.Array) -> State:
        cfg, info = self.cfg, dict(state.info)
        dr = info["dr"]
        k_noise, k_push, k_next = jax.random.split(info["rng"], 3)
        action = jnp.clip(action, -1.0, 1.0)  # the policy's Gaussian is unsquashed
        applied = jnp.where(dr.action_delay > 0, info["last_action"], action)
        targets = self.rows.motor_targets[info["row"]] + cfg.obs.action_scale * applied
        actuators = randomization.apply_to_actuators(self.actuators, dr)
        info["push"], info["push_timer"] = randomization.push(k_push, info["push_timer"], cfg.randomization,
                                                              cfg.randomize, cfg.ctrl_dt)
        data = state.pipeline_state
        data = data.replace(qvel=data.qvel.at[0:2].add(info["push"]))
        data, frame = self.physics.step(data, targets, self.model_fields(dr), actuators)
        row = jnp.minimum(info["row"] + 1, self.reference.n_steps)
        done = self.terminated(frame, row)
        q = self.quantities(frame, row, action, info["last_action"], 1.0 - done.astype(jnp.float32))
        reward, terms = self.reward_terms.total(q, cfg.reward, cfg.ctrl_dt)
        reward = jnp.where(jnp.isfinite(reward), reward, 0.0)
        terms["motor_pos_error"] = jnp.sqrt(jnp.mean((q.motor_pos - q.ref_motor_pos) ** 2))
        terms["orientation_error"] = orientation_error(q.torso_quat, q.ref_torso_quat)
        terms["end_effector_error"] = jnp.mean(jnp.linalg.norm(q.end_effectors - q.ref_end_effectors, axis=-1))
        info.update(row=row, last_action=action, rng=k_next)
        obs, info = self._observe(frame, info, k_noise)
        return state.replace(pipeline_state=data, obs=obs, reward=reward, done=done.astype(jnp.float32),
                             metrics={**state.metrics, **terms}, info=info)

    def quantities(self, frame: Frame, row: jax.Array, action: jax.Array, last_action: jax.Array,
                   alive: jax.Array) -> TrackQuantities:
        """What the reward terms read: the robot in ``frame`` beside the reference's ``row``."""
        ref, a = self.rows, self.addresses
        return TrackQuantities(
            motor_pos=frame.qpos[a.motors.qpos], ref_motor_pos=ref.motor_pos[row],
            motor_vel=frame.qvel[a.motors.dof], ref_motor_vel=ref.motor_vel[row],
            torso_quat=frame.qpos[3:7], ref_torso_quat=ref.torso_quat[row],
            torso_height=frame.qpos[2], ref_torso_height=ref.torso_pos[row, 2],
            end_effectors=self.end_effectors(frame), ref_end_effectors=ref.end_effectors[row],
            action=action, last_action=last_action, alive=alive,
        )

    def terminated(self, frame: Frame, row: jax.Array) -> jax.Array:
        """A large deviation from the reference's ``row``: the torso turned more than ``max_orientation_error``,
        its height off by more than ``max_height_error`` or horizontally further than ``max_position_error``; or
        a state that is not finite."""
        cfg, ref = self.cfg, self.rows
        turned = orientation_error(frame.qpos[3:7], ref.torso_quat[row]) > cfg.max_orientation_error
        height = jnp.abs(frame.qpos[2] - ref.torso_pos[row, 2]) > cfg.max_height_error
        drift = jnp.linalg.norm(frame.qpos[0:2] - ref.torso_pos[row, :2]) > cfg.max_position_error
        return turned | height | drift | ~jnp.all(jnp.isfinite(frame.qpos[0:7]))

    def end_effectors(self, frame: Frame) -> jax.Array:
        """(4, 3) feet and hands in the torso frame, m."""
        points = jnp.concatenate([frame.feet_pos, frame.hands_pos])
        return in_torso_frame(frame.qpos[0:3], frame.qpos[3:7], points, xp=jnp)

    @classmethod
    def write_export(cls, out: Path, arrays: dict[str, np.ndarray], cfg: TrackConfig, meta: dict,
                     description: RobotDescription, action_space: dict[str, np.ndarray] | None) -> Path:
        """The motion's motor targets per control step and the look-ahead (`MotionTargets`: the `track` policy plays
        them), the motion file's text in the metadata (``motion_yaml``)."""
        if action_space is None or "motor_targets" not in action_space:
            raise ToddlerbotError(f"{out}: the run holds no record of its motion's reference ({ACTION_SPACE})")
        motion = MotionTargets(str(action_space["motion"]), action_space["motor_targets"],
                               int(action_space["motion_steps"]), tuple(cfg.lookahead))
        text = read_text(motion_path(cfg.motion), "motion file", max_bytes=MAX_MOTION_BYTES)
        meta = {**meta, "motion": cfg.motion, "motion_yaml": text, "hold_s": cfg.hold_s,
                "variant": description.spec.variant}
        return atomic_savez(out, {**arrays, **motion.arrays(), **robot_arrays(description),
                                  "action_motor_index": np.arange(description.n_motors),
                                  "obs_config": np.array(cfg.obs.to_json()), "meta": np.array(json.dumps(meta))})

    @classmethod
    def shipped_export(cls, cfg: TrackConfig) -> Path:
        """``track_<motion>.npz`` beside the shipped walking policies, for a built-in motion on the packaged robot
        (the get-up policy plays the get-up motions' with them, `policies.get_up.shipped_trackers`)."""
        if cfg.motion not in builtin_motions() or cfg.variant is not None:
            raise ToddlerbotError(f"--ship: only trackers of a built-in motion on the packaged robot ship (this run: "
                                  f"motion {cfg.motion!r}, variant {cfg.variant!r})")
        return SHIPPED_WEIGHTS / f"track_{cfg.motion}.npz"

    def record_action_space(self, run_dir: Path) -> None:
        """The motion tracked (`REFERENCE_RECORD`) and its reference's tables (`ACTION_SPACE`)."""
        atomic_write_text(run_dir / REFERENCE_RECORD, f"motion {self.cfg.motion}\n")
        atomic_savez(run_dir / ACTION_SPACE, self.reference.arrays())

    def model_fields(self, dr: randomization.DRParams) -> dict[str, jax.Array]:
        """The env's randomised model parameters (both backends apply them)."""
        return randomization.model_fields(self._nominal, dr, self.addresses.floor_geom, self.addresses.torso_body)

    # observations --------------------------------------------------------------------------------------------
    def _sensed(self, s: Sensors, gravity: jax.Array, last_action: jax.Array) -> jax.Array:
        obs = self.cfg.obs
        return track_frame(s.motor_pos, self.home_motor_pos, s.motor_vel, last_action, s.gyro, gravity,
                           obs.motor_vel_scale, obs.gyro_scale, xp=jnp)

    def _actor_obs(self, info: dict) -> jax.Array:
        """The sensed history, the reference's phase and its motor targets ahead (relative to home)."""
        return track_actor_obs(info["history"], info["row"], self.rows.motor_targets, self.cfg.lookahead,
                               self.home_motor_pos, xp=jnp)

    def _observe(self, frame: Frame, info: dict, key: jax.Array) -> tuple[dict[str, jax.Array], dict]:
        cfg, ref, row = self.cfg, self.rows, info["row"]
        a = self.addresses
        sensors = Sensors(motor_pos=frame.qpos[a.motors.qpos], motor_vel=frame.qvel[a.motors.dof],
                          gyro=frame.gyro, imu_quat=frame.imu_quat)
        # the reset has no earlier reading: there the IMU is fresh
        aged = aged_imu(info.get("sensors", sensors), sensors, info["dr"].imu_age / cfg.ctrl_dt)
        noisy, gravity = add_noise(key, aged, cfg.obs, info["dr"].obs_noise_level)
        info["history"] = push_frame(info["history"], self._sensed(noisy, gravity, info["last_action"]))
        info["sensors"] = sensors
        actor = self._actor_obs(info)
        privileged = {
            "torso_height": frame.qpos[2:3], "torso_quat": frame.qpos[3:7], "ref_torso_quat": ref.torso_quat[row],
            "torso_vel": frame.qvel[0:6], "position_error": frame.qpos[0:3] - ref.torso_pos[row],
            "motor_error": ref.motor_pos[row] - sensors.motor_pos,
            "end_effector_error": self.end_effectors(frame) - ref.end_effectors[row],
            "push": info["push"], "floor_friction": info["dr"].floor_friction[None],
        }
        clean = self._sensed(sensors, -frame.imu_z, info["last_action"])
        return {"state": actor, "privileged_state": critic_obs(actor, clean, privileged)}, info
