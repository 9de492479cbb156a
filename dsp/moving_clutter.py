"""Hall echoes that move with the radar, found over the whole sweep and removed before the fit.

A static radar's hall echoes are the same in every frame; the refined estimator removes them with
the far beams' mean (the static template, :func:`dsp.refine_estimate`). A moving radar's are not:
a wall's echo drifts across the sweep at the radar's speed along the wall's normal and its phase
turns from frame to frame, so no template made of other frames cancels it, and one that lies within
a range cell and a Doppler cell of the RIS return biases the fit (``docs/moving-radar.md``, "Hall
clutter that moves with the radar").

Such an echo is nevertheless one coherent tone over the whole sweep. To first order (the model the
synthesis uses for a traced hall, ``model.motion.advance_paths``) an echo of delay τ at t_ref and
delay rate ν is, in frame m (centre t_m, uncentred chirp k and sample n),

    α · e^{−j2π f_c ν (t_m − t_ref)} · e^{−j2π f_c ν T_c k} · e^{−j2π (S (τ + ν (t_m − t_ref)) + f_c ν) T_s n}:

one complex amplitude α for the whole sweep, where the RIS return has one per beam (its pattern
and the RIS's phases). Over the sweep's far beams (|A_m| < 0.1 of the peak, where the RIS return
is at least 20 dB down) the echo's frame-to-frame phase resolves its delay rate to
``1 / (f_c T_far)``, T_far the time those frames span: 0.0064 m/s over a 0.39 s sweep at 60 GHz,
against a frame's Doppler cell of 0.39 m/s. An echo 0.07 m/s from the RIS return, inside one
Doppler cell, is eleven of those apart.

:func:`cancel_moving_clutter` searches the far frames for such tones around the RIS return's track
(±``span_bins`` range bins, ±``span_cells`` Doppler cells, Hann-windowed to keep resolved echoes'
sidelobes out), with the return projected out of each frame (it has an amplitude of its own in every
beam, so what it leaves at other frequencies is not taken for an echo). Each candidate is refined on
the frames themselves: delay and rate, the rate's frame-rate aliases (one Doppler cell apart for
frames back to back, the frame-to-frame phase is the same), an echo beyond the search followed to
its peak, then the delay's curvature γ (τ + ν t + γ t²: a radar passing a wall sees its range curve
by v_⊥² t²/(2d)). It is kept when one amplitude explains it (its coherence, :data:`MIN_COHERENCE`: a
RIS path whose power follows the beams is left in) and its coherent SNR passes the search's
threshold; then α is estimated over the far frames, the tone subtracted from every frame, and the
next one looked for. The return's own track (within ``exclude_bins`` and ``exclude_resolution`` of
it) is never searched.

Limits: an echo with the return's own delay and rate (within those) is not separable from it by its
phase history and is left in; one whose range curves by more than :data:`MAX_CURVATURE_CYCLES` carrier
cycles at the far frames' ends is removed less completely; the amplitude is taken as constant over
the sweep (a wall's echo changes by a few per cent over 0.4 m of walk at 7 m).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal

from .dtft_subspace import as_cube, dtft_phasors
from .radar import RadarConfig
from .validation import fields_equal, finite, positive

__all__ = ["MovingEcho", "ClutterCancellation", "cancel_moving_clutter", "hann_kernel", "MIN_COHERENCE",
           "MIN_FAR_BEAMS", "MAX_CURVATURE_CYCLES"]

#: Far beams (|A_m| < 0.1 of the peak) a search needs: fewer cannot resolve an echo's delay rate.
MIN_FAR_BEAMS = 8

#: An echo is removed only when one amplitude for the whole sweep explains at least this share of the far
#: frames' energy at it (its coherence, :class:`MovingEcho`): a hall echo's amplitude is the same in every
#: frame (measured 0.81 at 22 dB of coherent SNR, 0.99-1.0 above 35 dB), a RIS path's follows the beams
#: (0.08 for a leg whose main lobe lies over the far beams, ``tests/dsp/test_moving_clutter.py``).
MIN_COHERENCE = 0.5
#: The largest curvature of an echo's delay fitted, as carrier cycles f_c γ t² at the far frames' farthest
#: time t from the reference [cycles] (6: 0.37 m/s² of range curvature over a 0.39 s sweep, a walker at 1 m/s
#: passing a wall 1.3 m away), and the step of its first scan [cycles].
MAX_CURVATURE_CYCLES = 6.0
_CURVATURE_STEP = 0.25
#: A table candidate whose coherence is below this before any refinement is left in at once (a RIS path
#: measures 0.08-0.3 there; a hall echo seen at an alias or off its peak 0.5 or more).
_QUICK_COHERENCE = 0.4
#: Candidates left in (not coherent) before the search gives up.
_MAX_REJECTED = 3
#: Frames whose s_m is below this share are left out of the coherence (where the hypothesis sits on the
#: return's own track they carry no information on it, only noise).
_MIN_SHARE = 0.05

#: Table step of the search, in range bins (fast time) and Doppler cells (slow time); the hypotheses'
#: delay step in bins. Bilinear interpolation of the Hann-windowed DTFT at these steps is within 0.2 % (its curvature).
_TABLE_STEP = 0.1
_DELAY_STEP = 0.1


@dataclass(frozen=True, eq=False)
class MovingEcho:
    """One hall echo found and removed by :func:`cancel_moving_clutter`.

    Attributes
    ----------
    delay : float
        τ at the reference time, range-Doppler coupling removed (as ``Localization.delay``) [s].
    delay_rate : float
        ν [s/s] at the reference time (its radial velocity is ν c/2).
    delay_curvature : float
        γ [s/s²]: its delay is τ + ν t + γ t² (t from the reference time); γ c/2 is its range's
        curvature, v_⊥²/(2d) for a radar passing a wall at speed v_⊥ across the echo's line [m/s²].
    amplitude : complex
        α: the echo's amplitude per sample at the reference time [√W].
    snr : float
        Its coherent SNR over the far frames, |T|² over the noise of the statistic [linear].
    range_offset : float
        Its delay less the RIS return's, in un-padded range bins [bins].
    doppler_offset : float
        Its delay rate less the return's, in a frame's Doppler cells [cells].
    coherence : float
        The share of the far frames' energy at the echo that its one amplitude explains [0-1].
    """

    delay: float
    delay_rate: float
    delay_curvature: float
    amplitude: complex
    snr: float
    range_offset: float
    doppler_offset: float
    coherence: float

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class ClutterCancellation:
    """Result of :func:`cancel_moving_clutter`.

    Attributes
    ----------
    cube : complex array [M, K, N]
        The beat cube with the echoes removed [√W]; the input itself (not a copy) when none was found.
    echoes : tuple of MovingEcho
        The echoes removed, strongest first.
    reference_time : float
        t_ref the echoes' delays refer to [s] (the clock of ``RadarConfig.beam_times``).
    threshold : float
        The detection threshold on an echo's coherent SNR [linear].
    far_beams : int
        How many far beams the search used [count]; 0 when it did not run (too few).
    rejected : int
        Components over the threshold left in [count]: those one amplitude did not explain (coherence
        below :data:`MIN_COHERENCE`: returns whose power follows the beams, e.g. the RIS's own paths via
        a wall or the floor), or whose fit, curvature included, fell below the threshold.
    """

    cube: np.ndarray
    echoes: tuple[MovingEcho, ...]
    reference_time: float
    threshold: float
    far_beams: int
    rejected: int = 0

    @property
    def removed(self) -> bool:
        """Whether any echo was removed."""
        return len(self.echoes) > 0

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


def cancel_moving_clutter(
    cube: np.ndarray,
    radar: RadarConfig,
    *,
    delay: float,
    delay_rate: float,
    reference_time: float,
    weights: np.ndarray,
    noise_power: float,
    pfa: float = 1e-3,
    max_echoes: int = 4,
    span_bins: float = 3.0,
    span_cells: float = 1.5,
    exclude_bins: float = 0.35,
    exclude_resolution: float = 1.5,
) -> ClutterCancellation:
    """Find the hall echoes near a moving RIS return over the whole sweep and subtract them.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W] (host data).
    radar : RadarConfig
        Its timing gives each frame's centre t_m (``beam_times``).
    delay : float
        The RIS return's τ at ``reference_time``, coupling removed [s].
    delay_rate : float
        Its ν [s/s].
    reference_time : float
        t_ref [s].
    weights : float array [M]
        |A_m(θ̂)|, the RIS pattern at the fitted AoD: beams below 0.1 of the largest are searched.
    noise_power : float
        σ² per sample [W] (``Detection.noise_power``).
    pfa : float, default 1e-3
        Probability that noise alone yields an echo over the whole search.
    max_echoes : int, default 4
        Echoes removed at most.
    span_bins, span_cells : float, default 3.0, 1.5
        The search's half-widths around the return: range bins (un-padded) and a frame's Doppler
        cells. An echo biases the fit when it lies within about one of each; the search reaches
        the Hann windows' main lobes beyond (2 bins, 2 cells), so that a stronger echo just outside
        is found where it is (and removed) rather than where its main lobe spills into the return's
        cell. A stronger echo further out whose tail reaches the table is followed to its peak and
        removed: 20 dB over the return 4-5 bins away, it moves the un-windowed fit by tenths of a
        millimetre (``docs/moving-radar.md``).
    exclude_bins, exclude_resolution : float, default 0.35, 1.5
        The return's own track, never searched: within ``exclude_bins`` range bins and
        ``exclude_resolution`` times the sweep's rate resolution ``1/(f_c T_far)`` of it.

    Returns
    -------
    ClutterCancellation

    Raises
    ------
    ValueError
        A cube that is not [M, K, N]; a non-finite delay, rate, time or noise power; weights not of
        length M; ``pfa`` outside (0, 1), ``max_echoes`` not an integer >= 0, a span not > 0.
    """
    arr = as_cube(cube)
    if arr.ndim != 3:
        raise ValueError(f"cube has shape {arr.shape}, expected [M, K, N] (beams, chirps, samples)")
    m, k, n = arr.shape
    if not (isinstance(pfa, (int, float)) and 0.0 < pfa < 1.0):
        raise ValueError(f"pfa={pfa!r} must be a probability in (0, 1)")
    if isinstance(max_echoes, bool) or not isinstance(max_echoes, (int, np.integer)) or max_echoes < 0:
        raise ValueError(f"max_echoes={max_echoes!r} must be an integer >= 0")
    span_bins, span_cells = positive(span_bins, "span_bins", "range bins"), positive(span_cells, "span_cells", "cells")
    tau0 = finite(delay, "delay", "s")
    nu0 = finite(delay_rate, "delay_rate", "s/s")
    t_ref = finite(reference_time, "reference_time", "s")
    sigma2 = finite(noise_power, "noise_power", "W")
    w = np.asarray(weights, dtype=float)
    if w.shape != (m,):
        raise ValueError(f"weights has shape {w.shape}, expected ({m},): |A_m| of every beam")
    far = np.flatnonzero(w < 0.1 * w.max())
    threshold = float(-np.log(pfa))  # refined below with the number of hypotheses
    if far.size < MIN_FAR_BEAMS or not sigma2 > 0:
        return ClutterCancellation(cube=arr, echoes=(), reference_time=t_ref, threshold=threshold, far_beams=0)
    search = _Search(arr, radar, far, tau0, nu0, t_ref, span_bins, span_cells)
    threshold = float(-np.log(pfa / search.num_hypotheses))
    noise = sigma2 * search.window_energy  # T's variance under noise alone, per unit of its factor (``var``)
    out = arr
    echoes: list[MovingEcho] = []
    d_bins, d_res = search.offsets()
    skip = (np.abs(d_res)[:, None] < exclude_resolution) & (np.abs(d_bins)[None, :] < exclude_bins)  # [V, D]
    rejected = 0

    def leave(tau: float, nu: float) -> None:
        """Search no more around (τ, ν): a return left in."""
        near = (np.abs(search.nus - nu) / search.resolution <= 2.0)[:, None] & (
            np.abs(search.taus - tau) / search.bin_delay <= 0.7)[None, :]
        skip[near] = True

    table_power = None  # the table's statistic, again only after an echo is removed
    while len(echoes) < int(max_echoes) and rejected <= _MAX_REJECTED:
        if table_power is None:
            stat, norm = search.table_statistic()
            table_power = np.where(norm > 0, np.abs(stat) ** 2 / np.maximum(norm, 1e-300), 0.0) / noise
        power = np.where(skip, 0.0, table_power)
        i, j = np.unravel_index(int(np.argmax(power)), power.shape)
        if not power[i, j] > threshold:
            break
        if search.exact(search.taus[j], search.nus[i])[3] < _QUICK_COHERENCE:  # plainly a RIS path: not refined
            rejected += 1
            leave(search.taus[j], search.nus[i])
            continue
        fit = search.refine(*_peak(search.best_alias(search.taus[j], search.nus[i])), curvature=True)
        snr = abs(fit.stat) ** 2 / (fit.var * noise) if fit.var > 0 else 0.0
        if fit.coherence < MIN_COHERENCE or not snr > threshold:
            # a beam-dependent return (another RIS path), not a hall echo: left in
            rejected += 1
            leave(search.taus[j], search.nus[i])
            leave(fit.delay, fit.rate)
            continue
        alpha = fit.stat / (search.window_peak * fit.norm)  # E T = α W(0) Σ s_m
        tone = _tone(radar, m, k, n, fit, t_ref, alpha)
        if out is arr:  # the caller's cube is never written to
            out = arr.copy()
        out -= tone
        search.remove(fit, alpha)
        table_power = None
        echoes.append(MovingEcho(delay=float(fit.delay), delay_rate=float(fit.rate),
                                 delay_curvature=float(fit.curvature), amplitude=complex(alpha), snr=float(snr),
                                 range_offset=float((fit.delay - tau0) / search.bin_delay),
                                 doppler_offset=float((fit.rate - nu0) / search.cell_rate),
                                 coherence=float(fit.coherence)))
    return ClutterCancellation(cube=out, echoes=tuple(echoes), reference_time=t_ref, threshold=threshold,
                               far_beams=int(far.size), rejected=rejected)


def _peak(fit: "_Fit") -> tuple[float, float]:
    return fit.delay, fit.rate


def _tone(radar: RadarConfig, m: int, k: int, n: int, fit: _Fit, t_ref: float, alpha: complex) -> np.ndarray:
    """The echo of ``fit`` with amplitude ``alpha`` in every frame [M, K, N] (uncentred chirps and samples)."""
    f1, f2, carrier = _echo_frames(radar, radar.beam_times(m) - t_ref, fit.delay, fit.rate, fit.curvature)
    slow = alpha * np.exp(-2j * np.pi * _frac(carrier[:, None] + np.outer(f2, np.arange(k))))  # [M, K]
    fast = np.exp(-2j * np.pi * _frac(np.outer(f1, np.arange(n))))  # [M, N]
    return slow[:, :, None] * fast[:, None, :]


def _frac(x: np.ndarray) -> np.ndarray:
    return x - np.round(x)


class _Search:
    """The Hann-windowed 2-D DTFT of the far frames on a table around the RIS return's track, with the
    return projected out frame by frame, and the coherent statistic of the echo hypotheses from it.

    Frame m's table holds Z_m(g₁, g₂) = Σ_k Σ_n w_k w_n y[m,k,n] e^{j2π(g₁ n' + g₂ k')} (centred
    indices n', k'; Hann w) at g₁ = f₁,R(t_m) + d₁, g₂ = f₂,R + d₂, on steps of ``_TABLE_STEP``
    bin/cell. A tone at offsets δ_m from the track contributes c_m W(g − δ_m) (W = W_K W_N, real
    kernels). The return has an amplitude of its own in every frame (pattern, RIS phases, what is
    left of its far sidelobes), so it is projected out frame by frame: r_m = Z_m(0)/W(0) and
    Z'_m(g) = Z_m(g) − r_m W(g). An echo (τ, ν) of amplitude α then leaves
    E Z'_m(δ_m) = c_m W(0) s_m, s_m = 1 − ρ_m², ρ_m = W(δ_m)/W(0), with
    c_m = α e^{−j2π (f_c ν (t_m − t_ref) + f₁(t_m)(N−1)/2 + f₂(K−1)/2)}. The statistic is
    T = Σ_m s_m c̄_m/α · Z'_m(δ_m) = α W(0) Σ_m s_m² plus noise of variance (at most)
    σ² Σw_k² Σw_n² Σ_m s_m², so |T|² over that variance is the echo's coherent SNR and
    α̂ = T / (W(0) Σ_m s_m²).
    """

    def __init__(self, arr: np.ndarray, radar: RadarConfig, far: np.ndarray, tau0: float, nu0: float, t_ref: float,
                 span_bins: float, span_cells: float) -> None:
        _, k, n = arr.shape
        self.radar, self.far, self.tau0, self.nu0, self.t_ref = radar, far, tau0, nu0, t_ref
        self.k, self.n = k, n
        fc, ts, s, tc = radar.carrier_frequency, radar.sample_period, radar.slope, radar.chirp_interval
        self.bin_delay = 1.0 / (n * s * ts)  # one un-padded range bin [s]
        self.cell_rate = 1.0 / (k * fc * tc)  # one Doppler cell of a frame [s/s]
        self.times = radar.beam_times(arr.shape[0])[far] - t_ref  # [F]
        span = float(self.times.max() - self.times.min()) + k * tc
        self.resolution = 1.0 / (fc * span)  # the sweep's rate resolution [s/s]
        half_v = int(np.ceil(span_cells * self.cell_rate / (self.resolution / 2)))
        self.nus = nu0 + np.arange(-half_v, half_v + 1) * (self.resolution / 2)
        half_t = int(np.ceil(span_bins / _DELAY_STEP))
        self.taus = tau0 + np.arange(-half_t, half_t + 1) * _DELAY_STEP * self.bin_delay
        self.num_hypotheses = self.nus.size * self.taus.size / 2  # half-resolution steps: about half independent
        self.wk = scipy.signal.get_window("hann", k, fftbins=False)
        self.wn = scipy.signal.get_window("hann", n, fftbins=False)
        self.window_peak = float(self.wk.sum() * self.wn.sum())
        self.window_energy = float((self.wk**2).sum() * (self.wn**2).sum())
        self.kc = np.arange(k) - (k - 1) / 2.0
        self.nc = np.arange(n) - (n - 1) / 2.0
        # the table: d₁ over the delays and the migration of every rate, d₂ over the rates (grids through 0)
        dnu = np.abs(self.nus - nu0).max()
        max_mig = dnu * (np.abs(self.times).max() * s + fc) * ts * n
        j1 = int(np.ceil((span_bins + max_mig) / _TABLE_STEP)) + 2
        j2 = int(np.ceil(dnu * fc * tc * k / _TABLE_STEP)) + 2
        self.d1 = np.arange(-j1, j1 + 1) * _TABLE_STEP / n  # cycles/sample
        self.d2 = np.arange(-j2, j2 + 1) * _TABLE_STEP / k
        self.zero = (j2, j1)
        self.kern1 = self.kernel_n(self.d1)  # W_N on the table [D1]
        self.kern2 = self.kernel_k(self.d2)  # W_K [D2]
        f1r = _echo_frames(radar, self.times, tau0, nu0, 0.0)[0]  # the return's track [F]
        self.f1r, self.f2r = f1r, fc * nu0 * tc
        self.data = arr[far]  # [F, K, N]
        slow = dtft_phasors(self.f2r, self.kc, self.d2) * self.wk[None, :]  # [D2, K]
        base = np.stack([dtft_phasors(f, self.nc, np.zeros(1))[0] for f in f1r]) * self.wn[None, :]  # [F, N]
        grid = dtft_phasors(0.0, self.nc, self.d1).T  # [N, D1]: e^{j2π(f + d) n'} = e^{j2π f n'} e^{j2π d n'}
        rows = np.matmul(slow[None], self.data)  # [F, D2, N]
        self.table = np.matmul(rows * base[:, None, :], grid)  # [F, D2, D1]
        self.echoes: list[tuple[complex, np.ndarray, np.ndarray, float]] = []  # α, c_m/α [F], f₁(t_m) [F], f₂
        self._project()

    def kernel_n(self, d: np.ndarray, square: bool = False) -> np.ndarray:
        """W_N(d) = Σ_n w_n cos(2π d n'), the windowed fast-time kernel (w_n² with ``square``) [as d]."""
        return hann_kernel(d, self.n, square=square)

    def kernel_k(self, d: np.ndarray, square: bool = False) -> np.ndarray:
        """W_K(d), the windowed slow-time kernel (w_k² with ``square``)."""
        return hann_kernel(d, self.k, square=square)

    def _project(self) -> None:
        """r_m and the table with the return projected out of every frame."""
        self.r = self.table[:, self.zero[0], self.zero[1]] / self.window_peak  # [F]
        self.proj = self.table - self.r[:, None, None] * np.outer(self.kern2, self.kern1)[None]

    def _phase(self, tau: float | np.ndarray, nu: float, gamma: float = 0.0) -> np.ndarray:
        """c_m/α for the hypotheses (τ, ν, γ) [..., F]."""
        f1, f2, carrier = _echo_frames(self.radar, self.times, tau, nu, gamma)
        return np.exp(-2j * np.pi * _frac(carrier + f1 * (self.n - 1) / 2.0 + f2 * (self.k - 1) / 2.0))

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """The hypotheses' offsets from the return: delays in bins [D], rates in the sweep's resolution [V]."""
        return (self.taus - self.tau0) / self.bin_delay, (self.nus - self.nu0) / self.resolution

    def table_statistic(self) -> tuple[np.ndarray, np.ndarray]:
        """T and Σ_m s_m of every hypothesis, interpolated in the table, each [V, D] (rates × delays)."""
        r = self.radar
        fc, ts, s = r.carrier_frequency, r.sample_period, r.slope
        stat = np.empty((self.nus.size, self.taus.size), dtype=complex)
        norm = np.empty(stat.shape)
        step1, step2 = _TABLE_STEP / self.n, _TABLE_STEP / self.k
        rows = np.arange(self.far.size)[None, :]
        for i, nu in enumerate(self.nus):
            dnu = nu - self.nu0
            x2 = (fc * dnu * r.chirp_interval - self.d2[0]) / step2
            j2 = int(np.floor(x2))
            a2 = x2 - j2
            plane = (1 - a2) * self.proj[:, j2, :] + a2 * self.proj[:, j2 + 1, :]  # [F, D1]
            k2 = (1 - a2) * self.kern2[j2] + a2 * self.kern2[j2 + 1]
            d1 = ((self.taus[:, None] - self.tau0 + dnu * self.times[None, :]) * s + fc * dnu) * ts  # [D, F]
            x1 = (d1 - self.d1[0]) / step1
            j1 = np.floor(x1).astype(int)
            a1 = x1 - j1
            z = (1 - a1) * plane[rows, j1] + a1 * plane[rows, j1 + 1]  # [D, F]
            rho = ((1 - a1) * self.kern1[j1] + a1 * self.kern1[j1 + 1]) * k2 / self.window_peak
            stat[i] = np.sum(np.conj(self._phase(self.taus, nu)) * z, axis=1)
            norm[i] = np.sum(1.0 - rho**2, axis=1)
        return stat, norm

    def rows(self, nus: np.ndarray, gamma: float = 0.0) -> np.ndarray:
        """The far frames' windowed slow-time DTFT at each rate's f₂(t_m) [V, F, N]."""
        f2 = np.stack([_echo_frames(self.radar, self.times, 0.0, nu, gamma)[1] for nu in nus])  # [V, F]
        ek = np.exp(2j * np.pi * _frac(f2[:, :, None] * self.kc[None, None, :])) * self.wk  # [V, F, K]
        return np.matmul(np.swapaxes(ek, 0, 1), self.data).swapaxes(0, 1)  # one small product per frame

    def exact(self, tau: float, nu: float, gamma: float = 0.0,
              rows: np.ndarray | None = None) -> tuple[complex, float, float, float]:
        """T, Σ_m s_m, T's noise variance per unit σ² Σw_k²Σw_n², and the coherence at (τ, ν, γ), from the
        frames themselves (``rows``: :meth:`rows` at ν and γ [F, N]) less the echoes removed so far
        (:meth:`batch` for one hypothesis)."""
        stat, norm, var, coherence = self.batch(np.array([tau]), nu, np.array([gamma]), rows)
        return complex(stat[0]), float(norm[0]), float(var[0]), float(coherence[0])

    def batch(self, taus: np.ndarray, nu: float, gammas: np.ndarray,
              rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """T, Σ_m s_m, T's noise variance per unit σ² Σw_k²Σw_n², and the coherence of the hypotheses
        (τ_b, ν, γ_b) [B] each, from the frames' ``rows`` (:meth:`rows` at ν [F, N]; default at ν and γ_0)
        less the echoes removed so far.

        The coherence |Σ_m c̄_m Z'_m|² / (Σ_m s_m · Σ_m |Z'_m|²/s_m) (at most 1, Cauchy–Schwarz) is the share
        of the frames' energy at the hypothesis that one amplitude for the whole sweep explains: near 1 for
        a hall echo, low for a RIS path whose power follows the beams (:data:`MIN_COHERENCE`).
        """
        taus, gammas = np.asarray(taus, dtype=float), np.asarray(gammas, dtype=float)
        if rows is None:
            rows = self.rows(np.array([nu]), float(gammas[0]))[0]
        f1, f2, carrier = _echo_frames(self.radar, self.times, taus, nu, gammas)  # [B, F] each
        if np.all(gammas == gammas[0]):  # one rate and curvature: the delays differ by one shift in every frame
            en = np.exp(2j * np.pi * _frac(f1[0][:, None] * self.nc)) * self.wn  # [F, N]
            shift = np.exp(2j * np.pi * _frac(np.outer(f1[:, 0] - f1[0, 0], self.nc)))  # [B, N]
            z = ((rows * en) @ shift.T).T
        else:
            en = np.exp(2j * np.pi * _frac(f1[:, :, None] * self.nc)) * self.wn  # [B, F, N]
            z = np.einsum("bfn,fn->bf", en, rows)
        for alpha, ph, f1e, f2e in self.echoes:
            z = z - alpha * ph * self.kernel_n(f1 - f1e) * self.kernel_k(f2 - f2e)
        d1, d2 = f1 - self.f1r, f2 - self.f2r
        rho = self.kernel_n(d1) * self.kernel_k(d2) / self.window_peak
        kappa = self.kernel_n(d1, square=True) * self.kernel_k(d2, square=True) / self.window_energy
        zp = z - self.r * self.window_peak * rho
        var = np.sum(1.0 + rho**2 - 2.0 * rho * kappa, axis=1)
        sm = 1.0 - rho**2
        phase = np.exp(-2j * np.pi * _frac(carrier + f1 * (self.n - 1) / 2.0 + f2 * (self.k - 1) / 2.0))
        terms = np.conj(phase) * zp
        stat = np.sum(terms, axis=1)
        use = sm >= _MIN_SHARE
        spread = np.sum(np.where(use, sm, 0.0), axis=1) * np.sum(
            np.where(use, np.abs(zp) ** 2 / np.where(use, sm, 1.0), 0.0), axis=1)
        coherent = np.abs(np.sum(np.where(use, terms, 0.0), axis=1)) ** 2
        coherence = np.where(spread > 0, coherent / np.where(spread > 0, spread, 1.0), 0.0)
        return stat, np.sum(sm, axis=1), var, coherence

    def _scores(self, taus: np.ndarray, nu: float, gammas: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """|T|²/Σ s_m of the hypotheses (τ_b, ν, γ_b) [B]."""
        stat, norm, _, _ = self.batch(taus, nu, gammas, rows)
        return np.where(norm > 0, np.abs(stat) ** 2 / np.where(norm > 0, norm, 1.0), 0.0)

    def refine(self, tau: float, nu: float, curvature: bool = False) -> "_Fit":
        """The least-squares fit of the echo beside a free return per frame near (τ, ν): the maximum of
        |T|²/Σ s by parabolas through 3 × 3 exact points in (τ, ν), the steps shrinking from the table's
        to a ninth of it over three rounds; with ``curvature``, the delay's curvature γ too (a scan over
        ±:data:`MAX_CURVATURE_CYCLES` of carrier phase at the far frames' ends first, then a parabola in
        γ after each round).
        """
        h1, h2 = _DELAY_STEP * self.bin_delay, self.resolution / 2
        reach = float(np.abs(self.times).max()) ** 2 * self.radar.carrier_frequency  # cycles per unit γ
        h3 = _CURVATURE_STEP / reach
        gamma = 0.0
        if curvature:
            grid = np.arange(-MAX_CURVATURE_CYCLES, MAX_CURVATURE_CYCLES + 1e-9, _CURVATURE_STEP) / reach
            rows = self.rows(np.array([nu]))[0]  # each frame's Doppler at γ = 0: the Hann window forgives it here
            gamma = float(grid[int(np.argmax(self._scores(np.full(grid.size, tau), nu, grid, rows)))])
        steps = np.array([-1.0, 0.0, 1.0])
        for _ in range(3):
            vs = nu + steps * h2
            rows = self.rows(vs, gamma)
            p = np.stack([self._scores(tau + steps * h1, v, np.full(3, gamma), rows[b]) for b, v in enumerate(vs)])
            tau += h1 * _vertex(p[1])
            nu += h2 * _vertex(p[:, 1])
            if curvature:
                gamma += h3 * _vertex(self._scores(np.full(3, tau), nu, gamma + steps * h3))
                h3 /= 3.0
            h1, h2 = h1 / 3.0, h2 / 3.0
        return _Fit(tau, nu, gamma, *self.exact(tau, nu, gamma))

    def best_alias(self, tau: float, nu: float) -> "_Fit":
        """The echo's peak from a table hypothesis: :meth:`refine` there and at its frame-rate aliases
        ν ± q/(f_c T_f) within one Doppler cell, each followed by :meth:`climb` while it sits on a scan's
        border; the best of them.

        The frame-to-frame phase of a rate ν is that of ν + q/(f_c T_f) (T_f the time between frames; one
        Doppler cell for frames back to back): only each frame's own Doppler window (Hann: half the
        amplitude one cell away) and the range migration tell them apart. A strong echo just outside the
        search shows inside it at an alias whose migrating range crosses the echo's during the sweep,
        and that is not where it is.
        """
        r = self.radar
        times = r.beam_times(2)
        alias = 1.0 / (r.carrier_frequency * float(times[1] - times[0]))  # [s/s]
        reach = int(np.floor(self.cell_rate / alias))  # within one Doppler cell: further, Hann's null
        best = None
        for q in range(-reach, reach + 1):
            start = (tau, nu) if q == 0 else self.scan(tau, nu + q * alias)
            fit = self.refine(*self.climb(*start))
            if best is None or fit.score > best.score:
                best = fit
        return best

    def climb(self, tau: float, nu: float, steps: int = 12) -> tuple[float, float]:
        """From (τ, ν), :meth:`scan` after scan while the best point is on a scan's border: the peak of an
        echo beyond the table (its tail at the table's edge is not where it is)."""
        for _ in range(steps):
            t, v = self.scan(tau, nu, rates=3, delays=5)
            inner = abs(t - tau) < 4.5 * _DELAY_STEP * self.bin_delay and abs(v - nu) < 1.0 * self.resolution
            tau, nu = t, v
            if inner:
                break
        return tau, nu

    def scan(self, tau: float, nu: float, rates: int = 8, delays: int = 2) -> tuple[float, float]:
        """The best of an exact grid around (τ, ν): ±``rates`` half resolutions, ±``delays`` delay steps."""
        vs = nu + np.arange(-rates, rates + 1) * self.resolution / 2
        ts = tau + np.arange(-delays, delays + 1) * _DELAY_STEP * self.bin_delay
        rows = self.rows(vs)
        scores = np.stack([self._scores(ts, v, np.zeros(ts.size), rows[b]) for b, v in enumerate(vs)])  # [V, T]
        b, t = np.unravel_index(int(np.argmax(scores)), scores.shape)
        return float(ts[t]), float(vs[b])

    def remove(self, fit: "_Fit", alpha: complex) -> None:
        """Take a removed echo out of the table (its kernels, in closed form) and of later :meth:`exact` values."""
        ph = self._phase(fit.delay, fit.rate, fit.curvature)
        f1e, f2e, _ = _echo_frames(self.radar, self.times, fit.delay, fit.rate, fit.curvature)
        k2 = self.kernel_k(self.d2[None, :] + (self.f2r - f2e)[:, None])  # [F, D2]
        k1 = self.kernel_n(self.d1[None, :] + (self.f1r - f1e)[:, None])  # [F, D1]
        self.table = self.table - (alpha * ph)[:, None, None] * k2[:, :, None] * k1[:, None, :]
        self.echoes.append((complex(alpha), ph, f1e, f2e))
        self._project()


@dataclass(frozen=True)
class _Fit:
    """An echo hypothesis fitted by :meth:`_Search.refine`: τ [s], ν [s/s], γ [s/s²], T, Σ s_m, var, coherence."""

    delay: float
    rate: float
    curvature: float
    stat: complex
    norm: float
    var: float
    coherence: float

    @property
    def score(self) -> float:
        """|T|²/Σ s_m, the least-squares fit's captured energy (up to a constant)."""
        return abs(self.stat) ** 2 / self.norm if self.norm > 0 else 0.0


def _echo_frames(radar: RadarConfig, times: np.ndarray, tau: Any, nu: float,
                 gamma: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An echo of delay τ(t) = τ + ν t + γ t² in frames centred at ``times`` (from t_ref) [F] [s]:
    f₁(t_m) [cycles/sample], f₂(t_m) [cycles/chirp] and the carrier's cycles f_c (τ(t_m) − τ), each
    [..., F] (``tau`` and ``gamma`` may carry leading axes, the same or broadcastable)."""
    fc, ts, s, tc = radar.carrier_frequency, radar.sample_period, radar.slope, radar.chirp_interval
    g = np.asarray(gamma, dtype=float)[..., None]
    rate = nu + 2.0 * g * times
    moved = nu * times + g * times**2
    f1 = ((np.asarray(tau, dtype=float)[..., None] + moved) * s + fc * rate) * ts
    return f1, fc * rate * tc, fc * moved


def hann_kernel(d: np.ndarray, size: int, square: bool = False) -> np.ndarray:
    """Σ_n w_n e^{j2π d n'} for the symmetric Hann window w of ``size`` points (``scipy.signal.get_window("hann",
    size, fftbins=False)``), centred indices n': real and even, in closed form [as d].

    With h = 1/(size − 1), w_n = ½ + ½ cos(2π h n'), so the sum is ½ D(d) + ¼ (D(d + h) + D(d − h)), D the
    Dirichlet kernel sin(π L d)/sin(π d) of L = ``size`` centred points; ``square`` gives the same sum over
    w_n² = ⅜ + ½ cos(2π h n') + ⅛ cos(4π h n'). ``d`` in cycles per sample.
    """
    x = np.asarray(d, dtype=float)
    h = 1.0 / (size - 1)
    if square:
        terms = ((0.375, 0.0), (0.25, h), (0.25, -h), (0.0625, 2 * h), (0.0625, -2 * h))
    else:
        terms = ((0.5, 0.0), (0.25, h), (0.25, -h))
    return sum(c * _dirichlet(x + o, size) for c, o in terms)


def _dirichlet(x: np.ndarray, size: int) -> np.ndarray:
    """Σ_{n'} e^{j2π x n'} over ``size`` centred indices: sin(π L x)/sin(π x), its limit at integers."""
    k = np.round(x)
    near = np.abs(x - k) < 1e-9
    den = np.where(near, 1.0, np.sin(np.pi * x))
    return np.where(near, size * np.cos(np.pi * k * (size - 1)), np.sin(np.pi * size * x) / den)


def _vertex(p: np.ndarray) -> float:
    """The vertex of the parabola through (−1, p₀), (0, p₁), (1, p₂), clipped to ±1."""
    curv = p[0] - 2.0 * p[1] + p[2]
    if not curv < 0:
        return 0.0
    return float(np.clip(0.5 * (p[0] - p[2]) / curv, -1.0, 1.0))
