"""The two estimators of :func:`dsp.self_localize`, each as its steps: estimate, 1σ bounds, residual tone.

``"paper"`` is the seed paper's method (best beam by P_ave, its grid peak: :func:`dsp.localize`);
``"refined"`` takes delay and Doppler off the grid from all beams and the AoD from a beam-pattern
fit (:func:`dsp.refine_estimate`). :data:`ESTIMATORS` maps each name to its :class:`Estimator`,
so that :func:`dsp.self_localize` chooses once and then runs the same chain for both
(``docs/estimation.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .aod_fit import AodFit, fit_aod
from .beamscan import BeamScan
from .crb import sweep_crb
from .detection import Detection
from .geometry import RisPose
from .localization import Localization, localize
from .pattern import BeamPattern
from .processing import ProcessingConfig
from .qualify import EstimatorBounds
from .radar import SPEED_OF_LIGHT, RadarConfig
from .refine import refine_estimate
from .residual import beam_dtft
from .sweep import BeamSweep

__all__ = ["SweepInputs", "SweepEstimate", "Estimator", "ESTIMATORS"]


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


def _paper_bounds(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, rho: float) -> EstimatorBounds:
    """The single-beam CRB plus the grid quantisation (step²/12) of delay, Doppler and AoD."""
    radar, sweep, pattern, processing = inp.radar, inp.sweep, inp.pattern, inp.processing
    m = inp.cube.shape[0]
    bound = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho,
                      beams=np.arange(m) == est.beam_index, phases="random")
    bound_all = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho, phases="random")
    grid_tau = radar.max_delay / processing.n_dft
    step_az = float(np.median(np.abs(np.diff(sweep.angles[:, 0])))) if m > 1 else 0.0
    sd_dist = float(np.hypot(bound.distance, grid_tau * SPEED_OF_LIGHT / 2 / np.sqrt(12)))
    grid_nu = 2 * radar.max_delay_rate / processing.k_dft
    sd_vel = float(np.hypot(bound.velocity, grid_nu * SPEED_OF_LIGHT / 2 / np.sqrt(12)))
    sd_az = float(np.hypot(bound_all.aod[0], step_az / np.sqrt(12)))
    return EstimatorBounds(distance=sd_dist, velocity=sd_vel, az=sd_az, el=bound_all.aod[1], kind="crb+grid")


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
    aod = np.array(est.aod.aod)
    amp2 = pattern.amplitude(aod, sweep.angles) ** 2
    times = radar.beam_times(arr.shape[0])
    beam_index = int(np.argmin(np.abs(sweep.angles[:, 0] - aod[0]) + np.abs(sweep.angles[:, 1] - aod[1])))
    return SweepEstimate(beam_index=beam_index, delay=est.delay, delay_rate=est.delay_rate, aod=aod, fit=est.aod,
                         magnitudes=est.beam_magnitude * (arr.shape[1] * arr.shape[2]), amplitude=est.amplitude,
                         time=float(amp2 @ times / amp2.sum()), beat_frequency=est.beat_frequency)


def _refined_bounds(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, rho: float) -> EstimatorBounds:
    """The sweep's CRB itself."""
    bound = sweep_crb(radar=inp.radar, sweep=inp.sweep, pattern=inp.pattern, aod=aod, peak_snr=rho, phases="random")
    return EstimatorBounds(distance=bound.distance, velocity=bound.velocity, az=float(bound.aod[0]), el=bound.aod[1],
                           kind="crb")


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
