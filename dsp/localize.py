"""The whole self-localization chain on a beat cube: :func:`self_localize` (Sec. III-B and III-C).

Detection (``dsp.detection``) -> the estimator's estimate (``dsp.estimators``: the paper's grid
peak or the refined one, chosen once) -> distance, reference time and a known height
(``dsp.qualify``) -> 1σ from the Cramér–Rao bound (``dsp.crb``) -> the flags (``dsp.flags``,
``docs/flags.md``; the AoD's 1σ widened by the pattern fit's excess under ``pattern-mismatch``) ->
the other candidates of the AoD fit (``Localization.alternatives``) -> :class:`Localization`.
Without a detection it presents no position. The result type and the paper's method on a scan,
:func:`localize`, are in ``dsp.localization``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Literal

import numpy as np

from .validation import finite, non_negative, positive
from .beamscan import scan_beams
from .detection import DEFAULT_PFA, Detection, check_beat_cube, detect_batch, detect_validated
from .drift import delay_drift, motion_rate
from .estimators import ESTIMATORS, SweepEstimate, SweepInputs
from .flags import GRATING_LOBE_DB, Flag, FlagContext, sweep_flags
from .floor_bounce import FloorLadder, floor_ladder, rung_spacing
from .impulses import screen_impulses
from .geometry import RisPose, direction_from_angles
from .localization import Alternative, Localization, NoPositionError, localize, no_position
from .moving_clutter import ClutterCancellation, cancel_moving_clutter
from .pattern import BeamPattern
from .processing import ProcessingConfig
from .aod_fit import PatternFit, pattern_fit
from .qualify import EstimatorBounds, Uncertainty, elevation_for_height, solve_elevation, sweep_uncertainty
from .radar import SPEED_OF_LIGHT, RadarConfig
from .residual import beam_values, residual_test
from .sweep import BeamSweep
from .xp import ArrayBackend, backend_of, is_host_array

__all__ = ["Localization", "NoPositionError", "localize", "self_localize"]

Estimator = Literal["paper", "refined"]

#: The refined estimator removes hall echoes that move with the radar (:func:`dsp.cancel_moving_clutter`) when
#: the return's delay rate turns its phase by at least this many cycles over the sweep, f_c |ν̂| T_sweep: one
#: cycle is the sweep's rate resolution, 6.4 mm/s of radial speed over a 0.39 s sweep at 60 GHz. Below it the
#: hall's echoes barely move from frame to frame and the static template removes them.
MOVING_CLUTTER_CYCLES = 1.0

#: ... and only when that rate is significant: at least this many of its own 1σ (the estimator's velocity bound at
#: the measured SNR). A static radar's rate is noise: at Table I's 0 dBm its σ is 1.4 cycles, so 55 % of static
#: sweeps crossed one cycle and were searched (0.15 s each on one core, and a host copy of a device cube) with
#: nothing found; three σ leaves 0.3 % of them.
MOVING_CLUTTER_SIGMAS = 3.0

#: An estimator's 1σ at the measured SNR (the ``bounds`` of :data:`dsp.estimators.ESTIMATORS`).
_Bounds = Callable[[SweepInputs, SweepEstimate, np.ndarray, float], EstimatorBounds]

#: The fastest motion across the RIS-radar line the ``pattern-mismatch`` test lets the AoD follow during a
#: sweep [m/s] (walking pace: 1 m/s across a 13.4 m leg turns the AoD 2.6° over a 1.2 s sweep; the
#: bound keeps a drift from mimicking a wrong pattern's width, which needs 8.7 m/s for a wrong mode
#: at 20 ms frames).
MAX_CROSS_SPEED = 2.0


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
    backend: ArrayBackend | None = None,
    detection: Detection | None = None,
    floor_height: float | None = None,
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
        no beam's grid maximum can be screened). The paper's estimator then searches only the
        beams that can be the best (:func:`dsp.scan_beams` ``best_only``: the same estimate and
        flags, ``scan`` None).
    backend : dsp.xp.ArrayBackend, optional
        Where the whole-cube work runs (``dsp.backend_for("cuda")`` for a GPU): the detector
        (:func:`dsp.detect_batch`) and every read of the cube by the estimators and the flags
        (:func:`dsp.dtft_subspace.contract_samples` and its siblings: small results come back).
        A host cube is copied there once. Default: where ``cube`` lives (NumPy for host data; a
        CuPy or array_api_strict cube stays on its device), the paper's grid search
        (:func:`dsp.scan_beams`: :mod:`dsp.devicegrid` on a device) included.
    detection : Detection, optional
        This cube's detection, already made by :func:`dsp.detect_batch` with the same ``pfa``,
        ``processing.min_range``, ``pattern``, ``sweep`` and ``oversample=2`` (a study's batch); it is
        then not computed again, and the cube is not screened for impulsive samples (the detection
        was made on it as given). Without it, lone ADC samples more than 20 dB above their chirp's
        median power (glitches: no beat signal reaches that) are zeroed first
        (:func:`dsp.impulses.screen_impulses`) and the flag ``impulsive-samples`` says how many and where.
    floor_height : float, optional
        World z of a floor under the radar and the RIS [m] (0 in a traced hall): the floor's ladder of
        the RIS return is read around the estimate (:func:`dsp.floor_bounce.floor_ladder`). When an
        earlier rung holds the straight leg, the refined estimator starts again there and takes the
        first arrival (flag ``first-arrival``); the paper's estimator keeps its peak (flag
        ``floor-leg``, its distance 1σ widened by the rungs it may be too long). Either way the
        distance 1σ includes the bias the rungs beside the estimate cause. None: no floor is modelled.

    Returns
    -------
    Localization
        With ``detection``, ``std``, ``flags`` and ``alternatives``; without a detection no position (NaN).
    """
    inp, ue_height, height_range = _checked(cube, sweep=sweep, radar=radar, processing=processing, pose=pose,
                                            loopback_delay=loopback_delay, estimator=estimator, pattern=pattern,
                                            pfa=pfa, ue_height=ue_height, height_range=height_range, scan=scan)
    steps = ESTIMATORS[estimator]
    # Pattern-matched windows on a half-bin grid (dsp.detect): 2 dB less SNR needed than the
    # whole-sweep test, and an off-grid return loses < 0.9 dB per axis instead of up to 3.9 dB.
    if backend is not None and not backend.is_numpy and is_host_array(inp.cube):
        # one explicit host -> device copy: the detector and the estimator's whole-cube reads run there
        inp = dataclasses.replace(inp, cube=backend.asarray(inp.cube))
    impulses = None
    if detection is None:  # a detection passed in was made on the cube as given (dsp.detect_batch: the studies)
        cube, impulses = screen_impulses(inp.cube)  # lone glitched ADC samples zeroed (dsp.impulses)
        if impulses.count:
            inp = dataclasses.replace(inp, cube=cube)
    if detection is not None:
        if not isinstance(detection, Detection):
            raise TypeError(f"detection must be a dsp.Detection (from dsp.detect_batch), got {type(detection).__name__}")
        det = detection
    elif is_host_array(inp.cube):
        det = detect_validated(inp.cube, radar, pfa=pfa, min_range=processing.min_range, max_candidates=5,
                               pattern=inp.pattern, sweep=sweep, oversample=2)
    else:  # a few numbers per candidate come back from the device
        on = backend_of(inp.cube)
        det = detect_batch(on.xp.expand_dims(inp.cube, axis=0), radar, backend=on, pfa=pfa,
                           min_range=processing.min_range, max_candidates=5, pattern=inp.pattern, sweep=sweep,
                           oversample=2)[0]
    # the paper's grid search runs where the cube is (dsp.devicegrid on a device): M results come back
    # scan=False: only the beams that can be the best are searched (the result keeps no scan)
    grid = scan_beams(inp.cube, sweep, radar, processing, best_only=not scan) if scan or steps.needs_scan else None
    if not det.detected:
        loc = no_position(grid, det)
        if not scan:
            loc = dataclasses.replace(loc, scan=None)
        if impulses is not None and impulses.count:
            loc = dataclasses.replace(loc, flags=loc.flags + (Flag("impulsive-samples", impulses.describe()),))
        return loc
    est = steps.estimate(inp, det, grid)
    floor_height = None if floor_height is None else finite(floor_height, "floor_height", "m")
    floor, moved = None, False
    if floor_height is not None:
        est, floor, moved = _first_arrival(inp, det, grid, est, estimator, floor_height, ue_height)
    clutter = _moving_clutter(inp, det, est, steps.bounds) if estimator == "refined" else None
    if clutter is not None and clutter.removed:  # the estimate again, on the cube without them
        inp = dataclasses.replace(inp, cube=clutter.cube)
        est = steps.estimate(inp, det, grid)
        if floor_height is not None:
            est, floor, moved = _first_arrival(inp, det, grid, est, estimator, floor_height, ue_height)

    distance = (est.delay - inp.loopback_delay) * SPEED_OF_LIGHT / 2.0
    velocity = est.delay_rate * SPEED_OF_LIGHT / 2.0
    t_ref = est.time
    if reference_time is not None:
        t_ref = finite(reference_time, "reference_time", "s")
        distance += velocity * (t_ref - est.time)
    aod, height_solved = solve_elevation(sweep, pose, distance, est.aod, ue_height)
    if est.located is not None and ue_height is None and reference_time is None:
        direction, position = est.located.direction, est.located.position  # bit-identical to localize()
    else:
        direction = pose.to_world(direction_from_angles(aod))
        position = pose.position + distance * direction

    std = _uncertainty(inp, est, det, steps.bounds, aod, distance, ue_height if height_solved else None,
                       extra_distance_std=_floor_distance_std(floor, moved))
    context = _flag_context(inp, est, det, steps.residual_frequency, aod, distance, ue_height=ue_height,
                            height_solved=height_solved, height_range=height_range, std=std)
    context = dataclasses.replace(context, floor=floor, floor_moved=moved, clutter=clutter, impulses=impulses)
    if context.pattern_fit is not None and context.pattern_fit.mismatch:
        std = _widened(std, inp.pose, aod, distance, context.pattern_fit.excess,
                       ue_height if height_solved else None)
        context = dataclasses.replace(context, std=std)
    return Localization(
        beam_index=est.beam_index, aod=aod, delay=float(est.delay), distance=float(distance),
        delay_rate=float(est.delay_rate), velocity=float(velocity), direction=direction, position=position,
        scan=grid if scan else None, detection=det, std=std, flags=sweep_flags(context), estimator=estimator,
        reference_time=float(t_ref),
        alternatives=_alternatives(inp, est, aod, distance, position, ue_height if height_solved else None),
    )


