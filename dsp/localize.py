"""AoD, distance, velocity and position of the UE from a beam scan (Sec. III-B and III-C).

:func:`localize` is the paper's method on a :class:`BeamScan`. :func:`self_localize` runs the
whole chain on a cube: detection (``dsp.detection``), the paper's estimate or the refined one
(``estimator="refined"``, ``dsp.refine``), the 1σ uncertainty from the Cramér–Rao bound
(``dsp.crb``) and the flags (``docs/flags.md``). Without a detection it presents no position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from .validation import finite, non_negative, positive
from .beamscan import BeamScan, scan_beams
from .crb import position_std, sweep_crb
from .drift import delay_drift
from .detection import DEFAULT_PFA, Detection, check_beat_cube, detect_validated
from .flags import Flag
from .geometry import RisPose, direction_from_angles
from .pattern import BeamPattern
from .processing import ProcessingConfig
from .qualify import Uncertainty, elevation_for_height, is_one_dimensional, sweep_flags
from .radar import SPEED_OF_LIGHT, RadarConfig
from .aod_fit import fit_aod
from .refine import refine_estimate
from .residual import beam_dtft, residual_test
from .sweep import BeamSweep

__all__ = ["Localization", "NoPositionError", "localize", "self_localize"]

Estimator = Literal["paper", "refined"]


class NoPositionError(ValueError):
    """Raised by :meth:`Localization.checked_position` when nothing was detected."""


@dataclass(frozen=True)
class Localization:
    """The UE's self-localization from one RIS sweep.

    Attributes
    ----------
    beam_index : int
        m̂, the beam with the largest average power.
    aod : float array [2]
        θ̂ = φ_m̂, ``[az, el]`` at the RIS, RIS frame [rad].
    delay : float
        τ̂: the peak delay of beam m̂, corrected for range-Doppler coupling,
        ``τ_m̂ - f_c ν̂ / S`` [s].
    distance : float
        d̂ = (τ̂ - τ_RB)·c/2, UE-RIS distance [m].
    delay_rate : float
        ν̂ [s/s].
    velocity : float
        v̂ = ν̂·c/2, radial velocity, positive when the UE-RIS distance grows [m/s].
    direction : float array [3]
        d(θ̂), unit vector from the RIS toward the UE, world frame.
    position : float array [3]
        x̂_UE = x_RIS + d̂ · d(θ̂), world frame [m].
    scan : BeamScan or None
        The paper's per-beam grid results (the estimate's source with the paper's estimator, the
        P_ave profile reports plot); None when :func:`self_localize` was asked not to compute it.
    detection : Detection or None
        The detector's outcome (:func:`self_localize`); None from :func:`localize`, which runs
        the paper's method on a scan without a detector.
    std : Uncertainty or None
        1σ of distance, velocity, AoD and position from the CRB at the measured SNR; None
        without a detection.
    flags : tuple of Flag
        Named warnings with cause and remedy (``docs/flags.md``).
    estimator : {"paper", "refined"}
        Which estimator produced the numbers.
    reference_time : float
        Time the position refers to, from the start of the sweep's first frame [s]
        (``docs/estimation.md``); NaN from :func:`localize`.

    Notes
    -----
    **No detection, no position.** When ``detection.detected`` is False, ``aod``, ``delay``,
    ``distance``, ``delay_rate``, ``velocity``, ``direction`` and ``position`` are all NaN
    (arithmetic on them stays NaN, comparisons are False), ``flags`` starts with
    ``no-detection`` and :meth:`checked_position` raises. ``beam_index`` then names the scan's
    strongest beam (for plots; without a scan the detector's strongest beam, -1 if it found no
    cell), not an AoD.
    """

    beam_index: int
    aod: np.ndarray
    delay: float
    distance: float
    delay_rate: float
    velocity: float
    direction: np.ndarray
    position: np.ndarray
    scan: BeamScan | None
    detection: Detection | None = None
    std: Uncertainty | None = None
    flags: tuple[Flag, ...] = ()
    estimator: str = "paper"
    reference_time: float = math.nan

    @property
    def detected(self) -> bool:
        """False when the detector found no RIS return (then every estimate is NaN)."""
        return self.detection is None or bool(self.detection.detected)

    @property
    def flag_codes(self) -> tuple[str, ...]:
        """The codes of :attr:`flags`."""
        return tuple(f.code for f in self.flags)

    def checked_position(self) -> np.ndarray:
        """The position [3] [m], or :class:`NoPositionError` when nothing was detected."""
        if not self.detected:
            raise NoPositionError("no RIS return was detected in this capture: there is no position "
                                  f"({'; '.join(str(f) for f in self.flags)})")
        return self.position


def localize(scan: BeamScan, *, radar: RadarConfig, pose: RisPose, loopback_delay: float) -> Localization:
    """Estimate the UE position from a :class:`BeamScan`.

    Parameters
    ----------
    scan : BeamScan
        Output of :func:`dsp.scan_beams`.
    radar : RadarConfig
        The radar that recorded the cube (for f_c and S).
    pose : RisPose
        Pose of the RIS whose beams were swept.
    loopback_delay : float
        τ_RB, the RIS's internal receive-to-transmit delay [s].

    Returns
    -------
    Localization
    """
    if not isinstance(scan, BeamScan):
        raise TypeError(f"scan must be a BeamScan from dsp.scan_beams, got {type(scan).__name__}")
    if not isinstance(pose, RisPose):
        raise TypeError(f"pose must be a RisPose, got {type(pose).__name__}")
    tau_rb = non_negative(loopback_delay, "loopback_delay", "s")
    m = scan.best_beam
    aod = np.array(scan.angles[m], dtype=float)
    nu = float(scan.delay_rate[m])
    tau = float(scan.delay[m]) - radar.carrier_frequency * nu / radar.slope
    distance = (tau - tau_rb) * SPEED_OF_LIGHT / 2.0
    direction = pose.to_world(direction_from_angles(aod))
    return Localization(
        beam_index=m,
        aod=aod,
        delay=tau,
        distance=float(distance),
        delay_rate=nu,
        velocity=nu * SPEED_OF_LIGHT / 2.0,
        direction=direction,
        position=pose.position + distance * direction,
        scan=scan,
    )


def self_localize(
    cube: Any,
    *,
    sweep: BeamSweep,
    radar: RadarConfig,
    processing: ProcessingConfig,
    pose: RisPose,
    loopback_delay: float,
    estimator: Estimator = "paper",
    pattern: BeamPattern | None = None,
    pfa: float = DEFAULT_PFA,
    ue_height: float | None = None,
    height_range: float = 1.0,
    reference_time: float | None = None,
    scan: bool = True,
) -> Localization:
    """Detect the RIS return in a beat cube ``[M, K, N]`` and localize the UE, with uncertainty and flags.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples (beams, chirps, samples) [√W]; M >= 2.
    sweep, radar, processing, pose, loopback_delay
        As :func:`scan_beams` and :func:`localize`.
    estimator : {"paper", "refined"}, default "paper"
        ``"paper"``: the paper's method (best beam by P_ave, grid peak), numbers identical to
        ``localize(scan_beams(...))``. ``"refined"``: delay/Doppler off the grid from all beams
        and the AoD from a beam-pattern fit (:func:`dsp.refine_estimate`).
    pattern : BeamPattern, optional
        The RIS array factor (for the refined AoD, the CRB and the flags); default
        ``BeamPattern()``: 16 × 4 relay RIS at λ/2, the paper's experiment.
    pfa : float, default 1e-3
        False-alarm probability per capture: an upper bound for the windowed, half-bin search
        used here (`dsp.detect` with ``pattern``, ``sweep``, ``oversample=2``).
    ue_height : float, optional
        Known world z of the radar [m]: for a 1-D sweep, the elevation is solved so that the
        position lies at that height (instead of assuming the sweep plane).
    height_range : float, default 1.0
        Height offset from the sweep plane [m] used to state the error of the
        ``elevation-assumed`` flag.
    reference_time : float, optional
        Move the distance to this time from the start of the sweep [s], with the measured
        radial velocity: ``d += v̂ (t - t_est)``. By default the position refers to t_est: the
        best beam's frame centre (paper) or the pattern-weighted mean frame time (refined).
    scan : bool, default True
        Run the paper's per-beam grid search for ``Localization.scan`` even when the refined
        estimator does not need it (reports plot its P_ave profile). ``False`` skips it with the
        refined estimator — every number of the result is the same, ``scan`` is None; a Monte
        Carlo study saves the search's cost (0.1-2 s per Table I cube, most at low SNR, where
        no beam's grid maximum can be screened). The paper's estimator always runs it.

    Returns
    -------
    Localization
        With ``detection``, ``std`` and ``flags``; without a detection no position (NaN).
    """
    if not isinstance(pose, RisPose):
        raise TypeError(f"pose must be a RisPose, got {type(pose).__name__}")
    tau_rb = non_negative(loopback_delay, "loopback_delay", "s")
    if estimator not in ("paper", "refined"):
        raise ValueError(f"estimator={estimator!r} must be 'paper' (the seed paper's method) or 'refined'")
    if not isinstance(sweep, BeamSweep):
        raise TypeError(f"sweep must be a BeamSweep, got {type(sweep).__name__}")
    if pattern is None:
        pattern = BeamPattern()
    if not isinstance(pattern, BeamPattern):
        raise TypeError(f"pattern must be a dsp.BeamPattern, got {type(pattern).__name__}")
    pattern = pattern.for_wavelength(radar.wavelength)
    if ue_height is not None:
        ue_height = finite(ue_height, "ue_height", "m")
    height_range = positive(height_range, "height_range", "m")
    arr = check_beat_cube(cube, radar)
    if sweep.num_beams != arr.shape[0]:
        raise ValueError(
            f"cube has {arr.shape[0]} beams (frames) but the sweep has {sweep.num_beams} angles; "
            "pass the BeamSweep the cube was recorded with"
        )
    # Pattern-matched windows on a half-bin grid (dsp.detect): 2 dB less SNR needed than the
    # whole-sweep test, and an off-grid return loses < 0.9 dB per axis instead of up to 3.9 dB.
    if not isinstance(scan, bool):
        raise TypeError(f"scan={scan!r} must be True or False")
    det = detect_validated(arr, radar, pfa=pfa, min_range=processing.min_range, max_candidates=5, pattern=pattern,
                          sweep=sweep, oversample=2)
    grid = scan_beams(arr, sweep, radar, processing) if scan or estimator == "paper" else None
    if not det.detected:
        return _no_position(grid, det)

    m = arr.shape[0]
    times = radar.beam_times(m)
    if estimator == "paper":
        loc = localize(grid, radar=radar, pose=pose, loopback_delay=tau_rb)
        tau, nu, aod = loc.delay, loc.delay_rate, np.array(loc.aod)
        mags, f1, f2 = beam_dtft(arr, radar, tau, nu)
        fit = fit_aod(mags, sweep, pattern, elevation=float(aod[1]))
        amp = np.abs(pattern.amplitude(aod, sweep.angles))
        beta = float(amp @ mags / (amp @ amp)) / (arr.shape[1] * arr.shape[2])
        t_est = float(times[loc.beam_index])
        beam_index = loc.beam_index
    else:
        est = refine_estimate(arr, sweep=sweep, radar=radar, pattern=pattern,
                              initial_delay=det.delay, initial_delay_rate=det.delay_rate)
        tau, nu, aod, fit = est.delay, est.delay_rate, np.array(est.aod.aod), est.aod
        mags = est.beam_magnitude * (arr.shape[1] * arr.shape[2])
        f1, f2 = est.beat_frequency
        beta = est.amplitude
        amp2 = pattern.amplitude(aod, sweep.angles) ** 2
        t_est = float(amp2 @ times / amp2.sum())
        beam_index = int(np.argmin(np.abs(sweep.angles[:, 0] - aod[0]) + np.abs(sweep.angles[:, 1] - aod[1])))

    distance = (tau - tau_rb) * SPEED_OF_LIGHT / 2.0
    velocity = nu * SPEED_OF_LIGHT / 2.0
    t_ref = t_est
    if reference_time is not None:
        t_ref = finite(reference_time, "reference_time", "s")
        distance += velocity * (t_ref - t_est)

    one_d = is_one_dimensional(sweep)
    height_solved = False
    if one_d and ue_height is not None and distance > 0:
        u = float(np.cos(aod[1]) * np.sin(aod[0]))
        sol = elevation_for_height(pose, distance, u, ue_height, near=float(aod[1]))
        if sol is not None:
            aod = np.array(sol)
            height_solved = True

    if estimator == "paper" and ue_height is None and reference_time is None:
        direction, position = loc.direction, loc.position  # bit-identical to localize()
    else:
        direction = pose.to_world(direction_from_angles(aod))
        position = pose.position + distance * direction

    # Uncertainty: the CRB at the measured SNR, per-beam phases random (what a phase-blind
    # estimator can reach: 1.09x / 1.34x the fixed-phase CRB in distance / AoD at 10 dB).
    noise = det.noise_power
    peak_snr = arr.shape[1] * arr.shape[2] * beta**2 / noise if noise > 0 else np.inf
    rho = float(min(max(peak_snr, 1e-12), 1e300))
    if estimator == "paper":
        bound = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho,
                          beams=np.arange(m) == beam_index, phases="random")
        bound_all = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho, phases="random")
        grid_tau = radar.max_delay / processing.n_dft
        step_az = float(np.median(np.abs(np.diff(sweep.angles[:, 0])))) if m > 1 else 0.0
        sd_dist = float(np.hypot(bound.distance, grid_tau * SPEED_OF_LIGHT / 2 / np.sqrt(12)))
        grid_nu = 2 * radar.max_delay_rate / processing.k_dft
        sd_vel = float(np.hypot(bound.velocity, grid_nu * SPEED_OF_LIGHT / 2 / np.sqrt(12)))
        sd_az = float(np.hypot(bound_all.aod[0], step_az / np.sqrt(12)))
        sd_el = bound_all.aod[1]
        kind = "crb+grid"
    else:
        bound = sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho, phases="random")
        sd_dist, sd_vel, sd_az, sd_el = bound.distance, bound.velocity, float(bound.aod[0]), bound.aod[1]
        kind = "crb"
    if one_d and height_solved:
        u0 = float(np.cos(aod[1]) * np.sin(aod[0]))
        sd_u = sd_az * abs(np.cos(aod[0]) * np.cos(aod[1]))

        def locate(p: np.ndarray) -> np.ndarray:
            s = elevation_for_height(pose, p[0], p[1], ue_height, near=float(aod[1]))
            a = s if s is not None else (float(aod[0]), float(aod[1]))
            return pose.position + p[0] * pose.to_world(direction_from_angles(np.array(a)))

        pos_sd = position_std(locate, [distance, u0], [sd_dist, sd_u])
        el_sd = float(np.linalg.norm(position_std(lambda p: np.array([elevation_for_height(
            pose, p[0], p[1], ue_height, near=float(aod[1]))[1], 0, 0]), [distance, u0], [sd_dist, sd_u])))
        aod_sd = np.array([sd_az, el_sd])
    else:
        pos_sd = position_std(
            lambda p: pose.position + p[0] * pose.to_world(direction_from_angles(p[1:3])),
            [distance, aod[0], aod[1]], [sd_dist, sd_az, sd_el])
        aod_sd = np.array([sd_az, sd_el])
    std = Uncertainty(distance=sd_dist, velocity=sd_vel, aod=aod_sd, position=pos_sd,
                      peak_snr_db=float(10 * np.log10(rho)), kind=kind)

    weights = np.abs(pattern.amplitude(aod, sweep.angles))
    if estimator == "paper":
        # The grid peak is off the tone by up to ¼ bin: at high SNR that alone leaves a residual.
        # Test at the off-grid frequencies instead (the paper's numbers are not changed).
        local = refine_estimate(arr, sweep=sweep, radar=radar, pattern=pattern, initial_delay=tau,
                                initial_delay_rate=nu, passes=1)
        f1, f2 = local.beat_frequency
    unresolved = residual_test(arr, radar, f1, f2, weights, cell_noise=noise * arr.shape[1] * arr.shape[2], pfa=pfa)
    apparent = f1 / (radar.slope * radar.sample_period)
    drift = delay_drift(arr, radar, delay=tau, delay_rate=nu, weights=weights)
    flags = sweep_flags(detection=det, fit=fit, magnitudes=mags, sweep=sweep, radar=radar, pose=pose, delay=tau,
                        apparent_delay=apparent, delay_rate=nu, loopback_delay=tau_rb, distance=distance, aod=aod,
                        unresolved=unresolved, ue_height=ue_height, height_solved=height_solved,
                        height_range=height_range, drift=drift)
    return Localization(
        beam_index=beam_index, aod=aod, delay=float(tau), distance=float(distance), delay_rate=float(nu),
        velocity=float(velocity), direction=direction, position=position, scan=grid, detection=det, std=std,
        flags=flags, estimator=estimator, reference_time=float(t_ref),
    )


def _strongest_beam(scan: BeamScan | None, det: Detection) -> int:
    """The scan's best beam, else the beam strongest in the detector's best cell (-1: none)."""
    if scan is not None:
        return scan.best_beam
    power = det.beam_power
    return int(np.argmax(power)) if power is not None and np.size(power) else -1


def _no_position(scan: BeamScan | None, det: Detection) -> Localization:
    """A Localization that carries the detection outcome and no numbers."""
    nan2, nan3 = np.full(2, np.nan), np.full(3, np.nan)
    if det.rejected:
        flag = Flag("no-beam-dependence",
                    f"{det.rejected} return(s) crossed the detection threshold ({det.threshold_db:.1f} dB) but none "
                    "follows the sweep: they are clutter, not the RIS; no position. Check that the RIS sweeps its "
                    "beam during the capture and that the frames are aligned with the sweep angles")
    else:
        flag = Flag("no-detection",
                    f"no beam-dependent return above the threshold: SNR {det.snr_db:.1f} dB (integrated over "
                    f"{det.integrated_beams} beams) < "
                    f"{det.threshold_db:.1f} dB at P_FA = {det.false_alarm_probability:g}; no position. Move closer, "
                    "raise the transmit power or the RIS gain, or accept a higher pfa")
    flags = (flag,) if flag.code == "no-detection" else (Flag("no-detection", "no RIS return detected: no position"), flag)
    return Localization(
        beam_index=_strongest_beam(scan, det), aod=nan2, delay=math.nan, distance=math.nan, delay_rate=math.nan,
        velocity=math.nan, direction=nan3, position=nan3, scan=scan, detection=det, std=None, flags=flags,
        estimator="none", reference_time=math.nan,
    )
