"""Physics backends of the walking environment: MJX (JAX: CPU or GPU) and classic MuJoCo on CPU threads.

Both step the training model (`toddlerbot.rl.model.training_model`) one control period at a time, applying the
actuator model every physics substep, with the env's own domain-randomised model fields and actuator arrays, and
return the same `Frame`: the few physics quantities `toddlerbot.rl.walk_env.WalkEnv` reads. Everything above the
physics (observations, rewards, commands, randomisation draws, pushes, termination) is the environment's one JAX
definition, whatever the backend.

* `MJXPhysics`: ``mjx.step`` in a ``lax.scan``; the state is ``mjx.Data``.
* `CPUPhysics`: the simulator's substep loop over per-env ``MjModel`` / ``MjData`` pairs, the batch split into
  chunks stepped on a thread pool, entered from jitted code through ``jax.pure_callback`` (batched: one call for
  the whole batch). Each chunk is one call of `toddlerbot.sim.actuated.step_batch`, which writes every env's
  randomised fields and state, steps it and copies its results out in compiled code without the GIL; what stays in
  Python per chunk is a few numpy calls and each env's contact list. The state is a small
  pytree of arrays (`CPUState`) that the host writes into scratch ``MjData`` before stepping, so the callback is a
  pure function of its inputs. Positions and velocities are carried as float32 pairs (hi + lo, about 48 bits) so
  that the float64 simulation continues where it stopped instead of being rounded to float32 every 20 ms.
"""

from __future__ import annotations

import copy
import functools
import operator
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import NamedTuple

import flax
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from toddlerbot.actuation.model import ActuatorArrays, friction_excess, motor_torque
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.actuated import BatchArrays, MotorAddresses, step_batch
from toddlerbot.sim.motor_drive import MotorDrive
from toddlerbot.sim.terrain import ground_geoms

MODEL_FIELDS = ("geom_friction", "dof_damping", "dof_armature", "dof_frictionloss", "body_mass", "body_inertia")
"""Model parameters domain randomisation changes per env (`toddlerbot.rl.randomization.model_fields`)."""


class Frame(NamedTuple):
    """What the environment reads from the physics after a control step (one env; batched under vmap). Site and
    body quantities are MuJoCo's of the last substep (computed before its integration, as ``mj_step`` leaves
    them)."""

    qpos: jax.Array
    qvel: jax.Array
    torso_z: jax.Array
    """(3,) the world z axis in the torso frame."""
    imu_z: jax.Array
    """(3,) the world z axis in the IMU frame."""
    feet_pos: jax.Array
    """(2, 3) left/right foot-centre sites, world frame, m."""
    feet_up_z: jax.Array
    """(2,) world-z component of each foot's up axis (1 = flat)."""
    hands_pos: jax.Array
    """(2, 3) left/right hand sites, world frame, m."""
    gyro: jax.Array
    """(3,) IMU angular velocity, rad/s."""
    imu_quat: jax.Array
    """(4,) IMU orientation, w x y z."""
    contact: jax.Array
    """(2,) left/right foot sole touching the ground (the floor or a terrain; penetrating contact), 0/1."""
    self_collision: jax.Array
    """Number of penetrating robot-robot contacts (neither geom is the ground)."""
    torque: jax.Array
    """(n_motors,) motor torques of the last substep, N*m."""