def _checked(cube: Any, *, sweep: BeamSweep, radar: RadarConfig, processing: ProcessingConfig, pose: RisPose,
             loopback_delay: float, estimator: str, pattern: BeamPattern | None, pfa: float, ue_height: float | None,
             height_range: float, scan: bool) -> tuple[SweepInputs, float | None, float]:
    """The arguments of :func:`self_localize`, checked in a fixed order: the inputs every step reads,
    ``ue_height`` [m] (or None) and ``height_range`` [m]. ``pfa`` is checked by the detector."""
    if not isinstance(pose, RisPose):
        raise TypeError(f"pose must be a RisPose, got {type(pose).__name__}")
    tau_rb = non_negative(loopback_delay, "loopback_delay", "s")
    if not isinstance(estimator, str) or estimator not in ESTIMATORS:
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
    if not isinstance(scan, bool):
        raise TypeError(f"scan={scan!r} must be True or False")
    inp = SweepInputs(cube=arr, sweep=sweep, radar=radar, processing=processing, pose=pose, loopback_delay=tau_rb,
                      pattern=pattern, pfa=pfa)
    return inp, ue_height, height_range


def _uncertainty(inp: SweepInputs, est: SweepEstimate, det: Detection,
                 bounds: _Bounds,
                 aod: np.ndarray, distance: float, solved_height: float | None, *,
                 extra_distance_std: float = 0.0) -> Uncertainty:
    """1σ from the CRB at the measured SNR, by the estimator's ``bounds``, per-beam phases random (what a
    phase-blind estimator can reach: 1.09x / 1.34x the fixed-phase CRB in distance / AoD at 10 dB); a
    bias the estimate may carry (``extra_distance_std`` [m], the floor's ladder) added to the distance's
    in quadrature before the position's is propagated."""
    b, rho = _bounds(inp, est, det, bounds, aod)
    if extra_distance_std > 0:
        b = dataclasses.replace(b, distance=float(np.hypot(b.distance, extra_distance_std)))
    return sweep_uncertainty(inp.pose, aod, distance, b, peak_snr=rho, solved_height=solved_height)


