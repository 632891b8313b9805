"""Seeded perturbations of the simulated robot, for measuring how robust a walking policy is.

A `Perturbation` changes the robot a policy walks on (initial joint offsets, torso mass, floor friction, motor
parameters), the ground it walks on (a terrain, `toddlerbot.sim.terrain`, drawn from the same seed) and pushes it
while it walks (horizontal velocity kicks of the torso). `Perturbation.sample` draws
one from a seed, so a set of perturbations is reproducible on every machine; what is asserted over them is a
rate (falls out of runs), never one trajectory.

    robot = perturbed_robot(description, perturbation)       # a MuJoCoRobot with the changed model
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from toddlerbot.actuation.catalogue import Catalogue
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig
from toddlerbot.sim.terrain import TerrainSpec, terrain_model


def scaled_parameters(params: object) -> tuple[str, ...]:
    """The actuator parameters `Perturbation.motor_scale` multiplies for a motor of these parameters: its model's
    table rows marked ``perturbed`` (appendix: damping, armature, frictionloss, tau_max, q_dot_max, kd_min,
    tau_brake)."""
    return tuple(p.name for p in type(params).parameters if p.perturbed)


@dataclass(frozen=True)
class KickTiming:
    """When kicks come: the first at ``start`` s, then every ``period`` s."""

    start: float = 2.0
    period: float = 2.5


@dataclass(frozen=True)
class Perturbation:
    """One perturbed robot and its kicks. The defaults are the nominal robot."""

    seed: int = 0
    """Seed of the kick directions (and of `sample`)."""
    joint_offset: tuple[float, ...] = ()
    """Motor-angle offsets added to the home pose at reset, rad, motor-id order (empty: none)."""
    torso_mass_scale: float = 1.0
    """Factor on the torso's mass and inertia."""
    friction: float | None = None
    """Sliding friction of the floor and every robot geom (MuJoCo takes the larger of a pair); None: the model's."""
    motor_scale: tuple[tuple[str, str, float], ...] = ()
    """(motor model, parameter, factor) entries applied to the catalogue (`scaled_parameters`)."""
    kick_speed: float = 0.0
    """Horizontal velocity change of each kick, m/s, in a uniformly random direction (0: no kicks)."""
    kick_timing: KickTiming = KickTiming()
    terrain: TerrainSpec | None = None
    """The ground, drawn from ``seed`` (None: the flat floor)."""

    @classmethod
    def sample(cls, seed: int, description: RobotDescription, joint_offset: float = 0.01, mass: float = 0.1,
               friction: tuple[float, float] = (0.5, 1.0), motor: float = 0.1, kick_speed: float = 0.0) -> Perturbation:
        """A perturbation drawn from ``seed``: joint offsets uniform in +-``joint_offset`` rad, torso mass x(1 +-
        ``mass``), friction uniform in ``friction``, each motor parameter x(1 +- ``motor``)."""
        rng = np.random.default_rng(seed)
        offsets = rng.uniform(-joint_offset, joint_offset, description.n_motors)
        scale = float(rng.uniform(1 - mass, 1 + mass))
        mu = float(rng.uniform(*friction))
        motor_scale = tuple(
            (model, param, float(factor)) for model in sorted({m.model for m in description.motors})
            for params in [scaled_parameters(description.catalogue[model].actuator)]
            for param, factor in zip(params, rng.uniform(1 - motor, 1 + motor, len(params)), strict=True))
        return cls(seed=seed, joint_offset=tuple(float(x) for x in offsets), torso_mass_scale=scale, friction=mu,
                   motor_scale=motor_scale, kick_speed=kick_speed)

    def describe(self) -> str:
        """A short text of what differs from the nominal robot."""
        parts = []
        if self.joint_offset:
            parts.append(f"joint offsets <= {max(abs(x) for x in self.joint_offset):.3f} rad")
        if self.torso_mass_scale != 1.0:
            parts.append(f"torso mass x{self.torso_mass_scale:.3f}")
        if self.friction is not None:
            parts.append(f"friction {self.friction:.2f}")
        if self.motor_scale:
            factors = [f for _, _, f in self.motor_scale]
            parts.append(f"motor params x{min(factors):.2f}..{max(factors):.2f}")
        if self.kick_speed:
            parts.append(f"kicks {self.kick_speed:g} m/s")
        if self.terrain is not None and not self.terrain.is_flat:
            parts.append(f"terrain {self.terrain} seed {self.seed}")
        return ", ".join(parts) or "nominal"


def perturbed_catalogue(catalogue: Catalogue, motor_scale: tuple[tuple[str, str, float], ...]) -> Catalogue:
    """The catalogue with each (model, parameter, factor) applied."""
    for model, param, factor in motor_scale:
        actuator = catalogue[model].actuator
        catalogue = catalogue.with_actuator(model, actuator.replace(**{param: getattr(actuator, param) * factor}))
    return catalogue


def perturbed_robot(description: RobotDescription, perturbation: Perturbation,
                    config: SimConfig | None = None) -> MuJoCoRobot:
    """A `MuJoCoRobot` of ``description`` on the perturbation's terrain, with its model changes and initial joint
    offsets."""
    if perturbation.motor_scale:
        description = RobotDescription(description.spec, perturbed_catalogue(description.catalogue,
                                                                              perturbation.motor_scale),
                                       description.motor_params_files)
    model = copy.copy(terrain_model(description, perturbation.terrain, perturbation.seed))
    torso = model.body(description.handles.torso).id
    model.body_mass[torso] *= perturbation.torso_mass_scale
    model.body_inertia[torso] *= perturbation.torso_mass_scale
    if perturbation.friction is not None:
        model.geom_friction[:, 0] = perturbation.friction
    robot = MuJoCoRobot(description, config, model=model)
    if perturbation.joint_offset:
        robot.initial_motor_offset = np.asarray(perturbation.joint_offset, dtype=float)
    return robot
