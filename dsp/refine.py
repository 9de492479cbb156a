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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import fields_equal, finite
from .aod_fit import AodFit, fit_aod
from .dtft_subspace import SubspaceDtft
from .pattern import BeamPattern
from .radar import RadarConfig
from .sweep import BeamSweep

__all__ = ["RefinedEstimate", "refine_estimate", "beam_dtft", "residual_test"]

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
    """

    delay: float
    delay_rate: float
    beat_frequency: tuple[float, float]
    aod: AodFit
    beam_magnitude: np.ndarray
    amplitude: float
    iterations: int
    converged: bool

    def peak_snr(self, noise_power: float, radar: RadarConfig) -> float:
        """ρ̂ = K N β̂² / σ² [linear], the post-integration SNR at the pattern peak."""
        return radar.num_chirps * radar.num_samples * self.amplitude**2 / noise_power

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]

def _bases(f: float, idx: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """exp(j2π (f + offsets) idx) [len(offsets), len(idx)]."""
    ph = np.outer(f + offsets, idx)
    return np.exp(2j * np.pi * (ph - np.round(ph)))


def _contract(cube: np.ndarray, basis: np.ndarray, beams: np.ndarray | None = None) -> np.ndarray:
    """``cube[beams] @ basis`` [M', K, P] without copying the selected beams first."""
    m, k, n = cube.shape
    p = basis.shape[1]
    basis = np.ascontiguousarray(basis)
    # One 2-D product per contiguous run of beams (a view, no copy): a single BLAS call is
    # far faster than numpy's stacked matmul when other processes share the cores.
    if beams is None:
        return (cube.reshape(m * k, n) @ basis).reshape(m, k, p)
    out = np.empty((beams.size, k, p), dtype=complex)
    runs = np.split(np.arange(beams.size), np.flatnonzero(np.diff(beams) != 1) + 1)
    for run in runs:
        lo, hi = beams[run[0]], beams[run[-1]] + 1
        out[run[0]:run[-1] + 1] = (cube[lo:hi].reshape((hi - lo) * k, n) @ basis).reshape(hi - lo, k, p)
    return out


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

    def magnitudes(self, f1: float, f2: float) -> np.ndarray:
        """|Z_m(f₁, f₂)| of every beam of the raw cube [M]."""
        return np.abs(self._at(f1, f2).evaluate(f1, f2))

    def derivatives(self, f1: float, f2: float, beams: np.ndarray) -> np.ndarray:
        """∂^{a+b}Z/∂f₁^a∂f₂^b, static template removed, [M', 3, 3]."""
        t = self._at(f1, f2)
        return t.evaluate(f1, f2, beams=beams, order=2, template=self.template())

    def zoom(self, f1: float, f2: float, beams: np.ndarray, weights: np.ndarray, offsets: int = 5) -> tuple[float, float]:
        """Best of an ``offsets`` × ``offsets`` grid over ±½ bin of Σ_m a_m |Z_m|."""
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
        obj = np.einsum("m,mab->ab", weights, np.abs(np.einsum("mil,ai,bl->mab", h, a, b)))
        i, j = np.unravel_index(int(np.argmax(obj)), obj.shape)
        return f1 + o1[i], f2 + o2[j]


def _newton(ev: _Evaluator, beams: np.ndarray, weights: np.ndarray, f1: float, f2: float, n: int, k: int,
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
        value = float(weights @ mag)
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
        grad = np.array([weights @ (r1 / mag), weights @ (r2 / mag)])
        h11 = weights @ (((np.conj(d1) * d1).real + (c * d11).real) / mag - r1 * r1 / mag**3)
        h22 = weights @ (((np.conj(d2) * d2).real + (c * d22).real) / mag - r2 * r2 / mag**3)
        h12 = weights @ (((np.conj(d1) * d2).real + (c * d12).real) / mag - r1 * r2 / mag**3)
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
        (variance σ²/M_far) costs ~1/M_far in variance. The AoD fit uses the raw cube.

    Returns
    -------
    RefinedEstimate

    Notes
    -----
    The cube is read once (:class:`dsp.dtft_subspace.SubspaceDtft` projections around the
    start, again only if the estimate leaves that ±½-bin region); every evaluation after that
    costs O(M r²) with r = 10, not O(M K N).
    """
    arr = np.asarray(cube, dtype=complex)
    m, k, n = arr.shape
    pat = pattern.for_wavelength(radar.wavelength)
    tau0 = finite(initial_delay, "initial_delay", "s")
    nu0 = finite(initial_delay_rate, "initial_delay_rate", "s/s")
    s_ts = radar.slope * radar.sample_period
    fct = radar.carrier_frequency * radar.chirp_interval
    f1 = (tau0 * radar.slope + radar.carrier_frequency * nu0) * radar.sample_period
    f2 = nu0 * fct

    ev = _Evaluator(arr, f1, f2)
    # Raw cube for the fit: the template would carry the RIS's own far sidelobes (random phases)
    # into every beam and bias the pattern fit by a fixed fraction of β, whatever the SNR.
    fit = fit_aod(ev.magnitudes(f1, f2), sweep, pat, elevation=elevation)
    if remove_static:
        far = np.abs(pat.amplitude(fit.aod, sweep.angles)) < 0.1
        if far.sum() >= 4:
            ev.far = far
    # Zoom: 5 × 5 points over ±½ bin (the start may be a cell of the un-padded grid).
    weights = np.abs(pat.amplitude(fit.aod, sweep.angles))
    sel = np.flatnonzero(weights >= min_weight * weights.max())
    f1, f2 = ev.zoom(f1, f2, sel, weights[sel])

    iterations = 0
    converged = False
    r = ev.magnitudes(f1, f2)
    for _ in range(max(1, int(passes))):
        weights = np.abs(pat.amplitude(fit.aod, sweep.angles))
        sel = np.flatnonzero(weights >= min_weight * weights.max())
        f1, f2, it, converged = _newton(ev, sel, weights[sel], f1, f2, n, k, max_iter)
        iterations += it
        r = ev.magnitudes(f1, f2)
        fit = fit_aod(r, sweep, pat, elevation=elevation)
    nu = f2 / fct
    # f₁ is defined modulo 1: keep the delay in [0, 1/(S T_s)).
    f1 = f1 % 1.0
    tau = f1 / s_ts - radar.carrier_frequency * nu / radar.slope
    kn = k * n
    return RefinedEstimate(
        delay=float(tau), delay_rate=float(nu), beat_frequency=(float(f1), float(f2)), aod=fit,
        beam_magnitude=r / kn, amplitude=fit.amplitude / kn, iterations=iterations, converged=converged,
    )


def beam_dtft(cube: Any, radar: RadarConfig, delay: float, delay_rate: float) -> tuple[np.ndarray, float, float]:
    """|Z_m| of every beam at (τ, ν): the un-windowed 2-D DTFT magnitude [M] [√W·K·N].

    Returns the magnitudes and the frequencies (f₁, f₂) [cycles/sample] they were taken at.
    """
    arr = np.asarray(cube, dtype=complex)
    m, k, n = arr.shape
    f1 = (delay * radar.slope + radar.carrier_frequency * delay_rate) * radar.sample_period
    f2 = delay_rate * radar.carrier_frequency * radar.chirp_interval
    en = _bases(f1, np.arange(n) - (n - 1) / 2.0, np.zeros(1))[0]
    ek = _bases(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0]
    return np.abs((arr.reshape(m * k, n) @ en).reshape(m, k) @ ek), float(f1), float(f2)


def residual_test(
    cube: Any,
    radar: RadarConfig,
    f1: float,
    f2: float,
    weights: Any,
    *,
    cell_noise: float,
    pfa: float = 1e-3,
    min_weight: float = 0.05,
) -> tuple[float, float] | None:
    """Is there a second return within half a resolution cell of the fitted tone?

    The per-beam least-squares tone at (f₁, f₂) is removed and the residual of the Hann-windowed
    DTFT is evaluated at the 8 points ±½ un-padded bin around it, summed over the beams with
    |A_m| >= ``min_weight`` (static returns removed as in :func:`refine_estimate`). The window
    keeps returns that are resolved (two or more cells away, e.g. multipath legs of the loop-back)
    from leaking into the test through the rectangular window's -13 dB sidelobes. With one tone
    the residual is noise only: ``Σ_m |R_m|²/σ²_cell`` (σ²_cell of the windowed sum) is at most
    Gamma(M', 1) (less, as the fit removed part of it), and the test flags when its maximum
    exceeds the Gamma(M', 1) level of probability pfa/8.

    Parameters
    ----------
    cube : complex array [M, K, N]
    radar : RadarConfig
    f1, f2 : float
        Fitted beat frequencies [cycles/sample].
    weights : float array [M]
        |A_m(θ̂)|.
    cell_noise : float
        Noise power of one un-padded DFT cell, K·N·σ² [W·K·N].
    pfa : float
        False-flag probability.

    Returns
    -------
    (statistic, threshold) when the test fires, else None.
    """
    import scipy.signal
    import scipy.special

    arr = np.asarray(cube, dtype=complex)
    m, k, n = arr.shape
    w = np.asarray(weights, dtype=float)
    sel = np.flatnonzero(w >= min_weight * w.max())
    far = w < 0.1 * w.max()
    n_idx = np.arange(n) - (n - 1) / 2.0
    k_idx = np.arange(k) - (k - 1) / 2.0
    offs1 = np.array([-0.5, 0.0, 0.5]) / n
    offs2 = np.array([-0.5, 0.0, 0.5]) / k
    wn = scipy.signal.get_window("hann", n, fftbins=False)
    wk = scipy.signal.get_window("hann", k, fftbins=False)
    bn = _bases(f1, n_idx, offs1).T * wn[:, None]  # [N, 3]
    bk = _bases(f2, k_idx, offs2) * wk[None, :]  # [3, K]
    g = _contract(arr, bn, sel)  # [M', K, 3]
    if far.sum() >= 4:
        g = g - (arr.mean(axis=0, where=far[:, None, None]) @ bn)[None]
    z = np.einsum("bk,mka->mab", bk, g)  # [M', 3, 3]
    # windowed DTFT of a unit tone at (f1, f2), seen at the offsets: the fitted tone's footprint
    kernel = np.outer(np.exp(-2j * np.pi * np.outer(offs1, n_idx)) @ wn,
                      np.exp(-2j * np.pi * np.outer(offs2, k_idx)) @ wk)  # [3, 3]
    resid = z - (z[:, 1, 1] / kernel[1, 1])[:, None, None] * kernel[None]
    window_noise = cell_noise * float(np.sum(wn**2) * np.sum(wk**2)) / (k * n)
    stat = (np.abs(resid) ** 2).sum(axis=0) / window_noise  # [3, 3]
    stat[1, 1] = 0.0
    thr = float(scipy.special.gammainccinv(sel.size, pfa / 8.0))
    best = float(stat.max())
    return (best, thr) if best > thr else None