def _bounds(inp: SweepInputs, est: SweepEstimate, det: Detection,
            bounds: _Bounds,
            aod: np.ndarray) -> tuple[EstimatorBounds, float]:
    """The estimator's ``bounds`` at the measured peak SNR, and that SNR ρ [linear] (clipped to 1e-12…1e300)."""
    arr = inp.cube
    noise = det.noise_power
    peak_snr = arr.shape[1] * arr.shape[2] * est.amplitude**2 / noise if noise > 0 else np.inf
    rho = float(min(max(peak_snr, 1e-12), 1e300))
    return bounds(inp, est, aod, rho), rho


def _moving_clutter(inp: SweepInputs, det: Detection, est: SweepEstimate,
                    bounds: _Bounds,
                    ) -> ClutterCancellation | None:
    """The hall echoes moving with the radar near the return, found and removed over the sweep
    (:func:`dsp.cancel_moving_clutter`), when the return moves: its phase turns by at least
    :data:`MOVING_CLUTTER_CYCLES` over the sweep and by :data:`MOVING_CLUTTER_SIGMAS` of its own 1σ (the
    estimator's velocity ``bounds``); else None. A device cube's search runs on one host copy of it."""
    radar = inp.radar
    span = radar.sweep_duration(inp.cube.shape[0])
    cycles = radar.carrier_frequency * abs(est.delay_rate) * span
    if not (cycles >= MOVING_CLUTTER_CYCLES and det.noise_power > 0):
        return None
    sigma_rate = 2.0 * _bounds(inp, est, det, bounds, est.aod)[0].velocity / SPEED_OF_LIGHT  # [s/s]
    if not cycles >= MOVING_CLUTTER_SIGMAS * radar.carrier_frequency * sigma_rate * span:
        return None  # the rate is the noise's (a NaN or infinite σ: no evidence of motion either)
    weights = np.abs(inp.pattern.amplitude(est.aod, inp.sweep.angles))
    return cancel_moving_clutter(backend_of(inp.cube).to_host(inp.cube), radar, delay=est.delay,
                                 delay_rate=est.delay_rate, reference_time=est.time, weights=weights,
                                 noise_power=det.noise_power, pfa=inp.pfa)


