"""The actuated plant: MuJoCo physics with the actuator model in the loop, for one robot or a batch of robots.

`step_actuated` is the one physics substep loop with motors: every substep a `MotorDrive` (the actuator model,
`toddlerbot.actuation.model.motor_torque`, plus the firmware's torque enable and torque limit) turns a robot's
motor targets into motor torques and MuJoCo's ``mj_step`` advances it. The loop is compiled with numba where it is
installed (`toddlerbot.sim.native`): the torques are computed in machine code next to the C ``mj_step``, without
the GIL, so callers may step disjoint batches on several threads. Everything that simulates motors in MuJoCo
steps through it: `toddlerbot.sim.mujoco_robot.MuJoCoRobot` (a batch of one), the RL environment's CPU backend
(`toddlerbot.rl.physics`, chunks of its batch on a thread pool), the hardware-in-the-loop plant behind the
Dynamixel emulator (`toddlerbot.hardware.plant.HilPlant`) and the sysID ``robot_joint`` rig.

`step_batch` runs the same loop for many robots in one compiled call and also writes each robot's inputs (model
fields, state) before it and copies its outputs after, by address (`BatchArrays`): the RL CPU backend's per-env
Python, which held the GIL while the other workers wanted it, is then a few numpy calls per chunk.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.actuation.model import friction_excess
from toddlerbot.sim.motor_drive import MotorDrive, drive_torque, parameters_of
from toddlerbot.sim.native import HAVE_NUMBA, address, compile_now, compiled, doubles, ints, mj_step


@dataclass(frozen=True)
class MotorAddresses:
    """Where each motor (motor-id order) lives in a MuJoCo model: its joint's qpos and dof address and its torque
    actuator's index."""

    qpos: np.ndarray
    dof: np.ndarray
    actuator: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, motor_names: Sequence[str]) -> MotorAddresses:
        """Addresses of the named motors (each motor's joint and actuator share its name)."""
        joints = [model.joint(name) for name in motor_names]
        return cls(np.array([j.qposadr[0] for j in joints]), np.array([j.dofadr[0] for j in joints]),
                   np.array([model.actuator(name).id for name in motor_names]))


def step_actuated(models: Sequence[mujoco.MjModel], datas: Sequence[mujoco.MjData], motors: MotorAddresses,
                  targets: np.ndarray, drive: MotorDrive, n_substeps: int,
                  sensors_last_only: bool = False) -> np.ndarray:
    """Advance each robot ``n_substeps`` physics steps holding its motor targets (``targets`` (batch, n_motors),
    rad) with the drive's parameters (shared by the batch or one row per robot). Returns the motor torques of the
    last substep, (batch, n_motors) N*m. A fitted load-dependent friction
    (`toddlerbot.actuation.model.friction_excess`) raises the motor joints' frictionloss every substep and is
    taken off again on return. ``sensors_last_only``: MuJoCo's sensors are evaluated in the last substep only (the
    dynamics do not read them, so the state is the same; this toggles the models' sensor flag, so only for models
    no other thread steps)."""
    if n_substeps < 1:
        raise ValueError(f"n_substeps must be >= 1, got {n_substeps}")
    if HAVE_NUMBA and not _robot.signatures:  # first call in the process: compiled or loaded, a bad cache redone
        compile_substeps(models[0], datas[0], motors, drive)
    targets = np.asarray(targets, dtype=float)
    torques = np.empty(targets.shape)
    for i, (m, d) in enumerate(zip(models, datas, strict=True)):
        torques[i] = _robot(*_robot_arguments(m, d, motors, np.ascontiguousarray(targets[i]), drive, i), n_substeps,
                            sensors_last_only)
    return torques


RETRY_SOLVER_ITERATIONS = 100
"""Newton and line-search iterations of a control step taken again after MuJoCo found it diverging: the spec's few
iterations (4/8) suit walking, and a hard impact of the whole body (a fall) can need many more (docs/simulation.md,
"Falls that diverged")."""
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
DIVERGED_SPEED = 50.0
"""rad/s (or m/s): a joint of the robot faster than this is numerical blow-up (its motors' no-load speeds are under
10 rad/s; a falling torso stays under 5 m/s). At 200 a step that threw the robot off a terrain at 55 m/s (both
soles in 91 height-field contacts, 4 solver iterations) passed as sound; at 50 it is taken again and stands."""
UNSTABLE_SPEED = 200.0
"""rad/s: a joint still faster than this after the step was taken again stops the run (`MuJoCoRobot`); between
`DIVERGED_SPEED` and this a retried step goes on (a hard pinch of the grippers can spin a finger that fast)."""


