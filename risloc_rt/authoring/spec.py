"""Declarative hall specs: a TOML file -> a validated, frozen :class:`HallSpec`.

Units are SI (metres, seconds, hertz, S/m) everywhere; angles are degrees in the TOML only
(keys ending in ``_deg``) and radians in the dataclasses. Unknown keys, wrong types and missing
required keys raise :class:`SpecError` (a ``ValueError``) naming the key path, e.g.
``objects[2].size[1]``, and the fix.

Schema
------
::

    [scene]
    name = "paper_hall"              # required; letters, digits, _ and - (the folder name by convention)
    description = "..."              # optional text
    frequency = 60e9                 # carrier [Hz] the materials are checked at; default 60e9

    [hall]
    size = [30.0, 18.0]              # rectangle [Lx, Ly] [m] with a corner at the origin, or
    # footprint = [[x, y], ...]      # a simple polygon [m], either orientation (made counter-clockwise)
    height = 7.0                     # floor-to-ceiling height [m], required
    wall_thickness = 0.2             # material thickness of walls/floor/ceiling when not given [m]

    [hall.materials]                 # each: "concrete" | {itu = "concrete", thickness = 0.2}
    walls = "concrete"               #   | {permittivity = 5.24, conductivity = 1.14, thickness = 0.2}
    floor = "concrete"               # all three required; an optional name = "..." names the material
    ceiling = "concrete"             # a table may add scattering_coefficient = S in [0, 1] (default 0:
                                     # smooth; sionna-rt's S, Lambertian; a scene with S > 0 is traced
                                     # with diffuse reflection; not for an RIS panel's material)

    [[objects]]                      # any number; name defaults to "<kind>_<index>"
    kind = "box"                     # center = [x, y, z], size = [sx, sy, sz], yaw_deg = 0
                                     # or min = [x, y, z], max = [x, y, z]
    kind = "pillar"                  # center = [x, y]; radius = r (round, segments = 32) or
                                     # size = [sx, sy] (square, yaw_deg); height = hall height; base = 0
    kind = "shelf"                   # a solid box-shaped rack on the floor (no levels modelled):
                                     # center = [x, y], size = [sx, sy, sz], yaw_deg = 0
    kind = "door" | "window"         # a panel closing a hole cut into a wall: size = [width, height] and
                                     # wall = i (edge i: vertex i -> i+1) with offset = distance of the
                                     # centre from the wall's start [m] and sill (door 0, window 1.0 m),
                                     # or position = [x, y, z] (the centre, snapped to the nearest wall);
                                     # inset = 0.01 (distance of the panel inside the wall plane) [m];
                                     # material default: door {itu="metal", thickness=0.04},
                                     # window {itu="glass", thickness=0.006}
    material = "metal"               # required for box/pillar/shelf (thickness default 0.1 m)

    [[meshes]]                       # any number
    file = "parts/rack.stl"          # OBJ/STL/PLY/GLB/GLTF/OFF, relative to the spec file
    scale = 0.001                    # number or [sx, sy, sz]: metres per file unit (0.001 for mm)
    rotate_deg = [0, 0, 90]          # extrinsic x, then y, then z about the world axes [deg]
    translate = [10.0, 5.0, 0.0]     # applied last [m]: p' = Rz Ry Rx (scale p) + translate
    material = "metal"               # required; name defaults to the file's stem

    [[ris]]                          # any number
    name = "ris0"                    # default "ris<index>"
    position = [19.38, 9.0, 1.2]     # centre of the element grid [m]
    facing = [6.0, 9.0, 1.2]         # a point the broadside faces, or normal = [nx, ny, nz]
    yaw_deg = 0.0                    # extra turn of the normal about `up` [deg]
    up = [0, 0, 1]                   # projected on the panel: the column axis w (docs/conventions.md)
    rows = 16                        # elements along u (azimuth)
    columns = 4                      # elements along w (elevation)
    spacing = "half-wavelength"      # or a pitch [m]; half-wavelength = c / frequency / 2
    amplification_db = 45.532        # ζ [dB]
    loopback_delay = 1.78e-9         # τ_RB [s]
    mode = "relay"                   # or "reflective"
    relay_rx_toward = [6.0, 9.0, 1.2]  # optional: point the relay's Rx beam at it (default broadside)
    panel = {width = 0.10, height = 0.05, material = "metal"}
                                     # the physical plate [m] (width along u, height along w); kept for
                                     # checks and plots, NOT written into the scene XML (the simulator
                                     # models it analytically)

    [radar]                          # optional (no radar positions when absent)
    positions = [[6.0, 9.0, 1.2]]    # [m], or
    # grid = {spacing = 1.0, height = 1.2, margin = 0.5}  # points over the footprint [m], x-major order
    facing = "ris0"                  # a RIS name or a point [x, y, z]; default the first RIS
    velocity = [0.0, 0.0, 0.0]       # [m/s]

Walls are numbered along the counter-clockwise footprint starting at its first vertex as written
(a clockwise footprint is reversed keeping vertex 0 first); a rectangle ``size = [Lx, Ly]`` is the
footprint ``[0,0], [Lx,0], [Lx,Ly], [0,Ly]``, so wall_0 is y = 0, wall_1 x = Lx, wall_2 y = Ly
and wall_3 x = 0. The footprint is the walls' inner face; their thickness only enters the
materials (sionna-rt traces every surface as a thin slab).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dsp import SPEED_OF_LIGHT
from dsp.budget import BudgetError

from . import polygon
from ._parse import SpecError, Table, check_vector, toml_type
from .materials import MaterialSpec, check_name, parse_material, register
from .objects import HallContext, HallObject, ImportedMesh, WallPanel, parse_mesh, parse_object
from .radios import RadarSpec, RisPanel, RisSpec, parse_radar, parse_ris

if TYPE_CHECKING:
    from ..model.plate import Plate
    from ..model.ris import RisConfig

__all__ = ["HallSpec", "HallMaterials", "RisPanel", "RisSpec", "RadarSpec", "SpecError", "load_spec", "loads_spec"]

_RESERVED = re.compile(r"^(floor|ceiling|wall_\d+)$")

#: Largest hall extent (footprint span or height) a spec may have [m]: a larger one is almost
#: always a hall written in millimetres (30000 for 30 m) and would be traced as a 30 km hall.
MAX_HALL_EXTENT = 1000.0
#: Smallest hall extent [m] (a smaller one is a hall written in kilometres or a typo).
MIN_HALL_EXTENT = 0.5
#: Carrier frequencies a spec may use [Hz] (sionna-rt's ITU materials span 1-100 GHz; custom ones more).
FREQUENCY_RANGE = (1e8, 1e13)


@dataclass(frozen=True)
class HallMaterials:
    """Materials of the hall's shell."""

    walls: MaterialSpec
    floor: MaterialSpec
    ceiling: MaterialSpec


