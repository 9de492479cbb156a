"""A walk's ``summary.json``: its figures from the rows of ``walk.parquet`` (``docs/tracking.md``, "Outputs")."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from dsp.tracking import nees_band

from .trajectory import Trajectory
from .walk_tracker import UPDATE_KINDS

__all__ = ["walk_summary"]


def _rms(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def _corner_error(rows: list[dict[str, Any]], trajectory: Trajectory, window: float = 2.0,
                  column: str = "track_error") -> float | None:
    """The largest track error [m] (``column``) within ``window`` [s] of an inner waypoint (a turn of the path)."""
    t = np.array([r["time"] for r in rows])
    err = np.array([r[column] for r in rows])
    near = np.zeros(len(rows), dtype=bool)
    for tw in trajectory.times[1:-1]:
        near |= np.abs(t - tw) <= window
    sel = near & np.isfinite(err)
    return float(err[sel].max()) if sel.any() else None


def _split_figures(rows: list[dict[str, Any]], trajectory: Trajectory, window: float = 1.5,
                   columns: tuple[str, str] = ("track_error", "nees")) -> dict[str, Any]:
    """The track's RMSE [m] over the sweeps updated on a fix, and its RMSE and mean NEES (with the 95 % band of
    that many χ² values) at least ``window`` [s] from a turn (an inner waypoint) and within it; ``columns``
    name the error and NEES columns (the smoothed track's: ``smooth_error``, ``smooth_nees``)."""
    t = np.array([r["time"] for r in rows])
    err = np.array([r[columns[0]] for r in rows])
    nees = np.array([r[columns[1]] for r in rows])
    dof = next((int(r["nees_dof"]) for r in rows if r["nees_dof"]), 0)
    turns = np.asarray(trajectory.times[1:-1], dtype=float)
    near = (np.min(np.abs(t[:, None] - turns[None, :]), axis=1) < window) if turns.size else np.zeros(t.size, bool)
    used = np.array([r["update"] == "used" for r in rows])
    out: dict[str, Any] = {"track_rmse_updated_m": _rms(err[used]), "turn_window_s": window}
    for name, sel in (("far_from_turns", ~near), ("near_turns", near)):
        ok = sel & np.isfinite(nees)
        out[name] = {"sweeps": int(sel.sum()), "track_rmse_m": _rms(err[sel]),
                     "nees_mean": float(np.mean(nees[ok])) if ok.any() else None,
                     "nees_band_95": list(nees_band(dof, int(ok.sum()))) if ok.any() and dof else None}
    return out


def _smoothed_summary(rows: list[dict[str, Any]], trajectory: Trajectory, dof: int, turns: Any) -> dict[str, Any]:
    """``summary.json``'s ``smoothed``: the smoothed track's RMSE [m], largest error [m], mean NEES with its
    95 % band, the same split by turns as the track's, how its estimates were made, the turns it placed [s]."""
    from dsp.smoothing import SMOOTH_KINDS

    err = np.array([r["smooth_error"] for r in rows])
    nees = np.array([r["smooth_nees"] for r in rows])
    ok = np.isfinite(nees)
    band = nees_band(dof, int(ok.sum())) if ok.any() and dof else (math.nan, math.nan)
    mean = float(np.mean(nees[ok])) if ok.any() else None
    split = _split_figures(rows, trajectory, columns=("smooth_error", "smooth_nees"))
    split["rmse_updated_m"] = split.pop("track_rmse_updated_m")
    for part in ("far_from_turns", "near_turns"):
        split[part]["rmse_m"] = split[part].pop("track_rmse_m")
    kinds = [r["smooth"] for r in rows]
    return {"rmse_m": _rms(err), "max_error_m": float(np.nanmax(err)) if np.isfinite(err).any() else None,
            "corner_max_error_m": _corner_error(rows, trajectory, column="smooth_error"),
            "nees_mean": mean, "nees_band_95": list(band),
            "nees_mean_in_band": bool(mean is not None and band[0] <= mean <= band[1]), **split,
            "kinds": {k: kinds.count(k) for k in SMOOTH_KINDS},
            "turns": [{"gap_s": [t.start, t.end], "time_s": t.time, "std_time_s": t.std_time} for t in turns]}


def walk_summary(rows: list[dict[str, Any]], *, scene: Path, trajectory: Trajectory, schedule: Any, seed: int,
                 radar: Any, height: Any, height_std: float, tracker: Any, gate_pfa: float,
                 wall: float, turns: Any = ()) -> dict[str, Any]:
    """``summary.json``: the walk's figures (units in the keys' names or ``docs/tracking.md``, "Outputs").

    Parameters
    ----------
    rows : list of dict
        The walk's rows (:data:`risloc_rt.studies.walk.COLUMNS`).
    scene : Path
        The scene folder.
    trajectory : Trajectory
        The walk [s, m].
    schedule : risloc_rt.model.time_division.TimeDivision
        When each RIS swept.
    seed : int
        The noise seed.
    radar : dsp.RadarConfig
        The radar (its transmit power is reported) [dBm].
    height : "path", float or None
        The known height as the walk was given it [m].
    height_std : float
        Its 1σ [m].
    tracker : risloc_rt.studies.walk_tracker.WalkTracker
        The tracker (its parameters are reported).
    gate_pfa : float
        The χ² gate's probability.
    wall : float
        The walk's wall time [s].
    turns : sequence of dsp.smoothing.Turn
        The turns the smoother placed.

    Returns
    -------
    dict
    """
    col = {k: np.array([r[k] for r in rows]) for k in ("fix_error", "track_error", "nees", "nis", "nees_dof",
                                                       "nis_dof")}
    status = [r["status"] for r in rows]
    kinds = [r["update"] for r in rows]
    view = np.array([r["in_view"] for r in rows], dtype=bool)
    fix = np.array([s == "fix" for s in status])
    tracked = np.isfinite(col["nees"])
    nees_dof = int(col["nees_dof"][tracked][0]) if tracked.any() else 0
    n_nees = int(tracked.sum())
    used = np.isfinite(col["nis"]) & np.array([k == "used" for k in kinds])  # the NIS of the updates made
    nis_dof = int(np.sum(col["nis_dof"][used]))
    band = nees_band(nees_dof, n_nees) if n_nees else (math.nan, math.nan)
    single = nees_band(nees_dof, 1) if n_nees else (math.nan, math.nan)
    inside = float(np.mean((col["nees"][tracked] >= single[0]) & (col["nees"][tracked] <= single[1]))) if n_nees else None
    nis_band = nees_band(1, nis_dof) if nis_dof else (math.nan, math.nan)
    fix_err = col["fix_error"][fix]
    return {
        "scene": scene.name, "trajectory": trajectory.source, "seed": int(seed), "length_m": trajectory.length,
        "duration_s": trajectory.duration, "sweeps": len(rows), "schedule": schedule.to_dict(),
        "tx_power_dbm": float(radar.tx_power_dbm),
        "height": height if height is None or isinstance(height, str) else float(height), "height_std_m": height_std,
        "tracker": tracker.describe(), "gate_pfa": gate_pfa,
        "sweeps_per_ris": {name: sum(r["ris"] == name for r in rows) for name in schedule.order},
        "sweeps_in_view": int(view.sum()), "fixes": int(fix.sum()), "fixes_in_view": int((fix & view).sum()),
        "fixes_out_of_view": int((fix & ~view).sum()),
        "fix_share_in_view": float((fix & view).sum() / view.sum()) if view.any() else None,
        "behind": status.count("behind"), "no_detection": status.count("no-detection"),
        "no_position": status.count("no-position"),
        "updates": {k: kinds.count(k) for k in UPDATE_KINDS},
        "fix_rmse_m": _rms(fix_err), "fix_median_error_m": float(np.median(fix_err)) if fix_err.size else None,
        "fix_rmse_in_view_m": _rms(col["fix_error"][fix & view]),
        "track_rmse_m": _rms(col["track_error"]),
        "track_max_error_m": float(np.nanmax(col["track_error"])) if tracked.any() else None,
        "corner_max_error_m": _corner_error(rows, trajectory), **_split_figures(rows, trajectory),
        "nees_dof": nees_dof, "nees_mean": float(np.mean(col["nees"][tracked])) if n_nees else None,
        "nees_band_95": list(band), "nees_mean_in_band": bool(band[0] <= np.mean(col["nees"][tracked]) <= band[1])
        if n_nees else False, "nees_share_in_single_band_95": inside, "nees_single_band_95": list(single),
        "smoothed": _smoothed_summary(rows, trajectory, nees_dof, turns),
        "nis_sum": float(np.sum(col["nis"][used])), "nis_dof": nis_dof,
        "nis_mean_per_dof": float(np.sum(col["nis"][used]) / nis_dof) if nis_dof else None,
        "nis_band_95_per_dof": list(nis_band),
        "seconds": {"trace": float(sum(r["seconds_trace"] for r in rows)),
                    "simulate": float(sum(r["seconds_simulate"] for r in rows)),
                    "dsp": float(sum(r["seconds_dsp"] for r in rows)), "total": float(wall)},
    }
