"""A proven upper bound of one beam's |z|² over every delay and Doppler, from a half-bin grid.

:func:`grid_bound` bounds the continuous maximum of a windowed beam's 2-D DTFT |z(ν, f)|² (and so
its grid maximum and its P_ave) without searching it: Szegő's inequality for exponential sums
(:mod:`dsp.gridscreen`, module notes, step c) once per axis on the complex64 half-bin grid, then
the few delay bins that could still reach a given level refined in float64. Given that level, a
cheaper bound comes first: the sum over chirps of |a_k| per delay bin (the triangle inequality), which
closes most delay bins of a beam well below the level without its Doppler transform. The paper's grid
search with ``best_only`` (:func:`dsp.gridscreen.screened_scan`) leaves out a beam whose bound is
below a P_ave already found.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

__all__ = ["BOUND_COLUMNS", "BOUND_REFINE", "grid_bound"]

#: Unit roundoff of float32.
_U32 = 2.0**-24

#: :func:`grid_bound` with a level: at most this many delay bins are refined, each this many times
#: finer on both axes (1.2× the maximum in power for Table I instead of 3.9).
BOUND_COLUMNS, BOUND_REFINE = 16, 4


def grid_bound(x32: np.ndarray, norm: float, doppler_length: int, level: float | None = None) -> float:
    """An upper bound of max |z(ν, f)|² over every Doppler ν and delay f of one windowed beam [W·gain²].

    ``x32 [K, N]`` is the windowed beam in complex64 (within 3u of w_K·w_N·y) and ``norm`` its
    Frobenius norm ‖x‖_F (float64). The half-bin grid — ``L >= 2K`` Doppler bins
    (``doppler_length``) by ``L_f = next_fast_len(2N)`` delay bins, one complex64 2-D transform —
    bounds the continuous maximum by Szegő's inequality (:mod:`dsp.gridscreen`, module notes, step c)
    once per axis. Per
    delay bin f_j, ``U_j = (max_q |z(ν_q, f_j)| + e)/cos α_ν`` bounds max_ν |z(ν, f_j)| (α_ν =
    π(K-1)/(2L)), and at the maximum (ν*, f*) the delay bin f_j nearest f* has
    ``|z(ν*, f_j)| >= M cos α_f`` (α_f = π(N-1)/(2 L_f)): ``M <= max_j U_j / cos α_f`` (each angle
    <= π/4: at most 4× in power, 3.9 for Table I). ``e = 50 u log₂(L L_f) √(L L_f) ‖x‖_F +
    4u √(KN) ‖x‖_F``: 50 times the complex64 FFT's normwise error for c = 1 (as the screen's slack)
    plus the cast and window (u = 2⁻²⁴).

    With ``level``, the chirp sum comes first: ``S_j = Σ_k |a_k(f_j)|`` (a_k the row transforms at the
    L_f delay bins) bounds |z(ν, f_j)| for every ν by the triangle inequality, no Doppler transform and
    no α_ν; ``S_j / cos α_f`` plus its slack ``(50 u log₂(L_f) √(L_f K) + 4u √(KN)) ‖x‖_F / cos α_f``
    (the row transforms' normwise error summed over the K rows, the cast and window) closes every delay
    bin where it is below √level, and only the bins left open get the Doppler transform; U_j is then
    the smaller of the two. A noise-only beam's sum is ≈ √(π/4) Σ_k ‖x_k‖ in a typical bin (Rayleigh
    |a_k|); where that is not below √level cos α_f the sum would close few bins and is skipped (a choice
    of work, never of validity). Table I, one core, the bounds of a study's 10 dBm runs: 0.76 ms
    against 1.36 ms (median 38 of 1200 delay bins left open); at 5 dBm the sum is skipped.

    With ``level`` (a |z|² the caller wants the bound below), the delay bins that could hold a
    maximum at or above it (``U_j >= √level cos α_f``), if at most ``BOUND_COLUMNS``, are refined:
    the delays within half a bin of each, at ``BOUND_REFINE`` times the spacing, in float64 by a
    matrix product, each with a ``BOUND_REFINE``·L-point Doppler transform. A maximum whose
    nearest delay bin is one of them lies within 1/(2·BOUND_REFINE·L_f) of a refined delay, so
    ``M <= max (U'/cos(α_f/r))`` over those (U' with α_ν/r), r = ``BOUND_REFINE``: 1.2× in power
    instead of 3.9 for Table I; elsewhere the coarse bound stays below √level. Their slack is
    ``(4u + 1e-12) √(KN) ‖x‖_F`` (the cast and window; float64 products). The bound returned is the
    larger of the two parts.
    """
    k, n = x32.shape
    length, length_f = int(doppler_length), _delay_length(n)
    rows = scipy.fft.fft(x32, n=length_f, axis=1, workers=1)  # [K, L_f]: a_k(f_j)
    alpha_f, alpha_nu = _angles(k, n, length)
    wanted = level is not None and level > 0
    # Noise's Σ_k |a_k| is ≈ √(π/4) Σ_k ‖x_k‖ in a typical delay bin (Rayleigh |a_k| of mean square ‖x_k‖²):
    # where that reaches √level the sum would leave most bins open and is not computed (work only)
    typical = np.sqrt(np.pi / 4.0) * float(np.sqrt((x32.real**2 + x32.imag**2).sum(axis=1, dtype=np.float64)).sum()) \
        if wanted else np.inf
    if wanted and typical < np.sqrt(level) * np.cos(alpha_f):
        # Σ_k |a_k(f_j)| >= |z(ν, f_j)| for every ν (the triangle inequality); its float32 allowance: the
        # row transforms' normwise error summed over the K rows, and the cast and window
        l1_slack = (50.0 * _U32 * np.log2(length_f) * np.sqrt(length_f * k) + 4.0 * _U32 * np.sqrt(k * n)) * norm
        upper = (np.abs(rows).sum(axis=0, dtype=np.float64) * (1.0 + 1e-6) + l1_slack) / np.cos(alpha_f)
        open_ = np.flatnonzero(upper >= np.sqrt(level) * (1.0 - 1e-9))
    else:
        upper, open_ = np.full(length_f, np.inf), np.arange(length_f)
    if open_.size:  # the delay bins the sum leaves open: their Doppler grid, one complex64 transform
        sub = rows if 2 * open_.size > length_f else rows[:, open_]
        z = scipy.fft.fft(sub, n=length, axis=0, workers=1)  # [L, ·]; |z| as the + sign's, mirrored
        columns = np.sqrt((z.real**2 + z.imag**2).max(axis=0).astype(np.float64))  # max_q |z(ν_q, f_j)|
        if sub is rows:
            columns = columns[open_]
        cells = float(length) * float(length_f)
        slack = (50.0 * _U32 * np.log2(cells) * np.sqrt(cells) + 4.0 * _U32 * np.sqrt(k * n)) * norm
        doppler = (columns * (1.0 + 1e-6) + slack) / (np.cos(alpha_nu) * np.cos(alpha_f))  # M if f* is nearest f_j
        upper[open_] = np.minimum(upper[open_], doppler)
    if not wanted:
        return float(upper.max() ** 2)
    cand = np.flatnonzero(upper >= np.sqrt(level) * (1.0 - 1e-9))
    if cand.size == 0 or cand.size > BOUND_COLUMNS:
        return float(upper.max() ** 2)
    r = BOUND_REFINE
    fine = np.unique((r * cand[:, None] + np.arange(-(r // 2), r // 2 + 1)[None, :]) % (r * length_f))
    phase = (np.arange(n)[:, None] * fine[None, :]) % (r * length_f)  # integer-reduced: exact phases
    kernel = np.exp(-2j * np.pi * phase / (r * length_f))  # e^{-j2π f n}, f = fine/(r L_f) [N, F]
    values = scipy.fft.fft(x32.astype(np.complex128) @ kernel, n=r * length, axis=0, workers=1)  # [rL, F]
    fine_max = float(np.sqrt((values.real**2 + values.imag**2).max()))
    # float64 sums of the complex64 beam: the cast and window as above, the products and FFT ~1e-12
    slack_fine = (4.0 * _U32 + 1e-12) * np.sqrt(k * n) * norm
    refined = (fine_max + slack_fine) / (np.cos(alpha_nu / r) * np.cos(alpha_f / r))
    outside = np.delete(upper, cand)
    return float(max(refined, float(outside.max()) if outside.size else 0.0) ** 2)


def _delay_length(n: int) -> int:
    """L_f of :func:`grid_bound`: the delay bins of its half-bin grid (>= 2N)."""
    return scipy.fft.next_fast_len(2 * n)


def _angles(k: int, n: int, length: int) -> tuple[float, float]:
    """(α_f, α_ν) of :func:`grid_bound` [rad]: σ times half a bin of its grid, per axis."""
    return np.pi * (n - 1) / (2.0 * _delay_length(n)), np.pi * (k - 1) / (2.0 * length)
