"""The AoD from the per-beam powers: the RIS beam pattern fitted across the sweep (``docs/estimation.md``).

With the delay and Doppler fixed, the likelihood of the AoD under one RIS tone of amplitude
β|A_m(θ)| and an unknown phase per beam is ``(Σ_m |A_m(θ)| r_m)² / Σ_m A_m(θ)²``, r_m = |Z_m|.
:func:`fit_aod` maximises it on a fine grid of the direction cosine u = cos(el)·sin(az) over the
sweep, then with Brent's method around the best grid point (a 2-D sweep: a (u, w) grid and
Nelder–Mead). It uses how the power falls off on both sides of the best beam, so it interpolates
between beams instead of picking one; the other local maxima within reach are kept as candidates
(the ``grating-lobe`` flag reads them).

With the noise variance s² of the complex values behind r_m known (``noise_variance``), the phases
can be **marginalised** instead of profiled (uniform prior, the carrier phase of each frame is
random): the likelihood of (θ, b) is then

    Σ_m log I₀(2 b |A_m(θ)| r_m / s²) − b² Σ_m A_m(θ)² / s²,

b = K N β the tone's magnitude at the pattern peak, profiled out by Newton's method (one root).
log I₀(x) is square-law, x²/4, for a beam near the noise floor and linear, x − ½ log 2πx, for a
strong one: the beams at low SNR, whose magnitudes are mostly the Rayleigh noise floor, no longer
weigh as if they were signal. For large x it tends to the profiled likelihood.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.special

from .validation import as_finite_array, fields_equal, finite
from .pattern import BeamPattern, dirichlet
from .sweep import BeamSweep

__all__ = ["AodFit", "PatternFit", "fit_aod", "pattern_fit", "bessel_ratio", "log_i0"]


@dataclass(frozen=True, eq=False)
class AodFit:
    """Beam-pattern fit of per-beam magnitudes.

    Attributes
    ----------
    aod : float array [2]
        ``[az, el]`` [rad] (el is the assumed one for a 1-D sweep).
    direction_cosine : float
        û = cos(el)·sin(az), what a 1-D azimuth sweep measures [unitless].
    amplitude : float
        β̂ in the units of the magnitudes (|A| = 1 at the peak).
    candidates : float array [C, 2]
        Other local maxima of the fit objective inside the swept span, ``[az, relative level dB]``
        (<= 0), strongest first; a grating lobe or a strong sidelobe shows here.
    twins : float array [T, 3]
        The grating-lobe twins of the estimate outside the swept span: every azimuth whose direction
        cosine differs from û by a whole number of grating periods λ/(q d) and that is visible
        (|u| < cos el), ``[az, level dB relative to the fit at û, searched]``. The pattern cannot tell
        them from the estimate (level 0 dB up to rounding: the array factor is periodic in u); ``searched`` is 1
        for a twin within the fit's search range (the span ± one null width: the fit could have
        chosen it), 0 beyond. Empty for a relay RIS at λ/2 (period 2: no twin is visible).
    """

    aod: np.ndarray
    direction_cosine: float
    amplitude: float
    candidates: np.ndarray
    twins: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]

def bessel_ratio(x: Any) -> np.ndarray:
    """g(x) = I₁(x)/I₀(x) for x >= 0: d/dx log I₀(x), from 0 (x/2 near 0) to 1 (1 − 1/(2x))."""
    x = np.minimum(np.asarray(x, dtype=float), 1e300)
    return scipy.special.i1e(x) / scipy.special.i0e(x)


def bessel_ratio_slope(x: Any, g: Any = None) -> np.ndarray:
    """g'(x) = 1 − g/x − g² (½ at 0; its asymptotic series for x > 100, where that cancels).

    ``g``: g(x) if already computed.
    """
    x = np.asarray(x, dtype=float)
    g = bessel_ratio(x) if g is None else np.asarray(g, dtype=float)
    out = 1.0 - g / np.maximum(x, 1e-300) - g * g
    small = x < 1e-8
    if small.any():
        out = np.where(small, 0.5, out)
    big = x > 100.0
    if big.any():
        y = 1.0 / np.where(big, x, 1.0)
        out = np.where(big, y * y * (0.5 + y * (0.25 + 0.375 * y)), out)
    return out


def log_i0(x: Any) -> np.ndarray:
    """log I₀(x) for x >= 0, without overflow."""
    x = np.minimum(np.asarray(x, dtype=float), 1e300)
    return np.log(scipy.special.i0e(x)) + x


def _marginal_amplitude(amp: np.ndarray, r: np.ndarray, s2: float, iterations: int = 30) -> np.ndarray:
    """b̂ maximising Σ log I₀(2 b a r/s²) − b² Σa²/s² over the last axis (``amp`` [..., M]).

    F(b) = Σ a r g(2 b a r/s²) − b Σ a² is concave with F(0) = 0; Newton's method from the
    profiled b₀ = Σ a r/Σ a² (F(b₀) <= 0, as g <= 1) decreases monotonically to the positive
    root, or to 0 when there is none (no tone above the noise floor). Stops when every step is
    below 10⁻¹² of b₀.
    """
    a = np.abs(amp)
    ar = a * r
    aa = (a * a).sum(axis=-1)
    safe = np.where(aa > 0, aa, 1.0)
    b = ar.sum(axis=-1) / safe
    tol = 1e-12 * np.maximum(b, 1e-300)
    ar2 = ar * ar * (2 / s2)
    for _ in range(iterations):
        x = 2 * b[..., None] * ar / s2
        g = bessel_ratio(x)
        f = (ar * g).sum(axis=-1) - b * aa
        df = (ar2 * bessel_ratio_slope(x, g)).sum(axis=-1) - aa
        step = np.where(df < 0, f / np.where(df < 0, df, -1.0), 0.0)
        b = np.maximum(b - step, 0.0)
        if np.all(np.abs(step) <= tol):
            break
    return np.where(aa > 0, b, 0.0)


def _marginal_objective(amp: np.ndarray, r: np.ndarray, s2: float) -> tuple[np.ndarray, np.ndarray]:
    """(max_b of the marginal log-likelihood, b̂) over the last axis."""
    a = np.abs(amp)
    b = _marginal_amplitude(a, r, s2)
    val = log_i0(2 * b[..., None] * a * r / s2).sum(axis=-1) - b * b * (a * a).sum(axis=-1) / s2
    return val, b


def _objective(amp: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(Σ|A| r)² / ΣA² over the last axis."""
    a = np.abs(amp)
    den = (a * a).sum(axis=-1)
    num = (a * r).sum(axis=-1)
    return np.where(den > 0, num * num / np.where(den > 0, den, 1.0), 0.0)


