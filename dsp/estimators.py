"""The two estimators of :func:`dsp.self_localize`, each as its steps: estimate, 1σ bounds, residual tone.

``"paper"`` is the seed paper's method (best beam by P_ave, its grid peak: :func:`dsp.localize`);
``"refined"`` takes delay and Doppler off the grid from all beams and the AoD from a beam-pattern
fit (:func:`dsp.refine_estimate`). :data:`ESTIMATORS` maps each name to its :class:`Estimator`,
so that :func:`dsp.self_localize` chooses once and then runs the same chain for both
(``docs/estimation.md``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.special

from .aod_fit import AodFit, fit_aod
from .beamscan import BeamScan
from .crb import sweep_crb, window_factors
from .detection import Detection
from .geometry import RisPose
from .localization import Localization, localize
from .pattern import BeamPattern
from .processing import ProcessingConfig, window_vector
from .qualify import EstimatorBounds
from .radar import SPEED_OF_LIGHT, RadarConfig
from .refine import RefinedEstimate, refine_estimate
from .drift import delay_drift, motion_rate
from .dtft_subspace import contract_chirps, dtft_phasors
from .residual import beam_dtft, beam_values, drift_shifts
from .sweep import BeamSweep

__all__ = ["SweepInputs", "SweepEstimate", "Estimator", "ESTIMATORS", "debiased_peak_snr", "beam_choice_std"]


@dataclass(frozen=True, eq=False)
class SweepInputs:
    """What every step of :func:`dsp.self_localize` reads, validated.

    Attributes
    ----------
    cube : complex array [M, K, N]
        Beat samples (beams, chirps, samples) [√W], through :func:`dsp.check_beat_cube`.
    sweep : BeamSweep
    radar : RadarConfig
    processing : ProcessingConfig
    pose : RisPose
    loopback_delay : float
        τ_RB [s].
    pattern : BeamPattern
        The RIS array factor at the radar's wavelength.
    pfa : float
        False-alarm probability per capture [unitless].
    """

    cube: np.ndarray
    sweep: BeamSweep
    radar: RadarConfig
    processing: ProcessingConfig
    pose: RisPose
    loopback_delay: float
    pattern: BeamPattern
    pfa: float


@dataclass(frozen=True, eq=False)
class SweepEstimate:
    """One estimator's numbers for a detected return, before distance, uncertainty and flags.

    Attributes
    ----------
    beam_index : int
        The best beam (paper), or the beam nearest the fitted AoD (refined).
    delay : float
        τ̂, corrected for range-Doppler coupling [s].
    delay_rate : float
        ν̂ [s/s].
    aod : float array [2]
        ``[az, el]`` [rad], RIS frame.
    fit : AodFit
        The beam-pattern fit of the AoD (the paper's estimator fits it for the flags only).
    magnitudes : float array [M]
        Per-beam magnitude of the return [√W·K·N].
    amplitude : float
        β̂, the return's amplitude at the pattern peak [√W].
    time : float
        The time the estimate refers to, from the start of the sweep's first frame [s].
    beat_frequency : (float, float)
        (f₁, f₂) the magnitudes were taken at [cycles/sample] (the paper's: its grid peak).
    located : Localization or None
        The paper's :func:`dsp.localize` result (its direction and position are reused as they
        are when nothing moves them); None for the refined estimator.
    delay_variance_factor : float
        What the estimator's own processing multiplies the variance of τ̂ and ν̂ by beyond the
        bound (the refined estimator's static template, :func:`dsp.refine.template_variance_factor`);
        1 for the paper's (its window is in its bounds) [unitless].
    """

    beam_index: int
    delay: float
    delay_rate: float
    aod: np.ndarray
    fit: AodFit
    magnitudes: np.ndarray
    amplitude: float
    time: float
    beat_frequency: tuple[float, float]
    located: Localization | None = None
    delay_variance_factor: float = 1.0


@dataclass(frozen=True)
class Estimator:
    """The steps of one estimator.

    Attributes
    ----------
    needs_scan : bool
        Whether :meth:`estimate` reads the paper's per-beam grid search (:func:`dsp.scan_beams`).
    estimate : callable
        ``(inputs, detection, scan) -> SweepEstimate``.
    bounds : callable
        ``(inputs, estimate, aod, peak_snr) -> EstimatorBounds``: 1σ at the (possibly height-solved)
        AoD [rad] and the measured peak SNR [linear].
    residual_frequency : callable
        ``(inputs, estimate) -> (f₁, f₂)`` [cycles/sample]: where the residual test removes the tone.
    """

    needs_scan: bool
    estimate: Callable[[SweepInputs, Detection, "BeamScan | None"], SweepEstimate]
    bounds: Callable[[SweepInputs, SweepEstimate, np.ndarray, float], EstimatorBounds]
    residual_frequency: Callable[[SweepInputs, SweepEstimate], "tuple[float, float]"]


def _paper_estimate(inp: SweepInputs, det: Detection, grid: BeamScan | None) -> SweepEstimate:
    """The best beam's grid peak (:func:`dsp.localize`), its pattern fit and amplitude."""
    arr, sweep, radar, pattern = inp.cube, inp.sweep, inp.radar, inp.pattern
    loc = localize(grid, radar=radar, pose=inp.pose, loopback_delay=inp.loopback_delay)
    tau, nu, aod = loc.delay, loc.delay_rate, np.array(loc.aod)
    mags, f1, f2 = beam_dtft(arr, radar, tau, nu)
    fit = fit_aod(mags, sweep, pattern, elevation=float(aod[1]))
    amp = np.abs(pattern.amplitude(aod, sweep.angles))
    beta = float(amp @ mags / (amp @ amp)) / (arr.shape[1] * arr.shape[2])
    times = radar.beam_times(arr.shape[0])
    return SweepEstimate(beam_index=loc.beam_index, delay=tau, delay_rate=nu, aod=aod, fit=fit, magnitudes=mags,
                         amplitude=beta, time=float(times[loc.beam_index]), beat_frequency=(f1, f2), located=loc)


def debiased_peak_snr(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, rho: float) -> float:
    """The peak SNR with the noise's share of the beams' magnitudes removed [linear].

    The measured ρ̂ = K N β̂²/σ̂² takes β̂ from the magnitudes r_m = |Z_m|, and E[r_m] exceeds the
    tone's b A_m by the noise (Rice): ρ̂ is biased high, by 9 % at Table I's 0 dBm (17.8 dB),
    which states every σ 4.5 % too small. Since E[r_m²] = b² A_m² + s² (s² = K N σ², b = K N β),

        ρ̃ = Σ_m A_m² (r_m² − s²) / (s² Σ_m A_m⁴)

    is unbiased (Table I, 0 dBm, 30 captures: ρ̃/ρ = 0.99 ± 0.02 against ρ̂/ρ = 1.09). σ̂² is
    recovered from ρ̂ and β̂ (σ̂² = K N β̂²/ρ̂: what :func:`dsp.self_localize` measured).

    Parameters
    ----------
    inp : SweepInputs
    est : SweepEstimate
        Its ``magnitudes`` r_m [√W·K·N] and ``amplitude`` β̂ [√W].
    aod : float array [2]
        Where the pattern A_m is evaluated [rad].
    rho : float
        ρ̂ [linear].

    Returns
    -------
    float
        ρ̃ in [1e-12, 1e300]; ρ̂ itself when β̂ or ρ̂ is not finite and positive.
    """
    kn = inp.cube.shape[1] * inp.cube.shape[2]
    beta = float(est.amplitude)
    if not (np.isfinite(beta) and beta > 0 and np.isfinite(rho) and rho > 0):
        return rho
    s2 = (kn * beta) ** 2 / rho
    a2 = inp.pattern.amplitude(aod, inp.sweep.angles) ** 2
    r2 = np.asarray(est.magnitudes, dtype=float) ** 2
    den = s2 * float(a2 @ a2)
    if not den > 0:
        return rho
    return float(min(max(float(a2 @ (r2 - s2)) / den, 1e-12), 1e300))


#: :func:`beam_choice_std`: beams on each side of the chosen one that may win, truth positions per cell,
#: magnitude quadrature points, and the SNR above which the choice is the nearest beam (noise < 10⁻⁴ of a step).
_CHOICE_NEIGHBOURS, _CHOICE_POINTS, _CHOICE_NODES, _CHOICE_MAX_SNR = 8, 12, 240, 1e8
#: Above this ν (a beam's amplitude over the noise's) the Rice distribution is taken as Gaussian.
_CHOICE_GAUSSIAN = 8.0
#: Range migration across the sweep, in un-padded fast-time bins, above which the refined AoD is fitted
#: again on every beam at its own drifted tone [bins] (:func:`_migrated`).
MIGRATION_REFIT_BINS = 0.25
#: The refined estimator's beams in its delay step: |A_m| at least this fraction of the peak (``refine_estimate``'s
#: ``min_weight``) [unitless].
REFINE_MIN_WEIGHT = 0.05


def beam_choice_std(pattern: BeamPattern, sweep: BeamSweep, beam: int, snr: float) -> float:
    """RMS azimuth error of choosing the strongest beam, the truth anywhere in the chosen beam's cell [rad].

    Each beam's statistic is modelled as a tone in noise, |X_m| with X_m = √ρ_w A_m(θ) + CN(0, 1):
    Rician, independent across beams (separate frames). The probability that beam j is the
    strongest is P_j(θ) = ∫ f_j(x) Π_{i≠j} F_i(x) dx (f, F the Rice density and distribution,
    F from the non-central χ² of 2|X|²), over the chosen beam's neighbours on its elevation row;
    then

        σ² = mean over θ in the cell of Σ_j P_j(θ) (θ_j − θ)²,

    the truth's position in its cell taken uniform (what the estimate cannot tell). At high SNR
    this is Δ²/12, the grid's quantisation; at low SNR it adds the jumps to neighbouring beams,
    several beams wide at Table I's 0 dBm, where a linearised boundary noise overstates them.

    Parameters
    ----------
    pattern : BeamPattern
        At the radar's wavelength.
    sweep : BeamSweep
    beam : int
        The chosen beam.
    snr : float
        ρ_w: the SNR of a beam steered exactly at the UE in the statistic that chooses (the
        paper's P_ave: ρ times the window's energy and peak factors, :func:`dsp.crb.window_factors`)
        [linear]; above 10⁸ it is taken as 10⁸ (the choice is then the nearest beam).

    Returns
    -------
    float
        σ [rad]; 0 for a beam without neighbours on its row.
    """
    ang = sweep.angles
    row = np.flatnonzero(np.abs(ang[:, 1] - ang[beam, 1]) < 1e-12)
    row = row[np.argsort(ang[row, 0], kind="stable")]
    pos = int(np.flatnonzero(row == beam)[0])
    cand = row[max(0, pos - _CHOICE_NEIGHBOURS): pos + _CHOICE_NEIGHBOURS + 1]
    if cand.size < 2:
        return 0.0
    az = ang[cand, 0]
    j = int(np.flatnonzero(cand == beam)[0])
    lo = (az[j] - az[j - 1]) / 2 if j > 0 else (az[j + 1] - az[j]) / 2
    hi = (az[j + 1] - az[j]) / 2 if j + 1 < az.size else lo
    frac = (np.arange(_CHOICE_POINTS) + 0.5) / _CHOICE_POINTS
    thetas = az[j] - lo + frac * (lo + hi)  # midpoints of equal parts of the cell
    amp = np.sqrt(min(max(float(snr), 0.0), _CHOICE_MAX_SNR))
    sq = []
    for t in thetas:
        nu = amp * np.abs(pattern.amplitude(np.array([t, ang[beam, 1]]), ang[cand]))  # [C] in units of the noise
        top = float(nu.max())
        live = nu > top - 12.0  # the others are below every node: density 0, distribution 1
        nu_l, az_l = nu[live], az[live]
        x = np.linspace(max(0.0, top - 12.0), top + 8.0, _CHOICE_NODES)  # |X|; σ per component 1/√2
        # Rice density of |X| with E|noise|² = 1: 2x exp(-(x - ν)²) I0e(2xν); distribution via ncx2 of 2|X|²
        dens = 2 * x[None] * np.exp(-((x[None] - nu_l[:, None]) ** 2)) * scipy.special.i0e(2 * x[None] * nu_l[:, None])
        if x[0] == 0.0:  # the nodes span the whole support: the distribution is the density's integral
            dist = np.clip(scipy.integrate.cumulative_trapezoid(dens, x, axis=1, initial=0.0), 0.0, 1.0)
        else:
            dist = np.empty_like(dens)
            big = nu_l > _CHOICE_GAUSSIAN
            # far above the noise the Rice law is N(ν + 1/(4ν), 1/2) to O(1/ν²); chndtr is slow there
            dist[big] = scipy.special.ndtr((x[None] - nu_l[big, None] - 0.25 / nu_l[big, None]) * np.sqrt(2.0))
            dist[~big] = scipy.special.chndtr(2 * x[None] ** 2, 2, 2 * nu_l[~big, None] ** 2)
        logd = np.log(np.clip(dist, 1e-300, 1.0))
        others = np.exp(logd.sum(axis=0)[None] - logd)  # Π_{i≠j} F_i
        p = scipy.integrate.trapezoid(dens * others, x, axis=1)
        if not p.sum() > 0:
            p, az_l = np.ones(1), az[j:j + 1]
        sq.append(float((p / p.sum()) @ (az_l - t) ** 2))
    return float(np.sqrt(np.mean(sq)))


def _paper_bounds(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, rho: float) -> EstimatorBounds:
    """The paper estimator's 1σ: its windowed single-beam peak and its beam choice, each on its grid.

    Delay and Doppler: the Hann-windowed periodogram peak of the best beam (the single-beam
    random-phase bound times the window's variance factor per axis, :func:`dsp.crb.window_factors`:
    2.34 for Hann), then rounded to the N_DFT × K_DFT grid (+ step²/12). Azimuth: the RMS error of
    the best-beam choice, grid included (:func:`beam_choice_std` at the P_ave statistic's SNR). All at the debiased SNR (:func:`debiased_peak_snr`). Half of each grid step is
    reported as ``grid``: the largest quantisation error (``docs/estimation.md``).
    """
    radar, sweep, pattern, processing = inp.radar, inp.sweep, inp.pattern, inp.processing
    m, k, n = inp.cube.shape
    rho = debiased_peak_snr(inp, est, aod, rho)
    bound = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho,
                      beams=np.arange(m) == est.beam_index, phases="random")
    bound_all = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho, phases="random")
    var_fast, _, energy_fast = window_factors(window_vector(processing.window, n))
    var_slow, peak_slow, _ = window_factors(window_vector(processing.window, k))
    coupling = radar.carrier_frequency / radar.slope  # τ = f₁/(S T_s) − (f_c/S) ν [s]
    var_nu = var_slow * bound.delay_rate**2
    var_tau = var_fast * max(bound.delay**2 - (coupling * bound.delay_rate) ** 2, 0.0) + coupling**2 * var_nu
    grid_tau = radar.max_delay / processing.n_dft
    grid_nu = 2 * radar.max_delay_rate / processing.k_dft
    sd_dist = float(np.sqrt(var_tau + (grid_tau**2 + (coupling * grid_nu) ** 2) / 12)) * SPEED_OF_LIGHT / 2
    sd_vel = float(np.sqrt(var_nu + grid_nu**2 / 12)) * SPEED_OF_LIGHT / 2
    step_az = float(np.median(np.abs(np.diff(sweep.angles[:, 0])))) if m > 1 else 0.0
    row = np.abs(sweep.angles[:, 1] - sweep.angles[est.beam_index, 1]) < 1e-12
    if np.isfinite(bound_all.aod[0]) and np.ptp(sweep.angles[row, 0]) > 0:
        sd_az = beam_choice_std(pattern, sweep, est.beam_index, rho * energy_fast * peak_slow)
    else:  # no azimuth steps on the chosen beam's row (or an unobservable azimuth): the bound and the grid
        sd_az = float(np.hypot(bound_all.aod[0], step_az / np.sqrt(12)))
    half = ((grid_tau + coupling * grid_nu) * SPEED_OF_LIGHT / 4, grid_nu * SPEED_OF_LIGHT / 4, step_az / 2)
    return EstimatorBounds(distance=sd_dist, velocity=sd_vel, az=sd_az, el=bound_all.aod[1], kind="crb+grid",
                           grid=tuple(float(v) for v in half), peak_snr=rho)


