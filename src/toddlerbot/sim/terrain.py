"""Terrain: seeded ground under the simulated robot, declared by name and parameters.

A terrain is written ``NAME[:KEY=VALUE[,KEY=VALUE...]]``, e.g. ``rough:height=0.02,cell=0.1`` or ``slope:degrees=-10``
(`parse_terrain`; every parameter is named, has a unit and a range, and a bad one is refused in one line), and is
generated from a seed (`terrain_heights`: same text and seed, same ground, on every machine). The kinds are a
registry (`TERRAINS`, `register_terrain`; installed packages add theirs through the entry-point group
``toddlerbot.terrains``): `Flat`, `Rough`, `Bumps`, `Slope`, `Stairs` and `Mix`, each a `Terrain` subclass whose
``parameters`` are its table and whose ``heights`` give the ground on a grid.

Every terrain becomes one MuJoCo height field (geom `TERRAIN_GEOM`, sampled every `CELL` m over a square of
half-width `EXTENT` m around the robot's start) on top of the scene's ``floor`` plane, which moves down to just below
the terrain's lowest point; the robot's collision geoms collide with it as with the floor (contype/conaffinity). A
height field rather than boxes because the MJX training backend collides it with the robot's boxes and spheres in
4 contacts per geom, where boxes need a collision call and up to 8 contacts per (robot box, terrain box) pair
(docs/simulation.md "Terrain", `benchmarks/bench_terrain.py`). The start square (half-width `START`, where the robot
stands at reset) is flat at z = 0, so the home keyframe needs no change.

    model = terrain_model(description, parse_terrain("rough:height=0.02"), seed=3)   # any consumer of a robot
    ground = Ground.of(model)            # None on the flat floor; ground.height(x, y): z of the ground there

Heights above the ground (the fall check, the RL termination and feet heights) subtract `Ground.height` under the
point; on the flat floor nothing is subtracted, so every flat-floor result stays bit-identical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.registry import Registry
from toddlerbot.robot.description import RobotDescription

TERRAIN_GEOM = "terrain"
"""Name of the height-field geom (and of its height field) a terrain adds."""
FLOOR_GEOM = "floor"
EXTENT = 2.0
"""Half-width of the terrain square around the start, m: a 10 s walk at the fastest reach (0.15 m/s) ends 1.5 m out.
Beyond it lies the floor plane, `FLOOR_DROP` below the terrain's lowest point."""
CELL = 0.02
"""Spacing of the height field's samples, m: an edge (a tile's, a stair's) rises over one cell."""
START = 0.25
"""Half-width of the flat square at z = 0 around the start (the robot's feet at home span 0.12 x 0.12 m)."""
MIN_START = 0.08
"""Smallest start square, half-width, m: the feet at home (0.06 m from the centre) with 2 cm to spare."""
BASE_DEPTH = 0.05
"""Thickness of the height field's solid base below its lowest point, m."""
FLOOR_DROP = BASE_DEPTH
"""How far the floor plane lies below the terrain's lowest point, m: at the height field's base, so that where the
terrain is at its lowest (the start square) the plane neither shows through it in renders nor collides as a second
ground (1 mm below, feet landing 2.4 mm deep into the height field touched it, and a turn in place on the start
square fell where it did not on 1 cm)."""

TERRAINS = Registry("terrain", entry_point_group="toddlerbot.terrains")
"""The terrain kinds `parse_terrain` accepts: `Terrain` subclasses, built-in ones first, then those of installed
packages (entry-point group ``toddlerbot.terrains``) and those added with `register_terrain`."""


def register_terrain(name: str, factory: str | type[Terrain] | None = None):
    """Offer a terrain kind by `name`: a `Terrain` subclass, or ``"module:attribute"`` imported on first use;
    without `factory`, a decorator. A name already registered is refused."""
    return TERRAINS.register(name, factory)


def terrain_names() -> tuple[str, ...]:
    return TERRAINS.names()


@dataclass(frozen=True)
class TerrainParameter:
    """One named parameter of a terrain kind: default, accepted range [low, high] and unit."""

    name: str
    default: float
    low: float
    high: float
    unit: str
    help: str


