"""Height field or boxes: which terrain both MuJoCo (CPU) and MJX collide with correctly, and at what cost.

The same ground, 3 cm tiles of random height on a 0.2 m grid over the 4 x 4 m terrain square
(`rough:height=0.03,cell=0.2`, seed 0; tiles wider than a sole, so that it can rest on one), built three ways: the
flat floor alone (reference), the height field `toddlerbot.sim.terrain` builds (one geom, samples every 2 cm), and one
box per tile (384 boxes; the 0.1 m tiles of `rough`'s default would be 1,600). Measured:

* correctness: a free box the size of a foot sole, set down 0.5 mm into four tiles, then stepped 0.5 s in MuJoCo and
  in MJX (4 ms steps, as RL trains): how far above its tile's top its bottom rests (0 = right);
* MJX: the contact slots a step carries for that one sole, compile time and time per physics step (jit, this
  machine's JAX device); boxes also with MJX's ``max_geom_pairs`` broad phase (the 8 nearest boxes);
* MuJoCo (CPU): control steps per second of the simulator (`MuJoCoRobot`, 20 physics steps each) holding the home
  pose at the start;
* with ``--robot``: the RL training model (`rl.model.training_model`, feet and hands colliding) on each ground in
  MJX: contact slots, compile time and time per control step (5 physics steps, the actuator model in the loop) of
  one robot holding home; boxes with the broad phase keeping the 16 nearest (box, box) pairs (both soles can touch
  6 tiles each). Times are the fastest of three repetitions.

Run: PYTHONPATH=src python benchmarks/bench_terrain.py [--skip-mjx] [--robot]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import CELL, EXTENT, START, add_terrain, parse_terrain, terrain_heights

TILE = 0.2
HEIGHT = 0.03
SOLE = (0.06, 0.0245, 0.021)  # half-sizes of the foot's collision box, m
TILES = [(2, 3), (5, 13), (15, 6), (11, 17)]  # (row, column) of the tiles the sole is set on


def _tiles() -> np.ndarray:
    """The tile heights `Rough(height=0.03, cell=0.2)` draws from seed 0 (rows along y)."""
    n = int(np.ceil(2 * EXTENT / TILE)) + 1
    return np.random.default_rng(0).uniform(0.0, HEIGHT, (n, n))


def _tile_centre(row: int, col: int) -> tuple[float, float]:
    return -EXTENT + (col + 0.5) * TILE, -EXTENT + (row + 0.5) * TILE


def add_ground(mj: mujoco.MjSpec, kind: str) -> None:
    """Add ``kind`` (flat, hfield, boxes, boxes-8) to an MjSpec that has a ``floor`` plane."""
    if kind == "hfield":
        add_terrain(mj, terrain_heights(parse_terrain(f"rough:height={HEIGHT},cell={TILE}"), seed=0))
    elif kind.startswith("boxes"):
        tiles = _tiles()
        for row in range(tiles.shape[0]):
            for col in range(tiles.shape[1]):
                x, y = _tile_centre(row, col)
                clear_of_start = max(abs(x), abs(y)) > START + CELL + TILE / 2  # flat there, as the height field
                if max(abs(x), abs(y)) < EXTENT and clear_of_start:
                    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=(TILE / 2, TILE / 2,
                                          tiles[row, col] / 2), pos=(x, y, tiles[row, col] / 2), contype=0,
                                          conaffinity=1)
        if kind == "boxes-8":
            mj.add_numeric(name="max_geom_pairs", data=[8])


def sole_model(kind: str) -> mujoco.MjModel:
    mj = mujoco.MjSpec()
    mj.option.timestep = 0.004
    mj.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=(0, 0, 0.05), contype=0, conaffinity=1)
    add_ground(mj, kind)
    body = mj.worldbody.add_body(name="sole")
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=SOLE, mass=0.2, contype=1, conaffinity=0)
    return mj.compile()


def _set_down(model: mujoco.MjModel, tile_height: float, x: float, y: float) -> mujoco.MjData:
    data = mujoco.MjData(model)
    data.qpos[:3] = x, y, tile_height + SOLE[2] - 0.0005
    return data


def cpu_rest_errors(kind: str) -> list[float]:
    """Sole bottom above its tile's top after 0.5 s in MuJoCo, m, per tile."""
    model, tiles = sole_model(kind), _tiles()
    errors = []
    for row, col in TILES:
        data = _set_down(model, tiles[row, col], *_tile_centre(row, col))
        mujoco.mj_step(model, data, 125)
        errors.append(float(data.qpos[2] - SOLE[2] - tiles[row, col]))
    return errors