@dataclass(frozen=True)
class HallSpec:
    """A validated hall spec (see the module docstring for the TOML schema).

    Attributes
    ----------
    name, description : str
    frequency : float
        Carrier the materials are checked at [Hz].
    footprint : tuple of (x, y)
        Counter-clockwise floor polygon, the walls' inner face [m].
    height : float
        Floor-to-ceiling height [m].
    wall_thickness : float
        Default shell material thickness [m].
    materials : HallMaterials
    objects : tuple
        :class:`~.objects.BoxObject`, :class:`~.objects.CylinderObject`, :class:`~.objects.WallPanel`.
    meshes : tuple of ImportedMesh
    ris : tuple of RisSpec
    radar : RadarSpec
    source : bytes
        The TOML text the spec was read from (the builder copies it byte for byte).
    source_path : Path or None
        The file, when read with :func:`load_spec`.
    base_dir : Path
        Folder that relative mesh paths start from.
    """

    name: str
    description: str
    frequency: float
    footprint: tuple[tuple[float, float], ...]
    height: float
    wall_thickness: float
    materials: HallMaterials
    objects: tuple[HallObject, ...] = ()
    meshes: tuple[ImportedMesh, ...] = ()
    ris: tuple[RisSpec, ...] = ()
    radar: RadarSpec = field(default_factory=RadarSpec)
    source: bytes = b""
    source_path: Path | None = None
    base_dir: Path = Path(".")

    @property
    def footprint_array(self) -> np.ndarray:
        """Footprint [V, 2] [m]."""
        return np.array(self.footprint, dtype=float)

    @property
    def wavelength(self) -> float:
        """λ = c / frequency [m]."""
        return SPEED_OF_LIGHT / self.frequency

    @property
    def wall_names(self) -> tuple[str, ...]:
        """``("wall_0", …)``, wall i on footprint edge i."""
        return tuple(f"wall_{i}" for i in range(len(self.footprint)))

    @property
    def object_names(self) -> tuple[str, ...]:
        """Every scene object, in the order the builder writes them."""
        return ("floor", "ceiling", *self.wall_names, *(o.name for o in self.objects), *(m.name for m in self.meshes))

    def all_materials(self) -> dict[str, MaterialSpec]:
        """Materials by name, in order of first use (shell, objects, meshes)."""
        out: dict[str, MaterialSpec] = {}
        for m in (self.materials.floor, self.materials.ceiling, self.materials.walls,
                  *(o.material for o in self.objects), *(m.material for m in self.meshes)):
            out.setdefault(m.name, m)
        return out

    def ris_configs(self) -> list["RisConfig"]:
        """Every RIS as a :class:`risloc_rt.model.ris.RisConfig` (list, spec order)."""
        return [r.to_config() for r in self.ris]

    def ris_panels(self) -> list["Plate"]:
        """Every RIS's plate as a :class:`risloc_rt.model.plate.Plate` (list, spec order).

        Metal is a perfect conductor (Γ = -1); other materials get the normal-incidence Fresnel
        coefficient of a half-space, Γ = (1 - √ε_c)/(1 + √ε_c), ε_c = ε_r - jσ/(2π f ε_0).
        """
        from ..model.plate import Plate

        out = []
        for r in self.ris:
            mat = r.panel.material
            if mat.itu == "metal":
                gamma: complex = -1.0
            else:
                eps_r, sigma = mat.properties(self.frequency)
                eps_c = eps_r - 1j * sigma / (2 * math.pi * self.frequency * 8.8541878128e-12)
                gamma = (1 - np.sqrt(eps_c)) / (1 + np.sqrt(eps_c))
            out.append(Plate(width=r.panel.width, height=r.panel.height, reflection=complex(gamma)))
        return out

    def radar_positions(self) -> np.ndarray:
        """Radar positions [P, 3] [m] (``[0, 3]`` when the spec has no ``[radar]``)."""
        return np.array(self.radar.positions, dtype=float).reshape(-1, 3)

    def radar_velocity(self) -> np.ndarray:
        """Radar velocity [3] [m/s]."""
        return np.array(self.radar.velocity, dtype=float)

    def radar_facing_point(self, ris_index: int = 0) -> np.ndarray:
        """The point the radar's boresight faces [3] [m].

        ``radar.facing`` when the spec gives one (a RIS name -> that RIS's position), else the
        position of RIS ``ris_index``.
        """
        facing = self.radar.facing
        if isinstance(facing, tuple):
            return np.array(facing, dtype=float)
        if isinstance(facing, str):
            return np.array(next(r.position for r in self.ris if r.name == facing), dtype=float)
        if not 0 <= ris_index < len(self.ris):
            raise ValueError(f"ris_index={ris_index} is out of range: the spec has {len(self.ris)} RIS and no "
                             "radar.facing; add facing = [x, y, z] to [radar] or a [[ris]] table")
        return np.array(self.ris[ris_index].position, dtype=float)

    def radar_boresights(self) -> np.ndarray:
        """Unit boresight of every radar position toward :meth:`radar_facing_point` [P, 3]."""
        d = self.radar_facing_point() - self.radar_positions()
        return d / np.linalg.norm(d, axis=1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# Parsing


def _parse_footprint(hall: Table) -> np.ndarray:
    if hall.has("size") == hall.has("footprint"):
        raise SpecError(hall.key("size"), "[hall] needs exactly one of 'size' (a rectangle) and 'footprint' (a polygon)",
                        "write size = [30.0, 18.0] or footprint = [[0, 0], [30, 0], [30, 18], [0, 18]]")
    if hall.has("size"):
        lx, ly = hall.vector("size", 2, unit="m", minimum=0.0, strict=True)
        return np.array([[0.0, 0.0], [lx, 0.0], [lx, ly], [0.0, ly]])
    raw = hall.raw("footprint")
    key = hall.key("footprint")
    if not isinstance(raw, list):
        raise SpecError(key, f"must be an array of [x, y] points, got a {toml_type(raw)}",
                        "write footprint = [[0, 0], [30, 0], [30, 18], [0, 18]]")
    pts = np.array([check_vector(p, f"{key}[{i}]", 2, unit="m") for i, p in enumerate(raw)], dtype=float).reshape(-1, 2)
    if len(pts) > 3 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]  # a closing repeat of the first vertex is harmless
    problem = polygon.simple_polygon_problem(pts)
    if problem:
        raise SpecError(key, f"the footprint {problem}",
                        "list the corners of a simple polygon once each, in order around the hall")
    return polygon.orient_ccw(pts)


