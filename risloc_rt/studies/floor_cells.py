"""A floor map's cells: one run's position from the RISs that saw it, the PEB of several RISs, folded returns, coverage.

What :mod:`risloc_rt.studies.floor_map` computes per cell and run once the runs are in
(``docs/studies.md``, "Floor maps"): :func:`cell_run_position` fuses the fixes of the RISs that
detected the radar (:func:`fuse_at_height`, the map's height known), :func:`folded_return` applies
``risloc locate``'s link-budget check for range aliasing to a run, :func:`multi_ris_peb` is the
bound of the geometry from the summed Fisher information, :func:`coverage` the share of the floor a
map covers. Pure functions of run rows and bounds: nothing is traced or simulated here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dsp.fusion import KNOWN_HEIGHT_STD

__all__ = ["COVERED_PD", "HEIGHT_STD", "cell_run_position", "coverage", "folded_return", "fuse_at_height",
           "multi_ris_peb", "row_float", "usable_run"]


#: A floor cell is covered when its detection probability is at least this (n/n runs for n < 100)
#: and its PEB is below the map's ``peb_bound``.
COVERED_PD = 0.99


#: The 1σ of the map's known radar height in the fusion [m] (``dsp.fusion.KNOWN_HEIGHT_STD``): the cell's
#: height is exact, as the single-RIS fix assumes it (``elevation-assumed``).
HEIGHT_STD = KNOWN_HEIGHT_STD


def row_float(value: Any) -> float:
    """A run row's float (None, as the run log writes NaN, is NaN).

    Parameters
    ----------
    value : float or None
        The row's value.

    Returns
    -------
    float
    """
    return float("nan") if value is None else float(value)


def multi_ris_peb(bounds: Any, position: Any) -> float:
    """The PEB of several RISs at one radar position with its height known: from the summed Fisher information.

    Each RIS i measures the radar's distance dᵢ and azimuth azᵢ (its frame) with the 1σ of its
    Cramér–Rao bound at that position (the fixed-phase ``distance`` [m] and ``angle`` [rad] of
    :func:`risloc_rt.studies.kernel.point_bound`, which the map's cell preparer computes from the
    RIS's own noiseless return; a 1-D sweep measures no elevation). With ``h(x, y)`` the
    measurements at height z = ``position[2]`` (known), the information on (x, y) is
    ``J = Σᵢ Hᵢᵀ diag(1/σ_d,ᵢ², 1/σ_az,ᵢ²) Hᵢ``, ``Hᵢ = ∂(dᵢ, azᵢ)/∂(x, y)`` (the closed form of
    ``dsp.RisFix.linearised`` at the truth), and the PEB is ``sqrt(trace(J⁻¹))``. For one RIS at
    the radar's height this is its own PEB, ``sqrt(σ_d² + d² σ_az²)`` (a test checks it against the
    bound's ``position``).

    Parameters
    ----------
    bounds : sequence of (dsp.RisPose, dict)
        Each RIS's pose and its bounds (``distance`` [m], ``angle`` [rad]) at ``position``.
    position : float array [3]
        The true radar position [m], world frame.

    Returns
    -------
    float
        PEB [m] (inf when the RISs cannot determine the position, e.g. no bound given).
    """
    from dsp import RisFix

    x = np.asarray(position, dtype=float)
    fixes = []
    for i, (pose, crb) in enumerate(bounds):
        d = float(np.linalg.norm(x - pose.position))
        if not (np.isfinite(crb["distance"]) and np.isfinite(crb["angle"]) and crb["distance"] > 0 and crb["angle"] > 0):
            continue
        fixes.append(RisFix(name=f"ris{i}", pose=pose, distance=d, std_distance=float(crb["distance"]),
                            aod=np.asarray(pose.angles_to(x), dtype=float), std_aod=[float(crb["angle"]), np.nan]))
    if not fixes:
        return float("inf")
    jac = np.vstack([f.linearised(x)[1][:, :2] for f in fixes])  # ∂r/∂(x, y) at the known height
    info = jac.T @ jac
    if np.linalg.cond(info) > 1e12:
        return float("inf")
    return float(np.sqrt(np.trace(np.linalg.inv(info))))


def fuse_at_height(fixes: Any, height: float, *, pfa: float = 1e-3) -> tuple[np.ndarray, Any]:
    """Fuse RIS fixes into one position at a known radar height.

    ``dsp.fuse_fixes`` with the height as one more measurement (``height=(height, HEIGHT_STD)``): its
    χ² test decides which fixes agree (an inconsistent one is left out and flagged) with the height
    known, and the position is returned at z = ``height``. RISs at one height cannot see the height
    (1-D sweeps), and the map's radar height is known, as the single-RIS fix assumes it.

    Parameters
    ----------
    fixes : sequence of dsp.RisFix
        One per detected RIS.
    height : float
        The radar's height z [m], world frame.
    pfa : float
        The χ² test's false-alarm probability (``dsp.fuse_fixes``).

    Returns
    -------
    position : float array [3]
        The fused position [m], z = ``height``.
    fused : dsp.FusedFix
        What ``dsp.fuse_fixes`` said (used, excluded, flags).
    """
    from dsp import fuse_fixes

    fused = fuse_fixes(fixes, pfa=pfa, height=(float(height), HEIGHT_STD))
    return np.array([fused.position[0], fused.position[1], float(height)]), fused


def cell_run_position(entries: Any, truth: Any,
                      height: float) -> tuple[float, tuple[str, ...], tuple[str, ...], tuple[str, ...]] | None:
    """One run of one cell: the position error of what its RISs gave (one fix as it is, several fused).

    Parameters
    ----------
    entries : sequence of (str, dsp.RisPose, dict)
        Each RIS that sees the cell: its name, pose and this run's row
        (:func:`risloc_rt.studies.kernel.run_once`: ``detected``, ``distance`` [m], ``aod_az`` [rad],
        ``std_distance`` [m], ``std_aod_az`` [rad], ``x``, ``y``, ``z`` [m], ``position_error`` [m], ``flags``;
        ``folded``: True when the link-budget check found the return folded, :func:`folded_return`:
        such a fix counts as no detection).
    truth : float array [3]
        The radar's true position [m].
    height : float
        Its known height [m] (:func:`fuse_at_height`).

    Returns
    -------
    (float, tuple of str, tuple of str, tuple of str) or None
        The position error [m], the RISs used, those left out as inconsistent and the fusion's flag
        codes (``inconsistent-ris`` also when the fixes disagree and the χ² test cannot say which is
        wrong: the position is their compromise; ``unobservable``: the height); None when no RIS
        detected the radar (or every detection was folded). One detection: that RIS's own ``position_error``; several: the error of
        :func:`fuse_at_height` over the fixes with a stated 1σ and a positive distance.
    """
    from dsp import RisFix, angles_from_direction

    found = [(name, pose, row) for name, pose, row in entries if usable_run(row)]
    if not found:
        return None
    fixes = []
    for name, pose, row in found:
        sd, sa, d = row_float(row.get("std_distance")), row_float(row.get("std_aod_az")), row_float(row.get("distance"))
        if not (np.isfinite(sd) and sd > 0 and np.isfinite(sa) and sa > 0 and np.isfinite(d) and d > 0):
            continue  # no stated 1σ, or a distance at or below zero (a return before the loop-back delay)
        rel = np.array([row_float(row["x"]), row_float(row["y"]), row_float(row["z"])]) - pose.position
        el = float(angles_from_direction(pose.to_local(rel / np.linalg.norm(rel)))[1])
        fixes.append(RisFix(name=name, pose=pose, distance=row_float(row["distance"]), std_distance=sd,
                            aod=[row_float(row["aod_az"]), el], std_aod=[sa, np.nan],
                            flags=tuple(f for f in (row.get("flags") or "").split(",") if f)))
    if len(fixes) < 2:  # one fix (or one that can be fused): that RIS's own position
        name, _, row = next(((n, p, r) for n, p, r in found if fixes and n == fixes[0].name), found[0])
        return row_float(row["position_error"]), (name,), (), ()
    position, fused = fuse_at_height(fixes, height)
    return (float(np.linalg.norm(position - np.asarray(truth, dtype=float))), tuple(fused.used),
            tuple(n for n, _ in fused.excluded), tuple(f.code for f in fused.flags))


def usable_run(row: dict[str, Any]) -> bool:
    """A run row that gives a position: detected, its return not found folded (:func:`folded_return`) and its
    distance above zero (a return folded to just before the loop-back delay is no fix either).

    Parameters
    ----------
    row : dict
        A run row (``detected``, ``folded``, ``distance`` [m]).

    Returns
    -------
    bool
    """
    return bool(row["detected"]) and not row.get("folded", False) and row_float(row.get("distance")) > 0


def folded_return(row: dict[str, Any], scenario: Any, pose: Any, peak_snr_db: float) -> Any:
    """The link-budget check for range aliasing of ``risloc locate`` on one run of a map point.

    A radar beyond a RIS's unambiguous range (21.8 m less τ_RB·c/2 at Table I) sees that RIS's
    return folded to ``d - R_max`` and localizes it there without a flag of the DSP's own;
    ``risloc_rt.io.report.process_capture`` checks the power
    (:func:`risloc_rt.model.power_check.range_alias_flag`: more than 10 dB below the link budget at
    d̂ and closer to it at d̂ + k·R_max raises ``aliased``). The map's runs go through
    ``dsp.self_localize`` alone, so the map applies the same check here, with the point's true
    post-integration SNR (its bound's ``peak_snr_db``, from the noiseless cube: what the estimate's
    fitted SNR estimates, within a fraction of a dB at a detectable SNR against the 10 dB margin) in
    place of the run's fitted one, and the run's own d̂ and azimuth.

    Parameters
    ----------
    row : dict
        A detected run row (``distance`` [m], ``aod_az`` [rad], ``x``, ``y``, ``z`` [m]).
    scenario : risloc_rt.model.Scenario
        The point's scenario (radar, RIS, sweep: ``hall_scenario(...).base``).
    pose : dsp.RisPose
        The RIS's pose.
    peak_snr_db : float
        The point's true post-integration SNR at the pattern peak [dB].

    Returns
    -------
    dsp.Flag or None
        The ``aliased`` flag when the power points to a folded return.
    """
    from types import SimpleNamespace

    from dsp import angles_from_direction

    from ..model.power_check import range_alias_flag

    if not row["detected"] or not np.isfinite(row_float(row.get("distance"))) or not np.isfinite(peak_snr_db):
        return None
    rel = np.array([row_float(row["x"]), row_float(row["y"]), row_float(row["z"])]) - pose.position
    el = float(angles_from_direction(pose.to_local(rel / np.linalg.norm(rel)))[1])
    loc = SimpleNamespace(detection=True, detected=True, distance=row_float(row["distance"]),
                          aod=np.array([row_float(row["aod_az"]), el]), std=SimpleNamespace(peak_snr_db=float(peak_snr_db)))
    capture = SimpleNamespace(radar=scenario.radar, ris=scenario.ris, sweep=scenario.sweep,
                              provenance={"source": "simulation"})
    return range_alias_flag(loc, capture)


def coverage(cells: list[dict[str, Any]], floor_cells: int, peb_bound: float) -> dict[str, Any]:
    """The share of the floor a map covers: cells with Pd >= :data:`COVERED_PD` and PEB below ``peb_bound``.

    Parameters
    ----------
    cells : list of dict
        The mapped cells (``detection_probability``, ``peb`` [m]).
    floor_cells : int
        Every floor cell, mapped or not (a cell no RIS sees counts as not covered).
    peb_bound : float
        The PEB bound [m].

    Returns
    -------
    dict
        ``peb_bound`` [m], ``detection_probability`` (:data:`COVERED_PD`), ``floor_cells``,
        ``mapped_cells``, ``covered`` (cells) and ``share`` (covered / floor cells): the issue's
        coverage; ``accurate`` and ``share_accurate``: covered cells whose position RMSE is below the
        bound too (a detection whose fix is wrong, e.g. a grating lobe or a path taken for the
        return, counts in Pd; this share says how much of the coverage the fixes deliver).
    """
    covered = [c for c in cells if c["detection_probability"] >= COVERED_PD and c["peb"] is not None
               and c["peb"] < peb_bound]
    accurate = sum(1 for c in covered if c["rmse_position"] is not None and c["rmse_position"] < peb_bound)
    share = (lambda n: n / floor_cells if floor_cells else 0.0)
    return {"peb_bound": float(peb_bound), "detection_probability": COVERED_PD, "floor_cells": int(floor_cells),
            "mapped_cells": len(cells), "covered": len(covered), "share": share(len(covered)),
            "accurate": accurate, "share_accurate": share(accurate)}
