"""Geometry rules of :func:`~.check.check_scene`: mesh quality, imported meshes, closure of the hall."""

from __future__ import annotations

import math

import numpy as np

from . import polygon
from .geometry import HallGeometry
from .issues import Issue, format_point
from .meshcheck import mesh_report
from .objects import WallPanel
from .spec import HallSpec

__all__ = ["mesh_issues", "import_issues", "open_issues", "UNITS_FACTOR", "UNITS_LIMIT", "PLACEMENT_TOL", "OPEN_RAYS"]

#: An imported mesh larger than this many hall sizes, or than :data:`UNITS_LIMIT`, is in the wrong unit.
UNITS_FACTOR = 10.0
#: [m].
UNITS_LIMIT = 100.0
#: How far an imported mesh may poke through the shell before it counts as outside [m].
PLACEMENT_TOL = 1e-3
#: Number of directions of the closure test, per interior point.
OPEN_RAYS = 128


def _kinds(spec: HallSpec) -> dict[str, str]:
    kinds = {"floor": "floor", "ceiling": "ceiling", **{w: "wall" for w in spec.wall_names}}
    kinds.update({o.name: o.kind for o in spec.objects})
    kinds.update({m.name: "mesh" for m in spec.meshes})
    return kinds


def mesh_issues(spec: HallSpec, geo: HallGeometry) -> list[Issue]:
    out = []
    kinds = _kinds(spec)
    for name in geo.names:
        mesh = geo.meshes[name]
        rep = mesh_report(np.asarray(mesh.vertices), np.asarray(mesh.faces))
        what = f"{kinds.get(name, 'object')} '{name}'"
        if len(rep.degenerate):
            i = int(rep.degenerate[0])
            corners = ", ".join(format_point(c) for c in np.asarray(mesh.vertices)[mesh.faces[i]])
            out.append(Issue(
                "error", "mesh.degenerate", name,
                f"{len(rep.degenerate)} of the {rep.num_faces} faces of {what} are degenerate (zero area, or all "
                f"three corners on one line), e.g. face {i} with corners {corners} m: such a face has no normal, "
                "so sionna-rt cannot reflect a ray off it",
                "remove them and re-export the mesh (trimesh: mesh.update_faces(mesh.nondegenerate_faces()); "
                "Blender: Mesh > Clean Up > Degenerate Dissolve)"))
        if len(rep.non_manifold):
            a, b = rep.non_manifold[0]
            out.append(Issue(
                "error", "mesh.non_manifold", name,
                f"{what} has {len(rep.non_manifold)} non-manifold edge(s), shared by three or more faces, e.g. "
                f"{format_point(a)} – {format_point(b)} m: its inside and outside are undefined",
                "split it into separate closed parts or delete the extra faces (Blender: Select > All by Trait > "
                "Non Manifold), then re-export"))
        if rep.misoriented_edges:
            out.append(Issue(
                "error", "mesh.flipped", name,
                f"{what} is wound inconsistently: across {rep.misoriented_edges} edge(s) neighbouring faces point "
                "their normals to opposite sides",
                "make the normals consistent (trimesh.repair.fix_normals(mesh); Blender: Mesh > Normals > "
                "Recalculate Outside) and re-export"))
        elif rep.flipped:
            out.append(Issue(
                "error", "mesh.flipped", name,
                f"the closed {what} has inward-facing normals (signed volume {rep.volume:.4g} m³ < 0), usually a "
                "mirrored export",
                "flip its faces (trimesh: mesh.invert(); Blender: Mesh > Normals > Recalculate Outside) and "
                "re-export; check that no axis was mirrored on export"))
    return out


def _hall_size(spec: HallSpec) -> float:
    return float(max(np.ptp(spec.footprint_array, axis=0).max(), spec.height))


