"""A built scene's triangles as numpy, for the simulator's input checks (no sionna, no rtree).

:func:`load_geometry` reads ``scene.xml`` and the PLY files it references with trimesh;
:meth:`HallGeometry.check_point` refuses a radar or RIS position outside the hall, inside a closed
object, or closer than a clearance to any surface, with a message that names the surface, the
distance and the fix.

Rays are intersected with a vectorised Möller–Trumbore test and distances come from
``trimesh.triangles.closest_point`` (trimesh's own ray module needs rtree, which is not a
dependency). Inside/outside of a closed object is its generalised winding number, which needs no
ray and cannot be fooled by a ray grazing an edge.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
import trimesh

from dsp.validation import as_finite_array

from ._parse import SpecError

__all__ = ["HallGeometry", "load_geometry", "PROBE_DIRECTIONS"]

#: Directions of the escape test: ±x, ±y, ±z and the 8 cube diagonals [14, 3], unit.
PROBE_DIRECTIONS = np.vstack([
    np.eye(3), -np.eye(3),
    np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]) / math.sqrt(3),
])
#: Barycentric slack of the ray test, so that a ray through a shared edge hits at least one side.
_EDGE_SLACK = 1e-9
#: Hits nearer than this along the ray are ignored [m].
_T_MIN = 1e-9


def _fmt(p: np.ndarray) -> str:
    return "[" + ", ".join(f"{v + 0.0:.3f}" for v in p) + "]"  # + 0.0 turns -0.0 into 0.0


@dataclass(frozen=True, eq=False)
class HallGeometry:
    """Triangles of a built scene, grouped by object.

    Attributes
    ----------
    xml_path : Path
    names : tuple of str
        Object names in XML order.
    materials : mapping
        Object name -> material name.
    thickness : mapping
        Object name -> its material's slab thickness [m] (NaN if the XML gives none).
    meshes : mapping
        Object name -> ``trimesh.Trimesh`` (vertices merged).
    triangles : float array [T, 3, 3]
        All triangles, world frame [m].
    owner : int array [T]
        Index into ``names`` of each triangle's object.
    closed : tuple of str
        Objects whose mesh is watertight (boxes, pillars, closed imported meshes).
    """

    xml_path: Path
    names: tuple[str, ...]
    materials: Mapping[str, str]
    thickness: Mapping[str, float]
    meshes: Mapping[str, trimesh.Trimesh]
    triangles: np.ndarray
    owner: np.ndarray
    closed: tuple[str, ...]

    @classmethod
    def from_xml(cls, xml_path: str | Path) -> "HallGeometry":
        """Load the ``ply`` shapes of a Mitsuba scene (paths relative to the XML's folder)."""
        xml_path = Path(xml_path).resolve()
        root = ET.parse(xml_path).getroot()
        mat_thickness: dict[str, float] = {}
        for bsdf in root.iter("bsdf"):
            bid = bsdf.get("id", "")
            t = bsdf.find("float[@name='thickness']")
            mat_thickness[bid] = float(t.get("value")) if t is not None else math.nan
        names, materials, thickness, meshes = [], {}, {}, {}
        for shape in root.iter("shape"):
            if shape.get("type") != "ply":
                raise ValueError(f"{xml_path}: shape {shape.get('id')!r} has type {shape.get('type')!r}; "
                                 "only 'ply' shapes are supported (scenes from risloc_rt.authoring.build)")
            sid = shape.get("id", "")
            name = sid[5:] if sid.startswith("mesh-") else sid
            fname = shape.find("string[@name='filename']")
            ref = shape.find("ref")
            if fname is None:
                raise ValueError(f"{xml_path}: shape {sid!r} has no filename")
            mesh = trimesh.load_mesh(xml_path.parent / fname.get("value", ""), process=True)
            bsdf_id = ref.get("id", "") if ref is not None else ""
            names.append(name)
            materials[name] = bsdf_id[4:] if bsdf_id.startswith("mat-") else bsdf_id
            thickness[name] = mat_thickness.get(bsdf_id, math.nan)
            meshes[name] = mesh
        if not names:
            raise ValueError(f"{xml_path}: the scene has no shapes")
        tris = np.concatenate([np.asarray(meshes[n].triangles, dtype=float) for n in names])
        owner = np.concatenate([np.full(len(meshes[n].faces), i) for i, n in enumerate(names)])
        closed = tuple(n for n in names if meshes[n].is_watertight)
        return cls(xml_path=xml_path, names=tuple(names), materials=MappingProxyType(materials),
                   thickness=MappingProxyType(thickness), meshes=MappingProxyType(meshes),
                   triangles=tris, owner=owner, closed=closed)

    @property
    def bounds(self) -> np.ndarray:
        """Axis-aligned bounds of the whole scene [2, 3] (min, max) [m]."""
        flat = self.triangles.reshape(-1, 3)
        return np.stack([flat.min(axis=0), flat.max(axis=0)])

    def ray_hits(self, origin: Any, directions: Any) -> tuple[np.ndarray, np.ndarray]:
        """First surface hit along rays from one origin.

        Parameters
        ----------
        origin : float array [3]
            [m].
        directions : float array [R, 3]
            Unit directions.

        Returns
        -------
        distance : float array [R]
            Distance to the first hit [m], ``inf`` where the ray escapes.
        owner : int array [R]
            Index into ``names`` of the surface hit, -1 where the ray escapes.
        """
        o = as_finite_array(origin, "origin", shape=(3,))
        d = as_finite_array(directions, "directions", shape=(None, 3))
        # Blocks of triangles keep the [R, T] temporaries near RAY_BLOCK elements (~100 B each), whatever
        # the scene's size; strict '<' keeps the first triangle of equal distance, as one argmin would.
        best = np.full(len(d), np.inf)
        owner = np.full(len(d), -1, dtype=np.int64)
        step = max(1, RAY_BLOCK // max(len(d), 1))
        for start in range(0, len(self.triangles), step):
            dist, first = _first_hits(o, d, self.triangles[start:start + step])
            better = dist < best
            best[better] = dist[better]
            owner[better] = self.owner[start + first[better]]
        return best, owner

    def first_hit(self, origin: Any, direction: Any) -> tuple[str | None, float]:
        """(object name, distance [m]) of the first surface along one ray; ``(None, inf)`` if it escapes."""
        d = as_finite_array(direction, "direction", shape=(3,))
        dist, who = self.ray_hits(origin, (d / np.linalg.norm(d))[None, :])
        return (self.names[who[0]] if who[0] >= 0 else None), float(dist[0])

    def nearest_surface(self, point: Any) -> tuple[str, float]:
        """(object name, distance [m]) of the surface closest to ``point`` [3]."""
        p = as_finite_array(point, "point", shape=(3,))
        closest = trimesh.triangles.closest_point(self.triangles, np.broadcast_to(p, (len(self.triangles), 3)))
        dist = np.linalg.norm(closest - p, axis=1)
        k = int(np.argmin(dist))
        return self.names[self.owner[k]], float(dist[k])

    def enclosing_object(self, point: Any) -> str | None:
        """Name of the closed object containing ``point`` [3], or ``None``.

        Notes
        -----
        Generalised winding number w = Σ Ω_t / 4π over the object's triangles, with the solid
        angle of a triangle (a, b, c) seen from the point (Van Oosterom & Strackee)
        ``Ω = 2 atan2(a·(b×c), |a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|)``; |w| ≈ 1 inside,
        0 outside, either winding.
        """
        p = as_finite_array(point, "point", shape=(3,))
        for name in self.closed:
            tri = np.asarray(self.meshes[name].triangles, dtype=float) - p
            a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
            la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
            num = np.einsum("ij,ij->i", a, np.cross(b, c))
            den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb \
                + np.einsum("ij,ij->i", b, c) * la
            if abs(np.sum(2 * np.arctan2(num, den)) / (4 * np.pi)) > 0.5:
                return name
        return None

    def check_point(self, point: Any, *, what: str = "radar", clearance: float = 0.05) -> None:
        """Refuse a position outside the hall, inside a closed object, or too near a surface.

        Parameters
        ----------
        point : float array [3]
            World frame [m].
        what : str
            What the point is (``"radar"``, ``"ris0"``), for the message.
        clearance : float
            Minimum distance to every surface [m]; 0.05 m keeps an antenna out of a wall slab.

        Raises
        ------
        SpecError
            (a ``ValueError``) naming ``what``, the nearest object, its distance and the fix.

        Notes
        -----
        "Outside" means one of the 14 :data:`PROBE_DIRECTIONS` rays leaves the scene without
        hitting a surface: true outside a closed hall (the vertical rays escape above or below
        a prism-shaped hall, or beside it) and inside a hall that has an opening.
        """
        p = as_finite_array(point, "point", shape=(3,))
        if not clearance >= 0:
            raise ValueError(f"clearance={clearance!r} must be >= 0 [m]")
        near, dist = self.nearest_surface(p)
        dists, _ = self.ray_hits(p, PROBE_DIRECTIONS)
        escaping = np.flatnonzero(~np.isfinite(dists))
        if len(escaping):
            lo, hi = self.bounds
            dirs = ", ".join(_fmt(PROBE_DIRECTIONS[i]).replace(".000", "") for i in escaping[:3])
            slab = self.thickness.get(near, math.nan)
            inside_slab = (f"; the nearest surface, '{near}', is {dist:.3f} m away: the point is inside its "
                           f"{slab:g} m thick {self.materials[near]} slab" if dist <= slab else "")
            raise SpecError(what, f"position {_fmt(p)} m is outside the hall: rays toward {dirs} leave the scene "
                            f"without hitting a surface (the scene spans x {lo[0]:g} … {hi[0]:g}, y {lo[1]:g} … "
                            f"{hi[1]:g}, z {lo[2]:g} … {hi[2]:g} m){inside_slab}",
                            f"move the {what} inside the hall; if it is inside, the hall has an opening "
                            "(a missing wall, floor or ceiling)")
        inside = self.enclosing_object(p)
        if inside is not None:
            lo, hi = self.meshes[inside].bounds
            raise SpecError(what, f"position {_fmt(p)} m is inside the closed object '{inside}' "
                            f"(bounds {_fmt(lo)} … {_fmt(hi)} m)",
                            f"move the {what} out of the object, at least {clearance:g} m from its surface")
        if dist < clearance:
            raise SpecError(what, f"position {_fmt(p)} m is {dist:.3f} m from '{near}' ({self.materials[near]}), "
                            f"closer than the clearance {clearance:g} m (touching or inside the surface)",
                            f"move the {what} at least {clearance - dist:.3f} m further from '{near}', into the hall")

    def check_points(self, points: Any, *, what: str = "radar", clearance: float = 0.05) -> None:
        """:meth:`check_point` for each row of ``points`` [P, 3]; ``what`` gets the row index."""
        pts = as_finite_array(points, "points", shape=(None, 3))
        for i, p in enumerate(pts):
            self.check_point(p, what=f"{what}[{i}]" if len(pts) > 1 else what, clearance=clearance)


def load_geometry(xml_path: str | Path) -> HallGeometry:
    """:meth:`HallGeometry.from_xml`."""
    return HallGeometry.from_xml(xml_path)


#: Ray-triangle pairs :meth:`HallGeometry.ray_hits` tests at once (about 100 bytes each).
RAY_BLOCK = 1 << 18


def _first_hits(o: np.ndarray, d: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Möller-Trumbore: distance [R] to the first of ``triangles`` [T, 3, 3] hit by the rays ``o + t d``
    (``inf`` where none is) and its index into ``triangles`` [R]."""
    v0 = triangles[:, 0]  # [T, 3]
    e1, e2 = triangles[:, 1] - v0, triangles[:, 2] - v0
    p = np.cross(d[:, None, :], e2[None, :, :])  # [R, T, 3]
    det = np.einsum("tk,rtk->rt", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - v0  # [T, 3]
    u = np.einsum("tk,rtk->rt", s, p) * inv
    q = np.cross(s, e1)  # [T, 3]
    v = (d @ q.T) * inv
    t = (q * e2).sum(axis=1)[None, :] * inv
    hit = ok & (u >= -_EDGE_SLACK) & (v >= -_EDGE_SLACK) & (u + v <= 1 + _EDGE_SLACK) & (t > _T_MIN)
    t = np.where(hit, t, np.inf)
    first = np.argmin(t, axis=1)
    dist = t[np.arange(len(d)), first]
    return dist, first