def _check_extent(hall: Table, footprint: np.ndarray, height: float) -> None:
    """Refuse a hall whose size is outside :data:`MIN_HALL_EXTENT` … :data:`MAX_HALL_EXTENT` (wrong units)."""
    span = float(np.max(np.ptp(footprint, axis=0)))
    for key, value in ((hall.key("size" if hall.has("size") else "footprint"), span), (hall.key("height"), height)):
        if value > MAX_HALL_EXTENT:
            raise SpecError(key, f"the hall spans {value:g} m, more than the {MAX_HALL_EXTENT:g} m a hall spec allows "
                            "(a hall written in millimetres?)", "give every length in metres, e.g. size = [30.0, 18.0]")
        if value < MIN_HALL_EXTENT:
            raise SpecError(key, f"the hall spans only {value:g} m, less than {MIN_HALL_EXTENT:g} m (a hall "
                            "written in kilometres?)", "give every length in metres, e.g. size = [30.0, 18.0]")


def _parse(data: dict[str, Any], *, source: bytes, source_path: Path | None, base_dir: Path) -> HallSpec:
    root = Table(data, "")
    scene = root.required_table("scene")
    name = check_name(scene.string("name"), scene.key("name"), what="scene")
    description = scene.string("description", default="")
    frequency = scene.number("frequency", unit="Hz", default=60e9, minimum=0.0, strict=True)
    if not FREQUENCY_RANGE[0] <= frequency <= FREQUENCY_RANGE[1]:
        raise SpecError(scene.key("frequency"), f"{frequency:g} Hz is outside {FREQUENCY_RANGE[0]:g} … "
                        f"{FREQUENCY_RANGE[1]:g} Hz", "give the carrier in hertz, e.g. frequency = 60e9")
    scene.finish()

    hall = root.required_table("hall")
    footprint = _parse_footprint(hall)
    height = hall.number("height", unit="m", minimum=0.0, strict=True, example="7.0")
    _check_extent(hall, footprint, height)
    wall_thickness = hall.number("wall_thickness", unit="m", default=0.2, minimum=0.0, strict=True)
    mats_t = hall.required_table("materials")
    registry: dict[str, MaterialSpec] = {}
    shell = {}
    for surface in ("walls", "floor", "ceiling"):
        key = mats_t.key(surface)
        shell[surface] = parse_material(mats_t.raw(surface, what='"concrete"'), key,
                                        default_thickness=wall_thickness, frequency=frequency)
        register(registry, shell[surface], key)
    mats_t.finish()
    hall.finish()

    ctx = HallContext(footprint=footprint, height=height, frequency=frequency, base_dir=base_dir, materials=registry)
    objects = tuple(parse_object(t, i, ctx) for i, t in enumerate(root.tables("objects")))
    meshes = tuple(parse_mesh(t, i, ctx) for i, t in enumerate(root.tables("meshes")))
    seen: dict[str, str] = {}
    for group, items in (("objects", objects), ("meshes", meshes)):
        for i, obj in enumerate(items):
            key = f"{group}[{i}].name"
            if _RESERVED.match(obj.name):
                raise SpecError(key, f"{obj.name!r} is reserved for the hall's shell (floor, ceiling, wall_<i>)",
                                "choose another name")
            if obj.name in seen:
                raise SpecError(key, f"object name {obj.name!r} is already used by {seen[obj.name]}",
                                "give each object a unique name")
            seen[obj.name] = key
    panels = [(i, o) for i, o in enumerate(objects) if isinstance(o, WallPanel)]
    for j, (ib, b) in enumerate(panels):
        for ia, a in panels[:j]:
            if (a.wall == b.wall and b.u_range[0] < a.u_range[1] and a.u_range[0] < b.u_range[1]
                    and b.z_range[0] < a.z_range[1] and a.z_range[0] < b.z_range[1]):
                raise SpecError(f"objects[{ib}]", f"{b.kind} {b.name!r} overlaps {a.kind} {a.name!r} (objects[{ia}]) "
                                f"on wall {b.wall}", "move one of them along the wall")

    ris_tables = root.tables("ris")
    ris = tuple(parse_ris(t, i, frequency, footprint, height) for i, t in enumerate(ris_tables))
    for i, r in enumerate(ris):
        if [x.name for x in ris].index(r.name) != i:
            raise SpecError(f"ris[{i}].name", f"RIS name {r.name!r} is used twice", "give each RIS a unique name")
    radar = parse_radar(root.table("radar"), ris, footprint, height)
    root.finish()
    return HallSpec(
        name=name, description=description, frequency=frequency,
        footprint=tuple((float(x), float(y)) for x, y in footprint), height=height, wall_thickness=wall_thickness,
        materials=HallMaterials(**shell), objects=objects, meshes=meshes, ris=ris, radar=radar,
        source=source, source_path=source_path, base_dir=base_dir,
    )


