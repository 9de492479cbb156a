"""The paper's grid search where the cube lives: every beam's grid maximum and P_ave on an array backend.

:func:`device_scan` returns what :func:`dsp.gridscreen.screened_scan` returns — for every beam the
cell (q, p) of the paper's N_DFT × K_DFT grid maximum, eqs. (2DDFT) and (argmaxmap), its |z(q, p)|²
and eq. (P_ave)'s mean around it — for a cube held by an :class:`dsp.xp.ArrayBackend` (CuPy on a
GPU; ``array_api_strict`` in the tests and CI), written once against the Python array API standard.
The cube stays on its device; 4·M numbers come back (one explicit copy per chunk of beams, with a
few scalars that size the candidate arrays).

It is the dense search of :mod:`dsp.gridscreen` (module notes a–d) in float64 throughout, for all
beams of a chunk at once (a handful of whole-array operations instead of the host screen's
per-beam branches and small products):

1. **Fine range transform.** ``a_k(p) = Σ_n w_k w_n y[k, n] e^{+j2π p n / N_DFT}`` by the
   backend's FFT, zero padded to N_DFT (complex128).
2. **Doppler plane.** ``c(r, p) = Σ_k a_k(p) e^{+j2π r k / L}`` at L = 2^⌈log₂ 2K⌉ points, and |c|.
3. **Lower bound T.** The exact grid values (bins q, float64 sums with phases reduced in
   integers) of the plane maximum's column within one plane bin of it; T = their largest less
   the slack: a grid value, so T ≤ the grid maximum.
4. **Szegő's bound** (:mod:`dsp.gridscreen`, note c): a value r at ν puts the grid maximum
   outside ``|ν - q*| < (arccos(r/T) - α₀)/σ``; only the plane intervals [r/L, (r+1)/L] whose
   ends leave room for it, split once at their midpoint, are kept; every grid bin in what is
   left, widened by one bin, is evaluated exactly.
5. **Choice.** Per beam the largest value, ties in the full search's order (smaller q, then
   smaller p), by three stable sorts of the candidates; P_ave from the Doppler row of q.

**Precision.** Every value is float64. A bound uses a value plus the slack ``1e-10·‖x‖₁`` (‖x‖₁
= Σ|w_k w_n y| of the beam, which bounds every |z|): a float64 FFT or sum errs by
``≲ c·u·log₂(n)·‖x‖₁`` with u = 2⁻⁵³ (1e-14 for these lengths), so the slack is 10⁴ times the
error and 10⁻⁸ of a noise-only beam's maximum at Table I (no measurable loss of pruning). The
values that decide agree with the full transform's to ~1e-13 relative (different summation
order): the same cell wins unless two cells are that close (a true tie; either is then the
grid maximum). A beam whose ‖x‖₁ is below ``_TINY`` (its |z|² would underflow where the full
search's does not, or the reverse) or that is all zeros is searched on its whole float64 grid
instead (every cell of a zero beam ties at 0: the first searchable one wins, as in the full search),
and so is a beam whose kept intervals could hold more than
:func:`dsp.gridscreen.whole_grid_bins` bins: its spectrum is flat in Doppler over most delay
columns (its energy in one ADC sample, a glitch), there is nothing to prune, and its grid is
cheaper than its candidates.

**Memory.** A chunk of c beams holds at most c·:func:`device_scan_bytes` (40 MB per beam at
Table I, of which 14 MB in every case: the transform, the plane and its masks; the rest is the
bound of the candidate arrays, reached only by a beam with nothing to prune); chunks are sized to
``DEVICE_SCAN_BYTES`` or the device's free memory, whichever is smaller. The candidates' values
are evaluated in blocks of ``_CANDIDATE_BLOCK``.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .gridscreen import whole_grid_bins
from .processing import ProcessingConfig
from .xp import ArrayBackend

__all__ = ["DEVICE_SCAN_BYTES", "device_scan", "device_scan_bytes"]

#: Most bytes one chunk of beams may hold on the device (the transform, plane and masks).
DEVICE_SCAN_BYTES = 2 * 2**30

#: Relative slack of a float64 value in a bound (per unit ‖x‖₁; module notes).
_SLACK = 1e-10

#: A beam with ‖x‖₁ below this is searched on its whole grid (its squares may underflow).
_TINY = 1e-120

#: Candidate grid bins evaluated per block (each block holds 2·K complex128 per bin).
_CANDIDATE_BLOCK = 1 << 15


def device_scan_bytes(k: int, n: int, n_dft: int, k_dft: int) -> int:
    """Device bytes per beam of :func:`device_scan`, at most [B].

    The windowed beam (16·K·N), its range transform and its columns (2 × 16·K·N_DFT), the complex
    plane and its magnitude (24·L·N_DFT, L the plane's length), three boolean masks (3·L·N_DFT),
    the intervals with a candidate end and their values (≤ 72 B for each of the L·N_DFT plane
    cells) and the candidate bins (40 B each, at most :func:`dsp.gridscreen.whole_grid_bins` per beam):
    ``N_DFT·(32K + 99L) + 16·K·N + 40·whole_grid_bins`` (40 MB at Table I).
    """
    return n_dft * (32 * k + 99 * _plane_length(k)) + 16 * k * n + 40 * whole_grid_bins(k_dft, n_dft)


def _plane_length(k: int) -> int:
    """L: the power of two >= 2K."""
    return 1 << int(math.ceil(math.log2(2 * k)))


@functools.lru_cache(maxsize=8)
def _phase_table(rows: int, cols: int, modulus: int) -> np.ndarray:
    """``e^{+j2π (r·c mod modulus)/modulus}`` [rows, cols] on the host: exact phases (integers reduced first)."""
    roots = np.exp(2j * np.pi * np.arange(modulus) / modulus)
    table = roots[np.outer(np.arange(rows, dtype=np.int64), np.arange(cols, dtype=np.int64)) % modulus]
    table.flags.writeable = False
    return table


def device_scan(
    cube: Any, processing: ProcessingConfig, first: int, window_kn: tuple[np.ndarray, np.ndarray],
    delays: np.ndarray, backend: ArrayBackend,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Grid maxima and P_ave of every beam of a cube on ``backend``'s device.

    Parameters
    ----------
    cube : complex array [M, K, N] of ``backend``
        Beat samples, not windowed [√W] (cast to complex128 on the device).
    processing : ProcessingConfig
        ``n_dft``, ``k_dft``, ``delta`` and ``doppler_search`` (``"full"``: every beam on its whole grid).
    first : int
        First searchable delay bin (``min_range``).
    window_kn : (float array [K], float array [N])
        The slow- and fast-time windows w_K, w_N (host).
    delays : float array [N_DFT]
        The delay grid [s] (host), for the P_ave window ``|τ_p' - τ_p| <= Δ``.
    backend : ArrayBackend
        Where ``cube`` lives.

    Returns
    -------
    q, p : int arrays [M]
        Doppler bin (FFT order) and delay bin of each beam's grid maximum (host).
    power : float array [M]
        Unnormalised |z(q, p)|² [W·gain²] (host).
    average : float array [M]
        Unnormalised mean of |z(q, p')|² over the P_ave bins p' [W·gain²] (host).
    """
    xp = backend.xp
    m, k, n = (int(v) for v in cube.shape)
    per_beam = device_scan_bytes(k, n, processing.n_dft, processing.k_dft)
    budget = DEVICE_SCAN_BYTES
    free = backend.free_memory()
    if free is not None:
        budget = min(budget, free // 2)
    step = max(1, budget // per_beam)
    plan = _Plan(backend, k, n, processing, first, window_kn, delays)
    out = [np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m), np.empty(m)]
    for i in range(0, m, step):
        stop = min(m, i + step)  # the standard leaves out-of-bounds slice ends unspecified
        block = xp.astype(cube[i:stop, ...], xp.complex128)
        for dst, src in zip(out, plan.scan(block)):
            dst[i:stop] = src
    return out[0], out[1], out[2], out[3]


@functools.lru_cache(maxsize=4)
def _device_tables(backend: ArrayBackend, k: int, k_dft: int, length: int) -> tuple[Any, Any]:
    """The K_DFT-grid and 2L-midpoint phase tables [K_DFT, K], [2L, K] on the backend's device (one copy each,
    kept for the next scans of the same backend: 9.8 MB at Table I)."""
    return (backend.asarray(_phase_table(k_dft, k, k_dft)), backend.asarray(_phase_table(2 * length, k, 2 * length)))


class _Plan:
    """The constants of one scan on one device: windows, phase tables, the P_ave window."""

    def __init__(self, backend: ArrayBackend, k: int, n: int, processing: ProcessingConfig, first: int,
                 window_kn: tuple[np.ndarray, np.ndarray], delays: np.ndarray) -> None:
        self.backend, self.xp = backend, backend.xp
        self.k, self.n, self.first = k, n, int(first)
        self.n_dft, self.k_dft = processing.n_dft, processing.k_dft
        self.full = processing.doppler_search == "full"
        self.length = _plane_length(k)
        self.sigma = math.pi * (k - 1)
        self.alpha0 = self.sigma / (2.0 * self.k_dft)
        w_k, w_n = window_kn
        self.window = backend.asarray(np.outer(w_k, w_n))  # [K, N] float64
        self.table, self.midpoints = _device_tables(backend, k, self.k_dft, self.length)  # [K_DFT, K], [2L, K]
        self.delays = backend.asarray(np.asarray(delays, dtype=np.float64))
        self.delta = processing.delta * (1.0 + 1e-9)  # ±Δ inclusive, as scan_beams
        # bins per side of the plane maximum for T: one plane bin either way, whole grid bins
        self.t_width = 2 * (-(-self.k_dft // self.length)) + 3

    def scan(self, x: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """q, p, |z(q, p)|² and P_ave (unnormalised) of the beams of ``x [c, K, N]`` (complex128 on the device), on the host."""
        xp, backend = self.xp, self.backend
        c = int(x.shape[0])
        xw = x * self.window
        l1 = backend.to_host(xp.sum(xp.abs(xw), axis=(1, 2)))  # ‖x‖₁ per beam [c]
        a = backend.ifft(xw, n=self.n_dft, axis=2)  # [c, K, N_DFT]
        whole = self.full | (l1 < _TINY)
        q = np.zeros(c, np.int64)
        p = np.full(c, self.first, np.int64)
        if not self.full and not np.all(whole):
            qd, pd, found = self._dense(a, l1, whole)
            q[found], p[found] = qd[found], pd[found]
            whole |= ~found  # no positive T, or nothing to prune (module notes): their whole grid
        for j in np.flatnonzero(whole):
            q[j], p[j] = self._whole_grid(a[int(j), ...])
        # the Doppler row of q: |z(q, p')|² at every p', its value at p and its mean over the P_ave window
        q_dev, p_dev = backend.asarray(q), backend.asarray(p)
        rows = xp.take(self.table, q_dev, axis=0)  # [c, K]
        z = xp.sum(a * rows[:, :, None], axis=1)  # [c, N_DFT]
        power_row = xp.real(z) ** 2 + xp.imag(z) ** 2
        tau = xp.take(self.delays, p_dev)
        inside = xp.abs(self.delays[None, :] - tau[:, None]) <= self.delta
        average = xp.sum(xp.where(inside, power_row, 0.0), axis=1) / xp.sum(xp.astype(inside, xp.float64), axis=1)
        peak = xp.take_along_axis(power_row, p_dev[:, None], axis=1)[:, 0]
        back = backend.to_host(xp.stack([peak, average]))
        return q, p, back[0], back[1]

    def _whole_grid(self, a: Any) -> tuple[int, int]:
        """(q, p) of one beam's maximum on its whole float64 grid (first in (q, p) order on a tie)."""
        xp = self.xp
        grid = self.backend.ifft(a, n=self.k_dft, axis=0)  # [K_DFT, N_DFT]
        power = xp.real(grid) ** 2 + xp.imag(grid) ** 2
        if self.first:
            power[:, :self.first] = -1.0
        flat = int(self.backend.to_host(xp.argmax(xp.reshape(power, (-1,)))))
        return divmod(flat, self.n_dft)

    def _dense(self, a: Any, l1: np.ndarray, skip: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, p, found) of the beams of ``a [c, K, N_DFT]`` not in ``skip`` by the bounded search (module notes).

        ``found`` [c] marks the beams it decided; the others (``skip``, no positive T, nothing to prune)
        are left to their whole grid."""
        xp, backend = self.xp, self.backend
        c, k, n_dft, k_dft, length = int(a.shape[0]), self.k, self.n_dft, self.k_dft, self.length
        dev = backend.device
        slack_host = _SLACK * np.where(skip, 0.0, l1)
        slack = backend.asarray(slack_host)  # [c]
        amp = xp.abs(backend.ifft(a, n=length, axis=1))  # [c, L, N_DFT]
        if self.first:
            amp[:, :, :self.first] = -math.inf
        # columns of a as rows: a_cols[b·N_DFT + p] = a[b, :, p]
        a_cols = xp.reshape(xp.permute_dims(a, (0, 2, 1)), (c * n_dft, k))
        # 3. T: exact grid values of the plane maximum's column within a plane bin of it
        top = xp.argmax(xp.reshape(amp, (c, length * n_dft)), axis=1)
        r0, p0 = top // n_dft, top % n_dft
        start = ((r0 - 1) * k_dft) // length
        q0 = (start[:, None] + xp.arange(self.t_width, device=dev)[None, :]) % k_dft  # [c, W]
        col0 = xp.take(a_cols, xp.arange(c, device=dev) * n_dft + p0, axis=0)  # [c, K]
        vals = xp.abs(xp.sum(xp.reshape(xp.take(self.table, xp.reshape(q0, (-1,)), axis=0),
                                        (c, self.t_width, k)) * col0[:, None, :], axis=2))
        t = xp.max(vals, axis=1) - slack  # [c]
        # 4. Szegő: the intervals [r, r+1] of a column with a candidate end, and what their ends exclude
        reach = min(0.5 * (self.sigma / length + 2.0 * self.alpha0), 0.5 * math.pi)
        mask = amp >= (t * math.cos(reach) - slack)[:, None, None]
        # a beam without a positive T (its searchable grid is within the slack of 0) finds no candidate: whole grid
        searched = xp.logical_and(backend.asarray(~skip), t > 0.0)
        mask = xp.logical_and(mask, searched[:, None, None])
        ends = xp.logical_or(mask, xp.roll(mask, -1, axis=1))
        beam, r, col = xp.nonzero(ends)
        flat_amp = xp.reshape(amp, (-1,))
        left = xp.take(flat_amp, (beam * length + r) * n_dft + col)
        right = xp.take(flat_amp, (beam * length + (r + 1) % length) * n_dft + col)
        t_i, s_i = xp.take(t, beam), xp.take(slack, beam)
        gap_l, gap_r = self._exclusion(left, t_i, s_i), self._exclusion(right, t_i, s_i)
        keep = gap_l + gap_r <= (1.0 + 1e-9) / length  # float64 rounding of the test itself
        # a beam whose kept intervals could hold more than whole_grid_bins has nothing to prune (flat in Doppler
        # over most columns, e.g. one ADC sample): its whole grid instead, as on the host
        heavy = self._kept_per_beam(beam, keep, c) * (-(-k_dft // length) + 4) > whole_grid_bins(k_dft, n_dft)
        if np.any(heavy):
            keep = xp.logical_and(keep, xp.take(backend.asarray(~heavy), beam))
        idx = xp.nonzero(keep)[0]
        beam, r, col = xp.take(beam, idx), xp.take(r, idx), xp.take(col, idx)
        gap_l, gap_r, t_i, s_i = xp.take(gap_l, idx), xp.take(gap_r, idx), xp.take(t_i, idx), xp.take(s_i, idx)
        # split each interval at its midpoint (the 2L grid): one exact value, the same test on the halves
        cols = xp.take(a_cols, beam * n_dft + col, axis=0)  # [I, K]
        mid = xp.abs(xp.sum(xp.take(self.midpoints, 2 * r + 1, axis=0) * cols, axis=1))
        gap_m = self._exclusion(mid, t_i, s_i)
        rf = xp.astype(r, xp.float64)
        lo = xp.concat([rf / length + gap_l, (rf + 0.5) / length + gap_m])
        hi = xp.concat([(rf + 0.5) / length - gap_m, (rf + 1.0) / length - gap_r])
        beam, col = xp.concat([beam, beam]), xp.concat([col, col])
        idx = xp.nonzero(lo <= hi + 1e-9 / length)[0]
        lo, hi, beam, col = xp.take(lo, idx), xp.take(hi, idx), xp.take(beam, idx), xp.take(col, idx)
        # the grid bins in what is left, widened by one bin
        q_lo = xp.astype(xp.ceil(lo * k_dft), xp.int64) - 1
        count = xp.astype(xp.floor(hi * k_dft), xp.int64) + 2 - q_lo
        total = int(backend.to_host(xp.sum(count)))
        qh, ph, found = np.zeros(c, np.int64), np.full(c, self.first, np.int64), np.zeros(c, bool)
        if total == 0:  # no beam with a positive T and something to prune (the maximum's interval survives)
            return qh, ph, found
        # bin i belongs to sub-interval src (the first whose running count passes i): a repeat by counts
        # that stay on the device (CuPy's repeat takes host counts only)
        ends_at = xp.cumulative_sum(count)
        index = xp.arange(total, dtype=xp.int64, device=dev)
        src = xp.searchsorted(ends_at, index, side="right")
        q = (xp.take(q_lo, src) + index - xp.take(ends_at - count, src)) % k_dft
        cell_col = xp.take(beam * n_dft + col, src)
        power = xp.empty((total,), dtype=xp.float64, device=dev)
        for s in range(0, total, _CANDIDATE_BLOCK):
            e = min(total, s + _CANDIDATE_BLOCK)
            z = xp.sum(xp.take(self.table, q[s:e], axis=0) * xp.take(a_cols, cell_col[s:e], axis=0), axis=1)
            power[s:e] = xp.real(z) ** 2 + xp.imag(z) ** 2
        # 5. per beam the largest value, then smaller q, then smaller p: three stable sorts
        b_of = cell_col // n_dft
        cell = q * n_dft + cell_col % n_dft
        order = xp.argsort(cell, stable=True)
        order = xp.take(order, xp.argsort(-xp.take(power, order), stable=True))
        order = xp.take(order, xp.argsort(xp.take(b_of, order), stable=True))
        sorted_beam = xp.take(b_of, order)
        head = xp.concat([xp.ones((1,), dtype=xp.bool, device=dev), sorted_beam[1:] != sorted_beam[:-1]])
        win = xp.take(order, xp.nonzero(head)[0])
        got = backend.to_host(xp.stack([xp.take(b_of, win), xp.take(q, win), xp.take(cell_col % n_dft, win)]))
        qh[got[0]], ph[got[0]], found[got[0]] = got[1], got[2], True
        return qh, ph, found

    def _kept_per_beam(self, beam: Any, keep: Any, c: int) -> np.ndarray:
        """Per beam of the chunk, how many of its intervals are kept (``beam`` ascending, as ``nonzero`` gives it) [c]."""
        xp, dev = self.xp, self.backend.device
        prefix = xp.concat([xp.zeros((1,), dtype=xp.int64, device=dev), xp.cumulative_sum(xp.astype(keep, xp.int64))])
        starts = xp.searchsorted(beam, xp.arange(c + 1, dtype=beam.dtype, device=dev), side="left")
        return self.backend.to_host(xp.take(prefix, starts[1:]) - xp.take(prefix, starts[:-1]))

    def _exclusion(self, value: Any, t: Any, slack: Any) -> Any:
        """(arccos(min(1, (value + slack)/t)) - α₀)/σ, >= 0: the reach [cycles] of a value's exclusion."""
        xp = self.xp
        ratio = xp.minimum(xp.ones_like(value), (value + slack) / t)
        if self.sigma == 0.0:  # one chirp: |g| is the same at every Doppler
            return xp.where(ratio < 1.0, xp.full_like(ratio, math.inf), xp.zeros_like(ratio))
        return xp.maximum(xp.zeros_like(value), xp.acos(ratio) - self.alpha0) / self.sigma
