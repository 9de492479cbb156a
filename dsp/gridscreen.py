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

**Precision (screen).** Only the screen is complex64; it decides which columns are evaluated,
never a value. Its error is bounded by the FFT's backward error,
``|ΔR_k(i)| ≤ c·u·log₂N·√N·‖x_k‖₂`` (u = 2⁻²⁴): an absolute slack of ``1e-5·√N·Σ_k ‖x_k‖₂``
per beam, 50× that bound for c = 1, is added to U. Every value that reaches the result is float64
and agrees with the full transform's to ~1e-13 relative (different summation order), so the same
cell wins unless two cells are within that of each other (a true tie, e.g. two identical
returns; either cell is then the grid maximum). The fine-column allowance of step 1 (scalloping
loss plus ``SCREEN_HEADROOM_DB``) is sized for sums of returns, not proven for every signal; the
dense search below uses no such allowance.

**Routing.** A beam with no return above the per-chirp noise (noise only) cannot be screened:
most of its columns stay above the bound. Such a beam is recognised early, from the bound of
32 of its samples refined against the largest refined native value, and sent to the dense
search without the screen's exact steps; a beam that reaches step 3 with more than
``_DENSE_FRACTION`` (1/8) of its columns above T₁ goes there too (evaluating them one by one
would cost more). Routing decides only the work, never the cell.

**Dense search** (:func:`_dense_beam`), for those beams, with every step proven:

a. *Fine range transform (complex64).* ``a_k(p) = Σ_n x[k, n] e^{+j2π p n / N_DFT}``, x the
   windowed beam, on the whole N_DFT grid by two matrix products (N_DFT = P₁·P₂, 11·109 for
   1199; the index split of Cooley–Tukey with the DFTs as products, p = P₂·a + b):
   ``v[b, k, d] = Σ_c e^{j2π b c / P₂} x[k, P₁c + d]`` and
   ``a[b, k, a] = Σ_d e^{j2π b d / N_DFT} e^{j2π d a / P₁} v[b, k, d]`` (P₁ + ⌈N/P₁⌉ products
   per output instead of N). Rows b and P₂ - b of the first are conjugate, so it is two real
   products (cos and sin rows, on the interleaved real and imaginary parts): half the work of
   the FFT at this prime-factor length (109), with an elementwise error bound. P₁ is the divisor
   with the fewest products among those whose tables fit :data:`DENSE_PLAN_BYTES`; a prime N_DFT
   too large for its N_DFT² table gets P₁ = 1, a plain DFT matrix (N products per output).
b. *Doppler plane (complex64).* ``c(r, p) = Σ_k a_k(p) e^{j2π r k / L}`` at L = 2^⌈log₂ 2K⌉
   points (256) by a power-of-two FFT (radix-4/2 Cooley–Tukey), and |c|.
c. *Szegő's bound.* In column p, ``g(ν) = Σ_k a_k(p) e^{j2π ν k}`` (ν in cycles per chirp) times
   ``e^{-jπ(K-1)ν}`` is a trigonometric sum of exponential type σ = π(K-1). For any phase φ,
   ``f = Re(e^{-jφ} e^{-jπ(K-1)ν} g)`` obeys ``f'² + σ²f² ≤ σ²M²``, M = max_ν |g| (Szegő's
   inequality, Szegő 1928; Duffin & Schaeffer 1937 for functions of exponential type), so
   ``θ = arccos(f/M)`` moves by at most σ|Δν| (``|θ'| = |f'|/√(M² - f²) ≤ σ``).
   Take q* the column's largest grid value m = |g(q*)| and φ its phase: θ(q*) = α with
   ``cos α = m/M ≥ cos α₀``, α₀ = σ/(2 K_DFT) (the maximum of |g| is within half a grid bin of a
   grid bin). Hence ``|g(ν)| ≥ M cos(α + σ|ν - q*|)`` for all ν, and a value r at ν puts q*
   outside ``|ν - q*| < (arccos(r/T) - α₀)/σ`` for any T ≤ m (arccos(r/M) ≥ arccos(r/T)).
d. *Search.* T is a lower bound of the grid maximum: the largest complex64 grid value next to
   the plane's maximum, minus its error bound. The grid maximum lies in the plane interval
   [r/L, (r+1)/L] of its column only if ``arccos(r_l/T) + arccos(r_r/T) ≤ σ/L + 2α₀`` (r_l, r_r
   upper bounds of the interval's end values), so only cells ≥ T·cos((σ/L + 2α₀)/2) (0.68·T for
   Table I) can border one. A surviving interval is split at its midpoint (one more complex64
   value, the same test at half the length); the grid bins left in the allowed sub-intervals,
   widened by one bin, are evaluated in complex64 (float64 sums of the complex64 a), and only
   those within the error bounds of the largest are evaluated in float64 (as in step 3). No
   margin in dB and no ``zoom_margin_db``: the bins that can hold the maximum are all kept.
   A beam whose surviving intervals could hold more than ``WHOLE_GRID_SHARE`` (1/64) of the grid's
   bins and more than ``WHOLE_GRID_MIN`` (each interval ≤ ⌈K_DFT/L⌉ + 4 of them) has nothing to prune — its spectrum is flat
   in Doppler over most delay columns, e.g. its energy is in one ADC sample (a glitch) — and is
   searched on its whole float64 grid instead (Table I, one core: 0.17 s and 338 MB peak, where
   its ~6·10⁶ candidate bins took 7.3 s and 4.6 GB). A beam whose energy is in one chirp is flat
   in Doppler only near its delay and stays with the bounded search (0.01 s).