def _pattern_check(inp: SweepInputs, f1: float, f2: float, weights: np.ndarray, noise_power: float, rate: float,
                   distance: float) -> PatternFit | None:
    """The beam pattern's fit to the per-beam values at the tone (:func:`dsp.aod_fit.pattern_fit`, the
    ``pattern-mismatch`` test), or None without a noise estimate."""
    if not noise_power > 0:
        return None
    radar = inp.radar
    times = radar.beam_times(inp.cube.shape[0])
    values, noise_gain = beam_values(inp.cube, radar, f1, f2, weights, drift_rate=rate, beam_times=times)
    return pattern_fit(np.abs(values), inp.sweep, inp.pattern, noise_variance=noise_power * noise_gain,
                       pfa=inp.pfa, beam_times=times, max_aod_rate=MAX_CROSS_SPEED / distance if distance > 0 else 0.0,
                       decide_only=True)


def _first_arrival(inp: SweepInputs, det: Detection, grid: Any, est: SweepEstimate, estimator: str,
                   floor_height: float, ue_height: float | None) -> tuple[SweepEstimate, FloorLadder | None, bool]:
    """The floor's ladder around ``est`` and, for the refined estimator, the estimate started again at the
    first arrival when an earlier rung holds it: (estimate, its ladder or None, whether it moved). The
    new start is kept when the refinement stays within ½ un-padded bin of it (the rung it was sent to)."""
    ladder = _ladder(inp, det, est, floor_height, ue_height)
    if ladder is None or ladder.steps_down == 0 or estimator != "refined":
        return est, ladder, False
    seed = est.delay - 2.0 * ladder.steps_down * ladder.spacing / SPEED_OF_LIGHT
    again = ESTIMATORS[estimator].estimate(inp, dataclasses.replace(det, delay=seed), grid)
    half_bin = 0.5 / (inp.radar.slope * inp.radar.sample_period * inp.cube.shape[2])
    if not abs(again.delay - seed) <= half_bin:
        return est, ladder, False
    return again, _ladder(inp, det, again, floor_height, ue_height) or ladder, True


