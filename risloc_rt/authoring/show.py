"""Plan and elevation drawing of a hall spec or scene folder: :func:`show_scene`.

The plan (x–y, seen from above) shows the walls with their numbers, doors and windows, objects
coloured by material, each RIS with its panel, boresight and beam-sweep fan, and the radar
positions with their boresight and the azimuth at which the RIS sees them. The elevation (x–z,
seen from -y) shows heights. Optionally the traced paths of one radar position are drawn in:
the monostatic echoes and the radar → RIS legs, as polylines through their interaction points.

Drawn with :mod:`risloc_rt.plotting` (its own Agg canvas, no pyplot state, an atomic write); nothing
here imports sionna, mitsuba or drjit.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dsp import BeamSweep

from ..plotting import new_figure, save_figure
from .objects import BoxObject, CylinderObject, WallPanel
from .spec import HallSpec, load_spec

__all__ = ["SceneFigure", "show_scene", "path_polylines"]

#: Face colours by ITU type (custom materials: grey-green).
MATERIAL_COLOURS = {"metal": "#7f8fa6", "concrete": "#b0b0b0", "wood": "#c8a165", "chipboard": "#d9b77c",
                    "plasterboard": "#e0dccf", "ceiling_board": "#e6e2d3", "glass": "#9fd3e6", "marble": "#d8d0c8",
                    "floorboard": "#b98c58"}
_CUSTOM_COLOUR = "#a9b8a0"
_RIS_COLOUR = "#7b2cbf"
_RADAR_COLOUR = "#d62728"
_MONO_COLOUR = "#ff7f0e"
_LEG_COLOUR = "#2ca02c"


@dataclass(frozen=True)
class SceneFigure:
    """What :func:`show_scene` drew.

    Attributes
    ----------
    path : Path
        The PNG written.
    plan_limits : float array [2, 2]
        ``[[x_min, x_max], [y_min, y_max]]`` of the plan view [m].
    elevation_limits : float array [2, 2]
        ``[[x_min, x_max], [z_min, z_max]]`` of the elevation view [m].
    counts : dict of str -> int
        Items drawn: ``walls``, ``objects``, ``meshes``, ``ris``, ``radars``, ``monostatic_paths``,
        ``ris_legs``.
    radar_index : int or None
        The radar position highlighted.
    """

    path: Path
    plan_limits: np.ndarray
    elevation_limits: np.ndarray
    counts: dict[str, int]
    radar_index: int | None = None


def _colour(material: Any) -> str:
    return MATERIAL_COLOURS.get(material.itu, _CUSTOM_COLOUR) if material.itu else _CUSTOM_COLOUR


def _resolve(scene: HallSpec | str | Path) -> HallSpec:
    if isinstance(scene, HallSpec):
        return scene
    path = Path(scene)
    if path.is_dir():
        path = path / "spec.toml"
    if not path.is_file():
        raise FileNotFoundError(f"{str(path)!r} does not exist; give a spec (TOML) or a scene folder with spec.toml")
    return load_spec(path)


def path_polylines(traced: Any) -> list[np.ndarray]:
    """One polyline [K, 3] [m] per path of a :class:`~risloc_rt.hall.traced.TracedPaths`: transmitter,
    interaction points, receiver (its length is the path's unfolded length, ``c·delay``)."""
    out = []
    for i in range(len(traced)):
        hits = traced.vertices[i][traced.interactions[i] != 0]
        out.append(np.vstack([traced.tx_position, hits, traced.rx_position]))
    return out


def _text_angle(e: np.ndarray) -> float:
    """Angle [deg] of text written along direction ``e`` [2], kept readable (-90° … 90°)."""
    a = math.degrees(math.atan2(e[1], e[0]))
    return a - 180 if a > 90 else a + 180 if a <= -90 else a


def _sweep_fan(pose: Any, az: np.ndarray, radius: float) -> np.ndarray:
    """Fan polygon [K, 3]: the RIS centre and the arc of directions d(az, 0) at ``radius`` [m]."""
    a = np.linspace(az.min(), az.max(), 61)
    d = np.outer(np.sin(a), pose.row_axis) + np.outer(np.cos(a), pose.normal)
    return np.vstack([pose.position, pose.position + radius * d])


def show_scene(scene: HallSpec | str | Path, out_png: str | Path, *, radar_index: int | None = None,
               paths: Any = None, sweep: BeamSweep | None = None, dpi: int = 130) -> SceneFigure:
    """Draw the plan and elevation of a hall into a PNG.

    Parameters
    ----------
    scene : HallSpec, or path of a spec (TOML) or of a scene folder
    out_png : str or Path
        The PNG to write (folders are created; written atomically).
    radar_index : int, optional
        Radar position to highlight (default: the one ``paths`` was traced from, if any).
    paths : risloc_rt.hall.HallPaths or risloc_rt.hall.raytrace.TraceResult, optional
        Traced paths of one radar position, drawn as polylines: monostatic echoes in orange, radar →
        RIS legs in green.
    sweep : dsp.BeamSweep, optional
        The RIS sweep whose azimuth span the fan shows (default -45° … 45°).
    dpi : int
        Resolution [dots per inch].

    Returns
    -------
    SceneFigure
    """
    spec = _resolve(scene)
    sweep = sweep if sweep is not None else BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    trace = getattr(paths, "trace", paths)
    if trace is not None and not (hasattr(trace, "monostatic") and hasattr(trace, "legs")):
        raise TypeError(f"paths must be a HallPaths or a TraceResult, got {type(paths).__name__}")
    radars = spec.radar_positions()
    if radar_index is None and trace is not None and len(radars):
        radar_index = int(np.argmin(np.linalg.norm(radars - trace.radar_position, axis=1)))
    if radar_index is not None and not 0 <= radar_index < max(len(radars), 1):
        raise ValueError(f"radar_index={radar_index} is out of range: the spec has {len(radars)} radar position(s)")

    views = _new_views(spec, dpi)
    floor_patch = _draw_shell(views, spec)
    _draw_objects(views, spec)
    _draw_meshes(views, spec)
    if trace is not None:
        _draw_paths(views, trace)
    _draw_ris(views, spec, sweep, radars, floor_patch)
    if len(radars):
        _draw_radars(views, spec, radars, radar_index)
    _finish(views, spec, radar_index, trace)
    out = save_figure(views.fig, out_png, tight=False, dpi=dpi)
    plan, elev = views.plan, views.elev
    return SceneFigure(path=out, plan_limits=np.array([plan.get_xlim(), plan.get_ylim()]),
                       elevation_limits=np.array([elev.get_xlim(), elev.get_ylim()]), counts=views.counts,
                       radar_index=radar_index)


@dataclass(frozen=True)
class _Views:
    """The figure being drawn: its plan and elevation axes, the hall's extent, what was drawn so far.

    ``lo``, ``hi``: footprint corners [2] [m]; ``size``: its larger side [m]; ``margin`` [m];
    ``counts`` and ``legend`` (label key -> handle) fill up as the steps draw.
    """

    fig: Any
    plan: Any
    elev: Any
    footprint: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    size: float
    margin: float
    height: float
    counts: dict[str, int] = field(default_factory=dict)
    legend: dict[str, Any] = field(default_factory=dict)


def _new_views(spec: HallSpec, dpi: int) -> _Views:
    """The figure, sized so that the plan and the elevation keep the hall's proportions."""
    fp = spec.footprint_array
    lo, hi = fp.min(axis=0), fp.max(axis=0)
    size = float(max(hi - lo))
    margin = 0.06 * size
    h = spec.height
    width_in = 11.0
    plan_h = (hi[1] - lo[1] + 2 * margin) / (hi[0] - lo[0] + 2 * margin) * width_in * 0.78
    elev_h = (h + 2 * margin) / (hi[0] - lo[0] + 2 * margin) * width_in * 0.78
    fig = new_figure(figsize=(width_in, plan_h + elev_h + 1.6), dpi=dpi)
    gs = fig.add_gridspec(2, 1, height_ratios=[plan_h, elev_h], hspace=0.28, left=0.07, right=0.76, top=0.9,
                          bottom=0.07)
    plan, elev = fig.add_subplot(gs[0]), fig.add_subplot(gs[1], sharex=None)
    counts = dict.fromkeys(("walls", "objects", "meshes", "ris", "radars", "monostatic_paths", "ris_legs"), 0)
    return _Views(fig=fig, plan=plan, elev=elev, footprint=fp, lo=lo, hi=hi, size=size, margin=margin, height=h,
                  counts=counts)


def _draw_shell(views: _Views, spec: HallSpec) -> Any:
    """Floor, numbered walls and the elevation's outline; returns the floor patch (the sweep fans are clipped to it)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    plan, elev, fp, h = views.plan, views.elev, views.footprint, views.height
    lo, hi = views.lo, views.hi
    floor_patch = Polygon(fp, closed=True, facecolor="#f4f4f4", edgecolor="none", zorder=0)
    plan.add_patch(floor_patch)
    for i in range(len(fp)):
        a, b = fp[i], fp[(i + 1) % len(fp)]
        plan.plot([a[0], b[0]], [a[1], b[1]], color="#333333", lw=2.5, solid_capstyle="round", zorder=2)
        mid = (a + b) / 2
        e = (b - a) / np.linalg.norm(b - a)
        out = np.array([e[1], -e[0]])  # outward for a counter-clockwise footprint
        plan.annotate(f"wall_{i}", mid, xytext=(out * 9), textcoords="offset points", ha="center",
                      va="center", fontsize=7, color="#555555", rotation=_text_angle(e), rotation_mode="anchor")
        if abs(e[0]) < 1e-9:  # a wall across the view: a line in the elevation
            elev.plot([a[0], a[0]], [0, h], color="#333333", lw=2.0, zorder=2)
        views.counts["walls"] += 1
    elev.plot([lo[0], hi[0]], [0, 0], color="#333333", lw=2.5, zorder=2)
    elev.plot([lo[0], hi[0]], [h, h], color="#333333", lw=2.5, zorder=2)
    elev.plot([lo[0], lo[0]], [0, h], color="#333333", lw=2.0, zorder=2)
    elev.plot([hi[0], hi[0]], [0, h], color="#333333", lw=2.0, zorder=2)
    views.legend["wall"] = Line2D([], [], color="#333333", lw=2.5, label=f"walls ({spec.materials.walls.describe()})")
    return floor_patch


def _draw_objects(views: _Views, spec: HallSpec) -> None:
    """Wall panels (doors, windows) along their wall; boxes and pillars by their footprint, coloured by material."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon

    plan, elev, fp, size = views.plan, views.elev, views.footprint, views.size
    for obj in spec.objects:
        colour = _colour(obj.material)
        if isinstance(obj, WallPanel):
            a, b = fp[obj.wall], fp[(obj.wall + 1) % len(fp)]
            e = (b - a) / np.linalg.norm(b - a)
            p0, p1 = a + obj.u_range[0] * e, a + obj.u_range[1] * e
            style = dict(color=colour, lw=5, solid_capstyle="butt", zorder=3)
            plan.plot([p0[0], p1[0]], [p0[1], p1[1]], **style)
            plan.annotate(obj.name, (p0 + p1) / 2, xytext=(np.array([-e[1], e[0]]) * 9), textcoords="offset points",
                          ha="center", va="center", fontsize=6.5, color="#333333", rotation=_text_angle(e),
                          rotation_mode="anchor")
            x0, x1 = sorted((p0[0], p1[0]))
            z0, z1 = obj.z_range
            elev.add_patch(Polygon([[x0, z0], [x1, z0], [x1, z1], [x0, z1]], closed=True, facecolor=colour,
                                   edgecolor="#333333", lw=0.8, alpha=0.8, zorder=3))
            views.legend[f"{obj.kind}:{colour}"] = Line2D([], [], color=colour, lw=5,
                                                          label=f"{obj.kind} ({obj.material.describe()})")
        else:
            corners = obj.corners_xy()
            plan.add_patch(Polygon(corners, closed=True, facecolor=colour, edgecolor="#333333", lw=0.8, zorder=3))
            ext = np.ptp(corners, axis=0)
            small = isinstance(obj, CylinderObject) or ext.max() < 0.04 * size
            plan.annotate(obj.name, corners.mean(axis=0), xytext=(0, -0.5 * ext[1] / size * 400 - 4 if small else 0),
                          textcoords="offset points", ha="center", va="top" if small else "center", fontsize=6.5,
                          color="#222222", rotation=90 if ext[1] > 2 * ext[0] and not small else 0, zorder=6)
            z0, z1 = obj.z_range
            x0, x1 = corners[:, 0].min(), corners[:, 0].max()
            elev.add_patch(Polygon([[x0, z0], [x1, z0], [x1, z1], [x0, z1]], closed=True, facecolor=colour,
                                   edgecolor="#333333", lw=0.8, alpha=0.6, zorder=3))
            kind = obj.kind if isinstance(obj, BoxObject) else "pillar"
            views.legend[f"obj:{kind}:{colour}"] = Patch(facecolor=colour, edgecolor="#333333",
                                                         label=f"{kind} ({obj.material.itu or obj.material.name})")
        views.counts["objects"] += 1


def _draw_meshes(views: _Views, spec: HallSpec) -> None:
    """Imported meshes, hatched: their convex hull in the plan, their bounding box in the elevation."""
    if not spec.meshes:
        return
    from matplotlib.patches import Patch, Polygon
    from scipy.spatial import ConvexHull, QhullError

    from .shapes import scene_meshes

    plan, elev = views.plan, views.elev
    imported = {m.name: m for m in scene_meshes(spec) if m.kind == "mesh"}
    for m in spec.meshes:
        v = imported[m.name].vertices
        xy = v[:, :2]
        try:
            hull = xy[ConvexHull(xy).vertices]
        except (QhullError, ValueError):  # a flat or tiny mesh: its bounding box
            (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
            hull = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        colour = _colour(m.material)
        plan.add_patch(Polygon(hull, closed=True, facecolor=colour, edgecolor="#333333", lw=0.8, hatch="///",
                               zorder=3))
        plan.annotate(m.name, hull.mean(axis=0), ha="center", va="center", fontsize=6.5, zorder=6)
        elev.add_patch(Polygon([[v[:, 0].min(), v[:, 2].min()], [v[:, 0].max(), v[:, 2].min()],
                                [v[:, 0].max(), v[:, 2].max()], [v[:, 0].min(), v[:, 2].max()]], closed=True,
                               facecolor=colour, edgecolor="#333333", lw=0.8, alpha=0.6, hatch="///", zorder=3))
        views.legend[f"mesh:{colour}"] = Patch(facecolor=colour, edgecolor="#333333", hatch="///",
                                               label=f"imported mesh ({m.material.itu or m.material.name})")
        views.counts["meshes"] += 1


def _draw_paths(views: _Views, trace: Any) -> None:
    """The traced paths of one radar position as polylines: monostatic echoes, then the radar → RIS legs."""
    from matplotlib.lines import Line2D

    for key, traced, colour, label in (("monostatic_paths", trace.monostatic, _MONO_COLOUR, "traced echoes"),
                                       ("ris_legs", None, _LEG_COLOUR, "traced radar → RIS legs")):
        groups = [traced] if traced is not None else list(trace.legs)
        for g in groups:
            for line in path_polylines(g):
                views.plan.plot(line[:, 0], line[:, 1], color=colour, lw=0.7, alpha=0.45, zorder=4)
                views.elev.plot(line[:, 0], line[:, 2], color=colour, lw=0.7, alpha=0.45, zorder=4)
                views.counts[key] += 1
        views.legend[key] = Line2D([], [], color=colour, lw=1.2, label=f"{label} ({views.counts[key]})")


def _draw_ris(views: _Views, spec: HallSpec, sweep: BeamSweep, radars: np.ndarray, floor_patch: Any) -> None:
    """Each RIS: its panel, boresight arrow, name and beam-sweep fan (clipped to the floor)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon

    plan, elev, size = views.plan, views.elev, views.size
    az = sweep.angles[:, 0]
    for r in spec.ris:
        pose = r.pose
        p = pose.position
        dists = np.linalg.norm(radars - p, axis=1) if len(radars) else np.array([0.3 * size])
        fan = _sweep_fan(pose, az, float(dists.max()) * 1.08)
        fan_patch = Polygon(fan[:, :2], closed=True, facecolor=_RIS_COLOUR, edgecolor=_RIS_COLOUR, alpha=0.08,
                            lw=0.8, zorder=1)
        plan.add_patch(fan_patch)
        fan_patch.set_clip_path(floor_patch)  # the sweep ends at the walls
        half = max(r.panel.width / 2, 0.012 * size)  # the 10 cm panel, drawn at least 2.4 % of the hall
        u = pose.row_axis
        plan.plot([p[0] - half * u[0], p[0] + half * u[0]], [p[1] - half * u[1], p[1] + half * u[1]],
                  color=_RIS_COLOUR, lw=4, solid_capstyle="butt", zorder=7)
        arrow = 0.1 * size * pose.normal
        for ax, (i, j) in ((plan, (0, 1)), (elev, (0, 2))):
            ax.annotate("", xy=(p[i] + arrow[i], p[j] + arrow[j]), xytext=(p[i], p[j]),
                        arrowprops=dict(arrowstyle="-|>", color=_RIS_COLOUR, lw=1.5), zorder=7)
        plan.annotate(r.name, (p[0], p[1]), xytext=(-pose.normal[:2] * 14), textcoords="offset points",
                      ha="center", va="center", fontsize=8, color=_RIS_COLOUR, weight="bold", zorder=8)
        vh = max(r.panel.height / 2, 0.012 * size)
        w = pose.column_axis
        elev.plot([p[0] - vh * w[0], p[0] + vh * w[0]], [p[2] - vh * w[2], p[2] + vh * w[2]], color=_RIS_COLOUR,
                  lw=4, solid_capstyle="butt", zorder=7)
        views.counts["ris"] += 1
    if spec.ris:
        views.legend["ris"] = Line2D([], [], color=_RIS_COLOUR, lw=4, label="RIS panel + boresight")
        views.legend["fan"] = Patch(facecolor=_RIS_COLOUR, alpha=0.15, edgecolor=_RIS_COLOUR,
                                    label=f"beam sweep {np.rad2deg(az.min()):+.0f}° … {np.rad2deg(az.max()):+.0f}°")


def _draw_radars(views: _Views, spec: HallSpec, radars: np.ndarray, radar_index: int | None) -> None:
    """The radar positions with their boresight; labelled with the azimuth and distance the first RIS sees."""
    from matplotlib.lines import Line2D

    plan, elev, size = views.plan, views.elev, views.size
    bores = spec.radar_boresights()
    pose0 = spec.ris[0].pose if spec.ris else None
    for i, (q, bdir) in enumerate(zip(radars, bores)):
        big = i == radar_index
        ms = 9 if big else 6
        plan.plot(q[0], q[1], "o", color=_RADAR_COLOUR, ms=ms, mec="black" if big else _RADAR_COLOUR, zorder=9)
        elev.plot(q[0], q[2], "o", color=_RADAR_COLOUR, ms=ms, mec="black" if big else _RADAR_COLOUR, zorder=9)
        tip = q + 0.05 * size * bdir
        plan.annotate("", xy=tip[:2], xytext=q[:2], arrowprops=dict(arrowstyle="-|>", color=_RADAR_COLOUR, lw=1.2),
                      zorder=9)
        label = f"R{i}"
        if pose0 is not None:
            az_i = math.degrees(pose0.angles_to(q)[0])
            label += f"  {az_i:+.1f}°, {np.linalg.norm(q - pose0.position):.2f} m"
            if len(radars) <= 12:
                plan.plot([q[0], pose0.position[0]], [q[1], pose0.position[1]], ls=":", color=_RADAR_COLOUR,
                          lw=0.8, zorder=5)
        if len(radars) <= 12:
            away = -bdir[:2] / max(np.linalg.norm(bdir[:2]), 1e-9)  # label behind the radar
            plan.annotate(label, (q[0], q[1]), xytext=away * 8 + (0, 6 if abs(away[1]) <= 0.3 else 0),
                          textcoords="offset points",
                          ha="right" if away[0] < -0.3 else "left" if away[0] > 0.3 else "center",
                          va="top" if away[1] < -0.3 else "bottom" if away[1] > 0.3 else "center",
                          fontsize=7.5, color=_RADAR_COLOUR, zorder=9)
        views.counts["radars"] += 1
    views.legend["radar"] = Line2D([], [], marker="o", ls="", color=_RADAR_COLOUR,
                                   label="radar Ri: azimuth, distance\nseen from the RIS" if spec.ris else "radar")


def _finish(views: _Views, spec: HallSpec, radar_index: int | None, trace: Any) -> None:
    """Limits, equal aspect, grid and labels of both views; the title and the legend."""
    plan, elev, lo, hi, margin, h = views.plan, views.elev, views.lo, views.hi, views.margin, views.height
    plan.set_xlim(lo[0] - margin, hi[0] + margin)
    plan.set_ylim(lo[1] - margin, hi[1] + margin)
    elev.set_xlim(lo[0] - margin, hi[0] + margin)
    elev.set_ylim(-margin, h + margin)
    for ax in (plan, elev):
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, color="#dddddd", lw=0.5, zorder=-1)
        ax.set_axisbelow(True)
        ax.tick_params(labelsize=8)
    plan.set_xlabel("x [m]", fontsize=9)
    plan.set_ylabel("y [m]", fontsize=9)
    elev.set_xlabel("x [m]", fontsize=9)
    elev.set_ylabel("z [m]", fontsize=9)
    plan.set_title("plan (x–y, from above)", fontsize=9, loc="left")
    elev.set_title("elevation (x–z, from −y)", fontsize=9, loc="left")
    title = textwrap.fill(f"{spec.name}: {spec.description}" if spec.description else spec.name, 110, max_lines=2,
                          placeholder=" …")
    if radar_index is not None and trace is not None:
        title += f"\ntraced paths of radar position R{radar_index} (max depth {trace.settings.max_depth})"
    views.fig.suptitle(title, fontsize=10, x=0.07, ha="left")
    views.fig.legend(handles=list(views.legend.values()), loc="upper left", bbox_to_anchor=(0.77, 0.9),
                     fontsize=7.5, frameon=False)