e. *Precision.* Elementwise, with u = 2⁻²⁴ and ‖x‖₁ = Σ|x| over the beam (summed in float64):
   casting and windowing in float32 moves x by ≤ 3u|x|; a product of unit-modulus (rounded)
   coefficients with n complex inputs errs by ≤ √2(γ_{n+2} + u)·Σ|inputs| (γ_n = nu/(1-nu)),
   the real cos/sin products by ≤ 2(γ_{n+2} + u)·Σ|inputs| (|cos| + |sin| ≤ √2 on
   |re| + |im| ≤ √2|x|), and every intermediate of step a is bounded by the ℓ1 norm of its
   inputs, so ``|Δa_k(p)| ≤ e_a·‖x_k‖₁``, ``e_a = 2(γ_{⌈N/P₁⌉+2} + u) + √2(γ_{P₁+2} + u) + 3u``;
   a Cooley–Tukey pass of radix ρ adds ≤ 2(ρ+2)u·Σ_k|a_k(p)| (its outputs are unit-weighted
   sums of ρ values, each bounded by the ℓ1 norm of the values it sums). So a plane value errs by
   ≤ (e_a + e_L + 2u)·‖x‖₁ (e_L the sum over the passes; +2u for |·| in float32), a midpoint
   (complex64 products of K terms) by ≤ (e_a + √2(γ_{K+2} + u))·‖x‖₁ and a grid value (float64
   sums of the complex64 a) by ≤ e_a·‖x‖₁ + 1e-13·‖x‖₁; twice these are the slacks
   (≈ 1e-5–2e-5·‖x‖₁: 0.1 % of a noise-only maximum at Table I, measured errors 1e-3–1e-2 of
   them). Every value that reaches the result is float64, as above. A beam whose ‖x‖₁ is below
   1e-30 (float32 would lose it) is searched on the whole float64 grid instead.

**Best beam only** (``best_only=True``: :func:`dsp.localize` reads only the beam of largest P_ave).
The beams the dense search would take wait until the others are done; then, likeliest first (by
their largest refined native value) and two at a time, each is either searched as above or left
out when :func:`dsp.gridbound.grid_bound` — an upper bound of its |z|² at every delay and Doppler — is below the
largest P_ave found so far: its own P_ave, a mean of grid values |z|², cannot reach it. The bound
is the half-bin grid's maximum (L >= 2K Doppler by L_f >= 2N delay bins, one complex64 2-D
transform, 1.4 ms for a Table I beam against ~4–7 ms for its dense search; 0.8 ms where a sum over
chirps first closes most delay bins, :func:`dsp.gridbound.grid_bound`) divided by
cos α_f cos α_ν, Szegő's inequality of step c applied once per axis: at the continuous maximum
(ν*, f*), |z(ν*, f_j)| >= M cos α_f at the nearest delay bin f_j (α_f = π(N-1)/(2 L_f)), and on that
delay |z| reaches at least cos α_ν of its own maximum (>= that value) at its nearest Doppler bin.
Both angles are <= π/4, so the bound exceeds M² by at most 4× (Szegő's extremal function attains
it). Given the P_ave to stay below, the few delay bins (<= 16) whose Doppler bound could reach it
are refined 4× on both axes (float64, one matrix product and a 4L-point Doppler transform): a
maximum near them is then bounded within 1.2× (Table I), the rest stays below by the coarse bound.
The bound is computed only when 3× the beam's largest refined native value is below the best
P_ave (a prediction: work only), so a beam it is unlikely to exclude costs nothing more. The
left-out beams report the bound as their peak and P_ave, bins -1 (:attr:`dsp.BeamScan.bounded`).
The searched beams and the best one are bit for bit the full scan's; which beams are left out
depends on the data only (the rounds do not depend on the threads). Table I (UE at 10.3°), one
core: at 5 dBm 55 of the 55 noise-only beams left out (0.25 → 0.15 s per cube), at 10 dBm 54
(0.23 → 0.09 s; docs/benchmarks.md, 2026-11-28); at 0 dBm the best P_ave is within 1–3 dB of
the noise-only beams' maxima (none left out, the same time) and at 20 dBm no beam is noise only.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from queue import Empty, SimpleQueue
from typing import Callable

import numpy as np
import scipy.fft

from .budget import check_memory
from .gridbound import grid_bound
from .processing import ProcessingConfig, window_vector
from .threads import thread_count