@dataclass(frozen=True)
class Addresses:
    """Indices into the training model's arrays that `read_frame` needs."""

    motors: MotorAddresses
    torso_body: int
    imu_site: int
    foot_sites: np.ndarray
    foot_geoms: np.ndarray
    floor_geom: int
    ground_geoms: tuple[int, ...]
    """The floor and, on a terrain, its height field (`toddlerbot.sim.terrain.ground_geoms`)."""
    foot_up_axis: int
    """Which axis of a foot site points up at home, and its sign."""
    foot_up_sign: float
    hand_sites: np.ndarray
    hand_bodies: np.ndarray
    """The bodies holding the hand sites, which the env's pull on the hands acts on."""
    gyro: slice
    quat: slice

    @classmethod
    def of(cls, model: mujoco.MjModel, description: RobotDescription) -> Addresses:
        handles = description.handles
        home = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, home, model.key("home").id)
        mujoco.mj_forward(model, home)
        foot_sites = np.array([model.site(name).id for name in handles.feet_sites])
        hand_sites = np.array([model.site(name).id for name in handles.hand_sites])
        up = home.site_xmat[foot_sites[0]].reshape(3, 3)[2]  # world-z components of the site's axes
        axis = int(np.argmax(np.abs(up)))

        def sensor(name: str) -> slice:
            s = model.sensor(name)
            return slice(int(s.adr[0]), int(s.adr[0] + s.dim[0]))

        return cls(MotorAddresses.of(model, description.motor_names), model.body(handles.torso).id,
                   model.site(handles.imu_site).id, foot_sites,
                   np.array([model.geom(name).id for name in handles.feet_geoms]), model.geom("floor").id,
                   tuple(sorted(ground_geoms(model))), axis,
                   float(np.sign(up[axis])), hand_sites, model.site_bodyid[hand_sites],
                   sensor("imu_gyro"), sensor("imu_quat"))


def contact_state(a: Addresses, contact_geom, contact_dist, xp=jnp, env=None, n_envs: int = 1):
    """(left/right foot sole touching the ground as 0/1, number of penetrating robot-robot contacts) from contacts
    as (ncon, 2) geom pairs and (ncon,) distances, for one env, or with ``env`` (ncon,) naming each contact's env,
    for ``n_envs`` envs at once (numpy: classic MuJoCo's contacts of a batch, concatenated). The ground is the floor
    and a terrain's height field alike."""
    g1, g2 = contact_geom[:, 0], contact_geom[:, 1]
    touching = contact_dist < 0.0
    ground1, ground2 = (functools.reduce(operator.or_, [g == k for k in a.ground_geoms]) for g in (g1, g2))
    feet = [touching & ((ground1 & (g2 == f)) | (ground2 & (g1 == f))) for f in a.foot_geoms.tolist()]
    robot = touching & ~ground1 & ~ground2
    if env is None:
        return xp.stack([xp.any(f) for f in feet]).astype(xp.float32), xp.sum(robot).astype(xp.float32)
    count = lambda mask: np.bincount(env[mask], minlength=n_envs)  # noqa: E731
    return np.stack([count(f) > 0 for f in feet], axis=-1).astype(np.float32), count(robot).astype(np.float32)


def read_frame(a: Addresses, qpos, qvel, xmat, site_xpos, site_xmat, sensordata, contact, self_collision,
               torque) -> Frame:
    """The `Frame` of MuJoCo data arrays with any leading batch shape (``xmat`` (..., nbody, 3, 3), ``site_xmat``
    (..., nsite, 3, 3)), numpy or JAX."""
    return Frame(
        qpos=qpos, qvel=qvel, torso_z=xmat[..., a.torso_body, 2, :], imu_z=site_xmat[..., a.imu_site, 2, :],
        feet_pos=site_xpos[..., a.foot_sites, :],
        feet_up_z=a.foot_up_sign * site_xmat[..., a.foot_sites, 2, a.foot_up_axis],
        hands_pos=site_xpos[..., a.hand_sites, :],
        gyro=sensordata[..., a.gyro], imu_quat=sensordata[..., a.quat], contact=contact,
        self_collision=self_collision, torque=torque,
    )


