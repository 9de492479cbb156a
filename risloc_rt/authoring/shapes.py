"""Triangle meshes of a hall spec: floor, ceiling, walls (with door/window holes), objects.

Winding conventions (sionna-rt ignores them, FINDINGS §2, but :mod:`.geometry` and the tests use
them): the shell's normals point into the hall (floor +z, ceiling -z, walls inward), closed
objects' normals point out of the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dsp.budget import check_memory

from . import polygon
from ._parse import SpecError
from .materials import MaterialSpec
from .meshcheck import mesh_memory
from .objects import BoxObject, CylinderObject, ImportedMesh, WallPanel

if TYPE_CHECKING:
    from .spec import HallSpec

__all__ = ["SceneMesh", "scene_meshes", "box_mesh", "cylinder_mesh", "wall_mesh"]

#: Box faces over corners (-,-,-) (+,-,-) (+,+,-) (-,+,-) then the same at +z; normals outward.
_BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [2, 3, 7], [2, 7, 6], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class SceneMesh:
    """One scene object's triangles.

    Attributes
    ----------
    name : str
        Object name (``mesh-<name>`` in the XML, ``<name>`` in sionna-rt).
    kind : str
        ``floor``, ``ceiling``, ``wall``, ``box``, ``pillar``, ``shelf``, ``door``, ``window`` or ``mesh``.
    material : MaterialSpec
    vertices : float array [V, 3]
        World frame [m].
    faces : int array [F, 3]
        Vertex indices per triangle.
    """

    name: str
    kind: str
    material: MaterialSpec
    vertices: np.ndarray
    faces: np.ndarray


def box_mesh(center: tuple[float, ...], size: tuple[float, ...], yaw: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Closed box, 8 vertices [8, 3] [m] and 12 outward triangles [12, 3].

    Parameters
    ----------
    center, size : float [3]
        Centre and edge lengths [m].
    yaw : float
        Rotation about the vertical through the centre [rad].
    """
    h = np.asarray(size, dtype=float) / 2
    sx = np.array([-1, 1, 1, -1, -1, 1, 1, -1], dtype=float)
    sy = np.array([-1, -1, 1, 1, -1, -1, 1, 1], dtype=float)
    sz = np.array([-1, -1, -1, -1, 1, 1, 1, 1], dtype=float)
    local = np.column_stack([sx * h[0], sy * h[1], sz * h[2]])
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return local @ rot.T + np.asarray(center, dtype=float), _BOX_FACES.copy()