class Terrain:
    """A terrain kind: its parameter table (``parameters``) and the ground it makes (``heights``). Built with
    validated values (`parse_terrain` checks them first), available as attributes."""

    parameters: ClassVar[tuple[TerrainParameter, ...]] = ()
    help: ClassVar[str] = ""

    def __init__(self, **values: float) -> None:
        for p in self.parameters:
            setattr(self, p.name, float(values.get(p.name, p.default)))

    def heights(self, x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Ground z (m) at the grid points ``x``, ``y`` (2-D arrays, m, start at the origin), drawing what is random
        from ``rng``. The start square is flattened afterwards (`terrain_heights`)."""
        raise NotImplementedError


def _p(name: str, default: float, low: float, high: float, unit: str, help: str) -> TerrainParameter:
    return TerrainParameter(name, default, low, high, unit, help)


@register_terrain("flat")
class Flat(Terrain):
    help = "the floor plane (no height field)"

    def heights(self, x, y, rng):
        return np.zeros_like(x)


def _tile_index(v: np.ndarray, size: float) -> np.ndarray:
    return np.floor((v + EXTENT) / size).astype(int)


@register_terrain("rough")
class Rough(Terrain):
    help = "square tiles of seeded random height in [0, height]"
    parameters = (_p("height", 0.02, 0.0, 0.1, "m", "largest tile height"),
                  _p("cell", 0.1, 0.04, 1.0, "m", "tile width"))

    def heights(self, x, y, rng):
        n = math.ceil(2 * EXTENT / self.cell) + 1
        tiles = rng.uniform(0.0, self.height, (n, n))
        return tiles[_tile_index(y, self.cell), _tile_index(x, self.cell)]


@register_terrain("bumps")
class Bumps(Terrain):
    help = "smooth round hills of seeded random height up to height, one per width x width on average"
    parameters = (_p("height", 0.02, 0.0, 0.1, "m", "largest hill height"),
                  _p("width", 0.3, 0.1, 2.0, "m", "hill diameter (a Gaussian of sigma width / 4)"))

    def heights(self, x, y, rng):
        count = round((2 * EXTENT / self.width) ** 2)
        centres = rng.uniform(-EXTENT, EXTENT, (count, 2))
        peaks = rng.uniform(0.0, self.height, count)
        z = np.zeros_like(x)
        sigma2 = 2 * (self.width / 4) ** 2
        for (cx, cy), peak in zip(centres, peaks, strict=True):
            np.maximum(z, peak * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / sigma2), out=z)
        return z


def _distance_from_start(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """How far outside the start square a point is along the larger axis (0 inside), m: the terrain's square rings."""
    return np.maximum(np.maximum(np.abs(x), np.abs(y)) - START, 0.0)


@register_terrain("slope")
class Slope(Terrain):
    help = "the ground rises (degrees > 0) or falls (< 0) at that angle in every direction from the start square"
    parameters = (_p("degrees", 10.0, -30.0, 30.0, "deg", "slope angle: up (> 0) or down (< 0)"),)

    def heights(self, x, y, rng):
        return math.tan(math.radians(self.degrees)) * _distance_from_start(x, y)


@register_terrain("stairs")
class Stairs(Terrain):
    help = "square terraces around the start square: each step height up (> 0) or down (< 0), depth deep"
    parameters = (_p("height", 0.03, -0.1, 0.1, "m", "step height: up (> 0) or down (< 0)"),
                  _p("depth", 0.2, 0.05, 1.0, "m", "step depth (tread)"))

    def heights(self, x, y, rng):
        return self.height * np.ceil(_distance_from_start(x, y) / self.depth)


@register_terrain("mix")
class Mix(Terrain):
    help = ("for training: square patches, each flat, rough, bumps, a ramp (a pyramid) or a raised or sunken step, "
            "of seeded random size up to height / degrees")
    parameters = (_p("height", 0.03, 0.0, 0.1, "m", "largest tile, hill or step height"),
                  _p("degrees", 10.0, 0.0, 30.0, "deg", "steepest ramp"),
                  _p("patch", 1.0, 0.2, 2.0, "m", "patch width"))

    def heights(self, x, y, rng):
        n = math.ceil(2 * EXTENT / self.patch) + 1
        kinds = rng.integers(0, 5, (n, n))
        level = rng.uniform(0.0, 1.0, (n, n))
        row, col = _tile_index(y, self.patch), _tile_index(x, self.patch)
        # position inside its patch, from the patch centre, m
        u = (x + EXTENT) - (col + 0.5) * self.patch
        v = (y + EXTENT) - (row + 0.5) * self.patch
        rough = Rough(height=self.height, cell=0.1).heights(x, y, rng)
        bumps = Bumps(height=self.height, width=0.3).heights(x, y, rng)
        ramp = math.tan(math.radians(self.degrees)) * (self.patch / 2 - np.maximum(np.abs(u), np.abs(v)))
        step = self.height * np.where(np.maximum(np.abs(u), np.abs(v)) < self.patch / 4, 1.0, 0.0)
        raised = (row + col) % 2 == 0  # raised plateaus and sunken pits in a checkerboard
        pit_or_plateau = np.where(raised, step, self.height - step)
        z = np.choose(kinds[row, col], [np.zeros_like(x), rough, bumps, ramp, pit_or_plateau])
        return level[row, col] * z


@dataclass(frozen=True)
class TerrainSpec:
    """A terrain kind and its parameter values (the defaults filled in), as `parse_terrain` read them."""

    name: str
    values: tuple[tuple[str, float], ...] = ()

    def __str__(self) -> str:
        return self.name + (":" + ",".join(f"{k}={v:g}" for k, v in self.values) if self.values else "")

    def build(self) -> Terrain:
        return TERRAINS.get(self.name)(**dict(self.values))

    @property
    def is_flat(self) -> bool:
        return self.name == "flat"


def parse_terrain(text: str, option: str = "--terrain") -> TerrainSpec:
    """The terrain ``NAME[:KEY=VALUE,...]`` of ``text``, its values checked against the kind's table; one line
    naming ``option``, the text and what was expected otherwise."""
    def refuse(problem: str) -> ToddlerbotError:
        return ToddlerbotError(f"{option} {text[:60]!r}: {problem}")

    name, _, rest = text.strip().partition(":")
    if name not in TERRAINS:
        raise refuse(f"unknown terrain {name!r}; expected one of {', '.join(terrain_names())}")
    kind = TERRAINS.get(name)
    table = {p.name: p for p in kind.parameters}
    expected = f"{name} takes {', '.join(table) or 'no parameters'}"
    values = {p.name: p.default for p in kind.parameters}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, equals, raw = (s.strip() for s in item.partition("="))
        if key not in table:
            raise refuse(f"unknown parameter {key!r}; {expected}")
        if not equals:
            raise refuse(f"{key}: expected {key}=VALUE")
        try:
            value = float(raw)
        except ValueError:
            raise refuse(f"{key}={raw[:20]!r}: expected a number") from None
        p = table[key]
        if not p.low <= value <= p.high:  # NaN fails too
            raise refuse(f"{key}={raw}: expected {p.low:g} to {p.high:g} {p.unit} ({p.help})")
        values[key] = value
    return TerrainSpec(name, tuple(values.items()))


@dataclass(frozen=True)
class HeightGrid:
    """Ground z (m) sampled every ``cell`` m on a square of half-width ``extent`` m centred at the origin;
    ``z[row, col]`` lies at x = -extent + col * cell, y = -extent + row * cell (MuJoCo's height-field layout)."""

    z: np.ndarray
    extent: float
    cell: float

    @property
    def flat(self) -> bool:
        return not np.any(self.z)


def terrain_heights(terrain: TerrainSpec, seed: int, extent: float = EXTENT, cell: float = CELL,
                    start: float = START) -> HeightGrid:
    """The ground of ``terrain`` drawn from ``seed``, the start square of half-width ``start`` (and the cells it
    touches) flat at z = 0."""
    if not MIN_START <= start <= extent / 2:
        raise ToddlerbotError(f"start square half-width {start} m: expected {MIN_START}-{extent / 2} m")
    n = round(2 * extent / cell) + 1
    axis = np.linspace(-extent, extent, n)
    x, y = np.meshgrid(axis, axis)  # rows along y, columns along x
    z = np.asarray(terrain.build().heights(x, y, np.random.default_rng(seed)), dtype=float)
    if z.shape != x.shape or not np.all(np.isfinite(z)):
        raise ToddlerbotError(f"terrain {terrain}: heights must be finite, one per grid point {x.shape}")
    z[(np.abs(x) < start + cell) & (np.abs(y) < start + cell)] = 0.0  # every cell touching the square
    return HeightGrid(z, extent, cell)


def add_terrain(mj: mujoco.MjSpec, grid: HeightGrid) -> None:
    """Add ``grid`` to a robot's MjSpec with its scene (`robot.builder`'s ``floor``) as the height field
    `TERRAIN_GEOM`, colliding as the floor does; the floor plane moves down to `FLOOR_DROP` below its lowest point.
    A flat grid adds nothing."""
    if grid.flat:
        return
    low, high = float(grid.z.min()), float(grid.z.max())
    rise = max(high - low, 1e-9)
    nrow, ncol = grid.z.shape
    mj.add_hfield(name=TERRAIN_GEOM, size=[grid.extent, grid.extent, rise, BASE_DEPTH], nrow=nrow, ncol=ncol,
                  userdata=((grid.z - low) / rise).ravel().tolist())
    floor = mj.geom(FLOOR_GEOM)
    mj.worldbody.add_geom(name=TERRAIN_GEOM, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=TERRAIN_GEOM,
                          pos=(0.0, 0.0, low), contype=floor.contype, conaffinity=floor.conaffinity,
                          material=floor.material)
    floor.pos = (0.0, 0.0, min(low, 0.0) - FLOOR_DROP)


def terrain_mjspec(description: RobotDescription, terrain: TerrainSpec | None, seed: int = 0) -> mujoco.MjSpec:
    """The description's floating robot with its scene on ``terrain`` drawn from ``seed`` (None: flat)."""
    mj = description.mjspec("floating", scene=True)
    if terrain is not None:
        add_terrain(mj, terrain_heights(terrain, seed))
    return mj


def terrain_model(description: RobotDescription, terrain: TerrainSpec | None, seed: int = 0) -> mujoco.MjModel:
    """The compiled `terrain_mjspec` (home keyframe kept: the start square is at z = 0). On the flat floor it is the
    description's cached model itself: treat it as read-only."""
    if terrain is None or terrain_heights(terrain, seed).flat:
        return description.model("floating", scene=True)
    return terrain_mjspec(description, terrain, seed).compile()


def ground_geoms(model: mujoco.MjModel) -> frozenset[int]:
    """Ids of the geoms that are the ground: the floor and, where there is one, the terrain."""
    return frozenset(model.geom(name).id for name in (FLOOR_GEOM, TERRAIN_GEOM)
                     if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) >= 0)