__all__ = ["SCREEN_HEADROOM_DB", "WHOLE_GRID_MIN", "WHOLE_GRID_SHARE", "screened_scan", "scalloping_loss_db",
           "whole_grid_bins"]

#: Allowance (dB) beyond the window's single-tone scalloping loss for returns that interfere
#: between two native delay samples (two equal in-phase tones one bin apart: +1.1 dB for Hann).
SCREEN_HEADROOM_DB = 1.5

#: Relative float32 slack of the screen (see the module notes).
_F32_SLACK = 1e-5

#: Bytes of complex64 screen work per chunk of beams (cache-sized).
_SCREEN_CHUNK = 2 * 2**20

#: Unit roundoff of float32.
_U32 = 2.0**-24

#: Native samples whose bound is refined to predict a noise-only beam (routing only).
_ROUTE_SAMPLES = 32

#: ``best_only``: beams the dense search would take, searched (or bounded) this many at a time.
_DEFERRED_ROUND = 2
#: ``best_only``: the bound is computed for a beam only when this many times its largest refined
#: native |z|² is below the best P_ave (a prediction: it decides work, never a result).
_BOUND_PREDICT = 3.0

#: A beam goes to the dense search when more than this fraction of its columns stays above the
#: screen's bound (evaluating them one by one would cost more than the dense search).
_DENSE_FRACTION = 1 / 8

#: The dense search gives a beam to its whole float64 grid when the grid bins it would still have
#: to evaluate could exceed this share of the grid (and ``WHOLE_GRID_MIN``): a beam whose spectrum
#: is flat in Doppler over most delay columns (an impulse: its energy in one ADC sample, as a glitch
#: puts it) has nothing to prune, and its ~K_DFT·N_DFT candidate bins would cost more than the grid
#: and gigabytes of gathered kernel rows.
WHOLE_GRID_SHARE = 1 / 64
#: ... and at least this many bins (a small grid is searched by its bounds whatever it costs: cheap).
WHOLE_GRID_MIN = 2**16