def loads_spec(text: str, *, base_dir: str | Path = ".") -> HallSpec:
    """Parse a hall spec from TOML text.

    Parameters
    ----------
    text : str
        The TOML document.
    base_dir : str or Path
        Folder relative ``[[meshes]].file`` paths start from.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError("", f"not valid TOML: {exc}", "fix the syntax at the line and column given") from None
    return _parse(data, source=text.encode("utf-8"), source_path=None, base_dir=Path(base_dir).resolve())


def load_spec(path: str | Path) -> HallSpec:
    """Read and validate a hall spec file (TOML, schema in the module docstring).

    Raises
    ------
    SpecError
        Naming the file, the key path and the fix.
    dsp.budget.BudgetError
        A size the spec declares (``radar.grid.spacing``, a RIS's ``rows`` × ``columns``, a pillar's
        ``segments``) would need more memory than :func:`dsp.budget.memory_limit`; checked before
        anything of that size is made. Names the file and the key.
    FileNotFoundError
        When ``path`` does not exist.
    """
    path = Path(path)
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise SpecError("", f"not valid TOML: {exc}", "fix the syntax at the line and column given",
                        source=str(path)) from None
    try:
        return _parse(data, source=raw, source_path=path.resolve(), base_dir=path.resolve().parent)
    except SpecError as exc:
        raise exc.with_source(str(path)) from None
    except BudgetError as exc:  # a size the spec declares (a radar grid, a RIS, a pillar's segments)
        raise BudgetError(f"{path}: {exc}") from None