class Ground:
    """The height of the ground under a point of a model with a terrain: its height field (interpolated on MuJoCo's
    triangles, so it is the surface the physics collides with) and, beyond it, the floor."""

    def __init__(self, z: np.ndarray, extent: float, base: float, floor: float) -> None:
        self.z, self.extent, self.base, self.floor = z, extent, base, floor
        self.cell = 2 * extent / (z.shape[1] - 1)

    @classmethod
    def of(cls, model: mujoco.MjModel) -> Ground | None:
        """The ground of ``model``; None when it has no terrain (the floor plane at z = 0: heights are z)."""
        geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TERRAIN_GEOM)
        if geom < 0:
            return None
        field = model.geom_dataid[geom]
        nrow, ncol = model.hfield_nrow[field], model.hfield_ncol[field]
        start = model.hfield_adr[field]
        size = model.hfield_size[field]
        if size[0] != size[1] or nrow != ncol or np.any(model.geom_pos[geom, :2]):
            raise ToddlerbotError(f"geom {TERRAIN_GEOM!r}: expected a square height field at the origin")
        z = model.hfield_data[start:start + nrow * ncol].reshape(nrow, ncol) * size[2]
        floor = float(model.geom_pos[model.geom(FLOOR_GEOM).id, 2])
        return cls(z, float(size[0]), float(model.geom_pos[geom, 2]), floor)

    def height(self, x, y, xp=np):
        """Ground z (m) under points (x, y) (arrays of one shape, m), numpy or ``xp=jax.numpy``."""
        z = xp.asarray(self.z)
        n = self.z.shape[0]
        u, v = (x + self.extent) / self.cell, (y + self.extent) / self.cell
        col = xp.clip(xp.floor(u), 0, n - 2).astype(int)
        row = xp.clip(xp.floor(v), 0, n - 2).astype(int)
        fx, fy = u - col, v - row
        z00, z10 = z[row, col], z[row, col + 1]
        z01, z11 = z[row + 1, col], z[row + 1, col + 1]
        # MuJoCo splits each cell along its (0, 0)-(1, 1) diagonal
        upper = z00 + fx * (z11 - z01) + fy * (z01 - z00)
        lower = z00 + fx * (z10 - z00) + fy * (z11 - z10)
        inside = (xp.abs(x) <= self.extent) & (xp.abs(y) <= self.extent)
        return xp.where(inside, self.base + xp.where(fy > fx, upper, lower), self.floor)
