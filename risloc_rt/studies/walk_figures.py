"""The figures of a tracked walk (``risloc track``): the plan view, error against time, NEES and NIS.

Each takes a :class:`risloc_rt.studies.walk.WalkResult` and writes one PNG through
:mod:`risloc_rt.plotting` (matplotlib is imported when drawing).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from dsp.tracking import nees_band

__all__ = ["plot_plan", "plot_error", "plot_consistency"]


def _column(result: Any, key: str) -> np.ndarray:
    return np.array([r[key] for r in result.rows], dtype=float)


def plot_plan(result: Any, path: str | Path) -> Path:
    """Plan view: the hall's walls and objects, the RISs, the true path, the fixes by RIS and the track.

    Parameters
    ----------
    result : risloc_rt.studies.walk.WalkResult
        The walk.
    path : str or Path
        The PNG to write.

    Returns
    -------
    Path
    """
    from matplotlib.patches import Polygon

    from ..authoring.spec import load_spec
    from ..plotting import new_figure, save_figure

    spec = load_spec(result.scene / "spec.toml")
    fig = new_figure(figsize=(8.0, 7.0))
    ax = fig.add_subplot(1, 1, 1)
    fp = spec.footprint_array
    ax.add_patch(Polygon(fp, closed=True, facecolor="#f4f4f4", edgecolor="#333333", lw=1.5, zorder=1))
    for obj in spec.objects:
        if hasattr(obj, "corners_xy"):
            ax.add_patch(Polygon(obj.corners_xy(), closed=True, facecolor="#c8a165", edgecolor="#333333", lw=0.6,
                                 zorder=2))
    colours = ["#7b2cbf", "#1f77b4", "#2ca02c", "#ff7f0e", "#8c564b"]
    for i, (r, cfg) in enumerate(zip(spec.ris, spec.ris_configs())):
        p, n = cfg.pose.position, cfg.pose.normal
        c = colours[i % len(colours)]
        ax.plot([p[0]], [p[1]], marker="s", color=c, ms=8, zorder=5)
        ax.annotate(r.name, p[:2], xytext=(6, 6), textcoords="offset points", color=c, fontsize=8)
        ax.arrow(p[0], p[1], 1.2 * n[0], 1.2 * n[1], color=c, width=0.05, zorder=5)
    pts = result.trajectory.points
    ax.plot(pts[:, 0], pts[:, 1], color="#333333", lw=1.0, ls="--", label="true path", zorder=3)
    ris = np.array([r["ris"] for r in result.rows])
    for i, r in enumerate(spec.ris):
        sel = ris == r.name
        x, y = _column(result, "fix_x")[sel], _column(result, "fix_y")[sel]
        if np.isfinite(x).any():
            ax.plot(x, y, ls="none", marker=".", ms=4, color=colours[i % len(colours)], label=f"fixes ({r.name})",
                    zorder=4)
    ax.plot(_column(result, "track_x"), _column(result, "track_y"), color="#d62728", lw=1.2, label="track", zorder=4)
    ax.plot(_column(result, "smooth_x"), _column(result, "smooth_y"), color="#2ca02c", lw=1.0,
            label="smoothed track", zorder=4)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    s = result.summary
    ax.set_title(f"{s['scene']}: {s['sweeps']} sweeps, fixes {s['fixes']}, track RMSE "
                 f"{(s['track_rmse_m'] or math.nan) * 100:.2f} cm, smoothed "
                 f"{(s['smoothed']['rmse_m'] or math.nan) * 100:.2f} cm", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    return save_figure(fig, path)


def plot_error(result: Any, path: str | Path) -> Path:
    """Position error against time: the single fixes (by RIS), the track and the smoothed track, each with its 1σ.

    Parameters
    ----------
    result : risloc_rt.studies.walk.WalkResult
        The walk.
    path : str or Path
        The PNG to write.

    Returns
    -------
    Path
    """
    from ..plotting import new_figure, save_figure

    fig = new_figure(figsize=(8.0, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    t = _column(result, "time")
    ris = np.array([r["ris"] for r in result.rows])
    for name in sorted(set(ris)):
        sel = ris == name
        ax.semilogy(t[sel], _column(result, "fix_error")[sel], ls="none", marker=".", ms=4, label=f"fix ({name})")
    ax.semilogy(t, _column(result, "track_error"), color="#d62728", lw=1.2, label="track")
    ax.semilogy(t, _column(result, "track_sigma"), color="#d62728", lw=0.8, ls=":", label="track 1σ (sqrt trace)")
    ax.semilogy(t, _column(result, "smooth_error"), color="#2ca02c", lw=1.0, label="smoothed track")
    ax.semilogy(t, _column(result, "smooth_sigma"), color="#2ca02c", lw=0.8, ls=":", label="smoothed 1σ")
    coast = np.array([r["update"] in ("coast", "flagged", "gated") for r in result.rows])  # predicted only
    for tc in t[coast]:
        ax.axvline(tc, color="#cccccc", lw=0.5, zorder=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [m]")
    ax.set_title("error against time (grey: sweeps predicted only: coasted, flagged or gated)", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    return save_figure(fig, path)


def plot_consistency(result: Any, path: str | Path) -> Path:
    """NEES (the track's and the smoothed track's) and NIS per sweep against their 95 % χ² bands (per sweep, and
    of the walk's mean, the track's).

    Parameters
    ----------
    result : risloc_rt.studies.walk.WalkResult
        The walk.
    path : str or Path
        The PNG to write.

    Returns
    -------
    Path
    """
    from ..plotting import new_figure, save_figure

    fig = new_figure(figsize=(8.0, 6.0))
    t = _column(result, "time")
    s = result.summary
    kinds = np.array([r["update"] for r in result.rows])
    for i, (key, dof_key, name) in enumerate((("nees", "nees_dof", "NEES"), ("nis", "nis_dof", "NIS"))):
        ax = fig.add_subplot(2, 1, i + 1)
        v, dof = _column(result, key), _column(result, dof_key)
        ok = np.isfinite(v) & (dof > 0)
        if key == "nis":  # the updates made; a gated measurement's NIS is drawn apart (it is why it was gated)
            gated = ok & np.isin(kinds, ("gated", "restart"))
            ok &= kinds == "used"
            if gated.any():
                ax.semilogy(t[gated], v[gated] / dof[gated], ls="none", marker="x", ms=5, color="#d62728",
                            label="gated (not used)")
        ax.semilogy(t[ok], v[ok] / dof[ok], ls="none", marker=".", ms=4, label=f"{name} / dof")
        if key == "nees":
            sm = _column(result, "smooth_nees")
            good = np.isfinite(sm) & (dof > 0)
            ax.semilogy(t[good], sm[good] / dof[good], ls="none", marker="+", ms=4, color="#2ca02c",
                        label="smoothed track's NEES / dof")
        if ok.any():
            d = int(np.median(dof[ok]))
            lo, hi = nees_band(d, 1)
            ax.axhspan(lo / d, hi / d, color="#2ca02c", alpha=0.12, label=f"95 % band of one χ²({d}) / {d}")
            mean = float(np.sum(v[ok]) / np.sum(dof[ok]))
            mlo, mhi = nees_band(int(np.sum(dof[ok])), 1)
            ax.axhline(mean, color="#d62728", lw=1.0, label=f"walk mean {mean:.2f}")
            ax.axhspan(mlo / np.sum(dof[ok]), mhi / np.sum(dof[ok]), color="#d62728", alpha=0.15,
                       label="95 % band of the mean")
        ax.set_ylabel(f"{name} per dof")
        ax.legend(fontsize=7, loc="best")
    ax.set_xlabel("time [s]")
    fig.suptitle(f"filter consistency: NEES over {s['nees_dof']} states, NIS per measurement", fontsize=9)
    return save_figure(fig, path)