MAX_POWER_W = 500.0
ENERGY_SLACK_J = 2.0
"""A step whose robot gained more mechanical energy than `MAX_POWER_W` x the step's time plus this (J) was thrown by
the contact solver, not by its motors: their torque-speed envelopes allow 73 W for all 30 at once. A hard landing
that four Newton iterations did not resolve launched a fallen robot 3 m into the air with every joint under
`DIVERGED_SPEED` (121 J in one 20 ms step; docs/simulation.md "Falls that diverged")."""


def mechanical_energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Potential (gravity, springs) plus kinetic energy, J, of everything in the model, from the state's last
    dynamics (the mass matrix of its last substep)."""
    mujoco.mj_energyPos(model, data)
    mujoco.mj_energyVel(model, data)
    return float(data.energy.sum())


def diverged(data: mujoco.MjData) -> bool:
    """MuJoCo reset the state after a bad acceleration, the state is non-finite, or a velocity is beyond
    `DIVERGED_SPEED`."""
    if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
        return True
    speed = np.abs(data.qvel)
    return not (np.all(np.isfinite(speed)) and np.all(np.isfinite(data.qpos))) or bool(speed.max(initial=0.0) >
                                                                                  DIVERGED_SPEED)


def step_one_robot(model: mujoco.MjModel, data: mujoco.MjData, motors: MotorAddresses, targets: np.ndarray,
                   drive: MotorDrive, n_substeps: int, sensors_last_only: bool = False) -> tuple[np.ndarray, bool]:
    """`step_actuated` for one robot, taken again from its start with `RETRY_SOLVER_ITERATIONS` when it diverged:
    MuJoCo found a huge or non-finite acceleration (and reset the state), a joint ends faster than
    `DIVERGED_SPEED`, or the robot gained more energy than its motors can give (`MAX_POWER_W`). A step that diverges
    even then is left so, for the caller to report. Returns the motor torques (n_motors,) and whether the step was
    taken again. A step that does not diverge is exactly `step_actuated`'s."""
    start = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, start, _STATE)
    energy = mechanical_energy(model, data)
    torque = step_actuated([model], [data], motors, targets[None], drive, n_substeps, sensors_last_only)[0]
    gained = mechanical_energy(model, data) - energy
    if not diverged(data) and gained <= MAX_POWER_W * n_substeps * model.opt.timestep + ENERGY_SLACK_J:
        return torque, False
    mujoco.mj_setState(model, data, start, _STATE)
    data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 0
    iterations = model.opt.iterations, model.opt.ls_iterations
    model.opt.iterations = model.opt.ls_iterations = RETRY_SOLVER_ITERATIONS
    try:
        return step_actuated([model], [data], motors, targets[None], drive, n_substeps, sensors_last_only)[0], True
    finally:
        model.opt.iterations, model.opt.ls_iterations = iterations


def compile_substeps(model: mujoco.MjModel, data: mujoco.MjData, motors: MotorAddresses, drive: MotorDrive) -> None:
    """Compile the substep loop for this robot, or load it from numba's disk cache, without stepping
    (`toddlerbot.sim.native.compile_now`): otherwise the first `step_actuated` does it (seconds the first time),
    which a wall-clock run must not spend mid-run."""
    compile_now(_robot, *_robot_arguments(model, data, motors, np.zeros(len(motors.qpos)), drive, 0), 0, False)


def _robot_arguments(m: mujoco.MjModel, d: mujoco.MjData, motors: MotorAddresses, targets: np.ndarray,
                     drive: MotorDrive, i: int) -> tuple:
    """`_robot`'s arguments for robot ``i`` of a batch, less the substep count and the sensors' setting."""
    return (m._address, d._address, d.qpos, d.qvel, d.ctrl, m.dof_frictionloss, _flags_address(m), motors.qpos,
            motors.dof, motors.actuator, targets, drive.table(i), drive.torque_on, drive.limit,
            drive.has_friction_excess)


@compiled
def _robot(model_address: int, data_address: int, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray,
           frictionloss: np.ndarray, flags_address: int, qadr: np.ndarray, dofs: np.ndarray, actuators: np.ndarray,
           targets: np.ndarray, table: np.ndarray, torque_on: np.ndarray, limit: np.ndarray, budget: bool,
           n_substeps: int, sensors_last_only: bool) -> np.ndarray:
    """One robot's control step: `_substeps` with the model's own frictionloss kept and restored, and with
    ``sensors_last_only`` MuJoCo's sensors switched off but in the last substep (through the model's flags at
    ``flags_address``; 0: unknown, left on). Returns the last substep's torques."""
    own = frictionloss[dofs].copy()
    if sensors_last_only and n_substeps > 1 and flags_address != 0:
        flags = ints(flags_address, 1)
        flags[0] |= _NO_SENSOR
        _substeps(model_address, data_address, qpos, qvel, ctrl, frictionloss, own, qadr, dofs, actuators, targets,
                  table, torque_on, limit, budget, n_substeps - 1)
        flags[0] &= ~_NO_SENSOR
        tau = _substeps(model_address, data_address, qpos, qvel, ctrl, frictionloss, own, qadr, dofs, actuators,
                        targets, table, torque_on, limit, budget, 1)
    else:
        tau = _substeps(model_address, data_address, qpos, qvel, ctrl, frictionloss, own, qadr, dofs, actuators,
                        targets, table, torque_on, limit, budget, n_substeps)
    if budget:
        frictionloss[dofs] = own
    return tau


