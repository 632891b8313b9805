"""`RobotDescription`: everything derived from the robot spec and the motor catalogue, built once.

Every consumer (simulator and real backends, emulator, policies, gait generator, leg IK, RL environment,
design report, sysID rigs) receives one description instead of the spec, so a fitted ``params.json`` reaches
all of them and nothing re-derives the transmission map, the home pose or the motor groups on its own.

Derived objects are computed on first use and then cached on the description (``functools.cached_property``;
compiled MuJoCo models are cached per base and scene), so building a description is cheap and importing this
module loads nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import Catalogue, MotorModel, default_catalogue
from toddlerbot.actuation.model import ActuatorArrays, actuator_arrays
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.actuation.params_file import catalogue_with_params
from toddlerbot.registry import Registry
from toddlerbot.robot.builder import IMU_SITE, Base, compile_robot, home_joint_pos
from toddlerbot.robot.spec import MotorSpec, RobotSpec, load_spec
from toddlerbot.robot.transmission import TransmissionMap, build_transmission_map

HEAD_CAMERA = "head_camera"
FOOT_SITES = ("left_foot_center", "right_foot_center")
FOOT_GEOMS = ("left_foot_collision", "right_foot_collision")
HAND_SITES = ("left_hand_center", "right_hand_center")


@dataclass(frozen=True)
class Handles:
    """Names of the bodies, sites, geoms and camera that code looks up in a model, in one place."""

    torso: str
    imu_site: str
    feet_sites: tuple[str, str]
    """(left, right) sole-centre sites."""
    feet_geoms: tuple[str, str]
    """(left, right) sole collision geoms."""
    hand_sites: tuple[str, str]
    head_camera: str | None


@dataclass(eq=False)
class RobotDescription:
    """One robot as every consumer sees it: the validated spec, the motor catalogue (with any fitted
    parameters applied) and the objects derived from both.

    Build it with `RobotDescription.load()` (packaged spec and catalogue by default) or from objects you
    already have. Motor-space arrays are in motor-id order; joint-space arrays follow `joint_names`.
    """

    spec: RobotSpec
    catalogue: Catalogue = field(default_factory=default_catalogue)
    motor_params_files: tuple[str, ...] = ()
    """params.json files applied to the catalogue, for provenance (RL exports record them)."""
    _models: dict[tuple[str, bool], mujoco.MjModel] = field(default_factory=dict, init=False, repr=False)

    @classmethod
    def load(
        cls,
        spec_path: str | Path | None = None,
        variant: str | None = None,
        motor_params: Iterable[str | Path] = (),
        catalogue: Catalogue | None = None,
    ) -> RobotDescription:
        """Load the spec (and `variant`), apply fitted actuator parameters (sysID ``params.json`` files)."""
        paths = tuple(str(p) for p in motor_params)
        cat = catalogue or default_catalogue()
        if paths:
            cat = catalogue_with_params(paths, cat)
        return cls(load_spec(spec_path, variant), cat, paths)

    def with_variant(self, variant: str) -> RobotDescription:
        """The same robot (catalogue, fitted parameters) with a spec variant applied, e.g. ``gripper``."""
        return RobotDescription(self.spec.with_variant(variant), self.catalogue, self.motor_params_files)

    # ---- motors ----------------------------------------------------------------------------------------
    @cached_property
    def transmission(self) -> TransmissionMap:
        return build_transmission_map(self.spec)

    @cached_property
    def motors(self) -> tuple[MotorSpec, ...]:
        """Motor entries in motor-id order."""
        return tuple(self.spec.motors_by_id)

    @property
    def motor_names(self) -> tuple[str, ...]:
        return self.transmission.motor_names

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.transmission.joint_names

    @property
    def n_motors(self) -> int:
        return len(self.motors)

    @cached_property
    def motor_models(self) -> tuple[MotorModel, ...]:
        """Catalogue entry of each motor (fitted parameters applied)."""
        return tuple(self.catalogue[m.model] for m in self.motors)

    @cached_property
    def actuator_params(self) -> tuple[MotorParams, ...]:
        return tuple(model.actuator for model in self.motor_models)

    def actuator_arrays(self, kp: np.ndarray | None = None, kd: np.ndarray | None = None) -> ActuatorArrays:
        """Per-motor actuator-model arrays at firmware gains `kp`, `kd` (the spec's gains by default)."""
        kp = self.default_kp if kp is None else np.asarray(kp, dtype=float)
        kd = self.default_kd if kd is None else np.asarray(kd, dtype=float)
        return actuator_arrays(list(self.actuator_params), kp, kd)

    @cached_property
    def default_kp(self) -> np.ndarray:
        """Firmware position P gains from the spec (Dynamixel units)."""
        return _frozen([m.kp for m in self.motors])

    @cached_property
    def default_kd(self) -> np.ndarray:
        return _frozen([m.kd for m in self.motors])

    @cached_property
    def groups(self) -> dict[str, np.ndarray]:
        """Motor indices (motor-id order) of each spec group: ``neck``, ``waist``, ``leg``, ``arm``, ``gripper``."""
        out: dict[str, list[int]] = {}
        for i, motor in enumerate(self.motors):
            out.setdefault(motor.group, []).append(i)
        return {name: _frozen(idx, dtype=int) for name, idx in out.items()}

    def group_names(self, group: str) -> tuple[str, ...]:
        """Motor names of one group, in motor-id order (empty if the robot has no such group)."""
        return tuple(self.motor_names[i] for i in self.groups.get(group, ()))

    # ---- ranges and poses ------------------------------------------------------------------------------
    @cached_property
    def motor_range(self) -> np.ndarray:
        """(n_motors, 2) limits of each motor joint, rad (+-inf where the spec sets none)."""
        return _frozen([self.spec.joints[name].range or (-np.inf, np.inf) for name in self.motor_names])

    @cached_property
    def joint_range(self) -> np.ndarray:
        """(n_motors, 2) limits of each output joint, rad or m (+-inf where the spec sets none)."""
        return _frozen([self.spec.joints[name].range or (-np.inf, np.inf) for name in self.joint_names])

    @cached_property
    def home_joint_pos(self) -> np.ndarray:
        """Output-joint positions of the spec's home pose (joint_names order)."""
        return _frozen(home_joint_pos(self.spec, self.transmission))

    @cached_property
    def home_motor_pos(self) -> np.ndarray:
        """Motor angles (rad, motor-id order) of the spec's home pose, through the transmissions."""
        return _frozen(self.transmission.joint_to_motor(self.home_joint_pos))

    @cached_property
    def max_motor_speed(self) -> np.ndarray:
        """Each motor's no-load speed from its actuator parameters, rad/s (the slew limit's default)."""
        return _frozen([p.q_dot_max for p in self.actuator_params])

    # ---- names in the model ----------------------------------------------------------------------------
    @cached_property
    def handles(self) -> Handles:
        sites = {s.name for b in self.spec.bodies for s in b.sites}
        cameras = {c.name for b in self.spec.bodies for c in b.cameras}
        torso = next(b.name for b in self.spec.bodies if b.parent == "world")
        return Handles(
            torso=torso,
            imu_site=IMU_SITE if IMU_SITE in sites else "",
            feet_sites=FOOT_SITES,
            feet_geoms=FOOT_GEOMS,
            hand_sites=HAND_SITES,
            head_camera=HEAD_CAMERA if HEAD_CAMERA in cameras else None,
        )

    # ---- compiled models -------------------------------------------------------------------------------
    def mjspec(self, base: Base = "floating", scene: bool = True) -> mujoco.MjSpec:
        """A fresh MjSpec of this robot (catalogue and fitted parameters applied), for writing MJCF; the compiled
        model is cached as `model(base, scene)`."""
        mjspec, model = compile_robot(self.spec, base, scene, self.catalogue, self.transmission)
        self._models.setdefault((base, scene), model)
        return mjspec

    def model(self, base: Base = "floating", scene: bool = True) -> mujoco.MjModel:
        """The compiled MuJoCo model for a base (``floating`` or ``fixed``), with or without the scene; built
        once per (base, scene). Treat it as read-only: copy it (``copy.copy``) before changing options."""
        key = (base, scene)
        if key not in self._models:
            self.mjspec(base, scene)
        return self._models[key]


VARIANT_REGISTRY = Registry("variant", entry_point_group="toddlerbot.variants")
"""The model variants `--variant` offers (`toddlerbot model`, `design report`): each a function of the loaded
description returning the description and base to build; installed packages add theirs through the entry-point group
``toddlerbot.variants``, scripts with `register_variant`."""


def register_variant(name: str, factory: str | Callable[[RobotDescription], tuple[RobotDescription, Base]]
                     | None = None):
    """Offer a model variant by `name`: `factory` maps the description loaded from ``--spec`` (and
    ``--motor-params``) to ``(description, base)``, e.g. ``lambda d: (d.with_variant("backpack"), "floating")``,
    or is ``"module:attribute"`` imported on first use. Without `factory`, a decorator. A name already registered
    is refused."""
    return VARIANT_REGISTRY.register(name, factory)


def variant_names() -> tuple[str, ...]:
    """Every model variant name `load_variant` accepts, the built-in ones first."""
    return VARIANT_REGISTRY.names()


def load_variant(
    variant: str, spec_path: str | Path | None = None, motor_params: Iterable[str | Path] = ()
) -> tuple[RobotDescription, Base]:
    """The description and base of a model variant name as the CLI spells it: ``floating``, ``fixed`` (the
    packaged robot on either base), ``gripper`` (the gripper variant, floating) or a registered one."""
    factory = VARIANT_REGISTRY.get(variant)
    return factory(RobotDescription.load(spec_path, motor_params=motor_params))


def _floating(description: RobotDescription) -> tuple[RobotDescription, Base]:
    return description, "floating"


def _fixed(description: RobotDescription) -> tuple[RobotDescription, Base]:
    return description, "fixed"


GRIPPER = "gripper"
"""The spec's variant with parallel-jaw grippers instead of hands: the robot of the manipulation tasks."""


def _gripper(description: RobotDescription) -> tuple[RobotDescription, Base]:
    return description.with_variant(GRIPPER), "floating"


for _name, _factory in {"floating": _floating, "fixed": _fixed, GRIPPER: _gripper}.items():
    VARIANT_REGISTRY.register(_name, _factory)


def _frozen(values: Sequence | np.ndarray, dtype: type = float) -> np.ndarray:
    array = np.array(values, dtype=dtype)
    array.flags.writeable = False
    return array
