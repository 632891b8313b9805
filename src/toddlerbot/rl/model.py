"""The training variant of the robot's MuJoCo model: the spec's model, post-processed for fast MJX stepping.

Built from `toddlerbot.robot.builder.build_mjspec` (the same bodies, joints, transmissions and actuator
parameters as the CPU simulator) with, per `EnvConfig`:

* the MJX timestep and Newton solver / line-search iterations;
* collisions pruned to the ones walking needs (``contacts="feet_hands"``): the feet and hands against the ground
  (the floor and, on a terrain, its height field: both collide through contype/conaffinity, so pruning the robot's
  geoms keeps them) and the two feet against each other. Every other robot geom stops colliding; the spec's
  self-collision pairs (thighs, ankle links) are dropped. Fewer candidate contacts make every MJX step cheaper;
* the configuration's terrain (`EnvConfig.terrain`, `toddlerbot.sim.terrain`: a height field, which MJX collides
  with the feet and hands' boxes), drawn from its seed;
* the constraint Jacobian layout (dense or sparse);
* with ``linkage_loops=False`` each parallel linkage (the knees) coupled joint to joint instead of closed by
  weld loops: driven = drive, rod and bearing = ``rod_sign`` x driven (the transmission map's relation, so the
  kinematics are the same). In float32 MJX the stiff weld loops of the loaded knees give way (measured: the
  knee collapses after ~3.5 s of standing in 8 envs, and during the squat); one-dimensional joint couplings
  stay well conditioned.

The fitted actuator parameters of the description's catalogue (damping, armature, friction loss) are in it.
"""

from __future__ import annotations

import mujoco

from toddlerbot.rl.config import EnvConfig
from toddlerbot.robot.builder import build_mjspec
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import ParallelLinkage
from toddlerbot.sim.terrain import add_terrain, parse_terrain, terrain_heights

_JACOBIANS = {"dense": mujoco.mjtJacobian.mjJAC_DENSE, "sparse": mujoco.mjtJacobian.mjJAC_SPARSE}


def contact_geoms(description: RobotDescription) -> tuple[str, ...]:
    """Collision geoms that keep touching the floor in the pruned model: the soles and the hands' geoms."""
    handles = description.handles
    hand_bodies = {b.name for b in description.spec.bodies for s in b.sites if s.name in handles.hand_sites}
    hands = tuple(g.name for b in description.spec.bodies if b.name in hand_bodies for g in b.collision)
    return (*handles.feet_geoms, *hands)


def training_mjspec(description: RobotDescription, cfg: EnvConfig) -> mujoco.MjSpec:
    """The robot's MjSpec (with floor, and ``cfg.terrain`` drawn from ``cfg.terrain_seed``) carrying the training
    options of ``cfg``."""
    mj = build_mjspec(description.spec, scene=True, catalogue=description.catalogue)
    add_terrain(mj, terrain_heights(parse_terrain(cfg.terrain, "terrain"), cfg.terrain_seed,  # flat: nothing
                                    start=cfg.terrain_start))
    mj.option.timestep = cfg.sim_dt
    mj.option.iterations = cfg.solver_iterations
    mj.option.ls_iterations = cfg.solver_ls_iterations
    mj.option.jacobian = _JACOBIANS[cfg.jacobian]
    if cfg.contacts == "feet_hands":
        keep = set(contact_geoms(description))
        for geom in mj.geoms:
            if geom.contype and geom.name not in keep:
                geom.contype = geom.conaffinity = 0
        for pair in list(mj.pairs):
            mj.delete(pair)
        left, right = description.handles.feet_geoms
        mj.add_pair(name="feet", geomname1=left, geomname2=right)
    if not cfg.linkage_loops:
        _couple_linkages(mj, description)
    return mj


def _couple_linkages(mj: mujoco.MjSpec, description: RobotDescription) -> None:
    """Replace every parallel linkage's weld loops by joint equalities (see the module docstring)."""
    solref, solimp = description.spec.constraints.solref, description.spec.constraints.solimp
    loops = {eq.name: eq for eq in mj.equalities}

    def couple(joint: str, reference: str, coef: float) -> None:
        mj.add_equality(name=f"{joint}_coupling", type=mujoco.mjtEq.mjEQ_JOINT, name1=joint, name2=reference,
                        objtype=mujoco.mjtObj.mjOBJ_JOINT, data=[0.0, coef] + [0.0] * 10, solref=solref,
                        solimp=solimp)

    for t in description.spec.transmissions:
        if not isinstance(t, ParallelLinkage):
            continue
        couple(t.driven, t.drive, 1.0)
        for pair in t.rods:
            mj.delete(loops[f"{pair.rod}_loop"])
            couple(pair.rod, t.driven, float(t.rod_sign))
            couple(pair.bearing, t.driven, float(t.rod_sign))


def training_model(description: RobotDescription, cfg: EnvConfig) -> mujoco.MjModel:
    """The compiled training variant (see the module docstring)."""
    return training_mjspec(description, cfg).compile()