#: Grid cells (direction x beam) the AoD search evaluates per pass. Its grid steps by a null width / 8, so its points
#: grow with the RIS's rows: a capture declaring 52 171 x 2 elements took 1.1 GiB in one pass (61 beams, 3 · 10⁵
#: directions), past a 512 MiB memory limit; in passes of 2¹⁸ cells (2 MiB per float64 array) the working set stays
#: bounded at any size, and the paper's 16-row grid (≈ 100 directions) is one pass.
GRID_CELLS_PER_PASS = 2**18


def _over_grid(pattern: BeamPattern, u: np.ndarray, beams: np.ndarray, w: float,
               *functions: Callable[[np.ndarray], np.ndarray]) -> list[np.ndarray]:
    """Each of ``functions`` of the amplitudes A_m(u_i, w) [I, M], at every u_i of ``u`` [I], in passes of
    :data:`GRID_CELLS_PER_PASS` cells (each function reduces along the beams only: a point's value is its own)."""
    step = max(1, GRID_CELLS_PER_PASS // max(1, beams.shape[0]))
    out = [np.empty(u.size) for _ in functions]
    for i in range(0, u.size, step):
        amp = pattern.amplitude_u(u[i:i + step], beams, w=w)
        for values, function in zip(out, functions):
            values[i:i + step] = function(amp)
    return out


def fit_aod(magnitudes: Any, sweep: BeamSweep, pattern: BeamPattern, *, elevation: float | None = None,
            noise_variance: float | None = None) -> AodFit:
    """Fit the RIS beam pattern to per-beam magnitudes (maximum likelihood, phases unknown).

    Parameters
    ----------
    magnitudes : float array [M]
        r_m >= 0, e.g. |Z_m| at the estimated delay/Doppler [any unit].
    sweep : BeamSweep
    pattern : BeamPattern
        With its wavelength set.
    elevation : float, optional
        Elevation held fixed for a 1-D sweep [rad]; default the sweep's (common) elevation.
    noise_variance : float, optional
        s² = E|w|² of the complex noise of each value whose magnitude r_m is [unit of r²], e.g.
        K N σ² for the DTFT of a beam. Given: the phases are marginalised (module docstring);
        None: profiled, ``(Σ|A| r)²/ΣA²``. The candidates are the profiled objective's in both
        cases (their levels in dB are power ratios).

    Returns
    -------
    AodFit
    """
    r = as_finite_array(magnitudes, "magnitudes", shape=(sweep.num_beams,))
    s2 = None if noise_variance is None else float(noise_variance)
    if s2 is not None and not (np.isfinite(s2) and s2 > 0):
        raise ValueError(f"noise_variance must be finite and > 0, got {noise_variance!r}")

    def objective(amp: np.ndarray) -> np.ndarray:
        return _objective(amp, r) if s2 is None else _marginal_objective(amp, r, s2)[0]

    beams = sweep.angles
    el = float(np.mean(beams[:, 1])) if elevation is None else finite(elevation, "elevation", "rad")
    w = np.sin(el)
    u_beams = np.cos(beams[:, 1]) * np.sin(beams[:, 0])
    one_d = np.ptp(beams[:, 1]) < 1e-12
    cos_el = np.cos(el)
    lo = max(-cos_el, u_beams.min() - pattern.null_width)
    hi = min(cos_el, u_beams.max() + pattern.null_width)
    du = pattern.null_width / 8.0
    grid = np.linspace(lo, hi, max(3, int(np.ceil((hi - lo) / du)) + 1))
    if s2 is None:
        g, = _over_grid(pattern, grid, beams, w, lambda amp: _objective(amp, r))  # profiled: the candidates' levels
        obj = g
    else:
        g, obj = _over_grid(pattern, grid, beams, w, lambda amp: _objective(amp, r), objective)
    i = int(np.argmax(obj))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = scipy.optimize.minimize_scalar(
        lambda uu: -float(objective(pattern.amplitude_u(np.array([uu]), beams, w=w))[0]),
        bounds=(a, b), method="bounded", options={"xatol": 1e-9 * max(pattern.null_width, 1e-3)},
    )
    u_hat = float(res.x) if -res.fun >= obj[i] else float(grid[i])
    u_hat = _prefer_swept_twin(u_hat, u_beams, pattern.grating_period,
                               lambda uu: float(objective(pattern.amplitude_u(np.array([uu]), beams, w=w))[0]))
    az = float(np.arcsin(np.clip(u_hat / cos_el, -1.0, 1.0)))
    aod = np.array([az, el])
    if not one_d:
        # 2-D sweep: a (u, w) grid over the swept span, then Nelder-Mead on (u, w).
        w_beams = np.sin(beams[:, 1])
        w_null = pattern.grating_period / pattern.num_columns
        wg = np.linspace(max(-1.0, w_beams.min() - w_null), min(1.0, w_beams.max() + w_null),
                         max(3, int(np.ceil((np.ptp(w_beams) + 2 * w_null) / (w_null / 8))) + 1))

        def amp_uw(uu: float, ww: float) -> np.ndarray:
            return pattern.amplitude_u(np.array([uu]), beams, w=ww)

        g2 = np.array([_over_grid(pattern, grid, beams, ww, objective)[0] for ww in wg])  # [W, U]
        iw, iu = np.unravel_index(int(np.argmax(g2)), g2.shape)
        x0 = np.array([grid[iu], wg[iw]])
        simplex = x0 + np.array([[0.0, 0.0], [du, 0.0], [0.0, w_null / 8]])
        res2 = scipy.optimize.minimize(lambda x: -float(objective(amp_uw(x[0], x[1]))[0]), x0,
                                       method="Nelder-Mead",
                                       options={"initial_simplex": simplex, "xatol": 1e-10, "fatol": 0.0,
                                                "maxiter": 2000})
        uu, ww = (res2.x if -res2.fun >= g2[iw, iu] else x0)
        uu = _prefer_swept_twin(float(uu), u_beams, pattern.grating_period,
                                lambda x: float(objective(amp_uw(x, float(ww)))[0]))
        el2 = float(np.arcsin(np.clip(ww, -1, 1)))
        aod = np.array([float(np.arcsin(np.clip(uu / np.cos(el2), -1, 1))), el2])
        u_hat = float(uu)
    amp_hat = np.abs(pattern.amplitude(aod, beams))
    if s2 is None:
        beta = float((amp_hat * r).sum() / (amp_hat @ amp_hat)) if amp_hat @ amp_hat > 0 else 0.0
    else:
        beta = float(_marginal_amplitude(amp_hat, r, s2))
    # Other local maxima of the objective, separated from the best by more than a null width.
    # Only inside the swept span: beyond it the objective rests on a few sidelobes.
    peaks = np.flatnonzero((g[1:-1] >= g[:-2]) & (g[1:-1] > g[2:])) + 1
    inside = (grid[peaks] >= u_beams.min()) & (grid[peaks] <= u_beams.max())
    far = peaks[inside & (np.abs(grid[peaks] - u_hat) > pattern.null_width)]
    best = max(float(g.max()), 1e-300)
    cand = sorted(((float(np.arcsin(np.clip(grid[j] / cos_el, -1, 1))), float(10 * np.log10(max(g[j], 1e-300) / best)))
                   for j in far), key=lambda t: -t[1])
    w_hat = float(np.sin(aod[1]))
    cos_hat = float(np.cos(aod[1]))
    twins = []
    g_hat = max(float(_objective(pattern.amplitude_u(np.array([u_hat]), beams, w=w_hat), r)[0]), 1e-300)
    for t in _twins(u_hat, pattern.grating_period, cos_hat):
        if u_beams.min() <= t <= u_beams.max():
            continue  # inside the span: a local maximum, among the candidates
        level = float(_objective(pattern.amplitude_u(np.array([t]), beams, w=w_hat), r)[0])
        twins.append((float(np.arcsin(np.clip(t / cos_hat, -1, 1))),
                      float(10 * np.log10(max(level, 1e-300) / g_hat)), float(lo <= t <= hi)))
    return AodFit(aod=aod, direction_cosine=u_hat, amplitude=beta,
                  candidates=np.array(cand, dtype=float).reshape(-1, 2),
                  twins=np.array(twins, dtype=float).reshape(-1, 3))


#: Two twins' fit objectives tie when they differ by less than this fraction (the array factor is
#: periodic in u: a twin's objective equals the estimate's up to rounding, ~1e-15).
TWIN_TIE_RTOL = 1e-9


def _twins(u: float, period: float, limit: float) -> list[float]:
    """u + k·period for every whole k ≠ 0 with |u + k·period| < ``limit`` [direction cosine]."""
    k_lo, k_hi = int(np.ceil((-limit - u) / period)), int(np.floor((limit - u) / period))
    return [u + k * period for k in range(k_lo, k_hi + 1) if k != 0 and abs(u + k * period) < limit]


def _prefer_swept_twin(u_hat: float, u_beams: np.ndarray, period: float, value: Any) -> float:
    """The estimate, or its grating-lobe twin inside the swept span when the two fits tie.

    A reflective RIS at λ/2 (period λ/(q d) = 1) returns exactly the same beam powers for a UE at
    u and at u ± 1: the fit cannot choose, and its grid search took whichever came first — a twin
    beyond the sweep (−47.5° for a UE at 15.2°), 13.9 m away. When û lies outside the span
    [min u_m, max u_m] and a twin inside it ties (``value``, the fit objective, within
    :data:`TWIN_TIE_RTOL`), the twin is taken: the sweep is taken to cover the UE. The other one
    stays in :attr:`AodFit.twins` and raises ``grating-lobe``.
    """
    lo, hi = float(u_beams.min()), float(u_beams.max())
    if lo <= u_hat <= hi:
        return u_hat
    inside = [t for t in _twins(u_hat, period, 1.0) if lo <= t <= hi]
    if not inside:
        return u_hat
    best = value(u_hat)
    tied = [t for t in inside if value(t) >= best - TWIN_TIE_RTOL * abs(best)]
    return min(tied, key=lambda t: abs(t - 0.5 * (lo + hi))) if tied else u_hat


@dataclass(frozen=True, eq=False)
class PatternFit:
    """Goodness of fit of the beam pattern to the per-beam magnitudes (``pattern-mismatch``).

    Attributes
    ----------
    statistic : float
        χ²/dof-like ratio T = Σ_m (r_m − b̂|A_m|)² / Σ_m e_m [unitless], at the best fit of the
        pattern (allowing the AoD to drift across the sweep when frame times are given): about 1
        when the model is right (a little less: its parameters are fitted), e_m the expected squared
        residual of a Rice magnitude r_m about its amplitude.
    threshold : float
        The level T exceeds with probability ``pfa`` under the right model [unitless].
    dof : float
        The effective degrees of freedom ν of the scaled-χ² approximation [unitless].
    aod : float array [2]
        θ̂ of the fit, at the pattern-weighted mean frame time [rad].
    static_statistic : float
        T of the fit with the AoD held over the sweep [unitless] (= ``statistic`` without frame times).
    aod_rate : float
        The fitted du/dt of the direction cosine [1/s] (0 without frame times).
    """

    statistic: float
    threshold: float
    dof: float
    aod: np.ndarray
    static_statistic: float = math.nan
    aod_rate: float = 0.0

    @property
    def mismatch(self) -> bool:
        """The pattern does not explain the profile: ``statistic > threshold``."""
        return bool(self.statistic > self.threshold)

    @property
    def excess(self) -> float:
        """sqrt(T) when the test fires, else 1: the factor the AoD's 1σ is widened by [unitless]."""
        return float(np.sqrt(self.statistic)) if self.mismatch else 1.0

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


def _rice_mean(nu: np.ndarray, s2: float) -> np.ndarray:
    """E|ν + w|, w ~ CN(0, s²): s √π/2 · L_{1/2}(−ν²/s²) [unit of ν], with scaled Bessel functions."""
    y = nu * nu / s2
    return np.sqrt(np.pi * s2) / 2.0 * ((1 + y) * scipy.special.i0e(y / 2) + y * scipy.special.i1e(y / 2))


def _drifting_rss(r: np.ndarray, pattern: BeamPattern, beams: np.ndarray, w: float, u0: np.ndarray,
                  rate: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Σ (r − b̂|A_m(u0 + rate·dt_m)|)² with b̂ profiled, for every (rate, u0) pair [R, U]."""
    c = 2 * np.pi / pattern.grating_period
    ub = np.cos(beams[:, 1]) * np.sin(beams[:, 0])
    wb = np.sin(beams[:, 1])
    u = u0[None, :, None] + rate[:, None, None] * dt[None, None, :]  # [R, U, M]
    a = np.abs(dirichlet(c * (u - ub), pattern.num_rows) * dirichlet(c * (w - wb), pattern.num_columns))
    return float(r @ r) - _objective(a, r)


def pattern_fit(magnitudes: Any, sweep: BeamSweep, pattern: BeamPattern, *, noise_variance: float,
                pfa: float = 1e-3, elevation: float | None = None, beam_times: Any = None,
                max_aod_rate: float = 0.0, decide_only: bool = False) -> PatternFit:
    """Does the RIS beam pattern explain the per-beam magnitudes within the noise?

    The pattern is fitted by least squares (:func:`fit_aod`, profiled: b̂, θ̂ minimise
    Σ (r_m − b |A_m(θ)|)²) and the residual compared with what the noise alone leaves. Under the
    model r_m = |b A_m e^{jψ_m} + w_m|, w_m ~ CN(0, s²), is Rice distributed; its expected squared
    residual about ν_m = b̂|A_m| is e_m = 2ν_m² + s² − 2ν_m E[r_m] (s² for a beam at the noise floor,
    s²/2 for a strong one). T = Σ (r_m − ν_m)² / Σ e_m is compared with a scaled χ²: each term taken
    as e_m χ²₁ (variance 2e_m², an upper bound: a noise-floor beam's is e_m²), so T ν ~ χ²_ν with
    ν = (Σe_m)² / Σe_m² (Satterthwaite), and the threshold is χ²_ν's upper ``pfa`` quantile over ν.

    **A radar moving across the beam** turns the AoD during the sweep (1 m/s across a 13.4 m leg:
    2.6° over 61 frames of 20 ms) and smears the profile. With ``beam_times`` and ``max_aod_rate``
    the fit may also let the direction cosine drift, u_m = u₀ + u̇ (t_m − t̄), |u̇| <= ``max_aod_rate``
    (a 17 × 33 grid of (u̇, u₀) around the static fit, then Nelder–Mead): T is the better of the two
    fits. The bound matters: a drift at the sweep's own rate stretches the pattern's width, so an
    unbounded u̇ could mimic a wrong size or mode.

    A wrong mode (reflective for relay: a main lobe half as wide), spacing, size or pose leaves a
    residual that grows with the SNR: T ≫ 1.

    Parameters
    ----------
    magnitudes : float array [M]
        r_m = |Z_m| [any unit].
    sweep : BeamSweep
    pattern : BeamPattern
        With its wavelength set.
    noise_variance : float
        s² = E|w_m|² in the unit of r² (> 0).
    pfa : float, default 1e-3
        Probability that the test fires under the right model [unitless].
    elevation : float, optional
        For a 1-D sweep [rad], as :func:`fit_aod`.
    beam_times : float array [M], optional
        Frame centre of each beam [s] (``RadarConfig.beam_times``).
    max_aod_rate : float, default 0
        Largest |du/dt| the drifting fit may use [1/s], e.g. v_t,max / distance; 0: the AoD is held.
    decide_only : bool, default False
        True: when the static fit already passes (T <= threshold) the drifting fit is not tried,
        since it can only lower T: the decision (``mismatch``, ``excess``) is the same, ``statistic``
        is the static one and ``aod_rate`` 0. ``dsp.self_localize`` asks for this (its flag and σ read
        nothing else); a static radar's sweep then skips the drifting search (a 17 × 33 grid and ~120
        Nelder–Mead steps: 13 of the 15 ms of a Table I fit on one core).

    Returns
    -------
    PatternFit
    """
    import scipy.stats

    r = as_finite_array(magnitudes, "magnitudes", shape=(sweep.num_beams,))
    s2 = float(noise_variance)
    if not (np.isfinite(s2) and s2 > 0):
        raise ValueError(f"noise_variance must be finite and > 0, got {noise_variance!r}")
    if not isinstance(decide_only, bool):
        raise TypeError(f"decide_only={decide_only!r} must be True or False")
    fit = fit_aod(r, sweep, pattern, elevation=elevation)
    beams = sweep.angles
    a = np.abs(pattern.amplitude(fit.aod, beams))
    nu = max(fit.amplitude, 0.0) * a
    e = np.maximum(2 * nu * nu + s2 - 2 * nu * _rice_mean(nu, s2), 1e-6 * s2)
    rss = float(np.sum((r - nu) ** 2))
    static = rss / float(np.sum(e))
    dof = float(np.sum(e) ** 2 / np.sum(e * e))
    thr = float(scipy.stats.chi2.isf(pfa, dof) / dof)
    rate_hat = 0.0
    if beam_times is not None and max_aod_rate > 0 and not (decide_only and static <= thr):
        t = as_finite_array(beam_times, "beam_times", shape=(sweep.num_beams,))
        dt = t - float((a * a) @ t / max(float(a @ a), 1e-300))
        w = float(np.sin(fit.aod[1]))
        u_fit = fit.direction_cosine
        rates = np.linspace(-max_aod_rate, max_aod_rate, 17)
        u0 = u_fit + np.linspace(-1.0, 1.0, 33) * pattern.null_width
        grid = _drifting_rss(r, pattern, beams, w, u0, rates, dt)
        i, j = np.unravel_index(int(np.argmin(grid)), grid.shape)

        def cost(x: np.ndarray) -> float:
            rate = float(np.clip(x[1], -max_aod_rate, max_aod_rate))
            return float(_drifting_rss(r, pattern, beams, w, np.array([x[0]]), np.array([rate]), dt)[0, 0])

        x0 = np.array([u0[j], rates[i]])
        res = scipy.optimize.minimize(cost, x0, method="Nelder-Mead", options={
            "initial_simplex": x0 + np.array([[0.0, 0.0], [pattern.null_width / 16, 0.0],
                                              [0.0, max_aod_rate / 8 if rates[i] <= 0 else -max_aod_rate / 8]]),
            "xatol": 1e-9, "fatol": 1e-12 * max(rss, 1e-300), "maxiter": 400})
        best = min(float(res.fun), float(grid[i, j]))
        if best < rss:
            rss = best
            rate_hat = float(np.clip(res.x[1], -max_aod_rate, max_aod_rate)) if res.fun <= grid[i, j] \
                else float(rates[i])
    stat = rss / float(np.sum(e))
    return PatternFit(statistic=stat, threshold=thr, dof=dof, aod=fit.aod, static_statistic=static,
                      aod_rate=rate_hat)