@compiled
def _substeps(model_address: int, data_address: int, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray,
              frictionloss: np.ndarray, own_frictionloss: np.ndarray, qadr: np.ndarray, dofs: np.ndarray,
              actuators: np.ndarray, targets: np.ndarray, table: np.ndarray, torque_on: np.ndarray,
              limit: np.ndarray, budget: bool, n_substeps: int) -> np.ndarray:
    """One robot's ``n_substeps`` physics steps with the drive's torque (and friction budget) before each;
    returns the last substep's torques. Compiled, this runs in machine code with MuJoCo's C ``mj_step``."""
    tau = np.zeros(len(qadr))
    for _ in range(n_substeps):
        q, q_dot = qpos[qadr], qvel[dofs]
        tau = drive_torque(targets, q, q_dot, table, torque_on, limit)
        ctrl[actuators] = tau
        if budget:
            frictionloss[dofs] = own_frictionloss + friction_excess(q_dot, tau, parameters_of(table))
        mj_step(model_address, data_address)
    return tau


_NO_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)


def _disableflags_offset() -> int | None:
    """Byte offset of ``opt.disableflags`` in MuJoCo's ``mjModel`` struct, found by setting it to two patterns and
    finding the one int of the struct's start that follows both (the bindings give no address for it); None if
    that is not one place (then `step_batch` leaves the sensors on in every substep: the same state, 3 % slower)."""
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    seen = []
    for pattern in (0x2AAA, 0x1555):
        model.opt.disableflags = pattern
        seen.append(np.frombuffer(ctypes.string_at(model._address, 2048), dtype=np.int32) == pattern)
    found = np.flatnonzero(seen[0] & seen[1])
    return int(found[0]) * 4 if len(found) == 1 else None


_FLAGS_OFFSET = _disableflags_offset()


def _flags_address(model: mujoco.MjModel) -> int:
    """Where the model's ``opt.disableflags`` lives (0: unknown)."""
    return 0 if _FLAGS_OFFSET is None else model._address + _FLAGS_OFFSET