def _paper_residual_frequency(inp: SweepInputs, est: SweepEstimate) -> tuple[float, float]:
    """The tone off the grid: the grid peak is off it by up to ¼ bin, which alone leaves a residual at
    high SNR; one refinement pass finds it (the paper's numbers are not changed)."""
    local = refine_estimate(inp.cube, sweep=inp.sweep, radar=inp.radar, pattern=inp.pattern,
                            initial_delay=est.delay, initial_delay_rate=est.delay_rate, passes=1)
    return local.beat_frequency


def _refined_estimate(inp: SweepInputs, det: Detection, grid: BeamScan | None) -> SweepEstimate:
    """Delay and Doppler off the grid from all beams, the AoD from the pattern fit (:func:`dsp.refine_estimate`)."""
    arr, sweep, radar, pattern = inp.cube, inp.sweep, inp.radar, inp.pattern
    est = refine_estimate(arr, sweep=sweep, radar=radar, pattern=pattern,
                          initial_delay=det.delay, initial_delay_rate=det.delay_rate)
    est = _migrated(inp, est)
    aod = np.array(est.aod.aod)
    amp2 = pattern.amplitude(aod, sweep.angles) ** 2
    times = radar.beam_times(arr.shape[0])
    beam_index = int(np.argmin(np.abs(sweep.angles[:, 0] - aod[0]) + np.abs(sweep.angles[:, 1] - aod[1])))
    return SweepEstimate(beam_index=beam_index, delay=est.delay, delay_rate=est.delay_rate, aod=aod, fit=est.aod,
                         magnitudes=est.beam_magnitude * (arr.shape[1] * arr.shape[2]), amplitude=est.amplitude,
                         time=float(amp2 @ times / amp2.sum()), beat_frequency=est.beat_frequency,
                         delay_variance_factor=est.delay_variance_factor)


