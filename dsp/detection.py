"""Detection of the RIS return with a stated false-alarm probability (``docs/estimation.md``).

Two tests on the un-padded, un-windowed 2-D DFT of every beam, ``X_m[q, p]`` (K × N cells per
beam, independent under white noise):

1. **Sweep-CFAR** (the detector proper). ``D[q, p] = Σ_m |X_m - X̄|² / σ̂²``, X̄ the mean over
   beams. Anything identical in every frame (static clutter, the panel's structural reflection,
   Tx→Rx leakage) cancels exactly, whatever its strength; the RIS return, whose power follows the
   beam, does not. Under H0 (noise plus any static clutter) D ~ Gamma(M-1, 1) in every cell,
   independently, so the threshold η with ``1 - (1 - Q(M-1, η))^C = P_FA`` gives exactly P_FA
   per capture over the C searched cells (noise power known; σ̂² from the median of all cells).
2. **Sweep-modulation test**, at each cell that crossed η (strongest first): the power profile
   over the beams, P_m = |X_m|²/σ̂², must not be explainable by a return of constant amplitude
   (clutter whose phase moves from frame to frame, e.g. for a moving radar). Under that
   hypothesis 2P_m ~ χ'²(2, 2λ) independently; λ is estimated from the median over beams and the
   strongest beam must exceed the level that M such beams would exceed with probability P_FA.

The first cell that passes both is the detection. No cell above η: ``no-detection``; cells
above η but none beam-dependent: ``no-beam-dependence`` (and no detection).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.fft
import scipy.ndimage
import scipy.optimize
import scipy.special
import scipy.stats

from .validation import as_finite_array, fields_equal, non_negative, require_complex_samples
from .pattern import BeamPattern
from .radar import SPEED_OF_LIGHT, RadarConfig
from .sweep import BeamSweep
from .sweep_window import SweepWindows, sweep_windows
from .threads import thread_count

__all__ = ["Detection", "detect", "detect_validated", "check_beat_cube", "sweep_cfar_threshold"]

#: Default false-alarm probability per capture.
DEFAULT_PFA = 1e-3


def check_beat_cube(cube: Any, radar: RadarConfig, *, min_beams: int = 2) -> np.ndarray:
    """Validate a beat cube for detection/localization; return it as complex128 [M, K, N].

    Raises a one-line :class:`ValueError` for an empty, non-finite or all-zero cube, one with
    fewer than ``min_beams`` beams, or sizes that disagree with ``radar``.
    """
    require_complex_samples(cube, "cube")
    try:
        arr = np.asarray(cube, dtype=complex)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"cube must be a complex array [M, K, N], got {type(cube).__name__}: {exc}") from None
    if arr.ndim != 3:
        raise ValueError(f"cube has shape {list(arr.shape)}; it must be [M, K, N] = (beams, chirps, samples)")
    if arr.size == 0:
        raise ValueError(f"cube is empty (shape {list(arr.shape)}); record at least 2 beams of K chirps × N samples")
    arr = as_finite_array(arr, "cube", shape=(None, None, None), dtype=complex)
    m, k, n = arr.shape
    if (k, n) != (radar.num_chirps, radar.num_samples):
        raise ValueError(
            f"cube has shape [M, K, N] = {list(arr.shape)} but the radar has K={radar.num_chirps} chirps and "
            f"N={radar.num_samples} samples; pass the RadarConfig the cube was recorded with (axis order beams, chirps, samples)"
        )
    if m < min_beams:
        raise ValueError(
            f"cube has {m} beam(s); the AoD needs a sweep of at least {min_beams} beams (one frame per RIS beam)"
        )
    if not np.any(arr):
        raise ValueError("cube is all zeros: nothing was recorded; check the capture (ADC, file) before localizing")
    return arr


def sweep_cfar_threshold(pfa: float, num_beams: int, num_cells: int) -> float:
    """η such that the max over ``num_cells`` iid Gamma(M-1, 1) exceeds it with probability ``pfa``."""
    per_cell = -np.expm1(np.log1p(-pfa) / num_cells)
    return float(scipy.special.gammainccinv(num_beams - 1, per_cell))


def _modulation_threshold(power: np.ndarray, pfa: float) -> float:
    """Level the strongest of M constant-amplitude beams exceeds with probability ``pfa``."""
    m = power.size
    x = 2.0 * power  # ~ χ'²(2, 2λ) under constant amplitude
    med = float(np.median(x))
    nc = 0.0
    per_beam = -np.expm1(np.log1p(-pfa) / m)
    if med > 400.0:
        # Strong constant return: χ'²(2, nc) is then Gaussian, mean 2 + nc, variance 4 + 4 nc.
        nc = med - 2.0
        z = float(scipy.stats.norm.isf(per_beam))
        return (2.0 + nc + z * np.sqrt(4.0 + 4.0 * nc)) / 2.0
    if med > scipy.stats.chi2.median(2):
        f = lambda lam: scipy.stats.ncx2.median(2, lam) - med  # noqa: E731
        hi = 2.0 * med + 10.0
        nc = float(scipy.optimize.brentq(f, 1e-9, hi)) if f(1e-9) < 0 < f(hi) else 2.0 * med
    if nc <= 0:
        return float(scipy.stats.chi2.isf(per_beam, 2)) / 2.0
    return float(scipy.stats.ncx2.isf(per_beam, 2, nc)) / 2.0


@dataclass(frozen=True, eq=False)
class Detection:
    """Outcome of :func:`detect`: was a beam-dependent return found, and how strong.

    Attributes
    ----------
    detected : bool
        A cell passed the sweep-CFAR and the sweep-modulation test.
    snr_db : float
        Sweep-integrated post-integration SNR of the strongest cell that passed the sweep-CFAR
        (or of the strongest cell when none did), ``10 log10(D - (M-1))`` [dB]; -99 when D <= M-1.
    threshold_db : float
        The same quantity at the threshold, ``10 log10(η - (M-1))`` [dB]: detected needs
        ``snr_db >= threshold_db``.
    false_alarm_probability : float
        P_FA: probability per capture that noise (plus static clutter) alone crosses η anywhere.
    statistic, threshold : float
        D at the cell and η [unitless, in units of the noise power per cell].
    noise_power : float
        σ̂², noise power per beat sample [W] (median estimate).
    cell : (int, int)
        (q, p): slow- and fast-time bin of the un-padded DFT (FFT order), -1 when none.
    delay, delay_rate : float
        Cell centre: τ (range-Doppler coupling removed) [s], ν [s/s]; NaN when none.
    beam_power : float array [M]
        P_m = |X_m|²/σ̂² at the cell [unitless]; empty when none.
    beam_dependent : bool
        The cell passed the sweep-modulation test.
    rejected : int
        Cells above η that failed the sweep-modulation test (stronger than the detection, or all).
    num_cells : int
        C, cells searched.
    integrated_beams : int
        Degrees of freedom of the statistic under H0: M - 1 for the whole sweep, L for a window
        of L beams (``snr_db`` is ``10 log10(statistic - integrated_beams)``).
    """

    detected: bool
    snr_db: float
    threshold_db: float
    false_alarm_probability: float
    statistic: float = float("nan")
    threshold: float = float("nan")
    noise_power: float = float("nan")
    cell: tuple[int, int] = (-1, -1)
    delay: float = float("nan")
    delay_rate: float = float("nan")
    beam_power: np.ndarray = field(default_factory=lambda: np.zeros(0))
    beam_dependent: bool = False
    rejected: int = 0
    num_cells: int = 0
    integrated_beams: int = 0

    def to_dict(self) -> dict[str, Any]:
        """``{"detected", "snr_db", "threshold_db", "false_alarm_probability"}`` (plain JSON)."""
        return {"detected": bool(self.detected), "snr_db": float(self.snr_db),
                "threshold_db": float(self.threshold_db),
                "false_alarm_probability": float(self.false_alarm_probability)}

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]

def _db(x: float) -> float:
    return float(10.0 * np.log10(x)) if x > 0 else -99.0


def _sweep_statistics(x: np.ndarray, windows: SweepWindows | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Per cell: D = Σ_m |X_m - X̄|², and the max over windows of Σ_{m∈W} |X_m - X̄|² [Kₒ, Nₒ].

    One pass in blocks of cells: the mean over beams, E_m = |X_m - X̄|², their cumulative sum over
    the beams in float64 (D is its last row), and each window — a few runs of consecutive beams —
    as differences of it. Only numpy reductions, no BLAS: the result does not depend on the
    number of threads (a Monte Carlo study gives the same numbers on any machine).
    """
    m, ko, no = x.shape
    flat = x.reshape(m, ko * no)
    d_raw = np.empty(ko * no)
    best = None
    if windows is not None:
        runs = [np.split(w, np.flatnonzero(np.diff(w) != 1) + 1) for w in windows.beams]
        width = max(len(r) for r in runs)
        lo = np.zeros((len(runs), width), dtype=np.intp)  # unused run slots: lo = hi = 0, sum 0
        hi = np.zeros((len(runs), width), dtype=np.intp)
        for i, rr in enumerate(runs):
            for j, r in enumerate(rr):
                lo[i, j], hi[i, j] = r[0], r[-1] + 1
        best = np.empty(ko * no)
    block = 4_096  # cells per pass: the float64 running sums of a block stay in a 1 MiB L2 cache
    for c0 in range(0, ko * no, block):
        xb = flat[:, c0:c0 + block]
        dev = xb - xb.mean(axis=0)
        energy = dev.real**2 + dev.imag**2
        cum = np.zeros((m + 1, xb.shape[1]))
        for i in range(m):  # row by row: numpy's cumsum over the first axis is several times slower
            np.add(cum[i], energy[i], out=cum[i + 1])
        d_raw[c0:c0 + block] = cum[-1]
        if best is not None:
            top = best[c0:c0 + block]
            top.fill(-np.inf)
            total = np.empty(xb.shape[1])
            for rl, rh in zip(lo, hi):
                np.subtract(cum[rh[0]], cum[rl[0]], out=total)
                for j in range(1, width):
                    if rh[j]:
                        total += cum[rh[j]] - cum[rl[j]]
                np.maximum(top, total, out=top)
    return d_raw.reshape(ko, no), (best.reshape(ko, no) if best is not None else None)


