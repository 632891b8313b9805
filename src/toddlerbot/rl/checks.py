"""Physics checks of the MJX training environment against what the CPU simulator does (JAX; used by the
tests and by ``benchmarks/bench_rl.py``).

* `stand`: zero actions (leg targets = home) in a batch of environments; torso heights over time.
* `replay_motor_targets`: the nominal robot of the env's physics backend driven by a motor-target sequence (an
  open-loop motion), to compare with `toddlerbot.sim.mujoco_robot.MuJoCoRobot` driven by the same sequence.
* `stand_cpu`: the same training model stepped by CPU MuJoCo in float64 (cheap; separates solver settings that
  cannot work from float32 effects).
* `equality_residual`: how far the transmission constraints (joint couplings, linkage welds) are violated.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from toddlerbot.rl.walk_env import WalkEnv
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.actuated import MotorAddresses, step_actuated
from toddlerbot.sim.motor_drive import MotorDrive


@dataclass(frozen=True)
class StandResult:
    torso_height: np.ndarray
    """(control steps, envs) torso origin height, m."""
    qpos: np.ndarray
    """(samples, envs, nq) states every ``sample_every`` control steps, for constraint residuals."""
    fallen: np.ndarray
    """(envs,) True where the env's fall test fired at any step."""
    compile_s: float
    run_s: float
    """Wall time of the compiled rollout (``torso_height.size`` env steps)."""


def stand(env: WalkEnv, n_envs: int, seconds: float, seed: int = 0, sample_every: int = 25) -> StandResult:
    """Step ``n_envs`` environments with zero actions for ``seconds`` (jit-compiled as one scan)."""
    steps = round(seconds / env.cfg.ctrl_dt)
    reset, step = jax.vmap(env.reset), jax.vmap(env.step)
    zeros = jnp.zeros((n_envs, env.action_size))

    @jax.jit
    def run(key):
        def body(state, _):
            state = step(state, zeros)
            return state, (state.pipeline_state.qpos, state.done)

        _, (qpos, done) = jax.lax.scan(body, reset(jax.random.split(key, n_envs)), None, length=steps)
        return qpos, done

    key = jax.random.PRNGKey(seed)
    t0 = time.perf_counter()
    compiled = run.lower(key).compile()
    t1 = time.perf_counter()
    qpos, done = jax.device_get(compiled(key))
    t2 = time.perf_counter()
    return StandResult(np.asarray(qpos[:, :, 2]), np.asarray(qpos[sample_every - 1::sample_every]),
                       np.asarray(done).any(axis=0), t1 - t0, t2 - t1)


def replay_motor_targets(env: WalkEnv, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drive the env's nominal robot from the home state with (control steps, n_motors) motor targets, rad, one
    row per control period. Returns the torso height (steps,) m and the motor angles (steps, n_motors) rad
    after each period."""

    physics = env.physics

    @jax.jit
    def run(targets):
        def body(state, target):
            state, frame = physics.step(state, target, None, env.actuators)
            return state, (frame.qpos[2], frame.qpos[env.motor_qadr])

        return jax.lax.scan(body, physics.home_state, targets)[1]

    height, motor_pos = jax.device_get(run(jnp.asarray(targets, dtype=jnp.float32)))
    return np.asarray(height), np.asarray(motor_pos)


def stand_cpu(model: mujoco.MjModel, description: RobotDescription, seconds: float,
              sample_every: int = 25) -> tuple[float | None, np.ndarray, np.ndarray]:
    """The training model stepped with CPU MuJoCo (float64) holding the home pose with the actuator model.
    Returns (time of divergence in s or None, torso heights per physics step (m), sampled qpos)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    motors = MotorAddresses.of(model, description.motor_names)
    home, drive = np.asarray(description.home_motor_pos)[None], MotorDrive(description.actuator_arrays())
    heights, samples = [], []
    for k in range(round(seconds / model.opt.timestep)):
        step_actuated([model], [data], motors, home, drive, 1)
        if not np.all(np.isfinite(data.qpos)) or data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            return k * model.opt.timestep, np.array(heights), np.array(samples)
        heights.append(data.qpos[2])
        if k % sample_every == sample_every - 1:
            samples.append(data.qpos.copy())
    return None, np.array(heights), np.array(samples)


def equality_residual(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[float, str]:
    """Largest violation of the model's equality constraints (joint couplings in rad, weld anchors in m, weld
    orientations in rad) over states ``qpos`` (..., nq), evaluated with CPU MuJoCo, and the constraint's name."""
    data = mujoco.MjData(model)
    worst, name = 0.0, ""
    for q in np.reshape(qpos, (-1, model.nq)):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        n = data.nefc
        rows = np.flatnonzero(data.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        if rows.size:
            k = rows[np.argmax(np.abs(data.efc_pos[rows]))]
            if abs(data.efc_pos[k]) > worst:
                worst, name = float(abs(data.efc_pos[k])), model.eq(int(data.efc_id[k])).name
    return worst, name
