"""The robot spec: a declarative YAML description of the robot, validated into typed objects.

`load_spec()` reads a spec file (the packaged ToddlerBot v1 by default), validates every field and every
cross-reference, and applies a variant (e.g. ``gripper``) when asked. Errors name the file, the entry and
the problem.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from toddlerbot.actuation.catalogue import Catalogue, default_catalogue
from toddlerbot.errors import SpecError
from toddlerbot.yaml_input import read_yaml

DEFAULT_SPEC = resources.files("toddlerbot.robot") / "specs" / "toddlerbot_v1.yaml"

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


MAX_BODY_MASS_KG = 1000.0
"""Plausible ranges: finite is not enough (a 1e308 kg torso is finite). Bounds are far beyond any humanoid link but
far below what overflows a sum or a matrix product."""
MAX_INERTIA_KGM2 = 100.0
MAX_JOINT_DYNAMICS = 1000.0
"""Largest joint damping (N*m*s/rad), armature (kg*m^2) or friction loss (N*m)."""
TIMESTEP_RANGE_S = (1e-5, 0.05)
"""Physics timesteps MuJoCo can integrate this robot at (the spec uses 1 ms)."""
MAX_SOLVER_ITERATIONS = 1000


class _Strict(BaseModel):
    # allow_inf_nan: a NaN centre of mass or an infinite mass must never reach the model builder
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class JointSpec(_Strict):
    """A hinge or slide joint between a body and its parent."""

    name: str
    type: Literal["hinge", "slide"] = "hinge"
    axis: Vec3 = (0.0, 0.0, 1.0)
    pos: Vec3 = (0.0, 0.0, 0.0)
    range: tuple[float, float] | None = None
    """Lower and upper limit (rad or m); absent means unlimited."""
    damping: float = Field(0.0, ge=0, le=MAX_JOINT_DYNAMICS)
    armature: float = Field(0.0, ge=0, le=MAX_JOINT_DYNAMICS)
    frictionloss: float = Field(0.0, ge=0, le=MAX_JOINT_DYNAMICS)

    @field_validator("range")
    @classmethod
    def _ordered(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and value[0] > value[1]:
            raise ValueError(f"lower limit {value[0]} is greater than upper limit {value[1]}")
        return value


class GeomSpec(_Strict):
    """A collision primitive (also drawn, since the spec carries no meshes)."""

    name: str
    type: Literal["box", "sphere", "capsule", "cylinder"]
    size: list[float]
    """Half-extents (box), radius (sphere), or radius and half-length (capsule, cylinder), m."""
    pos: Vec3 = (0.0, 0.0, 0.0)
    quat: Quat = IDENTITY

    @model_validator(mode="after")
    def _size_fits_type(self) -> GeomSpec:
        expected = {"box": 3, "sphere": 1, "capsule": 2, "cylinder": 2}[self.type]
        if len(self.size) != expected or any(s <= 0 for s in self.size):
            raise ValueError(f"a {self.type} needs {expected} positive size value(s), got {self.size}")
        return self


class SiteSpec(_Strict):
    name: str
    pos: Vec3 = (0.0, 0.0, 0.0)
    quat: Quat = IDENTITY


class CameraSpec(_Strict):
    """A camera; it looks along its local -z with +y up (MuJoCo convention)."""

    name: str
    pos: Vec3
    quat: Quat = IDENTITY
    fovy: float = Field(45.0, gt=0, lt=180)
    """Vertical field of view, degrees."""


class BodySpec(_Strict):
    """A rigid link: pose relative to its parent, inertial properties, and at most one joint."""

    name: str
    parent: str
    pos: Vec3
    quat: Quat = IDENTITY
    mass: float = Field(gt=0, le=MAX_BODY_MASS_KG)
    """kg"""
    com: Vec3
    """Centre of mass in the body frame, m."""
    inertia: tuple[float, float, float]
    """Principal moments of inertia, kg*m^2."""
    inertia_quat: Quat = IDENTITY
    """Orientation of the principal axes in the body frame."""
    joint: JointSpec | None = None
    collision: list[GeomSpec] = []
    sites: list[SiteSpec] = []
    cameras: list[CameraSpec] = []

    @field_validator("inertia")
    @classmethod
    def _positive(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(0 < v <= MAX_INERTIA_KGM2 for v in value):
            raise ValueError(f"principal inertias must lie in (0, {MAX_INERTIA_KGM2:g}] kg*m^2, got {value}")
        return value


class MotorSpec(_Strict):
    """A Dynamixel motor driving one joint (its 'motor joint')."""

    id: int = Field(ge=0, le=252)
    """Dynamixel bus id."""
    joint: str
    """The joint the motor shaft turns; also the motor's name."""
    model: str
    """Motor catalogue name or alias, e.g. XC330-T288."""
    group: str
    kp: int = Field(ge=0, le=16383)
    """Firmware position P gain (Dynamixel units)."""
    ki: int = Field(0, ge=0, le=16383)
    kd: int = Field(0, ge=0, le=16383)
    kff1: int = Field(0, ge=0, le=16383)
    kff2: int = Field(0, ge=0, le=16383)
    control_mode: Literal["extended_position", "current_based_position"] = "extended_position"

    @property
    def name(self) -> str:
        return self.joint


