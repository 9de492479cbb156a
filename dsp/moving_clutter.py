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
sidelobes out), refines each one found, estimates α over the far frames and subtracts the tone
from every frame, the strongest first, until none exceeds the detection threshold. The RIS
return's own track (within ``exclude_bins`` and ``exclude_resolution`` of it) is never searched, so
the return is not cancelled; what its far sidelobes leave elsewhere is below the threshold for the
sidelobe levels of a 16-element RIS (tested).

Limits: the first-order model holds while the echo's range is linear in time over the sweep; its
curvature ``v_⊥² t² / (2d)`` (v_⊥ the radar's speed across the echo's line, d its length) turns the
phase by 4π/λ times that: 0.6 rad at the ends of a 0.39 s sweep at 1 m/s across a 7 m leg, when the
cancellation is left with about 10 % of the echo there. An echo with the RIS return's own delay
rate (within ``exclude_resolution``) is not separable from the return by its phase history and is
left in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal
import scipy.special

from .dtft_subspace import as_cube, dtft_phasors
from .radar import RadarConfig
from .validation import fields_equal, finite

__all__ = ["MovingEcho", "ClutterCancellation", "cancel_moving_clutter", "MIN_FAR_BEAMS"]

#: Far beams (|A_m| < 0.1 of the peak) a search needs: fewer cannot resolve an echo's delay rate.
MIN_FAR_BEAMS = 8

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
        ν [s/s] (its radial velocity is ν c/2).
    amplitude : complex
        α: the echo's amplitude per sample at the reference time [√W].
    snr : float
        Its coherent SNR over the far frames, |T|² over the noise of the statistic [linear].
    range_offset : float
        Its delay less the RIS return's, in un-padded range bins [bins].
    doppler_offset : float
        Its delay rate less the return's, in a frame's Doppler cells [cells].
    """

    delay: float
    delay_rate: float
    amplitude: complex
    snr: float
    range_offset: float
    doppler_offset: float

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
    """

    cube: np.ndarray
    echoes: tuple[MovingEcho, ...]
    reference_time: float
    threshold: float
    far_beams: int

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
    max_echoes: int = 3,
    span_bins: float = 1.0,
    span_cells: float = 0.6,
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
    max_echoes : int, default 3
        Echoes removed at most.
    span_bins, span_cells : float, default 1.0, 0.6
        The search's half-widths around the return: range bins (un-padded) and a frame's Doppler
        cells. Echoes further out are resolved by the fit's own window.
    exclude_bins, exclude_resolution : float, default 0.35, 1.5
        The return's own track, never searched: within ``exclude_bins`` range bins and
        ``exclude_resolution`` times the sweep's rate resolution ``1/(f_c T_far)`` of it.

    Returns
    -------
    ClutterCancellation

    Raises
    ------
    ValueError
        A non-finite delay, rate, time or noise power, or weights not of length M.
    """
    arr = as_cube(cube)
    m, k, n = arr.shape
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
    noise = sigma2 * search.window_energy  # the variance of T under noise alone, per unit Σ s_m²
    out = arr
    echoes: list[MovingEcho] = []
    for _ in range(int(max_echoes)):
        stat, norm = search.table_statistic()
        power = np.where(norm > 0, np.abs(stat) ** 2 / np.maximum(norm, 1e-300), 0.0) / noise
        d_bins, d_res = search.offsets()
        power[(np.abs(d_res)[:, None] < exclude_resolution) & (np.abs(d_bins)[None, :] < exclude_bins)] = 0.0
        i, j = np.unravel_index(int(np.argmax(power)), power.shape)
        if not power[i, j] > threshold:
            break
        tau, nu, t_stat, t_norm, t_var = search.refine(search.taus[j], search.nus[i])
        snr = abs(t_stat) ** 2 / (t_var * noise) if t_var > 0 else 0.0
        if not snr > threshold:
            break
        alpha = t_stat / (search.window_peak * t_norm)  # E T = α W(0) Σ s_m
        tone = alpha * _tone(radar, m, k, n, tau, nu, t_ref)
        out = out - tone if out is arr else _subtract(out, tone)
        search.remove(alpha, tau, nu)
        echoes.append(MovingEcho(delay=float(tau), delay_rate=float(nu), amplitude=complex(alpha), snr=float(snr),
                                 range_offset=float((tau - tau0) / search.bin_delay),
                                 doppler_offset=float((nu - nu0) / search.cell_rate)))
    return ClutterCancellation(cube=out, echoes=tuple(echoes), reference_time=t_ref, threshold=threshold,
                               far_beams=int(far.size))


def _subtract(out: np.ndarray, tone: np.ndarray) -> np.ndarray:
    out -= tone
    return out


def _tone(radar: RadarConfig, m: int, k: int, n: int, tau: float, nu: float, t_ref: float) -> np.ndarray:
    """The unit echo (α = 1) of delay ``tau`` at ``t_ref`` and rate ``nu`` in every frame [M, K, N]."""
    times = radar.beam_times(m) - t_ref
    fc, ts, s = radar.carrier_frequency, radar.sample_period, radar.slope
    f1 = ((tau + nu * times) * s + fc * nu) * ts  # [M] cycles/sample
    f2 = fc * nu * radar.chirp_interval
    frame = np.exp(-2j * np.pi * _frac(fc * nu * times))  # [M]
    slow = dtft_phasors(-f2, np.arange(k, dtype=float), np.zeros(1))[0]  # e^{-j2π f₂ k}
    fast = np.stack([dtft_phasors(-f, np.arange(n, dtype=float), np.zeros(1))[0] for f in f1])  # [M, N]
    return frame[:, None, None] * slow[None, :, None] * fast[:, None, :]


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
        f1r = self._f1(tau0, nu0)  # [F]
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
        d = np.asarray(d, dtype=float)
        w = self.wn**2 if square else self.wn
        return (np.cos(2 * np.pi * d.reshape(-1, 1) * self.nc[None, :]) @ w).reshape(d.shape)

    def kernel_k(self, d: np.ndarray, square: bool = False) -> np.ndarray:
        """W_K(d), the windowed slow-time kernel (w_k² with ``square``)."""
        d = np.asarray(d, dtype=float)
        w = self.wk**2 if square else self.wk
        return (np.cos(2 * np.pi * d.reshape(-1, 1) * self.kc[None, :]) @ w).reshape(d.shape)

    def _project(self) -> None:
        """r_m and the table with the return projected out of every frame."""
        self.r = self.table[:, self.zero[0], self.zero[1]] / self.window_peak  # [F]
        self.proj = self.table - self.r[:, None, None] * np.outer(self.kern2, self.kern1)[None]

    def _f1(self, tau: float | np.ndarray, nu: float) -> np.ndarray:
        r = self.radar
        return ((np.asarray(tau)[..., None] + nu * self.times) * r.slope + r.carrier_frequency * nu) * r.sample_period

    def _phase(self, tau: float | np.ndarray, nu: float) -> np.ndarray:
        """c_m/α for the hypotheses (τ, ν) [..., F]."""
        r = self.radar
        f1 = self._f1(tau, nu)
        f2 = r.carrier_frequency * nu * r.chirp_interval
        cyc = r.carrier_frequency * nu * self.times + f1 * (self.n - 1) / 2.0 + f2 * (self.k - 1) / 2.0
        return np.exp(-2j * np.pi * _frac(cyc))

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

    def rows(self, nus: np.ndarray) -> np.ndarray:
        """The far frames' windowed slow-time DTFT at each rate's f₂ [V, F, N]."""
        r = self.radar
        ek = np.stack([dtft_phasors(r.carrier_frequency * nu * r.chirp_interval, self.kc, np.zeros(1))[0]
                       for nu in nus]) * self.wk[None, :]  # [V, K]
        return np.moveaxis(np.matmul(ek[None], self.data), 1, 0)

    def exact(self, tau: float, nu: float, rows: np.ndarray | None = None) -> tuple[complex, float, float]:
        """T, Σ_m s_m and T's noise variance per unit σ² Σw_k²Σw_n² at (τ, ν), from the frames themselves
        (``rows``: :meth:`rows` at ν [F, N]) less the echoes removed so far."""
        r = self.radar
        f2 = r.carrier_frequency * nu * r.chirp_interval
        if rows is None:
            rows = self.rows(np.array([nu]))[0]
        f1 = self._f1(tau, nu)
        en = np.stack([dtft_phasors(f, self.nc, np.zeros(1))[0] for f in f1]) * self.wn[None, :]
        z = np.sum(rows * en, axis=1)
        for alpha, ph, f1e, f2e in self.echoes:
            z = z - alpha * ph * self.kernel_n(f1 - f1e) * float(self.kernel_k(np.array([f2 - f2e]))[0])
        d1, d2 = f1 - self.f1r, np.array([f2 - self.f2r])
        rho = self.kernel_n(d1) * float(self.kernel_k(d2)[0]) / self.window_peak
        kappa = self.kernel_n(d1, square=True) * float(self.kernel_k(d2, square=True)[0]) / self.window_energy
        zp = z - self.r * self.window_peak * rho
        var = float(np.sum(1.0 + rho**2 - 2.0 * rho * kappa))
        return complex(np.sum(np.conj(self._phase(tau, nu)) * zp)), float(np.sum(1.0 - rho**2)), var

    def refine(self, tau: float, nu: float) -> tuple[float, float, complex, float, float]:
        """(τ, ν, T, Σ s, var) at the maximum of |T|²/Σ s near a table hypothesis (the least-squares fit
        of the echo beside a free return per frame): parabolas through 3 × 3 exact points, the steps
        shrinking from the table's to a ninth of it, three times."""
        h1, h2 = _DELAY_STEP * self.bin_delay, self.resolution / 2

        def score(t: float, v: float, rows: np.ndarray) -> float:
            stat, norm, _ = self.exact(t, v, rows)
            return abs(stat) ** 2 / norm if norm > 0 else 0.0

        for _ in range(3):
            vs = nu + np.array([-1.0, 0.0, 1.0]) * h2
            rows = self.rows(vs)
            p = np.array([[score(tau + a * h1, v, rows[b]) for a in (-1, 0, 1)] for b, v in enumerate(vs)])
            tau += h1 * _vertex(p[1])
            nu += h2 * _vertex(p[:, 1])
            h1, h2 = h1 / 3.0, h2 / 3.0
        stat, norm, var = self.exact(tau, nu)
        return tau, nu, stat, norm, var

    def remove(self, alpha: complex, tau: float, nu: float) -> None:
        """Take a removed echo out of the table (its kernels, in closed form) and of later :meth:`exact` values."""
        r = self.radar
        ph, f1e, f2e = self._phase(tau, nu), self._f1(tau, nu), r.carrier_frequency * nu * r.chirp_interval
        k2 = self.kernel_k(self.d2 + self.f2r - f2e)  # [D2]
        k1 = self.kernel_n(self.d1[None, :] + (self.f1r - f1e)[:, None])  # [F, D1]
        self.table = self.table - (alpha * ph)[:, None, None] * k2[None, :, None] * k1[:, None, :]
        self.echoes.append((complex(alpha), ph, f1e, float(f2e)))
        self._project()


def _vertex(p: np.ndarray) -> float:
    """The vertex of the parabola through (−1, p₀), (0, p₁), (1, p₂), clipped to ±1."""
    curv = p[0] - 2.0 * p[1] + p[2]
    if not curv < 0:
        return 0.0
    return float(np.clip(0.5 * (p[0] - p[2]) / curv, -1.0, 1.0))
