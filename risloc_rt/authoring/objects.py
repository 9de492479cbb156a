"""Objects of a hall spec: boxes, pillars, shelves, doors, windows and imported meshes.

Each dataclass is the validated, SI form of one ``[[objects]]`` or ``[[meshes]]`` table (the
schema is in :mod:`risloc_rt.authoring.spec`); :mod:`.shapes` turns them into triangles.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from dsp.budget import check_memory

from . import polygon
from ._parse import SpecError, Table, check_number
from .materials import MaterialSpec, check_name, parse_material, register
from .meshcheck import mesh_memory

__all__ = [
    "BoxObject", "CylinderObject", "WallPanel", "ImportedMesh", "HallObject", "HallContext", "MESH_SUFFIXES",
    "OBJECT_KINDS", "euler_matrix", "parse_mesh", "parse_object",
]

#: Thickness of an object's material when the spec gives none [m] (sionna-rt's own default).
OBJECT_THICKNESS = 0.1
#: Default panel materials: door -> metal 4 cm, window -> glass 6 mm.
PANEL_DEFAULTS = {"door": ("metal", 0.04, 0.0), "window": ("glass", 0.006, 1.0)}
#: A door/window given by ``position`` snaps to the nearest wall within this distance [m].
PANEL_SNAP = 0.5
#: File types trimesh reads for ``[[meshes]]``.
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off")
#: Containment tolerance for objects touching a wall, the floor or the ceiling [m].
_TOL = 1e-6


@dataclass(frozen=True)
class BoxObject:
    """A closed box (``kind`` box, a square pillar, or a shelf).

    Attributes
    ----------
    name, kind : str
        Scene object name; the TOML kind (``"box"``, ``"pillar"``, ``"shelf"``).
    material : MaterialSpec
    center : (float, float, float)
        Box centre, world frame [m].
    size : (float, float, float)
        Edge lengths along the box's own x, y (before yaw) and z [m].
    yaw : float
        Rotation about the vertical through ``center``, counter-clockwise seen from above [rad].
    """

    name: str
    kind: Literal["box", "pillar", "shelf"]
    material: MaterialSpec
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0

    def corners_xy(self) -> np.ndarray:
        """Footprint corners [4, 2] [m], counter-clockwise."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return local @ np.array([[c, s], [-s, c]]) + np.asarray(self.center[:2])

    @property
    def z_range(self) -> tuple[float, float]:
        """(bottom, top) [m]."""
        return self.center[2] - self.size[2] / 2, self.center[2] + self.size[2] / 2


@dataclass(frozen=True)
class CylinderObject:
    """A round pillar: a closed cylinder standing on ``base``.

    Attributes
    ----------
    name : str
    kind : "pillar"
    material : MaterialSpec
    center : (float, float)
        Axis position in the xy plane [m].
    radius, base, height : float
        Radius, bottom height and height of the cylinder [m].
    segments : int
        Facets around the axis (the polygon is inscribed in the circle).
    """

    name: str
    kind: Literal["pillar"]
    material: MaterialSpec
    center: tuple[float, float]
    radius: float
    base: float
    height: float
    segments: int = 32

    def corners_xy(self) -> np.ndarray:
        """Facet corners [segments, 2] [m], counter-clockwise."""
        a = 2 * np.pi * np.arange(self.segments) / self.segments
        return np.asarray(self.center) + self.radius * np.column_stack([np.cos(a), np.sin(a)])

    @property
    def z_range(self) -> tuple[float, float]:
        """(bottom, top) [m]."""
        return self.base, self.base + self.height


@dataclass(frozen=True)
class WallPanel:
    """A door or window: a rectangular opening cut into a wall, closed by a thin panel.

    The wall mesh gets a hole and the panel, one quad (a thin slab of its material's thickness,
    as sionna-rt models every surface), sits ``inset`` inside the hall in front of the hole.

    Attributes
    ----------
    name : str
    kind : {"door", "window"}
    material : MaterialSpec
    wall : int
        Footprint edge the panel is on (edge i runs from vertex i to i+1 of the CCW footprint).
    offset : float
        Distance along the wall from its first vertex to the panel's centre [m].
    width, height : float
        Panel size along the wall and vertically [m].
    sill : float
        Height of the panel's bottom edge above the floor [m].
    inset : float
        Distance of the panel from the wall plane, into the hall [m].
    """

    name: str
    kind: Literal["door", "window"]
    material: MaterialSpec
    wall: int
    offset: float
    width: float
    height: float
    sill: float
    inset: float = 0.01

    @property
    def u_range(self) -> tuple[float, float]:
        """(start, end) along the wall [m]."""
        return self.offset - self.width / 2, self.offset + self.width / 2

    @property
    def z_range(self) -> tuple[float, float]:
        """(bottom, top) [m]."""
        return self.sill, self.sill + self.height