class SpurGear(_Strict):
    """A spur gear pair: driven = -(drive_teeth / driven_teeth) * drive (external gears reverse)."""

    type: Literal["spur_gear"]
    name: str
    drive: str
    driven: str
    drive_teeth: int = Field(gt=0)
    driven_teeth: int = Field(gt=0)

    @property
    def ratio(self) -> float:
        return self.drive_teeth / self.driven_teeth

    @property
    def joints(self) -> list[str]:
        return [self.drive, self.driven]


class RodPair(_Strict):
    rod: str
    """Body whose weld to `bearing` closes the loop; its joint carries the same name."""
    bearing: str


class ParallelLinkage(_Strict):
    """A four-bar parallel linkage: driven = drive; rod joints follow rod_sign * driven; welds close the loops."""

    type: Literal["parallel_linkage"]
    name: str
    drive: str
    driven: str
    rods: list[RodPair] = Field(min_length=1)
    rod_sign: Literal[-1, 1]

    @property
    def joints(self) -> list[str]:
        return [self.drive, self.driven] + [j for pair in self.rods for j in (pair.rod, pair.bearing)]


class BevelDifferential(_Strict):
    """Two motors on coupled bevel gears: roll = roll_coef*(m2 - m1), yaw = yaw_coef*(m1 + m2).

    Modelled as two fixed tendons whose length range is the backlash.
    """

    type: Literal["bevel_differential"]
    name: str
    drives: tuple[str, str]
    roll: str
    yaw: str
    roll_coef: float = Field(gt=0)
    yaw_coef: float = Field(gt=0)
    roll_backlash: float = Field(ge=0)
    """Half-width of the roll tendon's free range, rad."""
    yaw_backlash: float = Field(ge=0)

    @property
    def joints(self) -> list[str]:
        return [*self.drives, self.roll, self.yaw]


class RackAndPinion(_Strict):
    """A pinion on the motor moves racks: each driven slide = -pitch_radius * drive."""

    type: Literal["rack_and_pinion"]
    name: str
    drive: str
    driven: list[str] = Field(min_length=1)
    pitch_radius: float = Field(gt=0)
    """m per rad"""

    @property
    def joints(self) -> list[str]:
        return [self.drive, *self.driven]


Transmission = Annotated[
    SpurGear | ParallelLinkage | BevelDifferential | RackAndPinion, Field(discriminator="type")
]


class SimulationSpec(_Strict):
    """MuJoCo solver settings written into the generated model."""

    timestep: float = Field(ge=TIMESTEP_RANGE_S[0], le=TIMESTEP_RANGE_S[1])
    """Physics timestep, s."""
    integrator: Literal["Euler", "implicitfast", "implicit", "RK4"]
    solver: Literal["Newton", "CG", "PGS"]
    iterations: int = Field(gt=0, le=MAX_SOLVER_ITERATIONS)
    ls_iterations: int = Field(gt=0, le=MAX_SOLVER_ITERATIONS)
    cone: Literal["pyramidal", "elliptic"]


class ConstraintSpec(_Strict):
    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]


class ContactSpec(_Strict):
    self_pairs: list[tuple[str, str]] = []
    """Pairs of robot geoms that collide with each other (all robot geoms collide with the floor)."""


class VariantSpec(_Strict):
    """A variation of the base spec: bodies removed (with their subtrees) and added, motors and transmissions added."""

    description: str
    remove_bodies: list[str] = []
    add_bodies: list[BodySpec] = []
    add_motors: list[MotorSpec] = []
    add_transmissions: list[Transmission] = []
    home: dict[str, float] = {}


