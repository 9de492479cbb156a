"""``risloc calibrate --materials ... --scattering NAME``: a material's scattering coefficient S over the full simulator.

The material tracer's gradients hold S only through the specular loss √(1 − S²) per bounce; the diffuse returns a
scattering surface sends into other peaks' range cells (and folds) are not in that model, and on emulated recordings
they moved S by more than its σ (``docs/calibration-materials.md``, "Scattering coefficient"). So S is stated by its
profile likelihood over the full simulator (:func:`scattering_profiles`): at each S of :data:`SCATTERING_GRID` a scene
with that S is built, the captures' peaks are read against it as for the fit, and the other parameters are fitted
again; each peak's residual over S is smoothed (the diffuse paths are sampled anew for every S) and what the smooth
curve leaves, the simulator's own noise at that peak, is added to its σ.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .common import CliError, trace_settings

__all__ = ["scattering_profiles", "SCATTERING_GRID", "SCATTERING_FINE", "SCATTERING_SPAN"]

#: The scattering coefficients S [unitless] at which ``--scattering`` evaluates the full simulator (one scene, trace,
#: comparison and conditional fit each).
SCATTERING_GRID: tuple[float, ...] = tuple(round(0.05 * i, 2) for i in range(19))
#: Points of the fine S grid on which the smoothed profile is evaluated.
SCATTERING_FINE: int = 361
#: The smooth curve of each peak's residual is fitted to the computed S whose χ² is within this of the lowest (the
#: 99.7 % interval ends at Δχ² = 9; far beyond, the curve would bend to follow the steep walls of the profile).
SCATTERING_SPAN: float = 25.0


def scattering_profiles(args: argparse.Namespace, scene: Path, names: list[str], rough: list[str], fit: Any,
                        tmp: Path, progress: Callable[[int, float], None],
                        read_peaks: Callable[[argparse.Namespace, Path, list[str]], tuple[list, list[dict[str, Any]]]],
                        ) -> tuple[Any, list, list[dict[str, Any]], Path, dict[str, Any], dict[str, Any]]:
    """Each ``--scattering`` material's S by its profile likelihood over the full simulator (module docstring).

    At every S of :data:`SCATTERING_GRID` a scene folder with the fitted values and that S is built in ``tmp``, the
    captures' peaks are read against it exactly as for the fit (``read_peaks``: the beat model of every traced
    path, the diffuse returns of the scattering surfaces, range folding, the IF filter and G included) and the other
    parameters are fitted again (a conditional fit). Each peak's residual over S is then smoothed by least squares on
    the basis 1, 10 log10(1 − S²), S², S⁴ (:func:`_smooth_residuals`: the specular loss, the diffuse power and a
    bend), over the computed S whose χ² is within :data:`SCATTERING_SPAN` of the lowest; what the smooth curve
    leaves is the simulator's own noise at that peak (the diffuse paths' sampling and pruning change with S), added
    to the peak's σ in quadrature, and the profile is the χ² of the smooth residuals on a fine grid. Materials one
    after another, each conditional on the others' S at their start (then best) value.

    Parameters
    ----------
    args : argparse.Namespace
        The command line of ``risloc calibrate --materials`` (trace flags, ``--fixed``, ``--max-iter``, captures).
    scene : Path
        The source scene folder (with its ``spec.toml``).
    names : list of str
        The fitted materials.
    rough : list of str
        The ``--scattering`` materials, among ``names``.
    fit : MaterialFit
        The fit at the scene's own S (its values start the profiles).
    tmp : Path
        A temporary folder for the scene at each S.
    progress : callable
        ``progress(iteration, cost)`` of the final fit.
    read_peaks : callable
        ``read_peaks(args, scene, names) -> (observations, records)``: the captures' peaks against a scene, as for
        the fit.

    Returns
    -------
    tuple
        The fit, observations, records and scene folder at the computed S nearest the best;
        ``{"<material>:scattering": ProfileInterval}`` (grid in S²); and per material what ``material-fit.json`` adds,
        ``{"<material>:S": {computed_S, computed_chi2, peaks: [{distance_m, sigma_db, model_sigma_db}]}}``.

    Raises
    ------
    CliError
        No measured peak is explained at every S.
    """
    import contextlib
    import io
    import time

    from ..authoring.fitted_scene import write_fitted_scene
    from ..authoring.spec import loads_spec
    from ..hall.material_fit import fit_materials
    from ..hall.material_profile import ProfileInterval, profile_intervals_of

    settings = trace_settings(args)
    known = loads_spec((scene / "spec.toml").read_text(encoding="utf-8"), base_dir=scene).all_materials()
    current = {m: float(known[m].scattering_coefficient) for m in rough}
    base = {m: v[:2] for m, v in fit.values().items()}
    profiles: dict[str, Any] = {}
    notes: dict[str, Any] = {}
    points: dict[float, dict[str, Any]] = {}
    count = 0
    for m in rough:
        t0 = time.perf_counter()
        points = {}
        evaluations = 0
        for value in SCATTERING_GRID:
            count += 1
            values = _with_scattering(base, current, m, value)
            folder = write_fitted_scene(scene, tmp / f"variant-{count}", values, {"scattering_profile": m, "S": value})
            with contextlib.redirect_stdout(io.StringIO()):
                obs, recs = read_peaks(args, folder, names)
            cond = fit_materials(folder, obs, names, start=base, settings=settings, max_iter=args.max_iter,
                                 fixed=args.fixed, profile_check=False)
            evaluations += cond.evaluations
            keys = cond.identifiability.peaks
            points[value] = {"chi2": cond.chi2, "observations": obs, "records": recs, "folder": folder,
                             "values": _with_scattering(cond.values(), current, m, value),
                             "residuals": {key: float(r) for key, r in zip(keys, cond.residuals_db)},
                             "sigmas": {(i, k): float(obs[i].sigma_db[k]) for i, k in keys}}
            print(f"  scattering profile of {m}: S {value:.4g}, chi2 {cond.chi2:.5g}", file=sys.stderr, flush=True)
        grid = np.array(sorted(points))
        keys = sorted(set.intersection(*(set(points[g]["residuals"]) for g in grid)))
        if not keys:
            raise CliError(f"--scattering {m}: no measured peak is explained at every S of the profile")
        residuals = np.array([[points[g]["residuals"][key] for key in keys] for g in grid])
        sigmas = np.median(np.array([[points[g]["sigmas"][key] for key in keys] for g in grid]), axis=0)
        # the smooth curve is fitted where the profile matters: χ² within SCATTERING_SPAN of the lowest computed one
        raw = np.array([points[g]["chi2"] for g in grid])
        near = _near_minimum(raw)
        fine = np.linspace(float(grid[near].min()), float(grid[near].max()), SCATTERING_FINE)
        smooth, noise = _smooth_residuals(grid[near], residuals[near], fine)
        total = np.sqrt(sigmas ** 2 + noise ** 2)
        chi2 = np.sum((smooth / total) ** 2, axis=1)
        best = int(np.argmin(chi2))
        share = fine ** 2
        delta = chi2 - chi2[best]
        nearest = [grid[int(np.argmin(np.abs(grid - x)))] for x in fine]
        for arr in (share, delta):
            arr.setflags(write=False)
        prof = ProfileInterval(
            parameter=f"{m}:scattering", grid=share, delta_chi2=delta,
            values=tuple({**points[g]["values"], m: (*points[g]["values"][m][:2], float(x))} for g, x in zip(nearest, fine)),
            best=float(share[best]), chi2_min=float(chi2[best]), moved=False,
            limits=(float(share[0]), float(share[-1])), intervals=profile_intervals_of(share, delta, best),
            evaluations=evaluations, seconds=time.perf_counter() - t0)
        profiles[f"{m}:scattering"] = prof
        notes[f"{m}:S"] = {
            "computed_S": [float(g) for g in grid], "computed_chi2": [float(points[g]["chi2"]) for g in grid],
            "peaks": [{"distance_m": _peak_distance(points[grid[0]]["records"], key), "sigma_db": float(sg),
                       "model_sigma_db": float(nz)} for key, sg, nz in zip(keys, sigmas, noise)]}
        current[m] = float(fine[best])
        base = {k: v[:2] for k, v in points[nearest[best]]["values"].items()}
        print(f"scattering coefficient of {m} (profile over the full simulator, {grid.size} S computed, "
              f"{prof.seconds:.0f} s; the simulator's own noise at the peaks "
              + ", ".join(f"{nz:.2f}" for nz in noise) + f" dB): {prof.describe(1)}; 95.4 %: {prof.span(2)}")
    chosen = points[min(grid, key=lambda g: abs(g - current[rough[-1]]))]
    final = fit_materials(chosen["folder"], chosen["observations"], names, start=base, settings=settings,
                          max_iter=args.max_iter, fixed=args.fixed, progress=progress)
    return final, chosen["observations"], chosen["records"], chosen["folder"], profiles, notes


def _with_scattering(values: dict[str, tuple[float, ...]], current: dict[str, float], material: str,
                     value: float) -> dict[str, tuple[float, ...]]:
    """``{name: (ε_r, σ)}`` with S third for the profiled materials: ``value`` for ``material``, ``current`` for the
    others."""
    return {k: (*v[:2], value if k == material else current[k]) if k in current else v for k, v in values.items()}


def _peak_distance(records: list[dict[str, Any]], key: tuple[int, int]) -> float | None:
    """The measured distance [m] of explained peak ``key`` = (observation, peak) in the records."""
    i, k = key
    peaks = records[i]["peaks"] if i < len(records) else []
    return float(peaks[k]["distance_m"]) if k < len(peaks) else None


def _near_minimum(chi2: np.ndarray) -> np.ndarray:
    """The computed points whose χ² lies within :data:`SCATTERING_SPAN` of the lowest, as one run of neighbours around
    it, widened to at least 6 points (bool mask)."""
    best = int(np.argmin(chi2))
    lo = hi = best
    while lo > 0 and chi2[lo - 1] - chi2[best] <= SCATTERING_SPAN:
        lo -= 1
    while hi < chi2.size - 1 and chi2[hi + 1] - chi2[best] <= SCATTERING_SPAN:
        hi += 1
    while hi - lo + 1 < min(6, chi2.size):
        if lo > 0 and (hi == chi2.size - 1 or chi2[lo - 1] <= chi2[hi + 1]):
            lo -= 1
        else:
            hi += 1
    mask = np.zeros(chi2.size, bool)
    mask[lo:hi + 1] = True
    return mask


def _smooth_residuals(grid: np.ndarray, residuals: np.ndarray, fine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each peak's residual [dB] over S smoothed on the basis 1, 10 log10(1 − S²), S², S⁴; its value on ``fine`` [F, K]
    and the rms of what the smooth curve leaves [K] (dof-corrected; 0 with no more points than basis functions)."""
    def basis(x: np.ndarray) -> np.ndarray:
        u = np.asarray(x, dtype=float) ** 2
        return np.column_stack([np.ones_like(u), 10 * np.log10(1 - u), u, u ** 2])

    b = basis(grid)
    coef, *_ = np.linalg.lstsq(b, residuals, rcond=None)
    left = residuals - b @ coef
    dof = grid.size - b.shape[1]
    noise = np.sqrt(np.sum(left ** 2, axis=0) / dof) if dof > 0 else np.zeros(residuals.shape[1])
    return basis(fine) @ coef, noise
