"""What qualifies an estimate: its 1σ uncertainty and a known radar height.

Used by :func:`dsp.self_localize`: :func:`solve_elevation` turns a known height into the elevation
a 1-D sweep cannot see, :func:`sweep_uncertainty` turns an estimator's 1σ bounds into an
:class:`Uncertainty` with the position's 1σ. The formulas are in ``docs/estimation.md``; the
flags are in :mod:`dsp.flags`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize

from .validation import fields_equal
from .crb import position_std
from .geometry import RisPose, direction_from_angles
from .sweep import BeamSweep

__all__ = ["Uncertainty", "EstimatorBounds", "is_one_dimensional", "position_at", "elevation_for_height",
           "solve_elevation", "sweep_uncertainty"]


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """1σ of an estimate, from the Cramér–Rao bound at the measured SNR (``docs/estimation.md``).

    Attributes
    ----------
    distance : float
        [m].
    velocity : float
        [m/s].
    aod : float array [2]
        [az, el] [rad]; el is NaN when the sweep cannot see it and no height was given.
    position : float array [3]
        Along the world x, y, z axes [m] (elevation error not included when el is NaN).
    peak_snr_db : float
        The post-integration SNR at the pattern peak the bound was evaluated at [dB]: the measured
        one with the noise's share of the beams' magnitudes removed (unbiased; the plain measured
        one is 9 % high at 17.8 dB, ``docs/estimation.md``).
    kind : str
        ``"crb"`` (refined estimator: the bound, times the static template's variance factor for
        distance and velocity) or ``"crb+grid"`` (paper estimator: its Hann-windowed single-beam
        peak and its best-beam choice, plus the grid quantisation, step²/12, of delay, Doppler and
        AoD). The bound is :func:`dsp.sweep_crb` with ``phases="random"`` at the SNR corrected for
        the noise in the beams' magnitudes (``docs/estimation.md``, "What the stated 1σ is").
    grid : float array [3] or None
        A grid estimator's largest quantisation error, half its grid step, of distance [m],
        velocity [m/s] and azimuth [rad]: its error is this quantisation (fixed for a fixed
        geometry, a bias, not noise) plus bin jumps; None for an off-grid estimator.
    """

    distance: float
    velocity: float
    aod: np.ndarray
    position: np.ndarray
    peak_snr_db: float
    kind: str
    grid: np.ndarray | None = None

    @property
    def peb(self) -> float:
        """Position error bound sqrt(σ_x² + σ_y² + σ_z²) [m]."""
        return float(np.sqrt(np.sum(np.square(self.position))))

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary (NaN where not estimated)."""
        return {"distance": float(self.distance), "velocity": float(self.velocity),
                "aod": [float(v) for v in self.aod], "position": [float(v) for v in self.position],
                "peb": self.peb, "peak_snr_db": float(self.peak_snr_db), "kind": self.kind,
                "grid_max_error": None if self.grid is None else dict(zip(("distance", "velocity", "az"),
                                                                          (float(v) for v in self.grid)))}

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True)
class EstimatorBounds:
    """An estimator's 1σ of what it measures directly; :func:`sweep_uncertainty` adds the position's.

    Attributes
    ----------
    distance : float
        [m].
    velocity : float
        [m/s].
    az, el : float
        [rad]; ``el`` NaN when the sweep cannot see it.
    kind : str
        How they were made (:attr:`Uncertainty.kind`).
    grid : (float, float, float) or None
        Half the grid step of distance [m], velocity [m/s] and azimuth [rad] of a grid estimator
        (:attr:`Uncertainty.grid`); None off the grid.
    peak_snr : float or None
        The SNR the bounds were evaluated at when the estimator corrected the measured one
        (:func:`dsp.estimators.debiased_peak_snr`) [linear]; None: the measured one.
    """

    distance: float
    velocity: float
    az: float
    el: float
    kind: str
    grid: tuple[float, float, float] | None = None
    peak_snr: float | None = None


def is_one_dimensional(sweep: BeamSweep) -> bool:
    """All beams at one elevation: the sweep measures only u = cos(el)·sin(az)."""
    return bool(np.ptp(sweep.angles[:, 1]) < 1e-12)


def position_at(pose: RisPose, distance: float, az: float, el: float) -> np.ndarray:
    """The world position [3] [m] at ``distance`` [m] from the RIS along RIS-frame ``(az, el)`` [rad]."""
    return pose.position + distance * pose.to_world(direction_from_angles(np.array([az, el])))