class RobotSpec(_Strict):
    """A whole robot. Build it with `load_spec()`, which also validates cross-references."""

    name: str
    simulation: SimulationSpec
    constraints: ConstraintSpec
    contacts: ContactSpec = ContactSpec()
    bodies: list[BodySpec] = Field(min_length=1)
    motors: list[MotorSpec] = Field(min_length=1)
    transmissions: list[Transmission] = []
    home: dict[str, float] = {}
    variants: dict[str, VariantSpec] = {}
    variant: str | None = None
    """The variant applied to produce this spec, if any."""

    # ---- lookups -------------------------------------------------------------------------------
    @property
    def joints(self) -> dict[str, JointSpec]:
        return {b.joint.name: b.joint for b in self.bodies if b.joint is not None}

    @property
    def body_of_joint(self) -> dict[str, str]:
        return {b.joint.name: b.name for b in self.bodies if b.joint is not None}

    @property
    def motors_by_id(self) -> list[MotorSpec]:
        return sorted(self.motors, key=lambda m: m.id)

    @property
    def total_mass(self) -> float:
        return sum(b.mass for b in self.bodies)

    def geoms(self) -> list[GeomSpec]:
        return [g for b in self.bodies for g in b.collision]

    # ---- cross-reference checks ---------------------------------------------------------------
    @model_validator(mode="after")
    def _references(self) -> RobotSpec:
        catalogue: Catalogue = default_catalogue()
        seen: set[str] = {"world"}
        for body in self.bodies:
            if body.name in seen:
                raise ValueError(f"body {body.name!r}: name used twice")
            if body.parent not in seen:
                raise ValueError(f"body {body.name!r}: parent {body.parent!r} is not defined before it")
            seen.add(body.name)
        _unique("joint", [b.joint.name for b in self.bodies if b.joint])
        _unique("geom", [g.name for g in self.geoms()])
        _unique("site", [s.name for b in self.bodies for s in b.sites])
        _unique("motor id", [m.id for m in self.motors])
        joints = self.joints
        for motor in self.motors:
            if motor.joint not in joints:
                raise ValueError(f"motor id {motor.id}: joint {motor.joint!r} does not exist")
            if motor.model not in catalogue:
                raise ValueError(
                    f"motor {motor.joint!r} (id {motor.id}): unknown motor model {motor.model!r}; "
                    f"expected one of {sorted(catalogue.models)}"
                )
        _unique("motor joint", [m.joint for m in self.motors])
        bodies = {b.name for b in self.bodies}
        for t in self.transmissions:
            for joint in t.joints:
                if joint not in joints:
                    raise ValueError(f"transmission {t.name!r}: joint {joint!r} does not exist")
            if isinstance(t, ParallelLinkage):
                for pair in t.rods:
                    for body in (pair.rod, pair.bearing):
                        if body not in bodies:
                            raise ValueError(f"transmission {t.name!r}: body {body!r} does not exist")
        geoms = {g.name for g in self.geoms()}
        for pair in self.contacts.self_pairs:
            for geom in pair:
                if geom not in geoms:
                    raise ValueError(f"contacts.self_pairs: geom {geom!r} does not exist")
        for joint, value in self.home.items():
            if joint not in joints:
                raise ValueError(f"home: joint {joint!r} does not exist")
            limits = joints[joint].range
            if limits is not None and not limits[0] <= value <= limits[1]:
                raise ValueError(f"home: {joint} = {value} is outside its range {list(limits)}")
        return self

    # ---- variants -----------------------------------------------------------------------------
    def with_variant(self, name: str) -> RobotSpec:
        """The spec with variant `name` applied (validated again)."""
        if name not in self.variants:
            raise SpecError(f"{self.name}: unknown variant {name!r}; expected one of {sorted(self.variants)}")
        variant = self.variants[name]
        removed = set(variant.remove_bodies)
        for body in self.bodies:  # a removed body takes its subtree with it
            if body.parent in removed:
                removed.add(body.name)
        unknown = set(variant.remove_bodies) - {b.name for b in self.bodies}
        if unknown:
            raise SpecError(f"{self.name}: variant {name!r} removes unknown bodies {sorted(unknown)}")
        data = self.model_dump(exclude={"variants", "variant"})
        data["bodies"] = [b.model_dump() for b in self.bodies if b.name not in removed]
        data["bodies"] += [b.model_dump() for b in variant.add_bodies]
        data["motors"] = data["motors"] + [m.model_dump() for m in variant.add_motors]
        data["transmissions"] = data["transmissions"] + [t.model_dump() for t in variant.add_transmissions]
        data["home"] = {**self.home, **variant.home}
        data["variant"] = name
        return _validate(data, f"{self.name} (variant {name})")


def _unique(what: str, values: list) -> None:
    seen = set()
    for value in values:
        if value in seen:
            raise ValueError(f"{what} {value!r} is used twice")
        seen.add(value)


def _entry_label(raw: dict, loc: tuple) -> str:
    """'bodies[3] (left_calf)' for a location inside the raw spec data."""
    parts, node = [], raw
    for key in loc:
        if isinstance(key, int) and isinstance(node, list) and key < len(node):
            node = node[key]
            name = node.get("name") or node.get("joint") if isinstance(node, dict) else None
            parts[-1] = f"{parts[-1]}[{key}]" + (f" ({name})" if name else "")
        elif isinstance(node, dict) and key in node:
            node = node[key]
            parts.append(str(key))
        else:
            parts.append(str(key))
    return ".".join(parts) or "spec"


def _validate(data: object, source: str) -> RobotSpec:
    if not isinstance(data, dict):
        raise SpecError(f"{source}: expected a mapping at the top level")
    try:
        return RobotSpec.model_validate(data)
    except ValidationError as exc:
        problems = []
        for err in exc.errors():
            message = err["msg"].removeprefix("Value error, ")
            if err["type"] == "missing":
                message = "missing required field"
            elif err["type"] == "extra_forbidden":
                message = "unknown field"
            problems.append(f"{source}: {_entry_label(data, err['loc'])}: {message}")
        raise SpecError("; ".join(problems)) from None


def load_spec(path: str | Path | None = None, variant: str | None = None) -> RobotSpec:
    """Load and validate a robot spec (the packaged ToddlerBot v1 by default), optionally applying a variant."""
    source = Path(path) if path is not None else Path(str(DEFAULT_SPEC))
    data = read_yaml(source, "robot spec", SpecError)
    spec = _validate(data, str(source if path is not None else source.name))
    return spec.with_variant(variant) if variant else spec
