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

import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.special
import scipy.stats

from .validation import as_finite_array, fields_equal, non_negative, require_complex_samples
from .pattern import BeamPattern
from .radar import SPEED_OF_LIGHT, RadarConfig
from .sweep import BeamSweep
from .sweep_window import SweepWindows, sweep_windows
from .xp import ArrayBackend, backend_of, is_host_array, numpy_backend

__all__ = ["Detection", "detect", "detect_batch", "detect_validated", "sweep_statistics", "check_beat_cube", "sweep_cfar_threshold"]

#: Default false-alarm probability per capture.
DEFAULT_PFA = 1e-3


def check_beat_cube(cube: Any, radar: RadarConfig, *, min_beams: int = 2) -> np.ndarray:
    """Validate a beat cube for detection/localization; return it as complex128 [M, K, N].

    Raises a one-line :class:`ValueError` for an empty, non-finite or all-zero cube, one with
    fewer than ``min_beams`` beams, or sizes that disagree with ``radar``. A device array (CuPy,
    array_api_strict: :mod:`dsp.xp`) is checked where it lives and returned there, as complex128.
    """
    if not is_host_array(cube):
        return _check_device_cube(cube, radar, min_beams)
    require_complex_samples(cube, "cube")
    try:
        arr = np.asarray(cube, dtype=complex)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"cube must be a complex array [M, K, N], got {type(cube).__name__}: {exc}") from None
    _check_layout(arr.shape)
    if _finite_and_nonzero(arr):  # one BLAS pass instead of isfinite, all and any (a Table I cube: 2 ms, not 9)
        _check_sizes(arr.shape, radar, min_beams)
        return arr
    arr = as_finite_array(arr, "cube", shape=(None, None, None), dtype=complex)
    _check_sizes(arr.shape, radar, min_beams)
    if not np.any(arr):
        raise ValueError("cube is all zeros: nothing was recorded; check the capture (ADC, file) before localizing")
    return arr