def elevation_for_height(pose: RisPose, distance: float, u: float, height: float, *,
                         near: float = 0.0) -> tuple[float, float] | None:
    """(az, el) with cos(el)·sin(az) = u that put the UE at world z = ``height``.

    Parameters
    ----------
    pose : RisPose
    distance : float
        RIS–UE distance [m].
    u : float
        Measured direction cosine along the row axis [unitless].
    height : float
        World z of the radar [m].
    near : float
        When several elevations fit, the one closest to this [rad].

    Returns
    -------
    (float, float) or None
        [rad]; None when no elevation reaches that height.
    """
    if not (distance > 0 and abs(u) < 1):
        return None
    el_max = float(np.arccos(min(abs(u), 1.0))) * (1 - 1e-12)

    def z(el: float) -> float:
        az = float(np.arcsin(np.clip(u / np.cos(el), -1, 1)))
        return float(position_at(pose, distance, az, el)[2]) - height

    grid = np.linspace(-el_max, el_max, 181)
    vals = np.array([z(e) for e in grid])
    roots = []
    for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) <= 0):
        if vals[i] == 0:
            roots.append(grid[i])
            continue
        roots.append(scipy.optimize.brentq(z, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15))
    if not roots:
        return None
    el = float(min(roots, key=lambda e: abs(e - near)))
    return float(np.arcsin(np.clip(u / np.cos(el), -1, 1))), el


def solve_elevation(sweep: BeamSweep, pose: RisPose, distance: float, aod: np.ndarray,
                    height: float | None) -> tuple[np.ndarray, bool]:
    """The AoD with the elevation a 1-D sweep cannot see solved from the radar's known height.

    Parameters
    ----------
    sweep : BeamSweep
        Only a 1-D sweep (:func:`is_one_dimensional`) has its elevation solved.
    pose : RisPose
    distance : float
        RIS–UE distance [m]; nothing is solved unless it is positive.
    aod : float array [2]
        The estimate ``[az, el]`` [rad]; its u = cos(el)·sin(az) is kept.
    height : float or None
        World z of the radar [m]; None: nothing to solve.

    Returns
    -------
    aod : float array [2]
        ``[az, el]`` [rad] from :func:`elevation_for_height`, or ``aod`` itself when not solved.
    solved : bool
        Whether the elevation was solved.
    """
    if is_one_dimensional(sweep) and height is not None and distance > 0:
        u = float(np.cos(aod[1]) * np.sin(aod[0]))
        sol = elevation_for_height(pose, distance, u, height, near=float(aod[1]))
        if sol is not None:
            return np.array(sol), True
    return aod, False


def sweep_uncertainty(pose: RisPose, aod: np.ndarray, distance: float, bounds: EstimatorBounds, *,
                      peak_snr: float, solved_height: float | None = None) -> Uncertainty:
    """An estimator's 1σ of distance, velocity and AoD, with the position's 1σ propagated from them.

    Parameters
    ----------
    pose : RisPose
    aod : float array [2]
        The estimate ``[az, el]`` [rad] (after :func:`solve_elevation`).
    distance : float
        The estimated RIS–UE distance [m].
    bounds : EstimatorBounds
        The estimator's 1σ of distance [m], velocity [m/s], azimuth and elevation [rad].
    peak_snr : float
        The measured post-integration SNR at the pattern peak [linear]; ``bounds.peak_snr``, where
        given, replaces it (the SNR the bounds were evaluated at is the one reported).
    solved_height : float or None
        The radar's height [m] when the elevation was solved from it: the position then moves
        along u = cos(el)·sin(az) and the elevation's 1σ follows from the distance's and u's.

    Returns
    -------
    Uncertainty
    """
    sd_distance, sd_az, sd_el = bounds.distance, bounds.az, bounds.el
    if bounds.peak_snr is not None:
        peak_snr = bounds.peak_snr
    if solved_height is not None:
        u0 = float(np.cos(aod[1]) * np.sin(aod[0]))
        sd_u = sd_az * abs(np.cos(aod[0]) * np.cos(aod[1]))

        def locate(p: np.ndarray) -> np.ndarray:
            s = elevation_for_height(pose, p[0], p[1], solved_height, near=float(aod[1]))
            a = s if s is not None else (float(aod[0]), float(aod[1]))
            return pose.position + p[0] * pose.to_world(direction_from_angles(np.array(a)))

        pos_sd = position_std(locate, [distance, u0], [sd_distance, sd_u])
        el_sd = float(np.linalg.norm(position_std(lambda p: np.array([elevation_for_height(
            pose, p[0], p[1], solved_height, near=float(aod[1]))[1], 0, 0]), [distance, u0], [sd_distance, sd_u])))
        aod_sd = np.array([sd_az, el_sd])
    else:
        pos_sd = position_std(
            lambda p: pose.position + p[0] * pose.to_world(direction_from_angles(p[1:3])),
            [distance, aod[0], aod[1]], [sd_distance, sd_az, sd_el])
        aod_sd = np.array([sd_az, sd_el])
    return Uncertainty(distance=sd_distance, velocity=bounds.velocity, aod=aod_sd, position=pos_sd,
                       peak_snr_db=float(10 * np.log10(peak_snr)), kind=bounds.kind,
                       grid=None if bounds.grid is None else np.asarray(bounds.grid, dtype=float))