def _migrated(inp: SweepInputs, est: RefinedEstimate) -> RefinedEstimate:
    """``est`` with its delay and AoD estimated again on every beam read at its own drifted tone, when the
    return's delay migrates across the sweep by more than :data:`MIGRATION_REFIT_BINS` (a radar moving
    0.9 m/s radially crosses 9 range cells of Table I's chirp in a 0.39 s sweep); else ``est`` itself.

    Read at one frequency, a migrating return misleads both: the beams scanned far from the
    pattern-weighted mean time t̄ sit bins away from it, and their sidelobe slopes pull the delay's
    maximum off the delay at t̄ when the beams are not spread evenly around it (1.6 mm, 2.2 ms of
    motion, 4.4 m from a RIS whose beam the radar crosses early in the sweep), while their uneven
    loss of magnitude moves the fitted AoD (0.32-0.37° at 12.5 m, 40° off broadside). Beam m is read
    at f₁ + S T_s ν (t_m − t̄) (:func:`dsp.residual.drift_shifts`, ν the Doppler unwrapped by the measured
    drift, :func:`dsp.drift.motion_rate`): f₁ maximizing Σ_m a_m |Z_m| then refers to t̄, the time the
    estimate states; the AoD is fitted on those |Z_m| (``docs/estimation.md``, range migration). Twice,
    t̄ and the beams' weights following the new AoD.
    """
    arr, radar, sweep = inp.cube, inp.radar, inp.sweep
    m, k, n = arr.shape
    times = radar.beam_times(m)
    f1, f2 = est.beat_frequency
    weights = np.abs(inp.pattern.amplitude(est.aod.aod, sweep.angles))
    rate = motion_rate(radar, est.delay_rate,
                       delay_drift(arr, radar, delay=est.delay, delay_rate=est.delay_rate, weights=weights))
    span = abs(radar.slope * radar.sample_period * rate * float(times[-1] - times[0])) * n
    if not span > MIGRATION_REFIT_BINS:
        return est
    sel = np.flatnonzero(weights >= REFINE_MIN_WEIGHT * weights.max())
    ek = dtft_phasors(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0]
    rows = contract_chirps(arr, ek, sel)  # [M', N]
    far = np.flatnonzero(weights < 0.1 * weights.max())
    if far.size >= 4:  # what is the same in every frame (static returns, leakage), as refine_estimate removes it
        rows = rows - contract_chirps(arr, ek, far).mean(axis=0)[None, :]
    n_idx = np.arange(n) - (n - 1) / 2.0
    fit, magnitudes = est.aod, None
    for _ in range(2):
        shift = drift_shifts(radar, rate, times, weights)[sel]
        a = weights[sel]

        def cost(x: float) -> float:
            return -float(a @ np.abs(np.sum(rows * _phasor_rows(x + shift, n_idx), axis=1)))

        f1 = float(scipy.optimize.minimize_scalar(cost, bounds=(f1 - 0.5 / n, f1 + 0.5 / n), method="bounded",
                                                  options={"xatol": 1e-6 / n}).x)
        values, _ = beam_values(arr, radar, f1, f2, weights, drift_rate=rate, beam_times=times, windowed=False)
        magnitudes = np.abs(values)
        fit = fit_aod(magnitudes, sweep, inp.pattern)
        weights = np.abs(inp.pattern.amplitude(fit.aod, sweep.angles))
    f1 = f1 % 1.0
    delay = f1 / (radar.slope * radar.sample_period) - radar.carrier_frequency * est.delay_rate / radar.slope
    kn = k * n
    return dataclasses.replace(est, delay=float(delay), beat_frequency=(f1, f2), aod=fit,
                               beam_magnitude=magnitudes / kn, amplitude=fit.amplitude / kn)