def detect(
    cube: Any,
    radar: RadarConfig,
    *,
    pfa: float = DEFAULT_PFA,
    min_range: float = 0.0,
    max_candidates: int = 5,
    pattern: BeamPattern | None = None,
    sweep: BeamSweep | None = None,
    oversample: int = 1,
) -> Detection:
    """Detect the RIS return in a beat cube with false-alarm probability ``pfa`` per capture.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples (beams, chirps, samples) [√W], M >= 2.
    radar : RadarConfig
    pfa : float, default 1e-3
        False-alarm probability per capture, in (0, 1).
    min_range : float, default 0
        Cells whose delay (coupled, as on the DFT grid) is below ``2·min_range/c`` are not
        searched [m].
    max_candidates : int, default 5
        Cells above η tried by the sweep-modulation test, strongest first.
    pattern, sweep : BeamPattern, BeamSweep, optional
        Given both, the sweep-CFAR integrates windows of the L beams the pattern lights up
        together (:mod:`dsp.sweep_window`) instead of all M beams: 2 dB less SNR needed for the
        paper's sweep; the stated P_FA is then an upper bound (union over the windows).
    oversample : {1, 2}, default 1
        DFT oversampling per axis. 2 searches half-bin steps: an off-grid return loses at most
        0.9 dB per axis instead of 3.9 dB; the cells are then correlated and P_FA (a union over
        all searched cells) an upper bound. Costs a DFT 4× larger (computed in complex64).

    Returns
    -------
    Detection
    """
    return detect_validated(check_beat_cube(cube, radar), radar, pfa=pfa, min_range=min_range,
                            max_candidates=max_candidates, pattern=pattern, sweep=sweep, oversample=oversample)