@dataclass(frozen=True)
class ImportedMesh:
    """A triangle mesh read from a file (OBJ, STL, PLY, GLB/GLTF, OFF) by trimesh.

    A file vertex ``p`` lands at ``R @ (scale * p) + translate``, with
    ``R = Rz(γ) @ Ry(β) @ Rx(α)`` for ``rotation = (α, β, γ)``: rotations about the fixed world
    axes x, then y, then z (extrinsic x-y-z, i.e. intrinsic z-y'-x'').

    Attributes
    ----------
    name : str
    file : Path
        Absolute path of the mesh file.
    material : MaterialSpec
    scale : (float, float, float)
        Unit scale per axis, e.g. 0.001 for a file in millimetres [m per file unit].
    translate : (float, float, float)
        [m].
    rotation : (float, float, float)
        (α, β, γ) [rad].
    """

    name: str
    file: Path
    material: MaterialSpec
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    kind: Literal["mesh"] = "mesh"

    @property
    def matrix(self) -> np.ndarray:
        """4×4 homogeneous transform, file units -> world [m]."""
        m = np.eye(4)
        m[:3, :3] = euler_matrix(self.rotation) @ np.diag(self.scale)
        m[:3, 3] = self.translate
        return m


HallObject = BoxObject | CylinderObject | WallPanel


