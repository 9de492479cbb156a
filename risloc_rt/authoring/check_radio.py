"""Radio rules of :func:`~.check.check_scene`: radar and RIS placement, the sweep, grating lobes, range."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from dsp import SPEED_OF_LIGHT, BeamSweep, RadarConfig

from .geometry import HallGeometry
from .issues import Issue, Level, format_point, name_list
from .spec import HallSpec

__all__ = ["position_issues", "ris_issues", "range_issues", "RADAR_CLEARANCE", "RIS_FREE_AHEAD"]

#: Minimum distance of a radar from every surface [m]: keeps the antenna out of a wall slab.
RADAR_CLEARANCE = 0.05
#: Free space a RIS needs in front of it along its boresight [m].
RIS_FREE_AHEAD = 1.0


def _ris_clearance(r) -> float:
    """5 cm plus the panel's half-diagonal [m]."""
    return RADAR_CLEARANCE + 0.5 * math.hypot(r.panel.width, r.panel.height)


def position_issues(spec: HallSpec, geo: HallGeometry) -> list[Issue]:
    out = []
    for i, p in enumerate(spec.radar_positions()):
        what = f"radar.positions[{i}]"
        inside = geo.enclosing_object(p)
        if inside is not None:
            lo, hi = geo.meshes[inside].bounds
            out.append(Issue("error", "position.inside", what,
                             f"the radar at {format_point(p)} m is inside the closed object '{inside}' "
                             f"(bounds {format_point(lo)} … {format_point(hi)} m)",
                             f"move it out of '{inside}', at least {RADAR_CLEARANCE:g} m from its surface"))
            continue
        near, dist = geo.nearest_surface(p)
        if dist < RADAR_CLEARANCE:
            out.append(Issue("error", "position.clearance", what,
                             f"the radar at {format_point(p)} m is {dist:.3f} m from '{near}', "
                             f"closer than {RADAR_CLEARANCE:g} m: "
                             "the antenna would sit in the surface's slab, and sionna-rt drops path segments "
                             "shorter than 1 cm",
                             f"move it at least {RADAR_CLEARANCE - dist:.3f} m further from '{near}', into the hall"))
    for r in spec.ris:
        p = np.array(r.position)
        inside = geo.enclosing_object(p)
        if inside is not None:
            lo, hi = geo.meshes[inside].bounds
            out.append(Issue("error", "position.inside", r.name,
                             f"the RIS at {format_point(p)} m is inside the closed object '{inside}' "
                             f"(bounds {format_point(lo)} … {format_point(hi)} m)",
                             f"move it out of '{inside}'; it needs {_ris_clearance(r):.3f} m of free space around it"))
            continue
        near, dist = geo.nearest_surface(p)
        need = _ris_clearance(r)
        if dist < need:
            out.append(Issue(
                "error", "ris.clearance", r.name,
                f"the RIS at {format_point(p)} m is {dist:.3f} m from '{near}'; "
                f"it needs {need:.3f} m ({RADAR_CLEARANCE:g} m "
                f"plus the half-diagonal of its {r.panel.width:g} m × {r.panel.height:g} m panel): the panel must "
                "stand free of every surface (the simulator models it as a free-standing plate, not part of the "
                "scene), and sionna-rt drops path segments shorter than 1 cm, so a bounce this close to the "
                "RIS point is lost",
                f"move it at least {need - dist:.3f} m further from '{near}'"))
    return out


def _sweep_sin_range(sweep: BeamSweep) -> tuple[float, float]:
    az = sweep.angles[:, 0]
    return float(np.sin(az.min())), float(np.sin(az.max()))


def _hall_directions(spec: HallSpec, r) -> np.ndarray:
    """u·d for hall points d in front of the RIS, unit d [P] (the sine of their azimuth times cos el)."""
    fp = spec.footprint_array
    edge_pts = []
    for i in range(len(fp)):
        a, b = fp[i], fp[(i + 1) % len(fp)]
        n = max(2, int(np.linalg.norm(b - a) / 0.1))
        edge_pts.append(a + np.linspace(0, 1, n, endpoint=False)[:, None] * (b - a))
    xy = np.vstack(edge_pts)
    pts = np.vstack([np.column_stack([xy, np.full(len(xy), z)]) for z in (0.0, r.position[2], spec.height)])
    pose = r.pose
    rel = pts - pose.position
    front = rel @ pose.normal > 1e-6
    rel = rel[front] / np.linalg.norm(rel[front], axis=1, keepdims=True)
    return rel @ pose.row_axis


