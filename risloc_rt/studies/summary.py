"""Per-point statistics of a study: MAE and RMSE with 95 % intervals, detection, flags, bound, time.

Errors are taken over the **detected** runs (a run without a detection has no position); the
detection probability says how many those are. Distance error |d̂ − d| [m], angle error the
angle between the estimated and true directions [rad], position error ‖x̂ − x‖ [m].

Confidence intervals (95 %): percentile bootstrap with :data:`BOOTSTRAP` resamples of the
detected runs, its generator seeded from the study seed and the point
(``SeedSequence(seed, spawn_key=(point, 2**32 - 1))``), so the interval is reproducible; the
detection probability gets the Wilson score interval.

Coverage (:func:`coverage`): how honest the stated 1σ is. Over the detected runs with a finite
error and a finite, positive σ, the share whose |error| is within 1, 2 and 3 σ — distance
(``distance_error`` / ``std_distance``), azimuth (``aod_az_error`` / ``std_aod_az``) and position
(``position_error`` / ``peb``) — each with its Wilson 95 % interval. A Gaussian error has
68.3 / 95.4 / 99.7 % (:data:`GAUSSIAN_COVERAGE`); the position's ‖e‖ ≤ k·PEB has between that
(all of the error along one axis) and 1 − exp(−k²) = 63.2 / 98.2 / 99.99 % (a circular error in
two axes) (``docs/studies.md``).

Doubted runs: a detected run whose flags include one of a possible gross error
(:data:`dsp.fusion.DOUBT_CODES`: ``off-detection``, ``aliased``, ``grating-lobe``, ...; the codes a
fusion leaves out and the tracker skips) is counted in ``doubted``; ``mae_undoubted``, ``rmse_undoubted``
(with their bootstrap intervals) and ``rmse_undoubted_over_crb`` are taken over the other detected runs.
The MAE and RMSE themselves stay over every detected run: a flag does not change a number, and what a
user of the estimator would get includes its flagged runs.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np

from dsp.fusion import DOUBT_CODES

from .spec import StudySpec

__all__ = ["summarize", "coverage", "BOOTSTRAP", "COVERAGE_LEVELS", "GAUSSIAN_COVERAGE"]

#: Bootstrap resamples per interval.
BOOTSTRAP = 1000
_QUANTITIES = {"distance": "distance_error", "angle": "angle_error", "position": "position_error"}
#: Error column and stated-1σ column of each quantity whose coverage is counted.
_COVERED = {"distance": ("distance_error", "std_distance"), "angle": ("aod_az_error", "std_aod_az"),
            "position": ("position_error", "peb")}
#: The multiples of the stated σ whose coverage is counted.
COVERAGE_LEVELS = (1, 2, 3)
#: P(|e| <= kσ) for a Gaussian e, k = 1, 2, 3 [unitless].
GAUSSIAN_COVERAGE = (0.682689, 0.954500, 0.997300)


def _wilson(k: int, n: int, z: float = 1.959964) -> list[float]:
    if n == 0:
        return [0.0, 1.0]
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return [max(0.0, mid - half), min(1.0, mid + half)]


def _intervals(err: np.ndarray, rng: np.random.Generator) -> tuple[list[float], list[float]]:
    """95 % percentile-bootstrap intervals of MAE and RMSE of ``err`` [n]."""
    n = err.size
    if n < 2:
        return [math.nan, math.nan], [math.nan, math.nan]
    idx = rng.integers(0, n, size=(BOOTSTRAP, n))
    a = np.abs(err)[idx]
    mae = a.mean(axis=1)
    rmse = np.sqrt((a * a).mean(axis=1))
    q = [2.5, 97.5]
    return np.percentile(mae, q).tolist(), np.percentile(rmse, q).tolist()


def coverage(errors: Any, sigmas: Any) -> dict[str, Any]:
    """Share of errors within 1, 2 and 3 stated σ, with Wilson 95 % intervals.

    Parameters
    ----------
    errors : float array [R]
        Signed or absolute errors (any unit).
    sigmas : float array [R]
        The stated 1σ of each, same unit. Pairs with a non-finite error or a σ that is not finite
        and positive (no σ, an unobservable angle) are left out.

    Returns
    -------
    dict
        ``n`` (pairs counted), ``levels`` [1, 2, 3], ``share`` [3] (|e| <= kσ) [unitless] and ``ci95``
        [3][2] (Wilson score intervals; [0, 1] when n = 0).
    """
    e = np.abs(np.asarray(errors, dtype=float)).ravel()
    s = np.asarray(sigmas, dtype=float).ravel()
    if e.shape != s.shape:
        raise ValueError(f"errors ({e.size}) and sigmas ({s.size}) must have one σ per error")
    keep = np.isfinite(e) & np.isfinite(s) & (s > 0)
    e, s = e[keep], s[keep]
    n = int(e.size)
    counts = [int(np.count_nonzero(e <= k * s)) for k in COVERAGE_LEVELS]
    return {"n": n, "levels": list(COVERAGE_LEVELS),
            "share": [c / n if n else math.nan for c in counts],
            "ci95": [_wilson(c, n) for c in counts]}


def _errors(rows: list[dict[str, Any]], rng: np.random.Generator) -> tuple[dict, dict, dict, dict]:
    """MAE, RMSE and their 95 % intervals of each quantity over ``rows`` (non-finite errors left out;
    NaN without any): four dicts keyed like :data:`_QUANTITIES`, in its units."""
    mae, rmse, mae_ci, rmse_ci = {}, {}, {}, {}
    for name, col in _QUANTITIES.items():
        e = np.array([r[col] for r in rows], dtype=float)
        e = e[np.isfinite(e)]
        mae[name] = float(np.mean(np.abs(e))) if e.size else math.nan
        rmse[name] = float(np.sqrt(np.mean(e * e))) if e.size else math.nan
        mae_ci[name], rmse_ci[name] = _intervals(e, rng)
    return mae, rmse, mae_ci, rmse_ci


def summarize(spec: StudySpec, rows: list[dict[str, Any]], info: dict[str, Any]) -> dict[str, Any]:
    """The ``summary.json`` object: ``{"study": ..., "points": [...]}`` (module docstring).

    Parameters
    ----------
    spec : StudySpec
        The study.
    rows : list of dict
        The run rows of every point (runs >= ``spec.runs`` are ignored).
    info : dict
        What :func:`risloc_rt.studies.engine.execute` returned (bounds, preparation times, retries).

    Returns
    -------
    dict
        ``study``, ``key``, ``x`` (the figures' x parameter), ``units``, ``intervals``, ``retried``
        and ``points``: per point its parameters, detection probability (Wilson 95 % interval),
        MAE and RMSE of distance [m], angle [rad] and position [m] with bootstrap 95 % intervals,
        the CRB and the random-phase bound, their ratios, ``coverage`` of the stated 1σ (:func:`coverage`
        per quantity), ``doubted`` (detected runs flagged with a possible gross error) and
        ``mae_undoubted``, ``rmse_undoubted`` (MAE and RMSE over the others, with 95 % intervals) and
        ``rmse_undoubted_over_crb``, mean SNR [dB], flag counts and times [s].

    Raises
    ------
    RuntimeError
        A point has fewer than ``spec.runs`` runs in ``rows``.
    """
    points = spec.points()
    by_point: dict[int, list[dict[str, Any]]] = {p: [] for p in range(len(points))}
    for r in rows:
        if int(r["run"]) < spec.runs and int(r["point"]) in by_point:
            by_point[int(r["point"])].append(r)
    out = []
    for p, params in enumerate(points):
        rs = sorted(by_point[p], key=lambda r: int(r["run"]))
        if len(rs) != spec.runs:
            raise RuntimeError(f"point {p} has {len(rs)} of {spec.runs} runs in the log; rerun the study to finish it")
        det = [r for r in rs if r["detected"]]
        rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(p, 2**32 - 1)))
        mae, rmse, mae_ci, rmse_ci = _errors(det, rng)
        doubted = [bool(set((r.get("flags") or "").split(",")) & DOUBT_CODES) for r in det]
        # after the intervals above (the same generator): their resamples do not change
        mae_undoubted, rmse_undoubted, mae_undoubted_ci, rmse_undoubted_ci = _errors(
            [r for r, d in zip(det, doubted) if not d], rng)
        bounds = {k: float(v) for k, v in info["crb"][p].items()}
        crb = {k: v for k, v in bounds.items() if not k.endswith("_random_phase")}
        random_phase = {k[: -len("_random_phase")]: v for k, v in bounds.items() if k.endswith("_random_phase")}

        def over(b: dict[str, float], of: dict[str, float] = rmse) -> dict[str, float]:
            return {k: (of[k] / b[k] if b.get(k, 0) > 0 and math.isfinite(of[k]) else math.nan) for k in _QUANTITIES}

        ratio = over(crb)
        flags = Counter(code for r in rs for code in (r.get("flags") or "").split(",") if code)
        seconds = float(np.mean([r["seconds"] for r in rs]))
        prepare = float(info["prepare_seconds"].get(p, 0.0))
        out.append({
            "params": params,
            "runs": len(rs),
            "detected": len(det),
            "detection_probability": len(det) / len(rs),
            "detection_probability_ci95": _wilson(len(det), len(rs)),
            "mae": mae, "mae_ci95": mae_ci,
            "rmse": rmse, "rmse_ci95": rmse_ci,
            # the detected runs flagged with a possible gross error, and the MAE over the others
            "doubted": int(sum(doubted)),
            "mae_undoubted": mae_undoubted, "mae_undoubted_ci95": mae_undoubted_ci,
            "rmse_undoubted": rmse_undoubted, "rmse_undoubted_ci95": rmse_undoubted_ci,
            "rmse_undoubted_over_crb": over(crb, rmse_undoubted),
            "crb": crb,
            "rmse_over_crb": ratio,
            "bound_random_phase": random_phase,  # the per-beam phases random: dsp.sweep_crb(phases="random")
            "rmse_over_bound_random_phase": over(random_phase) if random_phase else {},
            # the stated 1σ's honesty: share of detected runs with |error| <= 1, 2, 3 σ (Wilson 95 %)
            "coverage": {name: coverage([r.get(ce, math.nan) for r in det], [r.get(cs, math.nan) for r in det])
                         for name, (ce, cs) in _COVERED.items()},
            "mean_snr_db": float(np.nanmean([r["snr_db"] for r in rs])) if rs else math.nan,
            "flags": dict(sorted(flags.items())),
            "seconds_per_run": seconds + prepare / len(rs),
            "seconds_per_run_dsp": seconds,
            "prepare_seconds": prepare,
        })
    return {
        "study": spec.to_dict(),
        "key": spec.key,
        "x": spec.x_name,
        "units": {"distance": "m", "angle": "rad", "position": "m", "seconds_per_run": "s (one core)"},
        "intervals": f"95 % percentile bootstrap ({BOOTSTRAP} resamples) over the detected runs; Wilson for the "
                     "detection probability and the coverage",
        "points": out,
        "retried": list(info.get("retried", [])),
    }