def detect_validated(arr: np.ndarray, radar: RadarConfig, *, pfa: float, min_range: float, max_candidates: int,
                     pattern: BeamPattern | None, sweep: BeamSweep | None, oversample: int) -> Detection:
    """:func:`detect` on a cube already through :func:`check_beat_cube` (no second pass over it).

    Parameters
    ----------
    arr : complex128 array [M, K, N]
        The cube as :func:`check_beat_cube` returns it [√W]; not checked again.
    radar : RadarConfig
    pfa, min_range, max_candidates, pattern, sweep, oversample
        As :func:`detect` (``min_range`` in m), all given explicitly.

    Returns
    -------
    Detection
    """
    if not (isinstance(pfa, (float, int)) and 0 < pfa < 1):
        raise ValueError(f"pfa={pfa!r} must lie in (0, 1), e.g. 1e-3")
    rmin = non_negative(min_range, "min_range", "m")
    if oversample not in (1, 2):
        raise ValueError(f"oversample={oversample!r} must be 1 (DFT bins) or 2 (half bins)")
    if (pattern is None) != (sweep is None):
        raise ValueError("pass both pattern and sweep (for the pattern-matched windows) or neither")
    m, k, n = arr.shape
    if sweep is not None and sweep.num_beams != m:
        raise ValueError(f"cube has {m} beams but the sweep has {sweep.num_beams} angles; pass the cube's BeamSweep")
    ko, no = k * oversample, n * oversample
    if oversample == 1:
        x = scipy.fft.ifft2(arr, axes=(1, 2), norm="forward", workers=thread_count())  # Σ y e^{+j2π(qk/K + pn/N)}, [M, K, N]
    else:  # single precision: the statistic needs ~1e-3, not 1e-16. Slow time first, then fast time:
        # the values of ifft2(s=(Kₒ, Nₒ)) bit for bit, without transforming the zero-padded rows (7-30 % faster).
        x = scipy.fft.ifft(arr.astype(np.complex64), n=ko, axis=1, norm="forward", workers=thread_count())
        x = scipy.fft.ifft(x, n=no, axis=2, norm="forward", workers=thread_count(), overwrite_x=True)
    fast = np.arange(no) / no  # beat frequency [cycles/sample] of bin p
    first = int(np.searchsorted(fast, 2.0 * rmin / SPEED_OF_LIGHT * radar.slope * radar.sample_period))
    if first >= no:
        raise ValueError(f"min_range={rmin} m excludes every delay bin (max range {radar.max_range:.3f} m); lower it")
    num_cells = ko * (no - first)
    cell_pfa = -np.expm1(np.log1p(-pfa) / num_cells)
    windows = None
    if pattern is not None:
        windows = sweep_windows(pattern.for_wavelength(radar.wavelength), sweep, cell_pfa=cell_pfa)
    d_raw, window_max = _sweep_statistics(x, windows)  # Σ_m |X_m - X̄|² and its best window, [Kₒ, Nₒ]
    # Under H0 d_raw/σ²_cell ~ Gamma(M-1, 1): its median over cells gives σ²_cell.
    cell_noise = float(np.median(d_raw)) / float(scipy.special.gammaincinv(m - 1, 0.5))
    if not cell_noise > 0:
        cell_noise = float(d_raw.mean()) / (m - 1)
    if not cell_noise > 0:
        cell_noise = np.finfo(float).tiny
    if windows is None:
        stat = d_raw / cell_noise  # [Kₒ, Nₒ]
        dof = m - 1
        eta = float(scipy.special.gammainccinv(dof, cell_pfa))
    else:
        stat = window_max / cell_noise
        dof = windows.size
        eta = windows.threshold(cell_pfa)
    stat[:, :first] = -np.inf
    thr_db = _db(eta - dof)
    noise_power = cell_noise / (k * n)

    peak = np.unravel_index(int(np.argmax(stat)), stat.shape)
    best = float(stat[peak])
    if best < eta:
        return Detection(False, _db(best - dof), thr_db, pfa, statistic=best, threshold=eta,
                         noise_power=noise_power, num_cells=num_cells, integrated_beams=dof)
    local = (scipy.ndimage.maximum_filter(stat, size=3, mode="wrap") == stat) & (stat >= eta)
    qs, ps = np.nonzero(local)
    order = np.argsort(stat[qs, ps])[::-1][: max(1, int(max_candidates))]
    rejected = 0
    chosen = None
    for i in order:
        q, p = int(qs[i]), int(ps[i])
        power = (np.abs(x[:, q, p].astype(complex)) ** 2) / cell_noise
        if power.max() > _modulation_threshold(power, pfa):
            chosen = (q, p, power)
            break
        rejected += 1
    if chosen is None:
        q, p = int(qs[order[0]]), int(ps[order[0]])
        power = (np.abs(x[:, q, p].astype(complex)) ** 2) / cell_noise
        s = float(stat[q, p])
        return Detection(False, _db(s - dof), thr_db, pfa, statistic=s, threshold=eta, noise_power=noise_power,
                         cell=(q, p), beam_power=power, beam_dependent=False, rejected=rejected, num_cells=num_cells,
                         integrated_beams=dof)
    q, p, power = chosen
    s = float(stat[q, p])
    f2 = q / ko if q <= ko // 2 else q / ko - 1.0
    nu = f2 / (radar.carrier_frequency * radar.chirp_interval)
    tau = p / (no * radar.slope * radar.sample_period) - radar.carrier_frequency * nu / radar.slope
    return Detection(True, _db(s - dof), thr_db, pfa, statistic=s, threshold=eta, noise_power=noise_power,
                     cell=(q, p), delay=float(tau), delay_rate=float(nu), beam_power=power, beam_dependent=True,
                     rejected=rejected, num_cells=num_cells, integrated_beams=dof)