def _finite_and_nonzero(arr: np.ndarray) -> bool:
    """True when the sum of squares of every real and imaginary part is finite and positive.

    Then every value is finite (a NaN or inf makes the sum NaN or inf) and one is not zero. False
    says nothing on its own: the sum also overflows for values beyond ~1e150 and underflows to 0 for
    values below ~1e-160, so the caller then runs the exact checks (and their messages).
    """
    if not arr.flags.c_contiguous:
        return False
    parts = arr.reshape(-1).view(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        ssq = float(np.dot(parts, parts))
    return math.isfinite(ssq) and ssq > 0.0


def _check_layout(shape: tuple[int, ...]) -> None:
    """A cube is three axes and not empty (one-line errors)."""
    if len(shape) != 3:
        raise ValueError(f"cube has shape {list(shape)}; it must be [M, K, N] = (beams, chirps, samples)")
    if 0 in shape:
        raise ValueError(f"cube is empty (shape {list(shape)}); record at least 2 beams of K chirps × N samples")


def _check_sizes(shape: tuple[int, ...], radar: RadarConfig, min_beams: int) -> None:
    """The cube's K and N are the radar's and it has at least ``min_beams`` beams (one-line errors)."""
    m, k, n = shape
    if (k, n) != (radar.num_chirps, radar.num_samples):
        raise ValueError(
            f"cube has shape [M, K, N] = {list(shape)} but the radar has K={radar.num_chirps} chirps and "
            f"N={radar.num_samples} samples; pass the RadarConfig the cube was recorded with (axis order beams, chirps, samples)"
        )
    if m < min_beams:
        raise ValueError(
            f"cube has {m} beam(s); the AoD needs a sweep of at least {min_beams} beams (one frame per RIS beam)"
        )


def _check_device_cube(cube: Any, radar: RadarConfig, min_beams: int) -> Any:
    """:func:`check_beat_cube` for an array on a device: the same rules and messages, evaluated there."""
    xp = backend_of(cube).xp
    if not xp.isdtype(cube.dtype, "complex floating"):
        raise TypeError(f"cube must hold complex beat samples [M, K, N], got dtype {cube.dtype}; "
                        "convert real ADC data with scipy.signal.hilbert")
    shape = tuple(int(v) for v in cube.shape)
    _check_layout(shape)
    _check_sizes(shape, radar, min_beams)
    arr = xp.astype(cube, xp.complex128, copy=False)
    if not bool(xp.all(xp.isfinite(arr))):
        raise ValueError("cube holds non-finite values (NaN or inf); check the capture before localizing")
    if not bool(xp.any(arr != 0)):
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


def _window_runs(windows: SweepWindows) -> list[list[tuple[int, int]]]:
    """Each window as its runs of consecutive beams, ``[(first, one past the last), ...]``."""
    return [[(int(r[0]), int(r[-1]) + 1) for r in np.split(w, np.flatnonzero(np.diff(w) != 1) + 1)]
            for w in windows.beams]


#: Cells per pass of the window statistics on the host: the float64 running sums of a block stay in cache.
HOST_CELL_BLOCK = 4_096


def sweep_statistics(x: Any, windows: SweepWindows | None, backend: ArrayBackend,
                     cell_block: int | None = None) -> tuple[Any, Any]:
    """Per cell: D = Σ_m |X_m - X̄|², and the max over windows of Σ_{m∈W} |X_m - X̄|², for a batch.

    Parameters
    ----------
    x : complex array [B, M, C] of ``backend``
        The beams' DFT values at C cells of B realizations [√W·K·N].
    windows : SweepWindows or None
    backend : dsp.xp.ArrayBackend
    cell_block : int, optional
        Cells per pass (default: :data:`HOST_CELL_BLOCK` / B on the host, all cells on a GPU).

    Returns
    -------
    d_raw, window_max : float64 arrays [B, C] of ``backend`` (``window_max`` None without windows)

    Notes
    -----
    One pass in blocks of cells: the mean over beams, E_m = |X_m - X̄|² (in the precision of x),
    their cumulative sum over the beams in float64 (D is its last row), and each window — a few
    runs of consecutive beams — as differences of it. Only elementwise operations and reductions
    along the beam axis: a realization's numbers depend neither on the batch size nor on the
    number of threads.
    """
    xp = backend.xp
    b, m, c = x.shape
    if cell_block is None:  # on the host the block's cells shrink with an explicit batch (B = 4: 0.113 s per cube, not 0.39)
        cell_block = max(256, HOST_CELL_BLOCK // b) if backend.name != "cupy" else c
    runs = None if windows is None else _window_runs(windows)
    d_parts, w_parts = [], []
    for c0 in range(0, c, cell_block):
        xb = x[:, :, c0:min(c0 + cell_block, c)]
        dev = xb - xp.mean(xb, axis=1, keepdims=True)
        energy = xp.astype(xp.real(dev) ** 2 + xp.imag(dev) ** 2, xp.float64)  # one cast per block, not per beam
        # the running sums over the beams in float64, beam by beam (a cumulative sum along a middle axis is
        # several times slower on NumPy); cum[i] = Σ_{m<i} E_m
        cum = [xp.zeros((b, xb.shape[-1]), dtype=xp.float64, device=backend.device)]
        for i in range(m):
            cum.append(cum[-1] + energy[:, i, :])
        d_parts.append(cum[m])
        if runs is not None:
            best = None
            for window in runs:
                (lo, hi), rest = window[0], window[1:]
                total = cum[hi] - cum[lo]
                for lo, hi in rest:
                    total = total + (cum[hi] - cum[lo])
                best = total if best is None else xp.maximum(best, total)
            w_parts.append(best)
    d_raw = xp.concat(d_parts, axis=-1)
    return d_raw, (xp.concat(w_parts, axis=-1) if runs is not None else None)


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
    return detect_batch(arr[None], radar, backend=numpy_backend(), pfa=pfa, min_range=min_range,
                        max_candidates=max_candidates, pattern=pattern, sweep=sweep, oversample=oversample)[0]


def detect_batch(cubes: Any, radar: RadarConfig, *, backend: ArrayBackend | None = None, pfa: float = DEFAULT_PFA,
                 min_range: float = 0.0, max_candidates: int = 5, pattern: BeamPattern | None = None,
                 sweep: BeamSweep | None = None, oversample: int = 1, workspace: Any = None) -> list[Detection]:
    """:func:`detect` on B realizations at once, on the array backend the cubes live on.

    The whole-cube work — the (half-bin) transform, the window statistics, the noise median, the
    threshold, the strongest cell and the local maxima above the threshold — runs on ``backend``
    for the whole batch; only a few numbers per realization come back to the host (the noise
    power, the best cell, ``max_candidates`` candidate cells and their M beam values), where the
    sweep-modulation test decides. The same realization gives the same :class:`Detection` in any
    batch (every step is elementwise or reduces along one realization's own axes).

    Parameters
    ----------
    cubes : complex array [B, M, K, N] of ``backend``
        Beat samples of B realizations [√W], already valid (finite, the radar's K and N: the caller
        checked them, e.g. a study's noiseless cube plus drawn noise); not checked again.
    radar : RadarConfig
    backend : dsp.xp.ArrayBackend, optional
        Where ``cubes`` live (default NumPy).
    pfa, min_range, max_candidates, pattern, sweep, oversample
        As :func:`detect`.
    workspace : complex array [B, M, Kₒ, Nₒ], optional
        NumPy only: where the transform is written (its dtype: complex64 for ``oversample=2``,
        complex128 for 1), reused by a caller that detects batch after batch (a fresh 150 MB per
        Table I cube costs ≈ 15 ms of page faults); the same detections (:meth:`dsp.xp.ArrayBackend.padded_ifft2`).
        Ignored on other backends.

    Returns
    -------
    list of Detection
        One per realization, in order.

    Notes
    -----
    Precision: with ``oversample=2`` the transform and the beam values are complex64 (the
    statistic needs ~1e-3, not 1e-16) and the running sums float64: a cell's statistic is within
    ~1e-6 relative of its float64 value, far below the noise of D itself (relative spread
    1/√(M-1)).
    """
    backend = numpy_backend() if backend is None else backend
    xp = backend.xp
    if isinstance(pfa, bool) or not isinstance(pfa, numbers.Real) or not 0 < pfa < 1:
        raise ValueError(f"pfa={pfa!r} must be a number in (0, 1), e.g. 1e-3")
    pfa = float(pfa)
    rmin = non_negative(min_range, "min_range", "m")
    if oversample not in (1, 2):
        raise ValueError(f"oversample={oversample!r} must be 1 (DFT bins) or 2 (half bins)")
    if (pattern is None) != (sweep is None):
        raise ValueError("pass both pattern and sweep (for the pattern-matched windows) or neither")
    if len(cubes.shape) != 4:
        raise ValueError(f"cubes have shape {list(cubes.shape)}; detect_batch needs [B, M, K, N]")
    b, m, k, n = (int(v) for v in cubes.shape)
    if sweep is not None and sweep.num_beams != m:
        raise ValueError(f"cube has {m} beams but the sweep has {sweep.num_beams} angles; pass the cube's BeamSweep")
    ko, no = k * oversample, n * oversample
    # Σ y e^{+j2π(qk/Kₒ + pn/Nₒ)}: slow time first, then fast time, without transforming the zero-padded rows.
    # Half bins in single precision (module notes); the DFT bins (oversample 1) in double.
    dtype = xp.complex128 if oversample == 1 else xp.complex64
    x = backend.padded_ifft2(cubes, (ko, no), dtype=dtype, out=workspace if backend.is_numpy else None)  # [B, M, Kₒ, Nₒ]
    fast = np.arange(no) / no  # beat frequency [cycles/sample] of bin p
    first = int(np.searchsorted(fast, 2.0 * rmin / SPEED_OF_LIGHT * radar.slope * radar.sample_period))
    if first >= no:
        raise ValueError(f"min_range={rmin} m excludes every delay bin (max range {radar.max_range:.3f} m); lower it")
    num_cells = ko * (no - first)
    cell_pfa = -np.expm1(np.log1p(-pfa) / num_cells)
    windows = None
    if pattern is not None:
        windows = sweep_windows(pattern.for_wavelength(radar.wavelength), sweep, cell_pfa=cell_pfa)
    flat = xp.reshape(x, (b, m, ko * no))
    d_raw, window_max = sweep_statistics(flat, windows, backend)  # Σ_m |X_m - X̄|² and its best window, [B, Kₒ·Nₒ]
    # Under H0 d_raw/σ²_cell ~ Gamma(M-1, 1): its median over cells gives σ²_cell.
    medians = backend.to_host(backend.median(d_raw, axis=1))
    means = backend.to_host(xp.mean(d_raw, axis=1))
    noise = np.empty(b)
    for i in range(b):
        cell_noise = float(medians[i]) / float(scipy.special.gammaincinv(m - 1, 0.5))
        if not cell_noise > 0:
            cell_noise = float(means[i]) / (m - 1)
        if not cell_noise > 0:
            cell_noise = np.finfo(float).tiny
        noise[i] = cell_noise
    if windows is None:
        raw, dof = d_raw, m - 1
        eta = float(scipy.special.gammainccinv(dof, cell_pfa))
    else:
        raw, dof = window_max, windows.size
        eta = windows.threshold(cell_pfa)
    searched = backend.asarray(np.tile(np.arange(no) >= first, ko))  # [Kₒ·Nₒ]: delay bins at or beyond min_range
    stat = xp.where(searched, raw / backend.asarray(noise)[:, None], -xp.inf)  # [B, Kₒ·Nₒ]
    thr_db = _db(eta - dof)
    best_stat = backend.to_host(xp.max(stat, axis=1))
    cand_cells, cand_stats, cand_values = _candidates(stat, flat, eta, (ko, no), max(1, int(max_candidates)), backend)
    out = []
    for i in range(b):
        out.append(_decide(radar, pfa=pfa, k=k, n=n, ko=ko, no=no, cell_noise=float(noise[i]),
                           best=float(best_stat[i]), eta=eta, dof=dof, thr_db=thr_db, num_cells=num_cells,
                           cells=cand_cells[i], stats=cand_stats[i], values=cand_values[i]))
    return out


def _candidates(stat: Any, flat: Any, eta: float, shape: tuple[int, int], count: int,
                backend: ArrayBackend) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``count`` strongest local maxima (3 × 3, wrapping) at or above ``eta`` of each realization.

    Returns host arrays: flat cell indices [B, count] (-1 where there are fewer), their statistics
    [B, count] (-inf there) and the beams' values at them, complex [B, M, count].
    """
    xp = backend.xp
    b = stat.shape[0]
    ko, no = shape
    grid = xp.reshape(stat, (b, ko, no))
    local = grid >= eta
    for dq in (-1, 0, 1):
        for dp in (-1, 0, 1):
            if dq or dp:
                local = xp.logical_and(local, grid >= xp.roll(grid, (dq, dp), axis=(1, 2)))
    masked = xp.reshape(xp.where(local, grid, -xp.inf), (b, ko * no))
    index = backend.asarray(np.arange(ko * no))
    cells, stats = [], []
    for _ in range(count):  # strongest first; equal values: the lower cell index first
        c = xp.argmax(masked, axis=1)  # [B]
        stats.append(xp.max(masked, axis=1))
        cells.append(c)
        masked = xp.where(index[None, :] == c[:, None], -xp.inf, masked)
    cell = xp.stack(cells, axis=1)  # [B, count]
    values = xp.take_along_axis(flat, xp.broadcast_to(cell[:, None, :], (b, flat.shape[1], count)), axis=2)
    stats_h = backend.to_host(xp.stack(stats, axis=1))
    cells_h = np.where(np.isfinite(stats_h), backend.to_host(cell), -1)
    return cells_h, stats_h, backend.to_host(values)


def _decide(radar: RadarConfig, *, pfa: float, k: int, n: int, ko: int, no: int, cell_noise: float,
            best: float, eta: float, dof: int, thr_db: float, num_cells: int, cells: np.ndarray,
            stats: np.ndarray, values: np.ndarray) -> Detection:
    """One realization's :class:`Detection` from its candidates: the sweep-modulation test, strongest first."""
    noise_power = cell_noise / (k * n)
    if best < eta or cells[0] < 0:
        return Detection(False, _db(best - dof), thr_db, pfa, statistic=best, threshold=eta,
                         noise_power=noise_power, num_cells=num_cells, integrated_beams=dof)
    rejected = 0
    chosen = None
    for j in range(cells.shape[0]):
        if cells[j] < 0:
            break
        power = (np.abs(values[:, j].astype(complex)) ** 2) / cell_noise
        if power.max() > _modulation_threshold(power, pfa):
            chosen = j
            break
        rejected += 1
    j = 0 if chosen is None else chosen
    q, p = divmod(int(cells[j]), no)
    power = (np.abs(values[:, j].astype(complex)) ** 2) / cell_noise
    s = float(stats[j])
    if chosen is None:
        return Detection(False, _db(s - dof), thr_db, pfa, statistic=s, threshold=eta, noise_power=noise_power,
                         cell=(q, p), beam_power=power, beam_dependent=False, rejected=rejected, num_cells=num_cells,
                         integrated_beams=dof)
    f2 = q / ko if q <= ko // 2 else q / ko - 1.0
    nu = f2 / (radar.carrier_frequency * radar.chirp_interval)
    tau = p / (no * radar.slope * radar.sample_period) - radar.carrier_frequency * nu / radar.slope
    return Detection(True, _db(s - dof), thr_db, pfa, statistic=s, threshold=eta, noise_power=noise_power,
                     cell=(q, p), delay=float(tau), delay_rate=float(nu), beam_power=power, beam_dependent=True,
                     rejected=rejected, num_cells=num_cells, integrated_beams=dof)