def _grating_lobes(x: float, spacing_ratio: float, a: float, b: float) -> list[float]:
    """sin φ of the grating lobes of a radar at u·d = x that fall in the sweep [a, b] (sines)."""
    out = []
    k_max = int(math.ceil(2 / spacing_ratio)) + 1
    for k in range(-k_max, k_max + 1):
        if k and a - 1e-12 <= x - k * spacing_ratio <= b + 1e-12:
            out.append(x - k * spacing_ratio)
    return out


def _serves(r, q: np.ndarray, radar: RadarConfig) -> bool:
    """Whether RIS ``r`` can localize a radar at ``q`` [m]: in front of its plane and within range."""
    rel = q - np.array(r.position)
    return bool(rel @ r.pose.normal > 0 and
                float(np.linalg.norm(rel)) + r.loopback_delay * SPEED_OF_LIGHT / 2 < radar.max_range)


def ris_issues(spec: HallSpec, geo: HallGeometry, radar: RadarConfig, sweep: BeamSweep) -> list[Issue]:
    out = []
    radars = spec.radar_positions()
    hard: Level = "error" if len(spec.ris) == 1 else "warning"
    a, b = _sweep_sin_range(sweep)
    lo_deg, hi_deg = np.rad2deg(np.arcsin([a, b]))
    # With several RISs a radar position needs one that serves it (in front, within range): another
    # RIS's back or range is then no issue of that position (issue 22, time division).
    served = [{r.name for r in spec.ris if _serves(r, q, radar)} for q in radars]
    for r in spec.ris:
        pose = r.pose
        p = pose.position
        # The boresight: free for RIS_FREE_AHEAD, and inside the hall.
        hit, dist = geo.first_hit(p, pose.normal)
        if hit is None:
            out.append(Issue("error", "ris.facing_wall", r.name,
                             f"the boresight of the RIS at {format_point(p)} m leaves the scene "
                             "without hitting a surface: it "
                             "points out of the hall",
                             "turn it to face the radar (facing = [x, y, z] in its [[ris]] table)"))
        elif dist < RIS_FREE_AHEAD:
            out.append(Issue("error", "ris.facing_wall", r.name,
                             f"the RIS at {format_point(p)} m faces '{hit}' {dist:.3f} m in front of it (normal "
                             f"{format_point(pose.normal)}): it points at the {hit.split('_')[0]}, not into the room",
                             f"turn it to face the radar (facing = [x, y, z]), or move it so that at least "
                             f"{RIS_FREE_AHEAD:g} m is free in front of it"))
        # Each radar position as the RIS sees it.
        behind, outside, blocked, far = [], [], [], []
        for i, q in enumerate(radars):
            rel = q - p
            d = float(np.linalg.norm(rel))
            az, el = pose.angles_to(q)
            other = len(spec.ris) > 1 and bool(served[i] - {r.name})
            if rel @ pose.normal <= 0:
                if not other:
                    behind.append((i, math.degrees(math.acos(np.clip(rel @ pose.normal / d, -1, 1)))))
                continue
            if not a - 1e-12 <= math.sin(az) <= b + 1e-12:
                outside.append((i, math.degrees(az)))
            hit_name, hit_dist = geo.first_hit(q, -rel)
            if hit_name is not None and hit_dist < d - 1e-6:
                blocked.append((i, hit_name, hit_dist))
            apparent = d + r.loopback_delay * SPEED_OF_LIGHT / 2
            if apparent >= radar.max_range and not other:
                far.append((i, d, apparent))
        if behind:
            idx = [f"radar.positions[{i}] ({ang:.0f}° off boresight)" for i, ang in behind]
            verb, them = ("is", "it") if len(idx) == 1 else ("are", "them")
            out.append(Issue(hard, "ris.radar_behind", r.name,
                             f"{name_list(idx)} {verb} behind the RIS plane: its beams cannot reach {them}",
                             "turn the RIS toward the radar (facing = [x, y, z]) or move the radar in front of it"))
        if far:
            idx = [f"radar.positions[{i}] ({d:.2f} m, apparent {ap:.2f} m)" for i, d, ap in far]
            out.append(Issue(hard, "ris.range", r.name,
                             f"the loop-back of {name_list(idx)} (distance + τ_RB·c/2) lies beyond the radar's "
                             f"{radar.max_range:.2f} m unambiguous range: it folds back and the distance cannot be "
                             "measured",
                             f"keep every radar closer than {radar.max_range - r.loopback_delay * SPEED_OF_LIGHT / 2:.2f} m "
                             "to the RIS"))
        if outside:
            idx = [f"radar.positions[{i}] ({az:+.1f}°)" for i, az in outside]
            out.append(Issue("warning", "ris.sweep", r.name,
                             f"{name_list(idx)} {'is' if len(idx) == 1 else 'are'} seen outside the beam sweep "
                             f"({lo_deg:+.1f}° … {hi_deg:+.1f}°): the AoD estimate stops at the sweep's edge",
                             "turn the RIS toward the radar or widen the sweep"))
        if blocked:
            idx = [f"radar.positions[{i}] (by '{n}' {dd:.2f} m from the radar)" for i, n, dd in blocked]
            out.append(Issue("warning", "ris.los", r.name,
                             f"the line of sight to {name_list(idx)} is blocked: the localization relies on the "
                             "direct RIS loop-back, which then arrives via a reflection (wrong AoD and distance)",
                             "move the radar, the RIS or the obstacle"))
        out += _grating_issue(spec, r, radars, a, b, lo_deg, hi_deg)
    return out