def whole_grid_bins(k_dft: int, n_dft: int) -> int:
    """Candidate grid bins above which a beam is searched on its whole grid instead (``WHOLE_GRID_SHARE``, ``WHOLE_GRID_MIN``)."""
    return max(int(k_dft * n_dft * WHOLE_GRID_SHARE), WHOLE_GRID_MIN)


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
    average_columns: Callable[[int], np.ndarray], workers: int | None = None, best_only: bool = False,
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
    best_only : bool, default False
        Search exactly only the beams that can have the largest P_ave (module notes, "Best beam
        only"): a beam the dense search would take whose proven bound :func:`dsp.gridbound.grid_bound` is below
        a P_ave already found is not searched. The best beam (argmax of ``average``, the first on
        a tie) and its numbers are those of the full result.

    Returns
    -------
    q, p : int arrays [M]
        Doppler bin (FFT order) and delay bin of each beam's grid maximum; -1 for a beam
        ``best_only`` did not search.
    power : float array [M]
        Unnormalised |z(q, p)|² (divide by the coherent gain²) [W·gain²]; for a beam not searched,
        the upper bound of its grid maximum.
    average : float array [M]
        Unnormalised mean of |z(q, p')|² over the P_ave bins p' [W·gain²]; for a beam not
        searched, the same upper bound (its P_ave cannot exceed it).
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
    first_native = int(np.floor(first * n_c / n_dft))
    q_best = np.empty(m, dtype=np.int64)
    p_best = np.empty(m, dtype=np.int64)
    power = np.empty(m)
    average = np.empty(m)
    step = max(1, _SCREEN_CHUNK // (8 * k * n_c))
    plan = _DensePlan.get(k, n, n_dft, processing.k_dft)
    # best_only: (beam, windowed complex64 beam, ‖x‖_F, lower bound of |z|, predicted level |z|²)
    deferred: list[tuple[int, np.ndarray, float, float, float]] = []

    def dense_search(j: int, x32: np.ndarray, lower: float) -> tuple[int, int, float, np.ndarray]:
        """:func:`_dense_beam` of beam j on a workspace of the plan's (kept for the next scan)."""
        try:
            work = plan.spare.get_nowait()
        except Empty:
            work = _DenseWork(plan)
        try:
            return _dense_beam(cube[j], x32, plan, work, first, w_k, w_n, lower)
        finally:
            plan.spare.put(work)

    def chunk(i: int) -> None:
        block = cube[i:i + step].astype(np.complex64)
        block *= w32
        norms = np.array([np.sqrt(np.vdot(b, b).real) for b in block], dtype=np.float64)  # ‖x‖_F [c]
        spec = scipy.fft.ifft(block, n=n_c, axis=-1, norm="forward")  # [c, K, n_c]; block kept for the dense search
        # Σ_k |R_k(i)| bounds |z| at every Doppler; the slack covers float32 (module notes).
        slack = _F32_SLACK * np.sqrt(k * n) * norms  # [c]
        u = np.abs(spec).sum(axis=1, dtype=np.float64) + slack[:, None]  # [c, n_c]
        # The bounds of every beam of the chunk at once: the 8 largest refined, then the routing.
        bound, refined = u**2, np.zeros(u.shape, dtype=bool)
        top = first_native + np.argsort(u[:, first_native:], axis=1)[:, -8:]  # [c, 8]
        _refine_many(spec, bound, refined, np.arange(u.shape[0]), top, slack, doppler_margin)
        noise_only = _noise_only(spec, bound, refined, top, slack, doppler_margin, delay_margin, first_native)
        for c in range(u.shape[0]):
            j = i + c
            y = cube[j]
            bounds = _ColumnBounds(spec[c], bound[c], doppler_margin, slack[c], refined[c])
            lower = -np.inf
            if noise_only[c]:
                dense = True
            else:
                fine = np.maximum(bounds.value[lo], bounds.value[hi]) * delay_margin  # [N_DFT]
                fine[:first] = -np.inf
                p0 = int(fine.argmax())
                cols = np.arange(max(first, p0 - reach), min(n_dft, p0 + reach + 1))
                q, pi, value, krow = zoom_block(_range_columns(y, cols, n_dft, w_k, w_n), processing)
                bounds.refine(np.flatnonzero(bounds.value * delay_margin >= value))
                fine = np.maximum(bounds.value[lo], bounds.value[hi]) * delay_margin
                fine[:first] = -np.inf
                above = np.flatnonzero(fine >= value)
                dense = above.size > n_dft * _DENSE_FRACTION
                lower = np.sqrt(value)
            if dense and best_only:  # searched after the others, if its bound can reach their P_ave
                # the largest refined native |z|² (<= the native grid's maximum): it orders the deferred
                # beams and predicts whether their bound can exclude them (work only, never a result)
                level = float(bound[c][refined[c]].max()) / doppler_margin if refined[c].any() else 0.0
                deferred.append((j, block[c], float(norms[c]), lower, level))
                continue
            if dense:
                q, p, value, krow = dense_search(j, block[c], lower)
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
    if deferred:
        # The likeliest first, in rounds of _DEFERRED_ROUND beams (searched on the threads): a round's
        # searches raise the P_ave that the next round's bounds must stay below. The rounds do not
        # depend on ``workers``, so neither does the result.
        searched = np.ones(m, dtype=bool)
        searched[[item[0] for item in deferred]] = False
        best = float(average[searched].max()) if searched.any() else -np.inf
        order = sorted(deferred, key=lambda item: (-item[4], item[0]))

        def search(item: tuple[int, np.ndarray, float, float, float]) -> None:
            j, x32, _, lower, _ = item
            q_best[j], p_best[j], power[j], krow = dense_search(j, x32, lower)
            average[j] = _row_values(cube[j], krow, average_columns(int(p_best[j])), n_dft, w_k, w_n).mean()

        pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
        try:
            for r0 in range(0, len(order), _DEFERRED_ROUND):
                todo = []
                for item in order[r0:r0 + _DEFERRED_ROUND]:
                    j, x32, norm, _, level = item
                    # the bound exceeds the native grid's maximum, by ~1.2-3.9x: computed where it may exclude
                    if _BOUND_PREDICT * level < best:
                        limit = grid_bound(x32, norm, plan.length, level=best)
                        if limit * (1.0 + 1e-9) < best:  # P_ave_j <= max |z_j|² <= limit < best
                            q_best[j], p_best[j], power[j], average[j] = -1, -1, limit, limit
                            continue
                    todo.append(item)
                if pool is not None and len(todo) > 1:
                    list(pool.map(search, todo))
                else:
                    for item in todo:
                        search(item)
                if todo:
                    best = max(best, float(average[[item[0] for item in todo]].max()))
        finally:
            if pool is not None:
                pool.shutdown()
    return q_best, p_best, power, average


def _refine_many(spec: np.ndarray, value: np.ndarray, done: np.ndarray, beams: np.ndarray, samples: np.ndarray,
                 slack: np.ndarray, doppler_margin: float) -> None:
    """:meth:`_ColumnBounds.refine` for several beams at once: ``samples [B, S]`` of ``beams [B]``.

    ``spec [c, K, n_c]``, ``value``/``done [c, n_c]`` (updated in place), ``slack [c]``.
    """
    z = scipy.fft.ifft(spec[beams[:, None], :, samples], axis=-1, norm="forward")  # [B, S, K] native Doppler grid
    peak = np.sqrt((z.real**2 + z.imag**2).max(axis=-1).astype(np.float64)) + slack[beams, None]
    rows = beams[:, None]
    value[rows, samples] = np.minimum(value[rows, samples], peak**2 * doppler_margin)
    done[rows, samples] = True


def _noise_only(spec: np.ndarray, value: np.ndarray, done: np.ndarray, top: np.ndarray, slack: np.ndarray,
                doppler_margin: float, delay_margin: float, first_native: int) -> np.ndarray:
    """Per beam of a chunk [c]: whether the screen would leave too many samples above its bound.

    A prediction (it only routes the beam): the largest refined native value (of the samples
    ``top [c, 8]``) stands in for the grid maximum, and the bound of ``_ROUTE_SAMPLES`` of the
    samples above it is refined; more than ``_DENSE_FRACTION`` of the samples predicted above
    sends the beam to the dense search.
    """
    n_c = value.shape[1]
    beams = np.arange(value.shape[0])
    level = value[beams[:, None], top].max(axis=1) / doppler_margin  # ≈ the native grid's largest |z|² [c]
    above = value[:, first_native:] * delay_margin >= level[:, None]
    count = above.sum(axis=1)
    result = np.zeros(value.shape[0], dtype=bool)
    check = np.flatnonzero(count > n_c * _DENSE_FRACTION)
    if check.size:
        spread = (np.arange(_ROUTE_SAMPLES) / (_ROUTE_SAMPLES - 1))[None, :] * (count[check, None] - 1)
        rank = np.cumsum(above[check], axis=1) - 1  # the rank of each sample above, per beam
        samples = np.empty((check.size, _ROUTE_SAMPLES), dtype=np.int64)
        for row, b in enumerate(check):  # evenly spread samples among those above
            samples[row] = first_native + np.searchsorted(rank[row], spread[row].astype(np.int64))
        _refine_many(spec, value, done, check, samples, slack, doppler_margin)
        still = (value[check[:, None], samples] * delay_margin >= level[check, None]).mean(axis=1)
        result[check] = count[check] * still > n_c * _DENSE_FRACTION
    return result


class _ColumnBounds:
    """Upper bounds on max_ν |z(ν, τ_i)|² per native delay sample i [n_c], tightened on demand.

    ``value`` starts as the triangle bound (Σ_k |R_k(i)|)², already refined where ``done``;
    :meth:`refine` replaces it, for the given samples, by the smaller of it and the native-grid
    Doppler maximum times ``doppler_margin``. Both arrays are updated in place.
    """

    def __init__(self, spec: np.ndarray, value: np.ndarray, doppler_margin: float, slack: float,
                 done: np.ndarray) -> None:
        self.spec, self.value, self.margin, self.slack, self.done = spec, value, doppler_margin, slack, done

    def refine(self, samples: np.ndarray) -> None:
        todo = samples[~self.done[samples]]
        if todo.size == 0:
            return
        z = scipy.fft.ifft(self.spec[:, todo], axis=0, norm="forward")  # [K, S] native Doppler grid
        peak = np.sqrt((z.real**2 + z.imag**2).max(axis=0).astype(np.float64)) + self.slack
        self.value[todo] = np.minimum(self.value[todo], peak**2 * self.margin)
        self.done[todo] = True


def _prime_factors(n: int) -> list[int]:
    """The prime factors of ``n`` with multiplicity, ascending."""
    out, p = [], 2
    while p * p <= n:
        while n % p == 0:
            out.append(p)
            n //= p
        p += 1
    return out + ([n] if n > 1 else [])


def _gamma(n: int) -> float:
    """γ_n = n·u/(1 - n·u) for float32: the relative error bound of an n-term sum."""
    return n * _U32 / (1.0 - n * _U32)


#: Bytes the dense plan's two tables may take while they are built (with their float64 and complex128
#: temporaries, :func:`_plan_bytes`). The split with the fewest products per output is taken among the divisors
#: of N_DFT within it: a prime N_DFT's own split P₁ = N_DFT builds an N_DFT² stage-2 table (a capture declaring
#: N_DFT = 13 763 took 7.2 GB, benchmarks/fuzz.py, 2026-11-28), and P₁ = 1 (a plain N_DFT x N DFT matrix in
#: stage 1) is taken there. Table I's split (11 · 109) needs 0.4 MiB.
DENSE_PLAN_BYTES = 64 * 2**20


def _plan_bytes(n: int, n_dft: int, p1: int) -> int:
    """Peak bytes of building :class:`_DensePlan`'s tables for the split N_DFT = P₁·P₂ of N samples."""
    p2, blocks = n_dft // p1, -(-n // p1)
    stage1 = (p2 // 2 + 1) * blocks * (8 + 8 + 8 + 4)  # int64 phase index, float64 cos and sin, the float32 table
    stage2 = p2 * p1 * p1 * (16 + 8) + 16 * (p1 * p1 + p2 * p1)  # complex128 product, complex64 table; two factors
    return stage1 + stage2


def _dense_split(n: int, n_dft: int) -> int:
    """P₁: the divisor of N_DFT with the fewest products per output, P₁ + ⌈N/P₁⌉, among those (other than 1
    where one is) whose tables fit :data:`DENSE_PLAN_BYTES`; the smallest tables' when none fits (the plan
    then checks them against the memory limit)."""
    divisors = [d for d in range(1, n_dft + 1) if n_dft % d == 0]
    fits = [d for d in divisors if _plan_bytes(n, n_dft, d) <= DENSE_PLAN_BYTES]
    pool = [d for d in fits if d > 1] or fits or [min(divisors, key=lambda d: _plan_bytes(n, n_dft, d))]
    return min(pool, key=lambda d: d + -(-n // d))


class _DensePlan:
    """The dense search's constants for one (K, N, N_DFT, K_DFT): tables and error bounds.

    Attributes
    ----------
    p1, p2, blocks : int
        N_DFT = P₁·P₂ and ⌈N/P₁⌉: the range transform's split (module notes, step a).
    stage1 : float32 array [2H, ⌈N/P₁⌉]
        ``cos(2π b c / P₂)`` over ``sin(2π b c / P₂)`` for b < H = ⌊P₂/2⌋ + 1 (rows b and P₂ - b
        are conjugate: two real products give all P₂ rows).
    stage2 : complex64 array [P₂, P₁, P₁]
        ``e^{j2π b d / N_DFT} e^{j2π d a / P₁}`` [b, d, a].
    length : int
        L, the Doppler plane's length (power of two >= 2K).
    sigma, alpha0 : float
        σ = π(K-1) [rad per cycle] and α₀ = σ/(2 K_DFT) [rad] (step c).
    err_plane, err_grid, err_mid : float
        Slack of a plane value, a grid value and a midpoint value per unit ‖x‖₁ (step e, doubled).
    midpoints : complex64 array [2L, K]
        ``e^{j2π m k / 2L}``: the kernel rows of the plane's midpoints (odd m).
    column : int array [P₂, P₁]
        The delay bin p = P₂·a + b of the plane's column [b, :, a].
    spare : SimpleQueue of _DenseWork
        Workspaces not in use (one per thread that ran a dense search; kept with the plan so that
        the next scan does not fault its pages in again).
    """

    _cache: dict[tuple[int, int, int, int], _DensePlan] = {}

    def __init__(self, k: int, n: int, n_dft: int, k_dft: int) -> None:
        p1 = _dense_split(n, n_dft)  # the fewest products per output within the table budget
        check_memory(_plan_bytes(n, n_dft, p1), f"processing.n_dft={n_dft} (the grid search's DFT tables for "
                     f"N = {n} samples, split {p1} x {n_dft // p1})",
                     fix="choose an N_DFT with small prime factors (the paper's 1199 = 11 x 109), or raise the limit")
        p2, blocks = n_dft // p1, -(-n // p1)
        self.k, self.n, self.n_dft, self.k_dft = k, n, n_dft, k_dft
        self.p1, self.p2, self.blocks = p1, p2, blocks
        b, c, d = np.arange(p2), np.arange(blocks), np.arange(p1)
        half = np.outer(b[:p2 // 2 + 1], c) % p2
        self.stage1 = np.concatenate([np.cos(2 * np.pi * half / p2), np.sin(2 * np.pi * half / p2)]).astype(np.float32)
        twiddle = np.exp(2j * np.pi * (np.outer(b, d) % n_dft) / n_dft)  # [b, d]
        small = np.exp(2j * np.pi * (np.outer(d, d) % p1) / p1)  # [d, a]
        self.stage2 = (twiddle[:, :, None] * small[None, :, :]).astype(np.complex64)
        self.length = 1 << int(np.ceil(np.log2(2 * k)))
        self.sigma = np.pi * (k - 1)
        self.alpha0 = self.sigma / (2.0 * k_dft)
        err_a = 2.0 * (_gamma(blocks + 2) + _U32) + np.sqrt(2.0) * (_gamma(p1 + 2) + _U32) + 3 * _U32
        err_l = sum(2.0 * (f + 2) for f in _prime_factors(self.length)) * _U32
        self.err_plane = 2.0 * (err_a + err_l + 2 * _U32)
        self.err_grid = 2.0 * (err_a + 1e-13)
        self.err_mid = 2.0 * (err_a + np.sqrt(2.0) * (_gamma(k + 2) + _U32))  # complex64 products
        self.midpoints = _dft_table(2 * self.length, k, 2 * self.length).astype(np.complex64)  # [2L, K]
        # Fine column p of the plane layout [b, r, a]: p = P₂·a + b.
        self.column = np.arange(p1)[None, :] * p2 + np.arange(p2)[:, None]  # [P₂, P₁]
        self.spare: SimpleQueue[_DenseWork] = SimpleQueue()

    @classmethod
    def get(cls, k: int, n: int, n_dft: int, k_dft: int) -> _DensePlan:
        """The plan for these sizes (kept for the last few)."""
        key = (k, n, n_dft, k_dft)
        if key not in cls._cache:
            if len(cls._cache) >= 4:
                cls._cache.pop(next(iter(cls._cache)))
            cls._cache[key] = cls(*key)
        return cls._cache[key]


class _DenseWork:
    """Buffers of one thread's dense search (reused beam after beam: no page faults)."""

    def __init__(self, plan: _DensePlan) -> None:
        k, p1, p2 = plan.k, plan.p1, plan.p2
        self.xs = np.zeros((plan.blocks, k, p1), np.complex64)  # x[k, P₁c + d] at [c, k, d]
        self.cs = np.empty((2 * (p2 // 2 + 1), 2 * k * p1), np.float32)  # C x over S x, re/im interleaved
        self.jsx = np.empty((p2 // 2 + 1, k * p1), np.complex64)
        self.v = np.empty((p2, k * p1), np.complex64)
        self.padded = np.zeros((p2, plan.length, p1), np.complex64)  # rows K.. stay zero
        self.a = self.padded[:, :k, :]  # a_k(P₂·a + b) at [b, k, a]
        self.amp = np.empty((p2, plan.length, p1), np.float32)
        self.mask = np.empty((p2, plan.length, p1), bool)
        self.ends = np.empty((p2, plan.length, p1), bool)


def _dense_beam(y: np.ndarray, x32: np.ndarray, plan: _DensePlan, work: _DenseWork, first: int, w_k: np.ndarray,
                w_n: np.ndarray, lower: float) -> tuple[int, int, float, np.ndarray]:
    """The grid maximum of one beam ``y [K, N]`` (not windowed) whose columns could not be screened.

    The module notes' dense search: the fine range transform and an L-point Doppler plane in
    complex64, Szegő's bound to keep only the grid bins that can hold the maximum, complex64
    values there and float64 values for the few within the error bounds of the largest.
    ``x32`` is the windowed beam in complex64 [K, N] (within 3u of w_K·w_N·y); ``lower`` is a grid
    amplitude |z| known not to exceed the maximum (or -inf). Returns (q, p, unnormalised |z|², kernel row of q [K]).
    """
    k, n = y.shape
    n_dft, k_dft, p1, p2, length = plan.n_dft, plan.k_dft, plan.p1, plan.p2, plan.length
    table = _dft_table(k_dft, k, k_dft)
    # a. The fine range transform, a_k(P₂·a + b) at [b, k, a].
    whole = n // p1
    work.xs[:whole].transpose(1, 0, 2)[...] = x32[:, :whole * p1].reshape(k, whole, p1)
    if whole < plan.blocks:
        work.xs[whole, :, :n - whole * p1] = x32[:, whole * p1:]
    l1 = float(np.abs(x32).sum(dtype=np.float64)) * (1.0 + 1e-6)  # >= ‖x‖₁ (x within 3u of x32)
    if l1 < 1e-30:  # zero, or so small that float32 loses it: the float64 grid decides
        if not np.any(y):  # every cell ties at 0 and the first searchable one wins
            return 0, first, 0.0, table[0]
        return _full_beam(y, plan, first, w_k, w_n)
    eps_plane, eps_grid = plan.err_plane * l1, plan.err_grid * l1
    # v[b] = C x + j S x and v[P₂-b] = C x - j S x: real products on the interleaved complex x.
    half = p2 // 2 + 1
    np.matmul(plan.stage1, work.xs.reshape(plan.blocks, k * p1).view(np.float32), out=work.cs)
    cx, sx = work.cs[:half].view(np.complex64), work.cs[half:].view(np.complex64)  # [H, K·P₁]
    np.multiply(sx, 1j, out=work.jsx)
    np.add(cx, work.jsx, out=work.v[:half])
    np.subtract(cx[1:p2 - half + 1][::-1], work.jsx[1:p2 - half + 1][::-1], out=work.v[half:])
    a = np.matmul(work.v.reshape(p2, k, p1), plan.stage2, out=work.a)  # into the zero-padded buffer
    # b. The Doppler plane at L points and its magnitude.
    amp = np.abs(scipy.fft.ifft(work.padded, axis=1, norm="forward"), out=work.amp)
    if first:
        b_out, a_out = np.nonzero(plan.column < first)
        amp[b_out, :, a_out] = -np.inf  # below any threshold, whatever the slack (not -1: a slack may exceed it)
    # d. T: the largest grid value next to the plane's maximum, less its error bound.
    b0, r0, a0 = np.unravel_index(int(amp.argmax()), amp.shape)
    q0 = np.arange((r0 - 1) * k_dft // length, -(-(r0 + 1) * k_dft // length) + 1) % k_dft
    t = max(lower * (1.0 - 1e-9), float(np.abs(table[q0] @ a[b0, :, a0]).max()) - eps_grid)
    if not t > 0.0:  # cannot happen for a beam that is not zero (module notes); the full grid then
        return _full_beam(y, plan, first, w_k, w_n)
    reach = plan.sigma / length + 2.0 * plan.alpha0  # σ·h + 2α₀, h = 1/L
    np.greater_equal(amp, t * np.cos(min(0.5 * reach, 0.5 * np.pi)) - eps_plane, out=work.mask)
    # The intervals [r, r+1] (flat index of r) with a candidate at either end.
    mask, ends = work.mask, work.ends
    np.logical_or(mask[:, :-1], mask[:, 1:], out=ends[:, :-1])
    np.logical_or(mask[:, -1], mask[:, 0], out=ends[:, -1])
    left = np.flatnonzero(ends)
    b, rem = np.divmod(left, length * p1)
    r, a_idx = np.divmod(rem, p1)
    right = (b * length + (r + 1) % length) * p1 + a_idx
    flat = amp.reshape(-1)
    gap_l = _exclusion(flat[left], t, eps_plane, plan)  # cycles around each end free of the maximum
    gap_r = _exclusion(flat[right], t, eps_plane, plan)
    keep = gap_l + gap_r <= (1.0 + 1e-9) / length  # float64 rounding of the test itself
    if int(np.count_nonzero(keep)) * (-(-k_dft // length) + 4) > whole_grid_bins(k_dft, n_dft):
        return _full_beam(y, plan, first, w_k, w_n)  # nothing to prune (a flat Doppler spectrum)
    b, r, a_idx, gap_l, gap_r = b[keep], r[keep], a_idx[keep], gap_l[keep], gap_r[keep]
    # Split each interval at its midpoint (2L grid): one more value, the same test on the halves.
    cols = a[b, :, a_idx]  # [I, K] complex64
    mid = np.abs(np.einsum("ik,ik->i", plan.midpoints[2 * r + 1], cols))
    gap_m = _exclusion(mid, t, plan.err_mid * l1, plan)
    start = np.concatenate([r / length + gap_l, (r + 0.5) / length + gap_m])
    stop = np.concatenate([(r + 0.5) / length - gap_m, (r + 1) / length - gap_r])
    b, a_idx = np.concatenate([b, b]), np.concatenate([a_idx, a_idx])
    ok = start <= stop + 1e-9 / length
    start, stop, b, a_idx = start[ok], stop[ok], b[ok], a_idx[ok]
    # The grid bins in the allowed sub-intervals, widened by one bin, in complex64.
    q_lo = np.ceil(start * k_dft).astype(np.int64) - 1
    count = np.floor(stop * k_dft).astype(np.int64) + 2 - q_lo
    total = int(count.sum())
    if total == 0:  # cannot happen: the maximum's interval always survives (module notes)
        return _full_beam(y, plan, first, w_k, w_n)
    offset = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    q = (np.repeat(q_lo, count) + offset) % k_dft
    b, a_idx = np.repeat(b, count), np.repeat(a_idx, count)
    value = np.abs(np.einsum("ik,ik->i", table[q], a[b, :, a_idx]))
    t = max(t, float(value.max()) - eps_grid)
    near = value + eps_grid >= t
    # float64 for those that can be the maximum; the full search's order on ties (q, then p).
    cells = np.unique(q[near] * n_dft + plan.column[b[near], a_idx[near]])
    q, p = np.divmod(cells, n_dft)
    columns, which = np.unique(p, return_inverse=True)
    exact = _range_columns(y, columns, n_dft, w_k, w_n)  # [K, C] float64
    z = np.einsum("ik,ki->i", table[q], exact[:, which])
    power = z.real**2 + z.imag**2
    best = int(np.lexsort((p, q, -power))[0])
    return int(q[best]), int(p[best]), float(power[best]), table[int(q[best])]


def _exclusion(value: np.ndarray, t: float, slack: float, plan: _DensePlan) -> np.ndarray:
    """(arccos(min(1, (value + slack)/t)) - α₀)/σ, >= 0: the reach [cycles] of a sample's exclusion."""
    ratio = np.minimum(1.0, (value.astype(np.float64) + slack) / t)
    if plan.sigma == 0.0:  # one chirp: |g| is the same at every Doppler
        return np.where(ratio < 1.0, np.inf, 0.0)
    return np.maximum(0.0, np.arccos(ratio) - plan.alpha0) / plan.sigma


def _full_beam(y: np.ndarray, plan: _DensePlan, first: int, w_k: np.ndarray,
               w_n: np.ndarray) -> tuple[int, int, float, np.ndarray]:
    """The grid maximum of ``y [K, N]`` by the whole float64 N_DFT × K_DFT transform (fallback)."""
    spectrum = scipy.fft.ifft(y * np.outer(w_k, w_n), n=plan.n_dft, axis=1, norm="forward")
    grid = scipy.fft.ifft(spectrum, n=plan.k_dft, axis=0, norm="forward")  # [K_DFT, N_DFT]
    power = grid.real**2 + grid.imag**2
    power[:, :first] = -1.0
    q, p = np.unravel_index(int(power.argmax()), power.shape)
    return int(q), int(p), float(power[q, p]), _dft_table(plan.k_dft, y.shape[0], plan.k_dft)[int(q)]


def _row_values(y: np.ndarray, krow: np.ndarray, columns: np.ndarray, n_dft: int, w_k: np.ndarray,
                w_n: np.ndarray) -> np.ndarray:
    """Unnormalised |z(q, p)|² at the delay columns p of the Doppler row with kernel ``krow`` [P]."""
    z = ((krow * w_k) @ y) @ (_dft_table(n_dft, y.shape[1], n_dft)[columns] * w_n).T
    return z.real**2 + z.imag**2