def _ladder(inp: SweepInputs, det: Detection, est: SweepEstimate, floor_height: float,
            ue_height: float | None) -> FloorLadder | None:
    """:func:`dsp.floor_bounce.floor_ladder` at the estimate's position (None without a noise estimate or a
    radar above the floor)."""
    distance = (est.delay - inp.loopback_delay) * SPEED_OF_LIGHT / 2.0
    aod, _ = solve_elevation(inp.sweep, inp.pose, distance, est.aod, ue_height)
    position = inp.pose.position + distance * inp.pose.to_world(direction_from_angles(aod))
    spacing = rung_spacing(inp.pose.position, position, floor_height)
    if not (spacing > 0 and det.noise_power > 0 and distance > 0):
        return None
    weights = np.abs(inp.pattern.amplitude(aod, inp.sweep.angles))
    return floor_ladder(inp.cube, inp.radar, delay=est.delay, delay_rate=est.delay_rate, weights=weights,
                        spacing=spacing, noise_power=det.noise_power, pfa=inp.pfa)


def _floor_distance_std(floor: FloorLadder | None, moved: bool) -> float:
    """The distance 1σ the floor's ladder adds [m]: the bias of the rungs beside the estimate, and when the
    estimate stays on a later rung (the paper's estimator), the rungs it may be too long by."""
    if floor is None:
        return 0.0
    late = 0.0 if moved else floor.steps_down * floor.spacing
    return float(np.hypot(floor.bias_std, late))


def _flag_context(inp: SweepInputs, est: SweepEstimate, det: Detection,
                  residual_frequency: Callable[[SweepInputs, SweepEstimate], tuple[float, float]],
                  aod: np.ndarray, distance: float, *, ue_height: float | None, height_solved: bool,
                  height_range: float, std: Uncertainty | None = None) -> FlagContext:
    """What the flag rules read: the estimate, the residual test at the estimator's tone, the delay's drift."""
    arr, radar = inp.cube, inp.radar
    weights = np.abs(inp.pattern.amplitude(aod, inp.sweep.angles))
    f1, f2 = residual_frequency(inp, est)
    drift = delay_drift(arr, radar, delay=est.delay, delay_rate=est.delay_rate, weights=weights)
    rate = motion_rate(radar, est.delay_rate, drift)
    unresolved = _unresolved(inp, f1, f2, weights, det.noise_power, rate)
    fit = _pattern_check(inp, f1, f2, weights, det.noise_power, rate, distance)
    return FlagContext(detection=det, fit=est.fit, magnitudes=est.magnitudes, sweep=inp.sweep, radar=radar,
                       pose=inp.pose, delay=est.delay, apparent_delay=f1 / (radar.slope * radar.sample_period),
                       delay_rate=est.delay_rate, loopback_delay=inp.loopback_delay, distance=distance, aod=aod,
                       unresolved=unresolved, ue_height=ue_height, height_solved=height_solved,
                       height_range=height_range, drift=drift, std=std, pattern_fit=fit, pattern=inp.pattern)


def _unresolved(inp: SweepInputs, f1: float, f2: float, weights: np.ndarray, noise_power: float,
                rate: float) -> tuple[float, float] | None:
    """The residual test (:func:`dsp.residual_test`) under both models of the return: the same tone in
    every beam (eq. (1), frozen geometry) and, when the radar moves (ν ≠ 0), a tone whose delay
    follows the motion across the sweep, τ + ν (t_m − t̄) at each beam's frame time. A second return
    is one neither explains: the flag needs both to fire, and reports the moving model's residual."""
    arr, radar = inp.cube, inp.radar
    cell_noise = noise_power * arr.shape[1] * arr.shape[2]
    frozen = residual_test(arr, radar, f1, f2, weights, cell_noise=cell_noise, pfa=inp.pfa)
    if frozen is None or rate == 0.0:
        return frozen
    return residual_test(arr, radar, f1, f2, weights, cell_noise=cell_noise, pfa=inp.pfa, drift_rate=rate,
                         beam_times=radar.beam_times(arr.shape[0]))


