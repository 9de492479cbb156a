"""The screened grid search: the paper's N_DFT × K_DFT grid maximum without the full transform.

:func:`screened_scan` returns, for every beam, the same grid cell (q, p) as the paper's full
2-D DFT, eq. (2DDFT) + eq. (argmaxmap), and the exact float64 values |z(q, p)|² that eq. (P_ave)
needs, while transforming only a few delay columns at full resolution:

1. **Screen (complex64).** The windowed cube is cast to complex64 and transformed along fast
   time at its own length (``next_fast_len(N)``, no zero padding: 1/4 of the work of a
   1199-point transform). For every native delay sample i of beam m the Doppler-free bound
   ``U[m, i] = Σ_k |R_k(i)|`` holds, by the triangle inequality, for *every* Doppler ν:
   ``|z(ν, τ_i)| ≤ U[m, i]`` (tight for a single tone: |R_k| is then the window times a
   constant). Where U is not small enough to rule a sample out, it is tightened to the
   sample's native K-point Doppler maximum times the window's scalloping loss at half a
   Doppler bin plus ``SCREEN_HEADROOM_DB``. A fine column p of the N_DFT grid lies between two
   native samples; its bound is the larger of the two times the window's scalloping loss at
   half a native delay bin plus ``SCREEN_HEADROOM_DB`` (1.5 dB) for interference between returns.
2. **Lower bound.** The fine columns around the column of largest bound are evaluated exactly
   (float64, below), giving a grid value T₁ ≤ max.
3. **Exact evaluation.** Every fine column whose bound reaches T₁ is evaluated exactly: the
   range DFT at that column, ``Σ_n w_n y[k, n] e^{+j2π p n / N_DFT}``, by a matrix product with
   integer-reduced phases (float64), then the Doppler grid by the zoom of
   :func:`dsp.beamscan.scan_beams` (a coarse ``zoom_oversampling``·K transform and the exact
   K_DFT-grid DFT in a strip around the coarse bins within ``zoom_margin_db`` of the maximum).
   The cell order is the full search's (q major, p minor, ascending), so a tie goes the same way.

**Precision.** Only the screen is complex64; it decides which columns are evaluated, never a
value. Its error is bounded by the FFT's backward error, ``|ΔR_k(i)| ≤ c·u·log₂N·√N·‖x_k‖₂``
(u = 2⁻²⁴): an absolute slack of ``1e-5·√N·Σ_k ‖x_k‖₂`` per beam, 50× that bound for c = 1, is
added to U. Every value that reaches the result is float64 and agrees with the full transform's
to ~1e-13 relative (different summation order), so the same cell wins unless two cells are within
that of each other (a true tie, e.g. two identical returns; either cell is then the grid maximum).

**Fallback.** A beam with more than a quarter of its columns above the bound (noise only, no
return above the per-chirp noise) is searched densely, as before: the 1199-point transform of the
whole beam and the zoom.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np
import scipy.fft

from .processing import ProcessingConfig, window_vector
from .threads import thread_count

__all__ = ["SCREEN_HEADROOM_DB", "screened_scan", "scalloping_loss_db"]

#: Allowance (dB) beyond the window's single-tone scalloping loss for returns that interfere
#: between two native delay samples (two equal in-phase tones one bin apart: +1.1 dB for Hann).
SCREEN_HEADROOM_DB = 1.5

#: Relative float32 slack of the screen (see the module notes).
_F32_SLACK = 1e-5

#: Bytes of complex64 screen work per chunk of beams (cache-sized).
_SCREEN_CHUNK = 4 * 2**20


def scalloping_loss_db(window: str, length: int, offset: float) -> float:
    """Power loss (dB, >= 0) of a tone ``offset`` bins off a DFT bin of a ``length``-sample window.

    ``-10 log10(|Σ w_n e^{j2π offset n/length}|² / (Σ w_n)²)``.
    """
    w = window_vector(window, length)
    n = np.arange(length)
    gain = abs(np.sum(w * np.exp(2j * np.pi * offset * n / length))) / np.sum(w)
    return float(-20.0 * np.log10(max(gain, 1e-300)))


@functools.lru_cache(maxsize=4)
def _dft_table(rows: int, cols: int, modulus: int) -> np.ndarray:
    """``e^{+j2π (r·c mod modulus)/modulus}`` [rows, cols]: exact phases (integers reduced first)."""
    roots = np.exp(2j * np.pi * np.arange(modulus) / modulus)  # the modulus distinct values
    table = roots[np.outer(np.arange(rows, dtype=np.int64), np.arange(cols, dtype=np.int64)) % modulus]
    table.flags.writeable = False
    return table


def _range_columns(y: np.ndarray, columns: np.ndarray, n_dft: int, w_k: np.ndarray, w_n: np.ndarray) -> np.ndarray:
    """``w_k Σ_n w_n y[k, n] e^{+j2π p n / N_DFT}`` at the delay columns p [K, P] (float64, exact phases)."""
    kernel = _dft_table(n_dft, y.shape[1], n_dft)[columns] * w_n  # [P, N]
    return (y @ kernel.T) * w_k[:, None]


def _fine_bins_near(coarse_bins: np.ndarray, k_coarse: int, k_dft: int) -> np.ndarray:
    """Fine-grid Doppler bins within one coarse bin spacing of each coarse bin (FFT order)."""
    ratio = k_dft / k_coarse
    reach = int(np.ceil(ratio))
    offsets = np.arange(-reach, reach + 1)
    fine = np.round(coarse_bins * ratio)[:, None].astype(np.int64) + offsets[None, :]
    return np.unique(np.mod(fine, k_dft))


def zoom_block(spectrum: np.ndarray, processing: ProcessingConfig) -> tuple[int, int, float, np.ndarray]:
    """Grid maximum of a block of range columns ``spectrum [K, P]`` over the K_DFT Doppler grid.

    Returns (q, column index into the block, unnormalised |z|², the Doppler kernel row of q [K]).
    The zoom of :func:`dsp.beamscan.scan_beams`: a coarse ``zoom_oversampling``·K transform, the
    coarse cells (Doppler bin, column) within ``zoom_margin_db`` of its maximum, and in each of
    their columns the exact K_DFT-grid DFT (phases reduced modulo K_DFT in integers) on the fine
    bins within one coarse bin of them.

    Why per cell: a column's slow-time DFT is an exponential sum of type σ = π(K-1) (per cycle of
    the Doppler axis), so near its maximum M it stays above M·cos(σ·|Δ|) (and above
    M·cos(σ|Δ| + α) near a value M·cos α); the coarse bin nearest the column's best fine bin is at
    most half a coarse bin away and so within 20·log10(1/cos(π/(2·oversampling))) dB (0.69 dB at
    4×) of the column's maximum, and the global maximum's column is within that of the coarse
    maximum. With ``zoom_margin_db`` above that, the fine bins near the candidate cells hold the
    grid maximum; the other columns of a candidate row need not be evaluated (they cost most
    of a noise-only beam before).
    """
    k = spectrum.shape[0]
    k_coarse = scipy.fft.next_fast_len(processing.zoom_oversampling * k)
    coarse = scipy.fft.ifft(spectrum, n=k_coarse, axis=0, norm="forward")  # [K_c, P]
    cpow = coarse.real**2 + coarse.imag**2
    rows, cols = np.nonzero(cpow >= cpow.max() * 10.0 ** (-processing.zoom_margin_db / 10.0))
    return _fine_maximum(spectrum, rows, cols, k_coarse, processing)


def _fine_maximum(columns: np.ndarray, rows: np.ndarray, cols: np.ndarray, k_coarse: int,
                  processing: ProcessingConfig) -> tuple[int, int, float, np.ndarray]:
    """The K_DFT-grid maximum near the candidate coarse cells (``rows``, ``cols``) of ``columns [K, P]``.

    Returns (q, column index, unnormalised |z|², kernel row of q [K]); ties go as in the full
    search (smaller q, then smaller column).
    """
    table = _dft_table(processing.k_dft, columns.shape[0], processing.k_dft)
    best_q, best_p, best_v = -1, -1, -np.inf
    for c in np.unique(cols):  # ascending columns
        fine = _fine_bins_near(rows[cols == c], k_coarse, processing.k_dft)  # ascending, unique
        z = table[fine] @ columns[:, c]  # [Q]
        power = z.real**2 + z.imag**2
        i = int(power.argmax())  # the first (smallest q) of equal values
        q, v = int(fine[i]), float(power[i])
        if v > best_v or (v == best_v and q < best_q):  # p ascends here: an equal value keeps the smaller p
            best_q, best_p, best_v = q, int(c), v
    return best_q, best_p, best_v, table[best_q]


def screened_scan(
    cube: np.ndarray, processing: ProcessingConfig, first: int, window_kn: tuple[np.ndarray, np.ndarray],
    average_columns: Callable[[int], np.ndarray], workers: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Grid maxima and P_ave of every beam of ``cube [M, K, N]``.

    Parameters
    ----------
    cube : complex128 array [M, K, N]
        Beat samples, not windowed [√W].
    processing : ProcessingConfig
    first : int
        First searchable delay bin (``min_range``).
    window_kn : (float array [K], float array [N])
        The slow- and fast-time windows w_K, w_N.
    average_columns : callable
        ``p -> int array``: the delay bins of eq. (P_ave) around a peak at bin p.
    workers : int, optional
        Threads over chunks of beams (default: up to 2, the CPU count); the result does not
        depend on it.

    Returns
    -------
    q, p : int arrays [M]
        Doppler bin (FFT order) and delay bin of each beam's grid maximum.
    power : float array [M]
        Unnormalised |z(q, p)|² (divide by the coherent gain²) [W·gain²].
    average : float array [M]
        Unnormalised mean of |z(q, p')|² over the P_ave bins p' [W·gain²].
    """
    m, k, n = cube.shape
    n_dft = processing.n_dft
    n_c = scipy.fft.next_fast_len(n)
    workers = thread_count() if workers is None else int(workers)
    # Fine column p sits at n_c·p/N_DFT native samples: between samples lo and lo + 1.
    pos = np.arange(n_dft) * (n_c / n_dft)
    lo = np.floor(pos).astype(np.int64) % n_c
    hi = (lo + 1) % n_c
    delay_margin = 10.0 ** ((scalloping_loss_db(processing.window, n, 0.5 * n / n_c) + SCREEN_HEADROOM_DB) / 10.0)
    doppler_margin = 10.0 ** ((scalloping_loss_db(processing.window, k, 0.5) + SCREEN_HEADROOM_DB) / 10.0)
    w_k, w_n = window_kn
    w32 = np.outer(w_k, w_n).astype(np.float32)
    reach = int(np.ceil(n_dft / n_c))  # fine columns per native sample
    q_best = np.empty(m, dtype=np.int64)
    p_best = np.empty(m, dtype=np.int64)
    power = np.empty(m)
    average = np.empty(m)
    step = max(1, _SCREEN_CHUNK // (8 * k * n_c))

    def chunk(i: int) -> None:
        block = cube[i:i + step].astype(np.complex64)
        block *= w32
        norms = np.array([np.sqrt(np.vdot(b, b).real) for b in block], dtype=np.float64)  # ‖x‖_F [c]
        spec = scipy.fft.ifft(block, n=n_c, axis=-1, norm="forward", overwrite_x=True)  # [c, K, n_c]
        # Σ_k |R_k(i)| bounds |z| at every Doppler; the slack covers float32 (module notes).
        u = np.abs(spec).sum(axis=1, dtype=np.float64) + (_F32_SLACK * np.sqrt(k * n) * norms)[:, None]  # [c, n_c]
        for c in range(u.shape[0]):
            j = i + c
            bounds = _ColumnBounds(spec[c], u[c] ** 2, doppler_margin, _F32_SLACK * np.sqrt(k * n) * norms[c])
            first_native = int(np.floor(first * n_c / n_dft))
            bounds.refine(first_native + np.argsort(u[c, first_native:])[-8:])
            fine = np.maximum(bounds.value[lo], bounds.value[hi]) * delay_margin  # [N_DFT]
            fine[:first] = -np.inf
            p0 = int(fine.argmax())
            cols = np.arange(max(first, p0 - reach), min(n_dft, p0 + reach + 1))
            y = cube[j]
            q, pi, value, krow = zoom_block(_range_columns(y, cols, n_dft, w_k, w_n), processing)
            bounds.refine(np.flatnonzero(bounds.value * delay_margin >= value))
            fine = np.maximum(bounds.value[lo], bounds.value[hi]) * delay_margin
            fine[:first] = -np.inf
            above = np.flatnonzero(fine >= value)
            if above.size > n_dft // 4:
                q, p, value, krow = _dense_beam(y, processing, first, w_k, w_n)
            else:
                p = int(cols[pi])
                extra = np.setdiff1d(above, cols, assume_unique=True)
                if extra.size:  # the other columns that may hold the maximum, as one more block
                    q2, pi2, value2, krow2 = zoom_block(_range_columns(y, extra, n_dft, w_k, w_n), processing)
                    p2 = int(extra[pi2])
                    if value2 > value or (value2 == value and (q2, p2) < (q, p)):  # the full search's order
                        q, p, value, krow = q2, p2, value2, krow2
            q_best[j], p_best[j], power[j] = q, p, value
            average[j] = _row_values(y, krow, average_columns(p), n_dft, w_k, w_n).mean()

    starts = range(0, m, step)
    if workers <= 1 or len(starts) < 2:
        for i in starts:
            chunk(i)
    else:  # numpy and scipy.fft release the GIL: chunks of beams on threads, same results
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for _ in pool.map(chunk, starts):
                pass
    return q_best, p_best, power, average


class _ColumnBounds:
    """Upper bounds on max_ν |z(ν, τ_i)|² per native delay sample i [n_c], tightened on demand.

    Starts from the triangle bound (Σ_k |R_k(i)|)²; :meth:`refine` replaces it, for the given
    samples, by the smaller of it and the native-grid Doppler maximum times ``doppler_margin``.
    """

    def __init__(self, spec: np.ndarray, triangle: np.ndarray, doppler_margin: float, slack: float) -> None:
        self.spec, self.value, self.margin, self.slack = spec, triangle.copy(), doppler_margin, slack
        self.done = np.zeros(triangle.shape, dtype=bool)

    def refine(self, samples: np.ndarray) -> None:
        todo = samples[~self.done[samples]]
        if todo.size == 0:
            return
        z = scipy.fft.ifft(self.spec[:, todo], axis=0, norm="forward")  # [K, S] native Doppler grid
        peak = np.sqrt((z.real**2 + z.imag**2).max(axis=0).astype(np.float64)) + self.slack
        self.value[todo] = np.minimum(self.value[todo], peak**2 * self.margin)
        self.done[todo] = True


def _dense_beam(y: np.ndarray, processing: ProcessingConfig, first: int, w_k: np.ndarray,
                w_n: np.ndarray) -> tuple[int, int, float, np.ndarray]:
    """The grid maximum of one beam ``y [K, N]`` (not windowed) whose columns could not be screened.

    The whole N_DFT × (oversampling·K) coarse plane in complex64 (the screen: it only picks
    cells), its cells within ``zoom_margin_db`` of the maximum — widened by a float32 slack of
    1e-5·√(K_c·N_DFT)·‖x‖, about 9× the transform's error bound — and the exact float64 K_DFT-grid
    values near them (:func:`_fine_maximum` on :func:`_range_columns`), as :func:`zoom_block` but
    without a float64 transform of the whole beam.
    """
    k, n = y.shape
    frame = (y * np.outer(w_k, w_n)).astype(np.complex64)
    k_coarse = scipy.fft.next_fast_len(processing.zoom_oversampling * k)
    spec = scipy.fft.ifft(frame, n=processing.n_dft, axis=-1, norm="forward")[:, first:]  # [K, P] complex64
    coarse = scipy.fft.ifft(spec, n=k_coarse, axis=0, norm="forward", overwrite_x=True)  # [K_c, P]
    amp = np.abs(coarse)
    slack = _F32_SLACK * np.sqrt(k_coarse * processing.n_dft) * float(np.linalg.norm(frame.astype(np.complex128)))
    floor = (float(amp.max()) - slack) * 10.0 ** (-processing.zoom_margin_db / 20.0) - slack
    picked = np.flatnonzero(amp.max(axis=0) >= floor)  # the candidate columns, ascending
    rows, sub = np.nonzero(amp[:, picked] >= floor)
    cols = picked[sub]
    exact = _range_columns(y, first + picked, processing.n_dft, w_k, w_n)  # [K, C] float64
    q, ci, value, krow = _fine_maximum(exact, rows, np.searchsorted(picked, cols), k_coarse, processing)
    return q, first + int(picked[ci]), value, krow


def _row_values(y: np.ndarray, krow: np.ndarray, columns: np.ndarray, n_dft: int, w_k: np.ndarray,
                w_n: np.ndarray) -> np.ndarray:
    """Unnormalised |z(q, p)|² at the delay columns p of the Doppler row with kernel ``krow`` [P]."""
    z = ((krow * w_k) @ y) @ (_dft_table(n_dft, y.shape[1], n_dft)[columns] * w_n).T
    return z.real**2 + z.imag**2
