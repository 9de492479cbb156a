"""Figures of the studies, drawn through :mod:`risloc_rt.plotting` (own Agg canvas, atomic write).

:func:`plot_summary`: a sweep in the paper's style (Figs 6–8), MAE of distance, angle and position
against the varied parameter, log scale, the Cramér–Rao bound dashed. :func:`plot_map`: a floor
map's four heat maps over the hall's outline. matplotlib is imported only when drawing.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..plotting import new_figure, save_figure
from .params import PARAMETERS, ris_size

__all__ = ["dsp_caption", "plot_summary", "plot_map", "x_value"]

_PANELS = (("distance", "distance MAE [m]", 1.0), ("angle", "angle MAE [deg]", 180 / math.pi),
           ("position", "position MAE [m]", 1.0))


def x_value(name: str, value: Any) -> float | None:
    """A numeric x for ``value`` of parameter ``name`` (RIS size: its number of elements).

    Parameters
    ----------
    name : str
        A study parameter (:data:`risloc_rt.studies.params.PARAMETERS`).
    value
        Its value, in the parameter's unit (e.g. dBm, deg, m).

    Returns
    -------
    float or None
        The value as a number in the same unit (``ris_size``: rows × columns), None for a
        categorical parameter.
    """
    if name == "ris_size":
        r, c = ris_size(value)
        return float(r * c)
    if PARAMETERS[name].kind in ("float", "int"):
        return float(value)
    return None


def _label(name: str) -> str:
    if name == "ris_size":
        return "RIS elements N_RIS (rows × columns)"
    unit = PARAMETERS[name].unit
    return f"{name} [{unit}]" if unit else name


def dsp_caption(devices: Any) -> str:
    """The figure title's device part: what ran the DSP of a study's runs.

    Parameters
    ----------
    devices : list of dict or None
        A summary's ``devices`` (each ``{"dsp": ArrayBackend.describe(), "trace": ...}``).

    Returns
    -------
    str
        ``"; DSP on NVIDIA H200 (cupy 14.2.0)"`` for a GPU (its model), ``"; DSP on CPU (numpy 2.4.6)"``
        for the host, several joined by commas; ``""`` when none is listed.
    """
    names = []
    for env in devices or ():
        dsp_env = env.get("dsp") if isinstance(env, dict) else None
        if not dsp_env:
            continue
        where = dsp_env.get("hardware", "?") if str(dsp_env.get("device", "")).startswith("cuda") else "CPU"
        name = f"{where.split(',')[0]} ({dsp_env.get('library', '?')})"
        if name not in names:
            names.append(name)
    return f"; DSP on {', '.join(names)}" if names else ""


def plot_summary(summary: dict[str, Any], path: str | Path, *, title: str | None = None) -> Path:
    """Three panels (distance, angle, position): MAE with 95 % intervals and CRB (dashed) vs the x parameter.

    Other varied parameters give one line each.

    Parameters
    ----------
    summary : dict
        A study's ``summary.json`` object (:func:`risloc_rt.studies.summary.summarize`): MAE and
        CRB in m and rad (drawn in m and deg).
    path : path-like
        The PNG to write (atomically).
    title : str, optional
        The figure's title (default: study name, runs per point, estimator and the DSP's device:
        a GPU's model or "CPU", with its array library, from the summary's ``devices``).

    Returns
    -------
    Path
        ``path``.
    """
    xname = summary["x"]
    others = [n for n in summary["study"]["vary"] if n != xname]
    groups: dict[str, list[dict[str, Any]]] = {}
    for pt in summary["points"]:
        label = ", ".join(f"{n}={pt['params'][n]}" for n in others)
        groups.setdefault(label, []).append(pt)
    categorical = xname is None or x_value(xname, summary["points"][0]["params"][xname]) is None
    fig, axes = new_figure(figsize=(13, 3.8), nrows=1, ncols=3)
    fig.set_layout_engine("constrained")
    for ax, (q, ylabel, scale) in zip(axes, _PANELS):
        for i, (label, pts) in enumerate(groups.items()):
            if categorical:
                xs = list(range(len(pts)))
            else:
                xs = [x_value(xname, p["params"][xname]) for p in pts]
            order = sorted(range(len(pts)), key=lambda j: xs[j])
            xs = [xs[j] for j in order]
            pts = [pts[j] for j in order]
            mae = [p["mae"][q] * scale for p in pts]
            lo = [max(m - p["mae_ci95"][q][0] * scale, 0) if math.isfinite(p["mae_ci95"][q][0]) else 0 for m, p in zip(mae, pts)]
            hi = [max(p["mae_ci95"][q][1] * scale - m, 0) if math.isfinite(p["mae_ci95"][q][1]) else 0 for m, p in zip(mae, pts)]
            color = f"C{i}"
            ax.errorbar(xs, mae, yerr=[lo, hi], marker="o", color=color, capsize=3, label=f"{label}: MAE" if label else "MAE (95 % CI)")
            crb = [p["crb"][q] * scale for p in pts]
            ax.plot(xs, crb, "--", color=color, alpha=0.8, label=f"{label}: CRB" if label else "CRB (1σ)")
        ax.set_yscale("log")
        ax.set_xlabel(_label(xname) if xname else "point")
        if categorical and groups:
            first = next(iter(groups.values()))
            ax.set_xticks(range(len(first)), [str(p["params"][xname]) for p in first])
        if xname == "ris_size":
            first = next(iter(groups.values()))
            ax.set_xscale("log", base=2)
            ticks = sorted({x_value(xname, p["params"][xname]) for p in first})
            ax.set_xticks(ticks, [str(int(t)) for t in ticks])
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    runs = summary["points"][0]["runs"] if summary["points"] else 0
    fig.suptitle(title or f"{summary['study']['name']}: {runs} runs per point, "
                 f"estimator {summary['points'][0]['params']['estimator'] if summary['points'] else '?'}"
                 f"{dsp_caption(summary.get('devices'))}")
    return save_figure(fig, path, tight=False, dpi=110)


def plot_map(spec: Any, cells: list[dict[str, Any]], settings: Any, path: str | Path, *, unseen: Any = None,
             coverage: dict[str, Any] | None = None) -> Path:
    """Heat maps over the hall outline: position RMSE, detection probability, PEB, dominant flag; with several
    RISs also the RIS that serves each cell.

    Parameters
    ----------
    spec : risloc_rt.authoring.spec.HallSpec
        The hall: its footprint [m], objects and RIS are drawn.
    cells : list of dict
        The map's cells (:class:`risloc_rt.studies.floor_map.MapResult`): ``x``, ``y`` [m],
        ``rmse_position`` and ``peb`` [m], ``detection_probability``, ``dominant_flag``.
    settings : risloc_rt.studies.floor_map.MapSettings
        Its ``spacing`` [m] sizes the cells; the rest goes into the title.
    path : path-like
        The PNG to write (atomically).
    unseen : float array [U, 3], optional
        Floor cells no RIS sees [m]: drawn as grey crosses.
    coverage : dict, optional
        :func:`risloc_rt.studies.floor_map.coverage`: its share goes into the title.

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Polygon, Rectangle

    from dsp import direction_from_angles

    poly = np.array(spec.footprint, dtype=float)
    xs = np.array([c["x"] for c in cells])
    ys = np.array([c["y"] for c in cells])
    s = settings.spacing
    flags = sorted({c["dominant_flag"] for c in cells})
    panels = [("position RMSE [m]", [c["rmse_position"] if c["rmse_position"] is not None else np.nan for c in cells], "log"),
              ("detection probability", [c["detection_probability"] for c in cells], "lin"),
              ("PEB (CRB) [m]", [c["peb"] for c in cells], "log"),
              ("dominant flag", [flags.index(c["dominant_flag"]) for c in cells], "cat")]
    configs = spec.ris_configs()
    names = [r.name for r in spec.ris]
    several = len(configs) > 1
    serving = names + ["none"]
    labels: dict[str, list[str]] = {"dominant flag": flags}
    if several:
        title = "served by (smallest own PEB, Pd >= 0.5)"
        panels.append((title, [serving.index(c.get("served_by") or "none") for c in cells], "cat"))
        labels[title] = serving
        if coverage:
            title = (f"covered (Pd >= {coverage['detection_probability']:g}, PEB < "
                     f"{1e3 * coverage['peb_bound']:g} mm)")
            panels.append((title, [int(c["detection_probability"] >= coverage["detection_probability"]
                                       and c["peb"] is not None and c["peb"] < coverage["peb_bound"]) for c in cells],
                           "cat"))
            labels[title] = ["not covered", "covered"]
    fig, axes = new_figure(figsize=(18, 8) if several else (12, 8), nrows=2, ncols=3 if several else 2)
    fig.set_layout_engine("constrained")
    for ax in axes.ravel()[len(panels):]:
        ax.set_axis_off()
    for ax, (title, values, scale) in zip(axes.ravel(), panels):
        v = np.array(values, dtype=float)
        flags_shown = labels.get(title, [])
        norm = LogNorm() if scale == "log" and np.nanmax(v[np.isfinite(v)], initial=0.0) > 0 else None
        cmap = "tab10" if scale == "cat" else ("viridis_r" if scale == "log" else "viridis")
        x0, y0 = xs.min(), ys.min()
        ix = np.rint((xs - x0) / s).astype(int)
        iy = np.rint((ys - y0) / s).astype(int)
        img = np.full((iy.max() + 1, ix.max() + 1), np.nan)
        img[iy, ix] = v
        xe = x0 - s / 2 + s * np.arange(ix.max() + 2)
        ye = y0 - s / 2 + s * np.arange(iy.max() + 2)
        sc = ax.pcolormesh(xe, ye, np.ma.masked_invalid(img), cmap=cmap, norm=norm,
                           vmin=None if norm is not None else (0 if scale == "cat" else 0.0),
                           vmax=None if norm is not None else (9 if scale == "cat" else 1.0))
        if scale == "cat":
            handles = [Line2D([], [], marker="s", ls="", color=colormaps["tab10"](i / 9),
                                  label=f) for i, f in enumerate(flags_shown)]
            ax.legend(handles=handles, fontsize=7, loc="upper left")
        else:
            fig.colorbar(sc, ax=ax)
        ax.add_patch(Polygon(poly, closed=True, fill=False, lw=2, color="k"))
        for ob in spec.objects:
            if hasattr(ob, "radius"):
                ax.add_patch(Circle(ob.center[:2], ob.radius, color="0.4"))
            elif hasattr(ob, "size"):
                ax.add_patch(Rectangle((ob.center[0] - ob.size[0] / 2, ob.center[1] - ob.size[1] / 2), ob.size[0],
                                       ob.size[1], angle=np.rad2deg(getattr(ob, "yaw", 0.0)), rotation_point="center",
                                       color="0.4"))
        if unseen is not None and len(unseen):
            u = np.asarray(unseen, dtype=float)
            ax.plot(u[:, 0], u[:, 1], "x", color="0.6", ms=4)
        for name, ris in zip(names, configs):
            p = ris.pose.position
            n = ris.pose.to_world(direction_from_angles(np.zeros(2)))  # boresight
            ax.plot(p[0], p[1], "r^", ms=10)
            ax.annotate("", xy=(p[0] + 2 * n[0], p[1] + 2 * n[1]), xytext=(p[0], p[1]), arrowprops={"color": "r"})
            if several:
                ax.annotate(name, xy=(p[0], p[1]), xytext=(4, 4), textcoords="offset points", color="r", fontsize=8)
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    covered = (f"; coverage {100 * coverage['share']:.0f} % (Pd >= {coverage['detection_probability']:g}, "
               f"PEB < {1e3 * coverage['peb_bound']:g} mm; x: floor no RIS sees)" if coverage else "")
    fig.suptitle(f"{settings.scene}: {len(cells)} cells, {settings.spacing:g} m grid at {settings.height:g} m, "
                 f"{settings.runs} runs each, {settings.estimator} estimator (RIS: red){covered}")
    return save_figure(fig, path, tight=False, dpi=100)