def euler_matrix(angles: tuple[float, float, float]) -> np.ndarray:
    """``Rz(γ) @ Ry(β) @ Rx(α)`` [3, 3] for ``angles = (α, β, γ)`` [rad]."""
    a, b, g = angles
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(g), -math.sin(g), 0], [math.sin(g), math.cos(g), 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class HallContext:
    """What object parsing needs to know about the hall."""

    footprint: np.ndarray  # [V, 2] CCW
    height: float
    frequency: float
    base_dir: Path
    materials: dict  # name -> MaterialSpec, filled while parsing


def _material(t: Table, ctx: HallContext, *, default: object = None, thickness: float = OBJECT_THICKNESS) -> MaterialSpec:
    value = t.raw("material", what='"metal"') if default is None else t.raw("material", default)
    mat = parse_material(value, t.key("material"), default_thickness=thickness, frequency=ctx.frequency)
    register(ctx.materials, mat, t.key("material"))
    return mat


def _check_inside(corners: np.ndarray, z_range: tuple[float, float], key: str, ctx: HallContext, what: str) -> None:
    inside = polygon.contains(ctx.footprint, corners) | (polygon.boundary_distance(ctx.footprint, corners) <= _TOL)
    if not np.all(inside):
        bad = corners[np.flatnonzero(~inside)[0]]
        raise SpecError(key, f"the {what} reaches outside the hall footprint (corner at "
                        f"[{bad[0]:.3f}, {bad[1]:.3f}] m)", "move it or make it smaller")
    lo, hi = z_range
    if lo < -_TOL or hi > ctx.height + _TOL:
        raise SpecError(key, f"the {what} spans z = {lo:.3f} … {hi:.3f} m, outside the hall's 0 … {ctx.height:g} m",
                        "move it or make it lower")


def parse_box(t: Table, kind: str, name: str, ctx: HallContext) -> BoxObject:
    """``kind = "box"``: ``center`` + ``size`` (+ ``yaw_deg``) or ``min`` + ``max``."""
    material = _material(t, ctx)
    if t.has("min") or t.has("max"):
        if t.has("center") or t.has("size") or t.has("yaw_deg"):
            raise SpecError(t.key("min"), "min/max cannot be combined with center/size/yaw_deg",
                            "give either center + size (+ yaw_deg) or min + max")
        lo = t.vector("min", 3, unit="m")
        hi = t.vector("max", 3, unit="m")
        for i in range(3):
            if not hi[i] > lo[i]:
                raise SpecError(f"{t.key('max')}[{i}]", f"{hi[i]:g} must be > min[{i}] = {lo[i]:g}",
                                "max is the box's upper corner")
        center = tuple((a + b) / 2 for a, b in zip(lo, hi))
        size = tuple(b - a for a, b in zip(lo, hi))
        yaw = 0.0
    else:
        center = t.vector("center", 3, unit="m")
        size = t.vector("size", 3, unit="m", minimum=0.0, strict=True)
        yaw = math.radians(t.number("yaw_deg", unit="deg", default=0.0))
    t.finish()
    box = BoxObject(name=name, kind="box", material=material, center=center, size=size, yaw=yaw)  # type: ignore[arg-type]
    _check_inside(box.corners_xy(), box.z_range, t.path, ctx, kind)
    return box


def parse_pillar(t: Table, name: str, ctx: HallContext) -> BoxObject | CylinderObject:
    """``kind = "pillar"``: ``center`` [x, y] with ``radius`` (round) or ``size`` [sx, sy] (square)."""
    material = _material(t, ctx)
    cx, cy = t.vector("center", 2, unit="m")
    height = t.number("height", unit="m", default=ctx.height, minimum=0.0, strict=True)
    base = t.number("base", unit="m", default=0.0)
    if t.has("radius") == t.has("size"):
        raise SpecError(t.key("radius"), "a pillar needs exactly one of 'radius' (round) and 'size' (square)",
                        "write radius = 0.3 or size = [0.4, 0.4]")
    if t.has("radius"):
        radius = t.number("radius", unit="m", minimum=0.0, strict=True)
        segments = t.integer("segments", default=32, minimum=3)
        # 4 triangles per segment (side quad, top and bottom fans), each kept by the build and the check.
        check_memory(mesh_memory(4 * segments), f"{t.key('segments')} = {segments:,} (a round pillar of "
                     f"{4 * segments:,} triangles)", fix="32 to 128 segments make a round pillar (128 facets of a "
                     "0.3 m pillar stand 0.09 mm from the circle)")
        t.finish()
        obj: BoxObject | CylinderObject = CylinderObject(name=name, kind="pillar", material=material, center=(cx, cy),
                                                         radius=radius, base=base, height=height, segments=segments)
    else:
        sx, sy = t.vector("size", 2, unit="m", minimum=0.0, strict=True)
        yaw = math.radians(t.number("yaw_deg", unit="deg", default=0.0))
        t.finish()
        obj = BoxObject(name=name, kind="pillar", material=material, center=(cx, cy, base + height / 2),
                        size=(sx, sy, height), yaw=yaw)
    _check_inside(obj.corners_xy(), obj.z_range, t.path, ctx, "pillar")
    return obj


def parse_shelf(t: Table, name: str, ctx: HallContext) -> BoxObject:
    """``kind = "shelf"``: a solid box-shaped rack standing on the floor, ``center`` [x, y] + ``size``."""
    material = _material(t, ctx)
    cx, cy = t.vector("center", 2, unit="m")
    size = t.vector("size", 3, unit="m", minimum=0.0, strict=True)
    yaw = math.radians(t.number("yaw_deg", unit="deg", default=0.0))
    t.finish()
    box = BoxObject(name=name, kind="shelf", material=material, center=(cx, cy, size[2] / 2), size=size, yaw=yaw)
    _check_inside(box.corners_xy(), box.z_range, t.path, ctx, "shelf")
    return box


def parse_panel(t: Table, kind: str, name: str, ctx: HallContext) -> WallPanel:
    """``kind = "door"``/``"window"``: ``wall`` + ``offset`` (+ ``sill``), or ``position``; ``size`` [w, h]."""
    itu, thickness, sill_default = PANEL_DEFAULTS[kind]
    material = _material(t, ctx, default={"itu": itu, "thickness": thickness}, thickness=thickness)
    width, height = t.vector("size", 2, unit="m", minimum=0.0, strict=True)
    inset = t.number("inset", unit="m", default=0.01, minimum=0.0, strict=True)
    fp = ctx.footprint
    n = len(fp)
    if t.has("wall") == t.has("position"):
        raise SpecError(t.key("wall"), f"a {kind} needs exactly one of 'wall' (+ 'offset') and 'position'",
                        "write wall = 0, offset = 2.5 or position = [x, y, z] (its centre)")
    if t.has("wall"):
        wall = t.integer("wall", minimum=0)
        if wall >= n:
            raise SpecError(t.key("wall"), f"wall {wall} does not exist: the footprint has {n} walls (0 … {n - 1})",
                            "walls are numbered along the counter-clockwise footprint from its first vertex")
        offset = t.number("offset", unit="m", example="<distance of the centre from the wall's start> [m]")
        sill = t.number("sill", unit="m", default=sill_default, minimum=0.0)
    else:
        px, py, pz = t.vector("position", 3, unit="m")
        a = fp
        d = np.roll(fp, -1, axis=0) - fp
        s = np.clip(np.sum((np.array([px, py]) - a) * d, axis=1) / np.sum(d * d, axis=1), 0.0, 1.0)
        dist = np.linalg.norm(a + s[:, None] * d - np.array([px, py]), axis=1)
        wall = int(np.argmin(dist))
        if dist[wall] > PANEL_SNAP:
            raise SpecError(t.key("position"), f"[{px:g}, {py:g}] is {dist[wall]:.3f} m from the nearest wall "
                            f"(wall {wall}); a {kind} must lie within {PANEL_SNAP} m of a wall",
                            "put the position on the wall it belongs to")
        offset = float(s[wall] * np.linalg.norm(d[wall]))
        sill = pz - height / 2
    t.finish()
    panel = WallPanel(name=name, kind=kind, material=material, wall=wall, offset=offset,  # type: ignore[arg-type]
                      width=width, height=height, sill=sill, inset=inset)
    length = float(np.linalg.norm(fp[(wall + 1) % n] - fp[wall]))
    u0, u1 = panel.u_range
    z0, z1 = panel.z_range
    if u0 < -_TOL or u1 > length + _TOL:
        raise SpecError(t.path, f"the {kind} spans {u0:.3f} … {u1:.3f} m along wall {wall}, which is "
                        f"{length:.3f} m long", "change its offset/position or width")
    if z0 < -_TOL or z1 > ctx.height + _TOL:
        raise SpecError(t.path, f"the {kind} spans z = {z0:.3f} … {z1:.3f} m, outside the wall's 0 … {ctx.height:g} m",
                        "change its sill/position or height")
    return panel


def parse_mesh(t: Table, index: int, ctx: HallContext) -> ImportedMesh:
    """One ``[[meshes]]`` table."""
    file_str = t.string("file")
    file = (ctx.base_dir / file_str).resolve()
    if not file.is_relative_to(ctx.base_dir.resolve()):
        raise SpecError(t.key("file"), f"{file_str!r} lies outside the spec's folder {ctx.base_dir}",
                        "copy the mesh into the spec's folder (e.g. parts/) and give its path relative to the spec, "
                        "so the scene folder is self-contained")
    if file.suffix.lower() not in MESH_SUFFIXES:
        raise SpecError(t.key("file"), f"{file_str!r} is not a mesh type trimesh reads here",
                        f"use one of {', '.join(MESH_SUFFIXES)}")
    if not file.is_file():
        raise SpecError(t.key("file"), f"{file} does not exist", "give the path relative to the spec file")
    default_name = re.sub(r"[^A-Za-z0-9_-]", "_", file.stem)
    if not re.match(r"^[A-Za-z]", default_name):
        default_name = f"mesh_{index}"
    name = check_name(t.string("name", default=default_name), t.key("name"), what="object")
    if t.has("scale") and isinstance(t.raw("scale"), list):
        scale = t.vector("scale", 3, unit="m per file unit", minimum=0.0, strict=True)
    else:
        s = check_number(t.raw("scale", 1.0), t.key("scale"), unit="m per file unit", minimum=0.0, strict=True)
        scale = (s, s, s)
    translate = t.vector("translate", 3, unit="m", default=(0.0, 0.0, 0.0))
    rot_deg = t.vector("rotate_deg", 3, unit="deg", default=(0.0, 0.0, 0.0))
    material = _material(t, ctx)
    t.finish()
    return ImportedMesh(name=name, file=file, material=material, scale=scale, translate=translate,
                        rotation=tuple(math.radians(a) for a in rot_deg))  # type: ignore[arg-type]


OBJECT_KINDS = ("box", "pillar", "shelf", "door", "window")


def parse_object(t: Table, index: int, ctx: HallContext) -> HallObject:
    """One ``[[objects]]`` table, dispatched on ``kind``."""
    kind = t.string("kind", choices=OBJECT_KINDS)
    name = check_name(t.string("name", default=f"{kind}_{index}"), t.key("name"), what="object")
    if kind == "box":
        return parse_box(t, kind, name, ctx)
    if kind == "pillar":
        return parse_pillar(t, name, ctx)
    if kind == "shelf":
        return parse_shelf(t, name, ctx)
    return parse_panel(t, kind, name, ctx)