def mjx_figures(kind: str) -> dict:
    """Contact slots, compile time, time per physics step and rest errors of the sole in MJX."""
    import jax
    from mujoco import mjx

    model, tiles = sole_model(kind), _tiles()
    sys = mjx.put_model(model)

    @jax.jit
    def run(d):
        return jax.lax.scan(lambda d, _: (mjx.step(sys, d), None), d, None, length=125)[0]

    starts = [mjx.put_data(model, _set_down(model, tiles[r, c], *_tile_centre(r, c))) for r, c in TILES]
    start = time.perf_counter()
    compiled = run.lower(starts[0]).compile()
    compile_s = time.perf_counter() - start
    ends = [compiled(s) for s in starts]
    jax.block_until_ready(ends)
    step_us = float("inf")
    for _ in range(3):  # the fastest of three: the shared VM's load only ever adds time
        start = time.perf_counter()
        jax.block_until_ready([compiled(s) for s in starts])
        step_us = min(step_us, (time.perf_counter() - start) / (125 * len(starts)) * 1e6)
    errors = [float(e.qpos[2]) - SOLE[2] - tiles[r, c] for e, (r, c) in zip(ends, TILES, strict=True)]
    return {"contacts": int(starts[0]._impl.contact.dist.shape[0]), "compile_s": compile_s, "step_us": step_us,
            "errors": errors}


def cpu_robot_rate(kind: str, description: RobotDescription, steps: int = 100) -> float:
    """Control steps per second of the simulator holding home at the start, on ``kind``."""
    mj = description.mjspec("floating", scene=True)
    add_ground(mj, kind)
    robot = MuJoCoRobot(description, model=mj.compile())
    robot.step(description.home_motor_pos)
    start = time.process_time()
    for _ in range(steps):
        robot.step(description.home_motor_pos)
    return steps / (time.process_time() - start)


def mjx_robot_figures(kind: str, description: RobotDescription) -> dict:
    """Contact slots, compile time and time per control step of the MJX training model holding home on ``kind``."""
    import jax
    import jax.numpy as jnp

    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.model import training_mjspec
    from toddlerbot.rl.physics import Addresses, MJXPhysics

    cfg = EnvConfig()
    mj = training_mjspec(description, cfg)
    add_ground(mj, "boxes" if kind == "boxes-16" else kind)
    if kind == "boxes-16":
        mj.add_numeric(name="max_geom_pairs", data=[16])
    model = mj.compile()
    physics = MJXPhysics(model, Addresses.of(model, description), cfg.n_substeps)
    targets = jnp.asarray(description.home_motor_pos, jnp.float32)
    actuators = description.actuator_arrays()
    actuators = type(actuators)(*(jnp.asarray(a, jnp.float32) for a in actuators))
    step = jax.jit(lambda state: physics.step(state, targets, None, actuators)[0])
    start = time.perf_counter()
    compiled = step.lower(physics.home_state).compile()
    compile_s = time.perf_counter() - start
    state = jax.block_until_ready(compiled(physics.home_state))
    step_ms = float("inf")
    for _ in range(3):  # the fastest of three blocks of 20 control steps
        start = time.perf_counter()
        for _ in range(20):
            state = compiled(state)
        jax.block_until_ready(state)
        step_ms = min(step_ms, (time.perf_counter() - start) / 20 * 1e3)
    return {"contacts": int(physics.home_state._impl.contact.dist.shape[0]), "compile_s": compile_s,
            "step_ms": step_ms, "torso_z": float(state.qpos[2])}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--skip-mjx", action="store_true")
    parser.add_argument("--robot", action="store_true", help="only the MJX training model on each ground")
    args = parser.parse_args()
    description = RobotDescription.load()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}")
    if args.robot:
        print("ground    | MJX training model: contacts  compile s  ms/control step  torso z after 61 steps (m)")
        for kind in ("flat", "hfield", "boxes-16"):
            f = mjx_robot_figures(kind, description)
            print(f"{kind:9} | {f['contacts']:>28}  {f['compile_s']:9.1f}  {f['step_ms']:15.1f}  {f['torso_z']:.4f}",
                  flush=True)
        return
    print("ground    | MuJoCo rest error (mm)      | MJX contacts  compile s  us/step  rest error (mm)      | "
          "sim control steps/s")
    for kind in ("flat", "hfield", "boxes", "boxes-8"):
        cpu = "flat floor" if kind == "flat" else " ".join(f"{e * 1e3:+.2f}" for e in cpu_rest_errors(kind))
        mjx = "-"
        if not args.skip_mjx:
            try:
                f = mjx_figures(kind)
                rest = "flat floor" if kind == "flat" else " ".join(f"{e * 1e3:+.2f}" for e in f["errors"])
                mjx = f"{f['contacts']:>5}  {f['compile_s']:9.1f}  {f['step_us']:7.1f}  {rest}"
            except Exception as exc:  # report what MJX refuses, then go on
                mjx = f"failed: {str(exc)[:60]}"
        rate = cpu_robot_rate(kind, description) if kind != "boxes-8" else float("nan")
        print(f"{kind:9} | {cpu:27} | {mjx:52} | {rate:.0f}", flush=True)


if __name__ == "__main__":
    main()