@dataclass(frozen=True)
class BatchArrays:
    """Each robot's MuJoCo arrays that `step_batch` writes before stepping and reads after, by address (a model's
    or data's arrays stay where they are for its lifetime), so that one compiled call steps a whole batch without
    touching Python per robot. Named ``model.FIELD`` or ``data.FIELD``; every robot shares the model's sizes."""

    writes: tuple[str, ...]
    reads: tuple[str, ...]
    sizes: np.ndarray
    """Length of each written, then each read array (float64 values)."""
    addresses: np.ndarray
    """(robots, writes + reads) int64."""
    robots: np.ndarray
    """(robots, 6) int64: the model, the data, qpos, qvel, ctrl, the model's dof_frictionloss."""
    flags: np.ndarray
    """(robots,) int64: each model's ``opt.disableflags`` (0: unknown, sensors stay on)."""
    warnings: np.ndarray
    """(robots,) int64: each data's count of bad-acceleration warnings (`mjWARN_BADQACC`)."""
    state_sizes: np.ndarray
    """nq, nv, nu of the model."""

    @classmethod
    def of(cls, models: Sequence[mujoco.MjModel], datas: Sequence[mujoco.MjData], writes: Sequence[str],
           reads: Sequence[str]) -> BatchArrays:
        def array(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
            owner, field = name.split(".")
            values = getattr(model if owner == "model" else data, field)
            if values.dtype != np.float64:
                raise ValueError(f"{name} is {values.dtype}, not float64")
            return values

        names = (*writes, *reads)
        bad = np.int64(mujoco.mjtWarning.mjWARN_BADQACC)
        return cls(tuple(writes), tuple(reads),
                   np.array([array(models[0], datas[0], name).size for name in names], dtype=np.int64),
                   np.array([[address(array(m, d, name)) for name in names] for m, d in zip(models, datas,
                                                                                              strict=True)],
                            dtype=np.int64).reshape(len(models), len(names)),
                   np.array([[m._address, d._address, address(d.qpos), address(d.qvel), address(d.ctrl),
                              address(m.dof_frictionloss)] for m, d in zip(models, datas, strict=True)],
                            dtype=np.int64).reshape(len(models), 6),
                   np.array([_flags_address(m) for m in models], dtype=np.int64),
                   np.array([address(d.warning.number[bad:bad + 1]) for d in datas], dtype=np.int64),
                   np.array([models[0].nq, models[0].nv, models[0].nu], dtype=np.int64))

    @property
    def write_size(self) -> int:
        return int(self.sizes[:len(self.writes)].sum())

    @property
    def read_size(self) -> int:
        return int(self.sizes[len(self.writes):].sum())


def step_batch(arrays: BatchArrays, robots: np.ndarray, motors: MotorAddresses, targets: np.ndarray,
               drive: MotorDrive, n_substeps: int, written: np.ndarray, sensors_last_only: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`step_actuated` for robots ``robots`` (indices into ``arrays``) in one compiled call: first each robot's
    ``arrays.writes`` are set from its row of ``written`` (robots, write_size) and its bad-acceleration warning
    count cleared, then its substeps run (the drive's parameter row per robot, or one shared), then its
    ``arrays.reads`` are copied out. Returns the last substep's motor torques (robots, n_motors), the reads
    (robots, read_size) and whether MuJoCo warned of a bad acceleration (it then reset that robot's state)."""
    if n_substeps < 1:
        raise ValueError(f"n_substeps must be >= 1, got {n_substeps}")
    if written.shape != (len(robots), arrays.write_size):
        raise ValueError(f"written has shape {written.shape}, expected {(len(robots), arrays.write_size)}")
    shared = (arrays.sizes, len(arrays.writes), arrays.state_sizes, motors.qpos, motors.dof, motors.actuator,
              drive.tables, drive.per_robot, drive.torque_on, drive.limit, drive.has_friction_excess, n_substeps,
              sensors_last_only)
    if HAVE_NUMBA and not _batch.signatures:  # compiled (or loaded) on no robot first, as `compile_substeps` does
        none = np.zeros(0, dtype=np.int64)
        compile_now(_batch, arrays.robots[none], arrays.addresses[none], arrays.flags[none], arrays.warnings[none],
                    np.zeros((0, arrays.write_size)), np.zeros((0, len(motors.qpos))),
                    np.zeros((0, arrays.read_size)), *shared)
    reads = np.empty((len(robots), arrays.read_size))
    torques, warned = _batch(arrays.robots[robots], arrays.addresses[robots], arrays.flags[robots],
                             arrays.warnings[robots], np.ascontiguousarray(written, dtype=float),
                             np.ascontiguousarray(targets, dtype=float), reads, *shared)
    return torques, reads, warned


@compiled
def _batch(robots: np.ndarray, addresses: np.ndarray, flags: np.ndarray, warnings: np.ndarray, written: np.ndarray,
           targets: np.ndarray, reads: np.ndarray, sizes: np.ndarray, n_writes: int, state_sizes: np.ndarray,
           qadr: np.ndarray, dofs: np.ndarray, actuators: np.ndarray, tables: np.ndarray, per_robot: bool,
           torque_on: np.ndarray, limit: np.ndarray, budget: bool, n_substeps: int, sensors_last_only: bool
           ) -> tuple[np.ndarray, np.ndarray]:
    """`step_batch`'s loop over robots: writes, `_robot`, reads, all in machine code without the GIL."""
    n = len(robots)
    torques = np.zeros((n, len(qadr)))
    warned = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        at = 0
        for k in range(n_writes):
            doubles(addresses[i, k], sizes[k])[:] = written[i, at:at + sizes[k]]
            at += sizes[k]
        warning = ints(warnings[i], 1)
        warning[0] = 0
        qpos, qvel = doubles(robots[i, 2], state_sizes[0]), doubles(robots[i, 3], state_sizes[1])
        ctrl, frictionloss = doubles(robots[i, 4], state_sizes[2]), doubles(robots[i, 5], state_sizes[1])
        torques[i] = _robot(robots[i, 0], robots[i, 1], qpos, qvel, ctrl, frictionloss, flags[i], qadr, dofs,
                            actuators, targets[i], tables[i if per_robot else 0], torque_on, limit, budget,
                            n_substeps, sensors_last_only)
        warned[i] = warning[0] != 0
        at = 0
        for k in range(n_writes, len(sizes)):
            reads[i, at:at + sizes[k]] = doubles(addresses[i, k], sizes[k])
            at += sizes[k]
    return torques, warned