def cylinder_mesh(center: tuple[float, float], radius: float, z0: float, z1: float,
                  segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed prism inscribed in a cylinder: vertices [2S + 2, 3] [m], outward triangles [4S, 3]."""
    a = 2 * np.pi * np.arange(segments) / segments
    ring = np.column_stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)])
    verts = np.vstack([np.column_stack([ring, np.full(segments, z0)]), np.column_stack([ring, np.full(segments, z1)]),
                       [[center[0], center[1], z0], [center[0], center[1], z1]]])
    k = np.arange(segments)
    k1 = (k + 1) % segments
    bc, tc = 2 * segments, 2 * segments + 1
    faces = np.vstack([
        np.column_stack([k, k1, k1 + segments]),  # sides
        np.column_stack([k, k1 + segments, k + segments]),
        np.column_stack([np.full(segments, tc), k + segments, k1 + segments]),  # top, +z
        np.column_stack([np.full(segments, bc), k1, k]),  # bottom, -z
    ])
    return verts, faces.astype(np.int64)


def _rect_faces_inward(n_verts: int) -> np.ndarray:
    return np.array([[0, 2, 1], [0, 3, 2]], dtype=np.int64) + n_verts


#: Python objects per wall cell while :func:`wall_mesh` builds it (a vertex tuple, its index entry,
#: two face lists) [bytes], besides the two triangles' :data:`.meshcheck.FACE_BYTES`.
WALL_CELL_BYTES = 400


def wall_mesh(p0: np.ndarray, p1: np.ndarray, height: float,
              holes: list[tuple[float, float, float, float]], *, where: str = "wall") -> tuple[np.ndarray, np.ndarray]:
    """Vertical wall over footprint edge p0 -> p1 (CCW footprint), with rectangular holes.

    Parameters
    ----------
    p0, p1 : float array [2]
        Edge end points [m].
    height : float
        [m].
    holes : list of (u0, u1, z0, z1)
        Openings, u along the edge from p0, z above the floor [m].
    where : str
        The wall, for the memory error (``"spec.toml: wall_1"``).

    Returns
    -------
    vertices [V, 3], faces [F, 3]
        One quad (two triangles) without holes; otherwise the grid of cells between all hole
        edges, minus the cells inside a hole (no T-junctions). Normals point into the hall.

    Raises
    ------
    dsp.budget.BudgetError
        The grid of ``C`` cells would need more than the memory limit: ``C · (WALL_CELL_BYTES + 2 ·
        FACE_BYTES)`` bytes (:data:`WALL_CELL_BYTES`, :func:`.meshcheck.mesh_memory`), checked before it is made.
    """
    e = p1 - p0
    length = float(np.linalg.norm(e))
    e = e / length
    us = np.unique(np.clip([0.0, length, *[v for h in holes for v in h[:2]]], 0.0, length))
    zs = np.unique(np.clip([0.0, height, *[v for h in holes for v in h[2:]]], 0.0, height))
    cells = (len(us) - 1) * (len(zs) - 1)
    check_memory(cells * WALL_CELL_BYTES + mesh_memory(2 * cells),
                 f"{where}: {len(holes):,} doors/windows cut it into {len(us) - 1:,} x {len(zs) - 1:,} = {cells:,} cells",
                 fix="use fewer doors and windows on one wall, or line them up (equal sills and heights share cells)")
    index: dict[tuple[int, int], int] = {}
    verts: list[tuple[float, float, float]] = []
    faces: list[list[int]] = []

    def vid(i: int, j: int) -> int:
        if (i, j) not in index:
            index[(i, j)] = len(verts)
            verts.append((p0[0] + us[i] * e[0], p0[1] + us[i] * e[1], zs[j]))
        return index[(i, j)]

    for i in range(len(us) - 1):
        for j in range(len(zs) - 1):
            uc, zc = (us[i] + us[i + 1]) / 2, (zs[j] + zs[j + 1]) / 2
            if any(h[0] < uc < h[1] and h[2] < zc < h[3] for h in holes):
                continue
            a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
            faces += [[a, c, b], [a, d, c]]  # clockwise in (u, z): normal = ẑ × e, into the hall
    return np.asarray(verts, dtype=float), np.asarray(faces, dtype=np.int64)


def _panel_mesh(spec: "HallSpec", panel: WallPanel) -> tuple[np.ndarray, np.ndarray]:
    fp = spec.footprint_array
    p0, p1 = fp[panel.wall], fp[(panel.wall + 1) % len(fp)]
    e = (p1 - p0) / np.linalg.norm(p1 - p0)
    n_in = np.array([-e[1], e[0]])
    (u0, u1), (z0, z1) = panel.u_range, panel.z_range
    corners = [(u0, z0), (u1, z0), (u1, z1), (u0, z1)]
    verts = np.array([[*(p0 + u * e + panel.inset * n_in), z] for u, z in corners])
    return verts, _rect_faces_inward(0)


def _imported(m: ImportedMesh, key: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        mesh = trimesh.load_mesh(m.file)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise SpecError(key, f"trimesh cannot read {m.file}: {exc}", "check the file and its format") from None
    if isinstance(mesh, trimesh.Scene):  # pragma: no cover - load_mesh concatenates scenes
        mesh = mesh.to_mesh()
    if len(mesh.faces) == 0:
        raise SpecError(key, f"{m.file} has no triangles", "export the mesh with its faces")
    verts = np.asarray(mesh.vertices, dtype=float) @ m.matrix[:3, :3].T + m.matrix[:3, 3]
    return verts, np.asarray(mesh.faces, dtype=np.int64)


def scene_meshes(spec: "HallSpec") -> list[SceneMesh]:
    """Every scene object's triangles, in :attr:`HallSpec.object_names` order."""
    fp = spec.footprint_array
    h = spec.height
    tri = polygon.triangulate(fp)
    floor_v = np.column_stack([fp, np.zeros(len(fp))])
    ceil_v = np.column_stack([fp, np.full(len(fp), h)])
    out = [SceneMesh("floor", "floor", spec.materials.floor, floor_v, tri),
           SceneMesh("ceiling", "ceiling", spec.materials.ceiling, ceil_v, tri[:, ::-1].copy())]
    panels = [o for o in spec.objects if isinstance(o, WallPanel)]
    for i in range(len(fp)):
        holes = [(*p.u_range, *p.z_range) for p in panels if p.wall == i]
        v, f = wall_mesh(fp[i], fp[(i + 1) % len(fp)], h, holes,
                         where=f"{spec.source_path or spec.name}: wall_{i}" if holes else f"wall_{i}")
        out.append(SceneMesh(f"wall_{i}", "wall", spec.materials.walls, v, f))
    for obj in spec.objects:
        if isinstance(obj, BoxObject):
            v, f = box_mesh(obj.center, obj.size, obj.yaw)
        elif isinstance(obj, CylinderObject):
            v, f = cylinder_mesh(obj.center, obj.radius, obj.base, obj.base + obj.height, obj.segments)
        else:
            v, f = _panel_mesh(spec, obj)
        out.append(SceneMesh(obj.name, obj.kind, obj.material, v, f))
    for i, m in enumerate(spec.meshes):
        v, f = _imported(m, f"meshes[{i}].file")
        out.append(SceneMesh(m.name, "mesh", m.material, v, f))
    return out