def _phasor_rows(freqs: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """exp(j2π f_m idx) for one frequency per row, phases reduced modulo 1 cycle first [M', L].

    Parameters
    ----------
    freqs : float array [M']
        One frequency per row [cycles/sample].
    idx : float array [L]
        Sample indices [samples].

    Returns
    -------
    complex array [M', L]
    """
    ph = np.outer(freqs, idx)
    return np.exp(2j * np.pi * (ph - np.round(ph)))


def _refined_bounds(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, rho: float) -> EstimatorBounds:
    """The sweep's random-phase CRB at the debiased SNR (:func:`debiased_peak_snr`), its distance and
    velocity times √F, F the static template's variance factor (``est.delay_variance_factor``)."""
    rho = debiased_peak_snr(inp, est, aod, rho)
    bound = sweep_crb(radar=inp.radar, sweep=inp.sweep, pattern=inp.pattern, aod=aod, peak_snr=rho, phases="random")
    f = float(np.sqrt(est.delay_variance_factor)) if est.delay_variance_factor > 0 else 1.0
    return EstimatorBounds(distance=bound.distance * f, velocity=bound.velocity * f, az=float(bound.aod[0]),
                           el=bound.aod[1], kind="crb", peak_snr=rho)


def _refined_residual_frequency(inp: SweepInputs, est: SweepEstimate) -> tuple[float, float]:
    """The refined estimate's own tone."""
    return est.beat_frequency


#: Estimator name -> its steps.
ESTIMATORS: dict[str, Estimator] = {
    "paper": Estimator(needs_scan=True, estimate=_paper_estimate, bounds=_paper_bounds,
                       residual_frequency=_paper_residual_frequency),
    "refined": Estimator(needs_scan=False, estimate=_refined_estimate, bounds=_refined_bounds,
                         residual_frequency=_refined_residual_frequency),
}