def _alternatives(inp: SweepInputs, est: SweepEstimate, aod: np.ndarray, distance: float, position: np.ndarray,
                  solved_height: float | None) -> tuple[Alternative, ...]:
    """Every other AoD the beam-pattern fit (``est.fit``) allows: its maxima in the span within
    ``GRATING_LOBE_DB`` of the best (those ``grating-lobe`` names; weaker ones are sidelobe wiggles of
    the noise) and the estimate's grating-lobe twins beyond the span; at the estimated distance, the
    elevation as the estimate's (or solved from the height). Strongest first."""
    fit, sweep, pose, pattern = est.fit, inp.sweep, inp.pose, inp.pattern
    u_of = lambda a: float(np.cos(a[1]) * np.sin(a[0]))  # noqa: E731
    u_est = u_of(aod)
    u_span = np.cos(sweep.angles[:, 1]) * np.sin(sweep.angles[:, 0])
    span = f"[{np.rad2deg(sweep.angles[:, 0].min()):+.1f}°, {np.rad2deg(sweep.angles[:, 0].max()):+.1f}°]"
    rows = [(a, lvl, "fit-maximum", None) for a, lvl in fit.candidates if lvl >= -GRATING_LOBE_DB]
    rows += [(a, lvl, "grating-twin", bool(searched)) for a, lvl, searched in fit.twins]
    if abs(u_of(fit.aod) - u_est) > 0.5 * pattern.null_width:  # the paper's beam is not the fit's maximum
        rows.append((float(fit.aod[0]), 0.0, "fit-maximum", None))
    out = []
    for az, level, kind, searched in rows:
        cand = np.array([az, aod[1]], dtype=float)
        if abs(u_of(cand) - u_est) <= 0.5 * pattern.null_width:
            continue  # the estimate itself
        if solved_height is not None:
            cand, _ = solve_elevation(sweep, pose, distance, cand, solved_height)
        where = pose.position + distance * pose.to_world(direction_from_angles(cand))
        if kind == "grating-twin":
            reason = (f"grating-lobe twin of the estimate ({round(level, 2) + 0.0:+.2f} dB: the beam powers cannot tell them "
                      f"apart) beyond the swept span {span}"
                      + (": the fit prefers the one inside the span" if searched else
                         ", outside the fit's search range (the span ± one null width)"))
        elif u_span.min() <= u_of(cand) <= u_span.max() and level >= 0.0:
            reason = "the beam-pattern fit's maximum; the paper's estimator takes the beam of highest P_ave"
        else:
            reason = f"another maximum of the beam-pattern fit, {-level:.1f} dB below the estimate's"
        out.append(Alternative(aod=cand, position=where, level_db=float(level), kind=kind, reason=reason,
                               offset=float(np.linalg.norm(where - position))))
    return tuple(sorted(out, key=lambda a: -a.level_db))


def _widened(std: Uncertainty, pose: RisPose, aod: np.ndarray, distance: float, factor: float,
             solved_height: float | None) -> Uncertainty:
    """``std`` with the AoD's 1σ times ``factor`` (``pattern-mismatch``: sqrt(T) of the pattern fit) and the
    position's AoD part with it: σ_p² + (factor² − 1) (∂p/∂az σ_az)² (and el when it is finite), the
    derivative by central differences [m/rad] (along u with the elevation re-solved when the height
    was given)."""
    sd_az, sd_el = float(std.aod[0]), float(std.aod[1])
    if not np.isfinite(sd_az) or factor <= 1.0:
        return std
    h = 1e-6

    def place(az: float, el: float) -> np.ndarray:
        if solved_height is not None:
            u = float(np.cos(el) * np.sin(az))
            sol = elevation_for_height(pose, distance, u, solved_height, near=float(aod[1]))
            az, el = sol if sol is not None else (az, el)
        return pose.position + distance * pose.to_world(direction_from_angles(np.array([az, el])))

    az0, el0 = float(aod[0]), float(aod[1])
    extra = ((place(az0 + h, el0) - place(az0 - h, el0)) / (2 * h) * sd_az) ** 2
    if np.isfinite(sd_el) and solved_height is None:
        extra = extra + ((place(az0, el0 + h) - place(az0, el0 - h)) / (2 * h) * sd_el) ** 2
    position = np.sqrt(np.square(std.position) + (factor**2 - 1.0) * extra)
    aod_sd = np.array([sd_az * factor, sd_el * factor if solved_height is None else sd_el])
    return dataclasses.replace(std, aod=aod_sd, position=position)