def _home(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    return data


def contacts_of(a: Addresses, datas: list[mujoco.MjData]) -> tuple[np.ndarray, np.ndarray]:
    """`contact_state` of each classic MuJoCo data (batch first)."""
    n = len(datas)
    ncon = [d.ncon for d in datas]
    return contact_state(a, np.concatenate([d.contact.geom[:k] for d, k in zip(datas, ncon, strict=True)]),
                         np.concatenate([d.contact.dist[:k] for d, k in zip(datas, ncon, strict=True)]), xp=np,
                         env=np.repeat(np.arange(n), ncon), n_envs=n)


def frames_of(a: Addresses, datas: list[mujoco.MjData], torque: np.ndarray) -> Frame:
    """The frames of classic MuJoCo data, stacked (batch first; ``torque`` (batch, n_motors))."""
    stack = lambda name: np.stack([getattr(d, name) for d in datas])  # noqa: E731
    n = len(datas)
    contact, self_collision = contacts_of(a, datas)
    return read_frame(a, stack("qpos"), stack("qvel"), stack("xmat").reshape(n, -1, 3, 3), stack("site_xpos"),
                      stack("site_xmat").reshape(n, -1, 3, 3), stack("sensordata"), contact, self_collision, torque)


class MJXPhysics:
    """MJX (JAX implementation) stepping, on whatever device JAX uses."""

    name = "mjx"

    def __init__(self, model: mujoco.MjModel, addresses: Addresses, n_substeps: int) -> None:
        self.model, self.addresses, self.n_substeps = model, addresses, n_substeps
        self.sys = mjx.put_model(model)
        home = _home(model)
        self.home_state = mjx.put_data(model, home)
        """The start state of every episode (computed once with classic MuJoCo: reset compiles no physics)."""
        self.home_frame = jax.tree.map(lambda x: jnp.asarray(x[0], jnp.float32),
                                       frames_of(addresses, [home], np.zeros((1, model.nu))))

    def state_of(self, start: CPUState) -> mjx.Data:
        """The state of an episode started from a classic MuJoCo state (`CPUState`, one env; e.g. a motion
        reference's row): the home state with its positions, velocities and solver warm start rounded to float32
        (a step computes everything else from these)."""
        return self.home_state.replace(qpos=start.qpos, qvel=start.qvel, qacc_warmstart=start.qacc_warmstart)

    def step(self, state: mjx.Data, targets: jax.Array, fields: dict[str, jax.Array] | None,
             actuators: ActuatorArrays, hand_force: jax.Array | None = None) -> tuple[mjx.Data, Frame]:
        """One control period holding motor targets (rad, motor-id order) with the env's model ``fields`` (None:
        the nominal model) and actuator arrays, ``hand_force`` (3,) N (world frame) pulling each hand."""
        model = self.sys if fields is None else self.sys.tree_replace(fields)
        m = self.addresses.motors
        force = jnp.zeros(3) if hand_force is None else hand_force
        state = state.replace(xfrc_applied=jnp.zeros_like(state.xfrc_applied)
                              .at[self.addresses.hand_bodies, :3].set(force))

        def substep(d: mjx.Data, _: None) -> tuple[mjx.Data, jax.Array]:
            tau = motor_torque(targets, d.qpos[m.qpos], d.qvel[m.dof], actuators, xp=jnp)
            # a fitted load-dependent friction budget raises the motors' frictionloss (adds exact zeros otherwise)
            excess = friction_excess(d.qvel[m.dof], tau, actuators, xp=jnp)
            stepped = model.tree_replace({"dof_frictionloss": model.dof_frictionloss.at[m.dof].add(excess)})
            return mjx.step(stepped, d.replace(ctrl=tau)), tau

        data, taus = jax.lax.scan(substep, state, None, length=self.n_substeps)
        c = data._impl.contact
        contact, self_collision = contact_state(self.addresses, c.geom, c.dist, xp=jnp)
        return data, read_frame(self.addresses, data.qpos, data.qvel, data.xmat, data.site_xpos, data.site_xmat,
                                data.sensordata, contact, self_collision, taus[-1])


@flax.struct.dataclass
class CPUState:
    """The float64 simulation state of one env, carried exactly in float32 arrays: qpos = ``qpos`` +
    ``qpos_lo[0]`` + ``qpos_lo[1]`` (likewise qvel and the constraint solver's warm start). The env reads and
    pushes ``qpos`` / ``qvel``."""

    qpos: jax.Array
    qpos_lo: jax.Array
    qvel: jax.Array
    qvel_lo: jax.Array
    qacc_warmstart: jax.Array
    qacc_warmstart_lo: jax.Array

    @classmethod
    def of_batch(cls, datas: list[mujoco.MjData]) -> CPUState:
        """The states of classic MuJoCo data, stacked (batch first)."""
        parts = [_split(np.stack([getattr(d, name) for d in datas])) for name in ("qpos", "qvel", "qacc_warmstart")]
        return cls(*(x for part in parts for x in part))

    def float64(self, i) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(qpos, qvel, qacc_warmstart) of env(s) ``i`` (an index or an index array) of a host-side (numpy) batch."""
        return (_join(self.qpos[i], self.qpos_lo[i]), _join(self.qvel[i], self.qvel_lo[i]),
                _join(self.qacc_warmstart[i], self.qacc_warmstart_lo[i]))


def _split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float64 (..., n) -> float32 (..., n) and (..., 2, n) parts whose float64 sum is x (24 + 24 + 24 bits hold
    the 53 of a double)."""
    hi = x.astype(np.float32)
    rest = x - hi
    mid = rest.astype(np.float32)
    return hi, np.stack([mid, (rest - mid).astype(np.float32)], axis=-2)


def _join(hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    return hi.astype(np.float64) + lo[..., 0, :].astype(np.float64) + lo[..., 1, :].astype(np.float64)


class CPUPhysics:
    """Classic MuJoCo (float64) on a thread pool, entered from JAX through ``jax.pure_callback``."""

    name = "cpu"

    def __init__(self, model: mujoco.MjModel, addresses: Addresses, n_substeps: int, threads: int = 0) -> None:
        self.model, self.addresses, self.n_substeps = model, addresses, n_substeps
        self.threads = threads or os.cpu_count() or 1
        self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="mujoco") if self.threads > 1 else None
        self._models: list[mujoco.MjModel] = []
        self._datas: list[mujoco.MjData] = []
        self._arrays: BatchArrays | None = None
        """Where `step_batch` writes and reads each scratch pair's arrays (`WRITTEN`, `READ`)."""
        home = _home(model)
        self.home_state = jax.tree.map(lambda x: jnp.asarray(x[0]), CPUState.of_batch([home]))
        self.home_frame = jax.tree.map(lambda x: jnp.asarray(x[0], jnp.float32),
                                       frames_of(addresses, [home], np.zeros((1, model.nu))))
        self._nominal = {name: np.array(getattr(model, name)) for name in MODEL_FIELDS}

    def state_of(self, start: CPUState) -> CPUState:
        """As `MJXPhysics.state_of`: here the classic MuJoCo state itself, float64 exactly."""
        return start

    def step(self, state: CPUState, targets: jax.Array, fields: dict[str, jax.Array] | None,
             actuators: ActuatorArrays, hand_force: jax.Array | None = None) -> tuple[CPUState, Frame]:
        """As `MJXPhysics.step` (any leading batch shape; under ``vmap`` the whole batch is one host call).
        ``fields`` None keeps the nominal model's float64 values."""
        fields = {} if fields is None else {k: jnp.asarray(v, jnp.float32) for k, v in fields.items()}
        hand_force = jnp.zeros((*jnp.shape(targets)[:-1], 3), jnp.float32) if hand_force is None \
            else jnp.asarray(hand_force, jnp.float32)
        out = (jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), self.home_state),
               jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, jnp.float32), self.home_frame))
        return jax.pure_callback(self._host_step, out, state, targets, fields, actuators, hand_force,
                                 vmap_method="broadcast_all")

    # host side ---------------------------------------------------------------------------------------------------
    def _host_step(self, state: CPUState, targets: np.ndarray, fields: dict, actuators: ActuatorArrays,
                   hand_force: np.ndarray):
        lead = np.shape(targets)[:-1]
        n = int(np.prod(lead))
        flat = lambda x: np.reshape(np.asarray(x), (n, *np.shape(x)[len(lead):]))  # noqa: E731
        state = jax.tree.map(flat, state)
        targets = flat(targets).astype(np.float64)
        fields = {k: flat(v).astype(np.float64) for k, v in fields.items()}
        actuators = ActuatorArrays(*(flat(x).astype(np.float64) for x in actuators))
        hand_force = flat(hand_force).astype(np.float64)
        self._ensure(n)
        chunks = np.array_split(np.arange(n), min(self.threads, n))
        run = lambda idx: self._step_chunk(idx, state, targets, fields, actuators, hand_force)  # noqa: E731
        results = list(self._pool.map(run, chunks)) if self._pool is not None and len(chunks) > 1 else \
            [run(idx) for idx in chunks]
        join = lambda *xs: np.reshape(np.concatenate(xs), (*lead, *np.shape(xs[0])[1:]))  # noqa: E731
        return (jax.tree.map(join, *(r[0] for r in results)),
                jax.tree.map(lambda *xs: join(*xs).astype(np.float32), *(r[1] for r in results)))

    def _ensure(self, n: int) -> None:
        if len(self._datas) >= n:
            return
        while len(self._datas) < n:  # one scratch model/data pair per env, reused by every call
            self._models.append(copy.copy(self.model))
            self._datas.append(mujoco.MjData(self.model))
        self._arrays = BatchArrays.of(self._models, self._datas, WRITTEN, READ)

    def _step_chunk(self, idx: np.ndarray, state: CPUState, targets: np.ndarray, fields: dict,
                    actuators: ActuatorArrays, hand_force: np.ndarray) -> tuple[CPUState, Frame]:
        n = len(idx)
        qpos, qvel, warmstart = state.float64(idx)  # the whole chunk at once: numpy calls cost per call
        pull = np.zeros((n, self.model.nbody, 6))
        pull[:, self.addresses.hand_bodies, :3] = hand_force[idx][:, None, :]
        nominal = {name: np.broadcast_to(x, (n, *x.shape)) for name, x in self._nominal.items()}
        model_rows = [(fields[name][idx] if fields else nominal[name]).reshape(n, -1) for name in MODEL_FIELDS]
        written = np.concatenate([*model_rows, qpos, qvel, warmstart, pull.reshape(n, -1)], axis=1)
        torque, reads, warned = step_batch(self._arrays, idx, self.addresses.motors, targets[idx],
                                           MotorDrive(ActuatorArrays(*(x[idx] for x in actuators))),
                                           self.n_substeps, written, sensors_last_only=True)
        read = dict(zip(READ, np.split(reads, np.cumsum(self._arrays.sizes[len(WRITTEN):])[:-1], axis=1),
                        strict=True))
        read["data.qpos"][warned] = np.nan  # MuJoCo reset the diverged data: end it
        contact, self_collision = contacts_of(self.addresses, [self._datas[i] for i in idx])
        frame = read_frame(self.addresses, read["data.qpos"], read["data.qvel"], read["data.xmat"].reshape(n, -1, 3, 3),
                           read["data.site_xpos"].reshape(n, -1, 3), read["data.site_xmat"].reshape(n, -1, 3, 3),
                           read["data.sensordata"], contact, self_collision, torque)
        parts = [_split(read[f"data.{name}"]) for name in ("qpos", "qvel", "qacc_warmstart")]
        return CPUState(*(x for part in parts for x in part)), frame


WRITTEN = (*(f"model.{name}" for name in MODEL_FIELDS), "data.qpos", "data.qvel", "data.qacc_warmstart",
           "data.xfrc_applied")
"""What the CPU backend writes into each env's scratch model and data before a control step."""
READ = ("data.qpos", "data.qvel", "data.qacc_warmstart", "data.xmat", "data.site_xpos", "data.site_xmat",
        "data.sensordata")
"""What it reads back after (with the contacts, read by `contacts_of`)."""


BACKENDS = {"mjx": MJXPhysics, "cpu": CPUPhysics}
