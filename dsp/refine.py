"""Off-grid estimation of delay, delay rate and AoD from the whole sweep (``docs/estimation.md``).

Maximum likelihood under the model of :mod:`dsp.crb` (one RIS tone, amplitude β|A_m(θ)|, an
unknown phase per beam, white noise). With the phases and β profiled out, the log-likelihood is

    L(f₁, f₂, θ) = (Σ_m |A_m(θ)| · |Z_m(f₁, f₂)|)² / Σ_m A_m(θ)²,

Z_m the exact (un-windowed, un-gridded) 2-D DTFT of beam m at the fast/slow-time frequencies
(f₁, f₂) [cycles/sample]. It is maximised by alternating

1. delay/Doppler: a 5 × 5 zoom over ±½ DFT bin, then Newton steps on Σ_m a_m |Z_m(f)| with
   analytic first and second derivatives, weights a_m = |A_m(θ̂)| (beams whose weight is below
   ``min_weight`` are skipped: they carry no information, only noise);
2. AoD: the beam pattern fitted to the per-beam magnitudes r_m = |Z_m(f̂)|, on a fine grid of
   the direction cosine u = cos(el)·sin(az) over the sweep, then Brent's method around the best
   grid point (for a 1-D sweep the elevation is held at the assumed value).

The fit uses how the power falls off on both sides of the best beam, so it interpolates between
beams instead of picking one.

``likelihood="marginal"`` (opt-in; the default profiles) marginalises each beam's phase (uniform
prior) instead of profiling it: with b = K N β and s² = K N σ² the noise variance of Z_m, the log-likelihood is

    Σ_m log I₀(2 b |A_m(θ)| |Z_m(f₁, f₂)| / s²) − b² Σ_m A_m(θ)² / s²,

square-law in |Z_m| for beams near the noise floor, linear (the profiled criterion) for strong
ones. Step 1 is then Newton's method on Σ_m log I₀(x_m), x_m = c_m |Z_m|, c_m = 2 b a_m / s²:
the gradient is that of Σ_m c_m g(x_m) |Z_m| with g = I₁/I₀ held fixed (per-beam weights
a_m g(x_m)), the Hessian adds Σ_m c_m² g'(x_m) ∇|Z_m| ∇|Z_m|ᵀ; b̂ and θ̂ come from the marginal
pattern fit (:func:`dsp.fit_aod` with ``noise_variance``). The first fit and the 5 × 5 zoom, from
a start up to ½ bin off the tone, still profile. σ² is estimated from the data
(:meth:`_Evaluator.noise_power`) unless given; with no noise at all it falls back to profiling.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.special

from .validation import fields_equal, finite
from .aod_fit import AodFit, bessel_ratio, bessel_ratio_slope, fit_aod, log_i0
from .dtft_subspace import SubspaceDtft, as_cube
from .pattern import BeamPattern
from .radar import RadarConfig
from .sweep import BeamSweep

__all__ = ["RefinedEstimate", "refine_estimate", "template_variance_factor"]

#: Newton stops when a step is below this fraction of an un-padded DFT bin on both axes; the
#: steps converge quadratically, so the error left is far smaller (and far below the CRB).
STEP_TOLERANCE = 1e-5


@dataclass(frozen=True, eq=False)
class RefinedEstimate:
    """Result of :func:`refine_estimate`.

    Attributes
    ----------
    delay : float
        τ̂ (range-Doppler coupling removed) [s].
    delay_rate : float
        ν̂ [s/s].
    beat_frequency : (float, float)
        (f̂₁, f̂₂): fast-time (S τ + f_c ν)·T_s and slow-time f_c ν T_c [cycles/sample].
    aod : AodFit
    beam_magnitude : float array [M]
        |Z_m(f̂)| / (K N): per-beam amplitude of the tone [√W].
    amplitude : float
        β̂ [√W]: amplitude a beam steered exactly at the UE would see.
    iterations : int
        Newton steps taken (all passes).
    converged : bool
        The last step was below ``STEP_TOLERANCE`` of a DFT bin on both axes.
    delay_variance_factor : float
        F >= 1 (in practice): how much the static template's noise raises the variance of τ̂ and ν̂
        over what the same beams give without it (:func:`template_variance_factor`; 1 without a
        template) [unitless].
    """

    delay: float
    delay_rate: float
    beat_frequency: tuple[float, float]
    aod: AodFit
    beam_magnitude: np.ndarray
    amplitude: float
    iterations: int
    converged: bool
    delay_variance_factor: float = 1.0

    def peak_snr(self, noise_power: float, radar: RadarConfig) -> float:
        """ρ̂ = K N β̂² / σ² [linear], the post-integration SNR at the pattern peak."""
        return radar.num_chirps * radar.num_samples * self.amplitude**2 / noise_power

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


class _Evaluator:
    """Z_m and its derivatives near the current estimate, from subspace projections (:mod:`dsp.dtft_subspace`).

    The moments are taken once around the start and again only if the estimate leaves the ±½-bin
    region where they hold. ``far`` marks the beams whose mean is the static template.
    """

    def __init__(self, cube: np.ndarray, f1: float, f2: float) -> None:
        self.cube = cube
        self.passes = 0
        self.far: np.ndarray | None = None
        self._build(f1, f2)

    def _build(self, f1: float, f2: float) -> None:
        self.proj = SubspaceDtft(self.cube, f1, f2)
        self.passes += 1

    def _at(self, f1: float, f2: float) -> SubspaceDtft:
        if not self.proj.covers(f1, f2):
            self._build(f1, f2)
        return self.proj

    def template(self) -> np.ndarray | None:
        if self.far is None:
            return None
        return self.proj.moments[self.far].mean(axis=0)

    def noise_power(self, f1: float, f2: float) -> float:
        """σ̂² per sample [W] from the moments' energy outside the tone at (f₁, f₂).

        Each beam's moments hold r₁ r₂ coefficients of CN(0, σ²) noise (orthonormal bases) plus
        the tone, which lies along the one direction a(f₁) ⊗ b(f₂) of norm √(K N): the residual
        ‖H_m‖² − |Z_m|²/(K N) is σ²·Gamma(r₁r₂ − 1). The median over the beams far from the main
        lobe (static template removed, variance factor 1 − 1/M_far), or over all beams without a
        template, divided by the median of Gamma(r₁r₂ − 1), is robust to the few beams holding
        more than noise.
        """
        _, k, n = self.cube.shape
        t = self._at(f1, f2)
        h = t.moments
        factor = 1.0
        if self.far is not None:
            h = h[self.far] - self.template()[None]
            factor = 1.0 - 1.0 / int(self.far.sum())
        a, b = t.coefficients(f1, f2)
        z = np.einsum("mil,i,l->m", h, a[0], b[0])
        resid = (np.abs(h) ** 2).sum(axis=(1, 2)) - np.abs(z) ** 2 / (k * n)
        dof = h.shape[1] * h.shape[2] - 1
        return float(np.median(resid) / scipy.special.gammaincinv(dof, 0.5) / factor)

    def magnitudes(self, f1: float, f2: float) -> np.ndarray:
        """|Z_m(f₁, f₂)| of every beam of the raw cube [M]."""
        return np.abs(self._at(f1, f2).evaluate(f1, f2))

    def derivatives(self, f1: float, f2: float, beams: np.ndarray) -> np.ndarray:
        """∂^{a+b}Z/∂f₁^a∂f₂^b, static template removed, [M', 3, 3]."""
        t = self._at(f1, f2)
        return t.evaluate(f1, f2, beams=beams, order=2, template=self.template())

    def zoom(self, f1: float, f2: float, beams: np.ndarray, weights: "_Criterion", offsets: int = 5) -> tuple[float, float]:
        """Best of an ``offsets`` × ``offsets`` grid over ±½ bin of the criterion."""
        _, k, n = self.cube.shape
        if self.proj.centre != (f1, f2):
            self._build(f1, f2)  # the grid spans ±½ bin around (f₁, f₂)
        t = self.proj
        o1 = np.linspace(-0.5, 0.5, offsets) / n
        o2 = np.linspace(-0.5, 0.5, offsets) / k
        a, b = t.coefficients(f1 + o1, f2 + o2)  # [O, r₁], [O, r₂]
        h = t.moments[beams]
        tpl = self.template()
        if tpl is not None:
            h = h - tpl[None]
        obj = weights.value(np.abs(np.einsum("mil,ai,bl->mab", h, a, b)))
        i, j = np.unravel_index(int(np.argmax(obj)), obj.shape)
        return f1 + o1[i], f2 + o2[j]


class _Criterion:
    """Σ_m φ_m(|Z_m|) over the selected beams: profiled φ = a_m |Z|, or marginal φ = log I₀(c_m |Z|).

    ``weights(mag)`` gives (w₁, w₂) = (φ', φ''): the gradient of the criterion is Σ w₁ ∇|Z_m|, its
    Hessian Σ w₁ ∇²|Z_m| + w₂ ∇|Z_m| ∇|Z_m|ᵀ.
    """

    def __init__(self, a: np.ndarray, c: np.ndarray | None = None) -> None:
        self.a = a
        self.c = c  # None: profiled

    def value(self, mag: np.ndarray) -> np.ndarray:
        """Criterion for magnitudes [M', ...] (summed over the first axis)."""
        shape = (-1,) + (1,) * (mag.ndim - 1)
        if self.c is None:
            return (self.a.reshape(shape) * mag).sum(axis=0)
        return log_i0(self.c.reshape(shape) * mag).sum(axis=0)

    def weights(self, mag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.c is None:
            return self.a, np.zeros_like(self.a)
        x = self.c * mag
        g = bessel_ratio(x)
        return self.c * g, self.c**2 * bessel_ratio_slope(x, g)


def template_variance_factor(z: Any, weights: Any, far: Any, num_far: int) -> float:
    """Variance of the delay/Doppler score with the static template removed, over that without it.

    The score of the delay step is Σ_m w_m ∇|Z_m|, whose noise is Re Σ_m w_m e^{-jφ_m} ∇n_m with
    n_m beam m's noise and φ_m its tone's phase. The template T = (1/M_far) Σ_{far} n_j is
    subtracted from every beam, so the noise becomes Σ_m ∇n_m (u_m − c/M_far·[m far]), u_m =
    w_m e^{-jφ_m}, c = Σ_m u_m, and (white noise, every beam the same variance)

        F = 1 + (|c|² − 2 Re(c̄ c_far)) / (M_far Σ_m w_m²),   c_far = Σ_{m far} u_m.

    The curvature is the same with and without the template, so F multiplies var τ̂ and var ν̂
    (``docs/estimation.md``, Limits: 1.12 for Table I, whose beams' phases are 0 or π).

    Parameters
    ----------
    z : complex array [M']
        Z_m of the beams of the delay step at the estimate (its phases φ_m are used).
    weights : float array [M']
        Their weights w_m in the score (the profiled criterion's a_m = |A_m(θ̂)|).
    far : bool array [M']
        Which of them are among the template's beams.
    num_far : int
        M_far, the template's beams [count].

    Returns
    -------
    float
        F [unitless]; 1 when there is no template (``num_far`` 0) or no weight.
    """
    w = np.asarray(weights, dtype=float)
    if num_far <= 0 or not np.any(w > 0):
        return 1.0
    u = w * np.exp(-1j * np.angle(np.asarray(z, dtype=complex)))
    c = u.sum()
    c_far = u[np.asarray(far, dtype=bool)].sum()
    return float(1.0 + (abs(c) ** 2 - 2.0 * (np.conj(c) * c_far).real) / (num_far * float(w @ w)))


def _newton(ev: _Evaluator, beams: np.ndarray, crit: _Criterion, f1: float, f2: float, n: int, k: int,
            max_iter: int) -> tuple[float, float, int, bool]:
    step_tol = (STEP_TOLERANCE / n, STEP_TOLERANCE / k)
    value_prev = None
    last = None
    it = 0
    converged = False
    for it in range(1, max_iter + 1):
        z = ev.derivatives(f1, f2, beams)
        z0 = z[:, 0, 0]
        mag = np.maximum(np.abs(z0), 1e-300)
        value = float(crit.value(mag))
        if value_prev is not None and value < value_prev * (1 - 1e-12) and last is not None:
            # Overshot: halve the previous step and retry.
            f1, f2 = f1 - last[0] / 2, f2 - last[1] / 2
            last = (last[0] / 2, last[1] / 2)
            if abs(last[0]) < step_tol[0] and abs(last[1]) < step_tol[1]:
                converged = True
                break
            continue
        value_prev = value
        d1, d2 = z[:, 1, 0], z[:, 0, 1]
        d11, d22, d12 = z[:, 2, 0], z[:, 0, 2], z[:, 1, 1]
        c = np.conj(z0)
        r1 = (c * d1).real
        r2 = (c * d2).real
        weights, w2 = crit.weights(mag)
        g1, g2 = r1 / mag, r2 / mag  # ∇|Z_m|
        grad = np.array([weights @ g1, weights @ g2])
        h11 = weights @ (((np.conj(d1) * d1).real + (c * d11).real) / mag - r1 * r1 / mag**3) + w2 @ (g1 * g1)
        h22 = weights @ (((np.conj(d2) * d2).real + (c * d22).real) / mag - r2 * r2 / mag**3) + w2 @ (g2 * g2)
        h12 = weights @ (((np.conj(d1) * d2).real + (c * d12).real) / mag - r1 * r2 / mag**3) + w2 @ (g1 * g2)
        hess = np.array([[h11, h12], [h12, h22]])
        if np.all(np.linalg.eigvalsh(hess) < 0):
            step = -np.linalg.solve(hess, grad)
        else:  # not concave here: a small gradient step
            step = grad / np.abs(np.diag(hess)).clip(min=1e-300) * 0.1
        step = np.clip(step, [-0.25 / n, -0.25 / k], [0.25 / n, 0.25 / k])
        f1, f2 = f1 + step[0], f2 + step[1]
        last = (step[0], step[1])
        if abs(step[0]) < step_tol[0] and abs(step[1]) < step_tol[1]:
            converged = True
            break
    return f1, f2, it, converged


def refine_estimate(
    cube: Any,
    *,
    sweep: BeamSweep,
    radar: RadarConfig,
    pattern: BeamPattern,
    initial_delay: float,
    initial_delay_rate: float,
    elevation: float | None = None,
    min_weight: float = 0.05,
    max_iter: int = 8,
    passes: int = 2,
    remove_static: bool = True,
    likelihood: str = "profile",
    noise_power: float | None = None,
) -> RefinedEstimate:
    """Refine delay, delay rate and AoD off the DFT grid, combining every beam.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W].
    sweep : BeamSweep
    radar : RadarConfig
    pattern : BeamPattern
        RIS array factor (wavelength defaults to the radar's).
    initial_delay, initial_delay_rate : float
        Start within ½ un-padded DFT bin of the peak, e.g. the grid search's or the detection's
        τ (coupling removed) [s] and ν [s/s].
    elevation : float, optional
        Elevation assumed for a 1-D sweep [rad]; default the sweep's.
    min_weight : float, default 0.05
        Beams with |A_m(θ̂)| below this are left out of the delay/Doppler step.
    max_iter : int, default 8
        Newton steps per pass.
    passes : int, default 2
        Delay/Doppler ↔ AoD alternations.
    remove_static : bool, default True
        In the delay/Doppler step, subtract from every beam the mean of the beams far from the
        RIS main lobe (|A_m| < 0.1, at least 4 of them): a return that is the same in every frame
        (the panel's structural reflection, static clutter, leakage) then no longer leaks into the
        RIS peak through the un-windowed DTFT's sidelobes. The template holds the RIS tone only
        at the same frequency (its far sidelobes), so the frequency stays unbiased; its noise
        (variance σ²/M_far, common to every beam) raises the delay's variance by about
        |Σ_m a_m e^{jφ_m}|² / (M_far Σ_m a_m²): ~1/M_far with random per-beam phases, 12 % at
        Table I whose beams' phases are 0 or π (``docs/estimation.md``, Limits). The AoD fit uses
        the raw cube.
    likelihood : {"profile", "marginal"}, default "profile"
        How each beam's unknown phase is removed (module docstring): profiled, ``Σ_m a_m |Z_m|``,
        or marginalised (uniform prior; weighs the beams near the noise floor by their SNR: the
        AoD no longer locks onto noise beams in undetected captures at low SNR and its MSE is
        2-10 % lower from 10 to 20 dB, but it costs 54-78 ms instead of 33-37 ms per Table I
        capture, over the 50 ms budget; ``docs/estimation.md``). Both sit at the random-phase
        bound (``dsp.sweep_crb(phases="random")``) over the detected captures.
    noise_power : float, optional
        σ² per sample [W], e.g. ``Detection.noise_power``; default estimated from the cube
        around the tone. Only the marginal likelihood uses it.

    Returns
    -------
    RefinedEstimate

    Notes
    -----
    The cube is read once (:class:`dsp.dtft_subspace.SubspaceDtft` projections around the
    start, again only if the estimate leaves that ±½-bin region); every evaluation after that
    costs O(M r²) with r = 10, not O(M K N).
    """
    arr = as_cube(cube)
    m, k, n = arr.shape
    pat = pattern.for_wavelength(radar.wavelength)
    tau0 = finite(initial_delay, "initial_delay", "s")
    nu0 = finite(initial_delay_rate, "initial_delay_rate", "s/s")
    s_ts = radar.slope * radar.sample_period
    fct = radar.carrier_frequency * radar.chirp_interval
    f1 = (tau0 * radar.slope + radar.carrier_frequency * nu0) * radar.sample_period
    f2 = nu0 * fct

    if likelihood not in ("marginal", "profile"):
        raise ValueError(f"likelihood must be 'marginal' or 'profile', got {likelihood!r}")
    marginal = likelihood == "marginal"
    kn = k * n
    sigma2 = None
    if noise_power is not None:  # checked whichever criterion runs: a bad value is a bad call
        sigma2 = finite(noise_power, "noise_power", "W")
        if sigma2 <= 0:
            raise ValueError(f"noise_power must be > 0 W, got {noise_power!r}")

    ev = _Evaluator(arr, f1, f2)

    def noise() -> float | None:
        """σ² per sample, or None (no noise to speak of: the marginal likelihood is the profiled one)."""
        if not marginal:
            return None
        if sigma2 is not None:
            return sigma2
        est = ev.noise_power(f1, f2)
        scale = float((np.abs(ev.proj.moments) ** 2).sum(axis=(1, 2)).max())
        return est if est > 1e-12 * scale else None

    def fit_at(mags: np.ndarray, s2: float | None) -> AodFit:
        # Raw cube for the fit: the template would carry the RIS's own far sidelobes (random
        # phases) into every beam and bias the pattern fit by a fixed fraction of β, whatever the SNR.
        return fit_aod(mags, sweep, pat, elevation=elevation, noise_variance=None if s2 is None else kn * s2)

    def criterion(fit: AodFit, s2: float | None) -> tuple[np.ndarray, _Criterion]:
        weights = np.abs(pat.amplitude(fit.aod, sweep.angles))
        sel = np.flatnonzero(weights >= min_weight * weights.max())
        if s2 is None:
            return sel, _Criterion(weights[sel])
        # Noise variance of the template-removed Z_m: K N σ² (1 ± 1/M_far).
        var = np.full(sel.size, float(kn * s2))
        if ev.far is not None:
            m_far = int(ev.far.sum())
            var *= np.where(ev.far[sel], 1.0 - 1.0 / m_far, 1.0 + 1.0 / m_far)
        return sel, _Criterion(weights[sel], 2.0 * fit.amplitude * weights[sel] / var)

    # The start may be ½ bin off the tone (up to 3.9 dB of scalloping per axis): the first fit
    # and the zoom profile the phases; the marginal likelihood takes over from the zoomed cell.
    fit = fit_at(ev.magnitudes(f1, f2), None)
    if remove_static:
        far = np.abs(pat.amplitude(fit.aod, sweep.angles)) < 0.1
        if far.sum() >= 4:
            ev.far = far
    # Zoom: 5 × 5 points over ±½ bin (the start may be a cell of the un-padded grid).
    sel, crit = criterion(fit, None)
    f1, f2 = ev.zoom(f1, f2, sel, crit)
    s2 = None

    iterations = 0
    converged = False
    r = ev.magnitudes(f1, f2)
    if marginal:  # σ² and β (in c_m) at the zoomed frequencies, within ⅛ bin of the tone
        s2 = noise()
        fit = fit_at(r, s2)
    for _ in range(max(1, int(passes))):
        sel, crit = criterion(fit, s2)
        f1, f2, it, converged = _newton(ev, sel, crit, f1, f2, n, k, max_iter)
        iterations += it
        r = ev.magnitudes(f1, f2)
        s2 = noise()
        fit = fit_at(r, s2)
    factor = 1.0
    if ev.far is not None:  # the template's noise, common to every beam (docs/estimation.md, Limits)
        z = ev.derivatives(f1, f2, sel)[:, 0, 0]
        factor = template_variance_factor(z, crit.weights(np.maximum(np.abs(z), 1e-300))[0], ev.far[sel],
                                          int(ev.far.sum()))
    nu = f2 / fct
    # f₁ is defined modulo 1: keep the delay in [0, 1/(S T_s)).
    f1 = f1 % 1.0
    tau = f1 / s_ts - radar.carrier_frequency * nu / radar.slope
    return RefinedEstimate(
        delay=float(tau), delay_rate=float(nu), beat_frequency=(float(f1), float(f2)), aod=fit,
        beam_magnitude=r / kn, amplitude=fit.amplitude / kn, iterations=iterations, converged=converged,
        delay_variance_factor=factor,
    )
