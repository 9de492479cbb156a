"""Which beams the detector integrates: windows of the sweep matched to the RIS beam pattern.

A RIS return lights up only the few beams whose main lobe covers the UE (about 5 of the paper's
61). Summing the power of all M beams (the plain sweep-CFAR) adds the noise of the M - 5 others;
summing only a window of L beams around each candidate direction keeps the signal and drops
most of that noise. For each beam c of the sweep, the window W_c is the L beams with the
largest pattern gain A_m(φ_c)² at c's own steering direction (a 1-D sweep: L neighbours; a 2-D
sweep: the nearest in both axes; a reflective RIS: its grating lobe's beams too). L is chosen
once per (pattern, sweep, false-alarm level) to need the least SNR at the threshold:

    L* = argmin_L (η_L - L) / median_c Σ_{m∈W_c} A_m(φ_c)²,   Q(L, η_L) = p_cell / G_L,

η_L the Gamma(L, 1) level of the per-cell false-alarm probability shared among the G_L distinct
windows (a union bound: the statistic of each window is at most Gamma(L, 1) under H0, so the
stated false-alarm probability is an upper bound).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.special

from .pattern import BeamPattern
from .sweep import BeamSweep

__all__ = ["SweepWindows", "sweep_windows"]

#: Largest window tried [beams].
MAX_WINDOW = 24


@dataclass(frozen=True, eq=False)
class SweepWindows:
    """Beam windows of the detector.

    Attributes
    ----------
    beams : int array [G, L]
        The beams of each distinct window, sorted.
    size : int
        L, beams per window.
    capture : float
        Median over centres of the pattern energy a window holds, Σ_{m∈W} A_m² [unitless]
        (the full sweep holds Σ_m A_m²).
    contiguous : bool
        Every window is a run of consecutive beams (a cumulative sum computes them all).
    """

    beams: np.ndarray
    size: int
    capture: float
    contiguous: bool

    @property
    def count(self) -> int:
        """G, distinct windows."""
        return int(self.beams.shape[0])

    def threshold(self, cell_pfa: float) -> float:
        """η: a window's statistic (<= Gamma(L, 1) under H0) exceeds it in a cell with
        probability at most ``cell_pfa`` for any of the G windows (union bound)."""
        return float(scipy.special.gammainccinv(self.size, cell_pfa / self.count))


def _windows(gain: np.ndarray, size: int) -> np.ndarray:
    """Distinct sorted top-``size`` beam sets of each row of ``gain`` [G, size]."""
    top = np.sort(np.argsort(-gain, axis=1, kind="stable")[:, :size], axis=1)
    return np.unique(top, axis=0)


def sweep_windows(pattern: BeamPattern, sweep: BeamSweep, *, cell_pfa: float) -> SweepWindows:
    """Windows matched to ``pattern`` over ``sweep`` for a per-cell false-alarm probability.

    Parameters
    ----------
    pattern : BeamPattern
        With its wavelength set.
    sweep : BeamSweep
        M >= 2 beams.
    cell_pfa : float
        False-alarm probability per delay–Doppler cell, in (0, 1).
    """
    angles = sweep.angles
    m = angles.shape[0]
    gain = pattern.amplitude(angles, angles) ** 2  # [centre c, beam m]
    ranked = -np.sort(-gain, axis=1)  # [M, M], largest first
    best = None
    for size in range(1, min(m, MAX_WINDOW) + 1):
        wins = _windows(gain, size)
        eta = float(scipy.special.gammainccinv(size, cell_pfa / wins.shape[0]))
        capture = float(np.median(ranked[:, :size].sum(axis=1)))
        need = (eta - size) / capture
        if best is None or need < best[0]:
            best = (need, size, wins, capture)
    _, size, wins, capture = best
    contiguous = bool(np.all(wins[:, -1] - wins[:, 0] == size - 1))
    wins.setflags(write=False)
    return SweepWindows(beams=wins, size=size, capture=capture, contiguous=contiguous)