def import_issues(spec: HallSpec, geo: HallGeometry) -> list[Issue]:
    out = []
    size = _hall_size(spec)
    limit = min(UNITS_FACTOR * size, UNITS_LIMIT)
    fp = spec.footprint_array
    for i, m in enumerate(spec.meshes):
        if m.name not in geo.meshes:
            continue
        mesh = geo.meshes[m.name]
        lo, hi = mesh.bounds
        extent = float(np.max(hi - lo))
        scale = m.scale[0] if len(set(m.scale)) == 1 else None
        scale_text = f"scale {scale:g}" if scale is not None else f"scale {list(m.scale)}"
        if extent > limit:
            new = f"{scale * 1e-3:g}" if scale is not None else str([s * 1e-3 for s in m.scale])
            out.append(Issue(
                "error", "mesh.units", m.name,
                f"mesh '{m.name}' ({m.file.name}) is {extent:.4g} m across after {scale_text}, {extent / size:.0f} "
                f"times the hall ({size:g} m): its file is in millimetres, not metres",
                f"set scale = {new} in meshes[{i}] (metres per file unit); it will then be "
                f"{extent * 1e-3:.3g} m across"))
            continue
        v = np.asarray(mesh.vertices)
        problems = []
        if lo[2] < -PLACEMENT_TOL:
            problems.append(f"reaches {-lo[2]:.3f} m below the floor")
        if hi[2] > spec.height + PLACEMENT_TOL:
            problems.append(f"reaches {hi[2] - spec.height:.3f} m above the ceiling")
        xy = v[:, :2]
        out_xy = ~(polygon.contains(fp, xy) | (polygon.boundary_distance(fp, xy) <= PLACEMENT_TOL))
        if np.any(out_xy):
            far = xy[out_xy][np.argmax(polygon.boundary_distance(fp, xy[out_xy]))]
            problems.append(f"leaves the footprint (vertex at [{far[0]:.3f}, {far[1]:.3f}] m is "
                            f"{polygon.boundary_distance(fp, far[None, :])[0]:.3f} m outside)")
        if problems:
            out.append(Issue(
                "error", "mesh.placement", m.name,
                f"mesh '{m.name}' ({m.file.name}, bounds {format_point(lo)} … {format_point(hi)} m after the transform) "
                + " and ".join(problems),
                f"fix translate / rotate_deg in meshes[{i}] (p' = Rz Ry Rx (scale·p) + translate); a file "
                "exported y-up stands upright with rotate_deg = [90, 0, 0]"))
    return out