def _grating_issue(spec: HallSpec, r, radars: np.ndarray, a: float, b: float, lo_deg: float,
                   hi_deg: float) -> list[Issue]:
    """Grating lobes: sin φ = u·d − k·s with s = λ/d (relay) or λ/(2d) (reflective: doubled gradient)."""
    lam = spec.wavelength
    s = lam / r.spacing if r.mode == "relay" else lam / (2 * r.spacing)
    x = _hall_directions(spec, r)
    if not len(x):
        return []
    x_lo, x_hi = float(x.min()), float(x.max())
    hit = any(max(x_lo - k * s, a) <= min(x_hi - k * s, b) for k in range(-int(2 / s) - 2, int(2 / s) + 3) if k)
    if not hit:
        return []
    reach = max(abs(a), abs(b))
    safe = s - reach  # |u·d| below this keeps every lobe out of the sweep
    safe_text = (f"radars seen within ±{math.degrees(math.asin(safe)):.1f}° of broadside get none"
                 if 0 < safe < 1 else "no direction in front of it is free of them")
    affected = []
    for i, q in enumerate(radars):
        rel = q - np.array(r.position)
        if rel @ r.pose.normal <= 0:
            continue
        xq = float(rel @ r.pose.row_axis / np.linalg.norm(rel))
        lobes = _grating_lobes(xq, s, a, b)
        if lobes:
            affected.append(f"radar.positions[{i}] ({math.degrees(math.asin(xq)):+.1f}° also peaks at "
                            + ", ".join(f"{math.degrees(math.asin(v)):+.1f}°" for v in lobes) + ")")
    factor = 1 if r.mode == "relay" else 2
    max_spacing = lam / (factor * (max(abs(x_lo), abs(x_hi)) + reach))
    return [Issue(
        "warning", "ris.grating_lobe", r.name,
        f"{r.mode} RIS with {r.spacing * 1e3:.3g} mm spacing ({r.spacing / lam:.3g} λ): directions in the hall "
        f"get a grating lobe inside the {lo_deg:+.0f}° … {hi_deg:+.0f}° sweep, so their AoD is ambiguous "
        f"({safe_text})" + (f"; affected: {name_list(affected)}" if affected else ""),
        ("use mode = \"relay\" (no grating lobe at λ/2), " if r.mode == "reflective" else "")
        + f"a spacing below {max_spacing * 1e3:.3g} mm, a narrower sweep, or keep the radars near broadside")]


# ---------------------------------------------------------------------------------------------
# Range


def range_issues(spec: HallSpec, geo: HallGeometry, radar: RadarConfig) -> list[Issue]:
    out = []
    radars = spec.radar_positions()
    limit = radar.max_range
    for name in ["floor", "ceiling", *spec.wall_names]:
        if name not in geo.meshes:
            continue
        tri = np.asarray(geo.meshes[name].triangles, dtype=float)
        far = []
        for i, q in enumerate(radars):
            closest = trimesh.triangles.closest_point(tri, np.broadcast_to(q, (len(tri), 3)))
            d = float(np.min(np.linalg.norm(closest - q, axis=1)))
            if d > limit:
                far.append((i, d))
        if far:
            idx = [f"radar.positions[{i}] ({d:.2f} m)" for i, d in far]
            i0, d0 = far[0]
            out.append(Issue(
                "warning", "range.walls", name,
                f"{name} is beyond the radar's {limit:.2f} m unambiguous range c/(2·S·T_s) from {name_list(idx)}: its "
                f"echo folds back (from {d0:.2f} m to an apparent {d0 % limit:.2f} m, d mod {limit:.2f} m, for positions[{i0}]) unless "
                "the IF filter removes it",
                f"expected in a large hall ('risloc trace' reports how strong the folded echo is); to avoid it keep "
                f"the radar within {limit:.2f} m of {name} or use a chirp with a longer unambiguous range"))
    return out