# ---------------------------------------------------------------------------------------------
# Closure of the hall


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit directions [n, 3]."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = math.pi * (1 + math.sqrt(5)) * k
    r = np.sqrt(1 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _interior_points(spec: HallSpec) -> np.ndarray:
    """Points spread over the hall [P, 3] [m], at least 0.3 m from the walls, plus the radars and RIS."""
    fp = spec.footprint_array
    lo, hi = fp.min(axis=0), fp.max(axis=0)
    step = float(np.max(hi - lo)) / 8
    xs = np.arange(lo[0] + step / 2, hi[0], step)
    ys = np.arange(lo[1] + step / 2, hi[1], step)
    xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    xy = xy[polygon.contains(fp, xy) & (polygon.boundary_distance(fp, xy) > min(0.3, step / 4))]
    pts = [np.column_stack([xy, np.full(len(xy), z)]) for z in (spec.height / 3, 2 * spec.height / 3)]
    extra = [spec.radar_positions(), np.array([r.position for r in spec.ris]).reshape(-1, 3)]
    return np.vstack(pts + extra)


def _exit_surface(spec: HallSpec, p: np.ndarray, d: np.ndarray) -> tuple[str, np.ndarray]:
    """Which shell surface of the ideal prism (footprint × [0, height]) a ray from inside leaves through."""
    best, name = math.inf, "?"
    if d[2] < 0:
        best, name = -p[2] / d[2], "floor"
    elif d[2] > 0:
        best, name = (spec.height - p[2]) / d[2], "ceiling"
    fp = spec.footprint_array
    for i in range(len(fp)):
        a, e = fp[i], fp[(i + 1) % len(fp)] - fp[i]
        den = d[0] * e[1] - d[1] * e[0]
        if abs(den) < 1e-12:
            continue
        r = a - p[:2]
        t = (r[0] * e[1] - r[1] * e[0]) / den
        s = (r[0] * d[1] - r[1] * d[0]) / den
        if 0 < t < best and -1e-9 <= s <= 1 + 1e-9:
            best, name = t, f"wall_{i}"
    return name, p + best * d


def _closure_geometry(spec: HallSpec, geo: HallGeometry) -> HallGeometry:
    """The shell, with each door/window panel moved into its wall plane (the 1 cm inset leaves a slit
    that rays could leak through; the panel does close the hole)."""
    shell = ["floor", "ceiling", *spec.wall_names]
    fp = spec.footprint_array
    tris, owner = [], []
    for k, name in enumerate(geo.names):
        t = geo.triangles[geo.owner == k]
        if name in shell:
            tris.append(t)
        else:
            panel = next((o for o in spec.objects if isinstance(o, WallPanel) and o.name == name), None)
            if panel is None:
                continue
            a, b = fp[panel.wall], fp[(panel.wall + 1) % len(fp)]
            e = (b - a) / np.linalg.norm(b - a)
            n_in = np.array([-e[1], e[0], 0.0])
            t = t - ((t[..., :2] - a) @ n_in[:2])[..., None] * n_in
            tris.append(t)
        owner.append(np.full(len(t), k))
    return HallGeometry(xml_path=geo.xml_path, names=geo.names, materials=geo.materials, thickness=geo.thickness,
                        meshes=geo.meshes, triangles=np.concatenate(tris), owner=np.concatenate(owner), closed=())


def open_issues(spec: HallSpec, geo: HallGeometry) -> list[Issue]:
    fp = spec.footprint_array
    shell = ["floor", "ceiling", *spec.wall_names]
    problems: dict[str, list[str]] = {name: [] for name in shell}
    # 1. Each surface must exist and cover its area (minus the holes its doors and windows close).
    for name in shell:
        if name not in geo.meshes:
            problems[name].append(f"scene.xml has no shape 'mesh-{name}'")
            continue
        if name in ("floor", "ceiling"):
            expected = abs(polygon.signed_area(fp))
        else:
            i = int(name.split("_")[1])
            length = float(np.linalg.norm(fp[(i + 1) % len(fp)] - fp[i]))
            holes = sum(o.width * o.height for o in spec.objects if isinstance(o, WallPanel) and o.wall == i)
            expected = length * spec.height - holes
        area = float(geo.meshes[name].area)
        if area < expected - max(1e-3, 1e-5 * expected):
            problems[name].append(f"covers {area:.3f} m² of the {expected:.3f} m² it must close")
    # 2. Rays from inside must hit the shell (or a door/window panel) in every direction.
    closure = _closure_geometry(spec, geo)
    dirs = _fibonacci_sphere(OPEN_RAYS)
    pts = _interior_points(spec)
    escapes: dict[str, list[np.ndarray]] = {}
    for p in pts:
        dist, _ = closure.ray_hits(p, dirs)
        for j in np.flatnonzero(~np.isfinite(dist)):
            surface, at = _exit_surface(spec, p, dirs[j])
            escapes.setdefault(surface, []).append(at)
    total = len(pts) * len(dirs)
    for surface, where in escapes.items():
        problems.setdefault(surface, []).append(
            f"{len(where)} of {total} test rays from inside leave the scene through it, e.g. at {format_point(where[0])} m")
    out = []
    for name, found in problems.items():
        if not found:
            continue
        if name.startswith("wall_"):
            i = int(name.split("_")[1])
            a, b = fp[i], fp[(i + 1) % len(fp)]
            span = f"footprint edge {i} from [{a[0]:g}, {a[1]:g}] to [{b[0]:g}, {b[1]:g}] m, 0 … {spec.height:g} m high"
        else:
            span = f"the footprint at z = {0.0 if name == 'floor' else spec.height:g} m"
        out.append(Issue("error", "hall.open", name,
                         f"the hall is open where {name} should be ({span}): " + "; ".join(found),
                         "the floor, ceiling and every wall must close the hall; rebuild the folder from its spec "
                         "(risloc scene build SPEC) instead of editing scene.xml or the meshes"))
    return out
