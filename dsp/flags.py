"""Named warnings attached to a localization or a capture inspection (``docs/flags.md``: cause and remedy of each).

One :class:`Flag` type serves both: a localization's flags (``dsp.Localization.flags``) and a raw
capture's inspection (``risloc_rt.measured.inspect_capture``, codes in :data:`INSPECTION_CODES`).

The flags of a detected estimate are a registry, as the scene checks' rules are
(``risloc_rt.authoring.issues.RULES``): each is a small rule over one :class:`FlagContext`,
registered in :data:`SWEEP_FLAG_RULES` in the order its flag is listed; :func:`sweep_flags` runs
them all. (``no-detection`` is not a rule: without a detection there is no estimate to qualify.)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .aod_fit import AodFit, PatternFit
from .detection import Detection
from .drift import DelayDrift
from .floor_bounce import RUNGS, FloorLadder
from .moving_clutter import ClutterCancellation
from .pattern import BeamPattern
from .geometry import RisPose
from .impulses import ImpulseScreen
from .qualify import Uncertainty, is_one_dimensional, position_at
from .radar import SPEED_OF_LIGHT, RadarConfig
from .sweep import BeamSweep

__all__ = ["Flag", "FLAG_CODES", "INSPECTION_CODES", "flag_codes", "GRATING_LOBE_DB", "OFF_DETECTION_CELLS",
           "FlagContext", "FlagRule", "SWEEP_FLAG_RULES", "sweep_flags"]

#: Every code a :class:`Flag` may carry, with a one-line meaning (``docs/flags.md``).
FLAG_CODES: dict[str, str] = {
    "no-detection": "nothing beam-dependent above the detection threshold: no position",
    "no-beam-dependence": "a strong return does not follow the sweep: it is not the RIS",
    "off-detection": ("the estimate is another peak than the RIS return the detector found: its distance and "
                      "position are not the RIS's"),
    "grating-lobe": "another lobe of the sweep is within a few dB: the AoD is ambiguous",
    "beam-edge": "the best beam is the first or last of the sweep: the UE may lie outside it",
    "aliased": "the return may lie beyond the unambiguous range or velocity",
    "unresolved-peaks": "two returns within one resolution cell: delay and AoD are biased",
    "moving-clutter": ("hall echoes that move with the radar lay within a cell of the RIS return: they were "
                       "removed before the fit"),
    "floor-leg": ("the estimate is the RIS's return via the floor, a rung after the straight leg: "
                  "the distance is too long"),
    "first-arrival": "the strongest RIS return came via the floor; the estimate is the earlier straight leg",
    "before-ris-delay": "the delay is shorter than the RIS loop-back delay: negative distance",
    "elevation-assumed": "a 1-D sweep cannot see elevation: the position assumes the sweep plane",
    "unobservable": "the sweep cannot observe an angle: its 1σ and the position's are infinite, not a number",
    "ris-facing-away": "the capture's true radar position lies behind the RIS plane: the RIS faces away from it",
    "pattern-mismatch": "the measured P_ave profile departs from the RIS model's beam pattern beyond the noise",
    "schedule-mismatch": "the recording does not support the sweep schedule's first_frame: the beams may be shifted",
    "damaged-beams": "frames of some beams hold zero-filled lost packets: their power and phase are wrong",
    "uncalibrated": "measured data without a calibration file: range offset and tau_RB are nominal",
    "inconsistent-ris": "the fixes of several RISs disagree beyond their 1σ: one is left out (named), or none can be",
    "impulsive-samples": ("lone ADC samples far above their chirp (a glitch, no beat signal): localization zeroes "
                          "them before detection"),
    # capture inspection (risloc_rt.measured.inspect_capture): the raw recording itself
    "dropped-packets": "the DCA1000 lost packets: frames hold zeros in their place",
    "truncated-frame": "the recording ends inside a frame: the incomplete frame is dropped",
    "clipping": "ADC words at a rail: the receiver saturated",
    "dc-offset": "the ADC samples have a DC offset above 1 % of full scale",
    "iq-imbalance": "I and Q differ in gain or phase: images of strong targets appear mirrored in range",
    "iq-order": "more power at negative beat frequencies: I and Q swapped or the lane order wrong",
    "peak-at-dc": "the strongest return is at range bin 0-1: DC offset or Tx-Rx leakage",
    "device-timing": "the radar configuration breaks a device timing rule",
}

#: The codes an inspection of a raw capture (not a localization) may carry.
INSPECTION_CODES: frozenset[str] = frozenset({
    "dropped-packets", "truncated-frame", "clipping", "dc-offset", "iq-imbalance", "iq-order", "peak-at-dc",
    "device-timing", "impulsive-samples"})


@dataclass(frozen=True)
class Flag:
    """One named warning about an estimate.

    Attributes
    ----------
    code : str
        One of :data:`FLAG_CODES`.
    message : str
        What was found, with numbers, and what to do.
    """

    code: str
    message: str

    def __post_init__(self) -> None:
        if self.code not in FLAG_CODES:
            raise ValueError(f"code={self.code!r} is not a flag code; valid codes are {sorted(FLAG_CODES)}")

    def to_dict(self) -> dict[str, Any]:
        """``{"code", "message"}``."""
        return {"code": self.code, "message": self.message}

    def __str__(self) -> str:
        return f"{self.code}: {self.message}"


def flag_codes(flags: Any) -> tuple[str, ...]:
    """The codes of a sequence of flags, in order."""
    return tuple(f.code for f in flags)


def _deg(x: float) -> str:
    return f"{np.rad2deg(x):+.2f}°"


#: A second lobe of the AoD fit within this many dB of the best raises ``grating-lobe`` [dB].
GRATING_LOBE_DB = 3.0
#: An estimate farther than this many resolution cells (range or velocity) from the detected return raises
#: ``off-detection`` [cells]. Measured (docs/flags.md, ``benchmarks/off_detection.py``): estimates of the detected
#: return lie within 0.32 cells of the detector's cell centre (1000 Table I runs at 0 and 10 dBm and 168 hall
#: captures, both estimators); the paper estimator's noise peaks at least 32 cells away.
OFF_DETECTION_CELLS = 1.0


@dataclass(frozen=True, eq=False)
class FlagContext:
    """What the flag rules of a detected estimate read (:func:`dsp.self_localize` fills it).

    Attributes
    ----------
    detection : Detection
        The detector's outcome (``rejected``: stronger returns skipped as clutter).
    fit : AodFit
        The beam-pattern fit of the AoD (its ``candidates``: other lobes and their levels [dB]).
    magnitudes : float array [M]
        Per-beam magnitude of the return (which beam is strongest) [√W, any common scale].
    sweep : BeamSweep
    radar : RadarConfig
    pose : RisPose
    delay : float
        τ̂, corrected for range-Doppler coupling [s].
    apparent_delay : float
        The delay the beat frequency alone reads, f₁/(S·T_s) [s] (where it sits in the range window).
    delay_rate : float
        ν̂ [s/s].
    loopback_delay : float
        τ_RB [s].
    distance : float
        d̂ [m].
    aod : float array [2]
        ``[az, el]`` [rad], RIS frame (elevation solved when ``height_solved``).
    unresolved : (float, float) or None
        The residual test's statistic and threshold [linear] when a second return was found, else None.
    ue_height : float or None
        The radar's known height [m], if given.
    height_solved : bool
        Whether the elevation was solved from ``ue_height``.
    height_range : float
        Height offset from the sweep plane the ``elevation-assumed`` message states the error for [m].
    drift : DelayDrift or None
        The delay's drift across the sweep (the unambiguous velocity check), if measured.
    std : Uncertainty or None
        The estimate's 1σ (:func:`dsp.qualify.sweep_uncertainty`), if computed: ``unobservable`` reads its
        infinite entries.
    pattern_fit : PatternFit or None
        The beam pattern's goodness of fit to the per-beam magnitudes (:func:`dsp.aod_fit.pattern_fit`),
        if computed: ``pattern-mismatch`` reads it.
    floor : FloorLadder or None
        The floor's ladder around the estimate (:func:`dsp.floor_bounce.floor_ladder`), when a floor
        height was given: ``floor-leg`` and ``first-arrival`` read it.
    floor_moved : bool
        Whether the estimate was moved down the ladder to the first arrival.
    clutter : ClutterCancellation or None
        The hall echoes moving with the radar that were searched for and removed before the fit
        (:func:`dsp.cancel_moving_clutter`), when the return moves: ``moving-clutter`` reads it.
    impulses : ImpulseScreen or None
        The impulsive samples zeroed before detection (:func:`dsp.impulses.screen_impulses`), when the
        cube was screened: ``impulsive-samples`` reads it.
    pattern : BeamPattern or None
        The RIS's beam pattern the fit used (its wavelength set), if known: ``grating-lobe`` names
        grating lobes as the cause only where the array has them in visible space.
    """

    detection: Detection
    fit: AodFit
    magnitudes: np.ndarray
    sweep: BeamSweep
    radar: RadarConfig
    pose: RisPose
    delay: float
    apparent_delay: float
    delay_rate: float
    loopback_delay: float
    distance: float
    aod: np.ndarray
    unresolved: tuple[float, float] | None
    ue_height: float | None
    height_solved: bool
    height_range: float
    drift: DelayDrift | None = None
    std: Uncertainty | None = None
    pattern_fit: PatternFit | None = None
    floor: FloorLadder | None = None
    floor_moved: bool = False
    clutter: ClutterCancellation | None = None
    impulses: ImpulseScreen | None = None
    pattern: BeamPattern | None = None


#: A rule: the message of its flag for this estimate, or None when the flag is not raised.
FlagRule = Callable[[FlagContext], "str | None"]

#: The rules of a detected estimate: flag code -> rule, in the order the flags are listed.
SWEEP_FLAG_RULES: dict[str, FlagRule] = {}


def _rule(code: str) -> Callable[[FlagRule], FlagRule]:
    """Register the decorated function as the rule of ``code`` (after those registered before)."""
    if code not in FLAG_CODES or code in SWEEP_FLAG_RULES:
        raise ValueError(f"{code!r} is not a flag code or already has a rule")

    def register(rule: FlagRule) -> FlagRule:
        SWEEP_FLAG_RULES[code] = rule
        return rule

    return register


def sweep_flags(context: FlagContext) -> tuple[Flag, ...]:
    """The flags of a detected estimate (``docs/flags.md``), in the order of :data:`SWEEP_FLAG_RULES`.

    Parameters
    ----------
    context : FlagContext

    Returns
    -------
    tuple of Flag
    """
    flags = []
    for code, rule in SWEEP_FLAG_RULES.items():
        message = rule(context)
        if message is not None:
            flags.append(Flag(code, message))
    return tuple(flags)


@_rule("no-beam-dependence")
def _clutter_skipped(c: FlagContext) -> str | None:
    if not c.detection.rejected:
        return None
    return (f"{c.detection.rejected} return(s) stronger than the one used crossed the detection threshold "
            "but do not follow the sweep (clutter, the panel's structure, leakage): they were skipped; "
            "check that the right return was taken (raise min_range to skip near ones)")


@_rule("off-detection")
def _not_the_detected_return(c: FlagContext) -> str | None:
    det, radar = c.detection, c.radar
    if c.floor_moved or not (np.isfinite(det.delay) and np.isfinite(det.delay_rate)):
        return None  # moved down the floor's ladder on purpose (first-arrival), or a detection without a cell
    gap = (c.delay - det.delay) * SPEED_OF_LIGHT / 2.0  # [m]
    velocity_gap = (c.delay_rate - det.delay_rate) * SPEED_OF_LIGHT / 2.0  # [m/s]
    # a moving return drifts across the sweep: the detector's cell is where the whole sweep's statistic peaks
    drift = abs(det.delay_rate) * SPEED_OF_LIGHT / 2.0 * radar.sweep_duration(c.sweep.num_beams)
    allowed = OFF_DETECTION_CELLS * radar.range_resolution + drift
    rungs = [0.0] if c.floor is None else [k * c.floor.spacing for k in RUNGS]  # the floor's legs of the return
    off_range = min(abs(gap - r) for r in rungs) > allowed
    off_velocity = abs(velocity_gap) > OFF_DETECTION_CELLS * radar.velocity_resolution
    if not (off_range or off_velocity):
        return None
    detected = (det.delay - c.loopback_delay) * SPEED_OF_LIGHT / 2.0
    return (f"the estimate ({c.distance:.3f} m, {c.delay_rate * SPEED_OF_LIGHT / 2:+.2f} m/s) is {abs(gap):.3f} m "
            f"and {abs(velocity_gap):.2f} m/s from the RIS return the detector found ({detected:.3f} m, "
            f"{det.delay_rate * SPEED_OF_LIGHT / 2:+.2f} m/s), more than a resolution cell "
            f"({radar.range_resolution * 100:.1f} cm, {radar.velocity_resolution:.2f} m/s"
            + (f", {drift * 100:.1f} cm of drift over the sweep" if drift > 0 else "")
            + "): it is another peak (at low SNR the paper's estimator can take a beam's noise peak; or an echo "
            "stronger than the RIS in the chosen beam), so its distance and position are not the RIS's and lie "
            "beyond their 1σ; use the refined estimator, which starts from the detected return, or raise the SNR "
            "(transmit power, chirps)")


@_rule("grating-lobe")
def _second_lobe(c: FlagContext) -> str | None:
    fit = c.fit
    strong = fit.candidates[fit.candidates[:, 1] >= -GRATING_LOBE_DB] if fit.candidates.size else fit.candidates
    twins = fit.twins[(fit.twins[:, 2] > 0) & (fit.twins[:, 1] >= -GRATING_LOBE_DB)]
    if not strong.size and not twins.size:
        return None
    others = [f"{_deg(a)} ({lvl:+.1f} dB)" for a, lvl in strong]
    others += [f"{_deg(a)} ({lvl:+.1f} dB, beyond the swept span: not chosen, the sweep is taken to cover "
               "the UE)" for a, lvl, _ in twins]
    head = f"the AoD is ambiguous: the beam-pattern fit peaks at az {_deg(c.aod[0])} and also at {', '.join(others)}"
    p = c.pattern
    if p is not None and p.wavelength is not None:
        # grating lobes repeat every λ/(q·d) in u = cos(el)·sin(az): none in visible space when that period is >= 2
        period = p.wavelength / (p.gradient_factor * p.element_spacing)
        kind = (f"{'relay' if p.gradient_factor == 1 else 'reflective'}, element pitch "
                f"{p.element_spacing / p.wavelength:.2f} λ")
        if period >= 2.0:
            return (f"{head}; this RIS has no grating lobe in visible space ({kind}): the other maxima come from "
                    "noise in the per-beam powers or a second return; every candidate is in estimate.alternatives; "
                    "raise the SNR, or use a second sweep/RIS to decide")
        return (f"{head}; this RIS ({kind}) has grating lobes (sin φ = sin θ ∓ {period:.2f}): every candidate is "
                "in estimate.alternatives; use a relay RIS at λ/2, a narrower sweep, or a second sweep/RIS to decide")
    return (f"{head}; a reflective RIS with λ/2 spacing has grating lobes (sin φ = sin θ ∓ 1): "
            "every candidate is in estimate.alternatives; use a relay RIS, a narrower sweep, or a second "
            "sweep/RIS to decide")


@_rule("beam-edge")
def _at_sweep_edge(c: FlagContext) -> str | None:
    sweep, aod = c.sweep, c.aod
    az_lo, az_hi = float(sweep.angles[:, 0].min()), float(sweep.angles[:, 0].max())
    best = int(np.argmax(c.magnitudes))
    at_edge = best in (0, sweep.num_beams - 1)
    outside = not (az_lo + 1e-9 < float(aod[0]) < az_hi - 1e-9)
    if not (is_one_dimensional(sweep) and (at_edge or outside)):
        return None
    where = (f"the strongest beam is the {'first' if best == 0 else 'last'} of the sweep "
             f"(az {_deg(sweep.angles[best, 0])})" if at_edge else
             f"the AoD az {_deg(aod[0])} lies at or beyond the edge of the swept span "
             f"[{_deg(az_lo)}, {_deg(az_hi)}]")
    return (f"{where}: the UE may lie outside the swept span, where the AoD is pulled to the edge or "
            "taken from a sidelobe; widen the sweep")


@_rule("aliased")
def _maybe_aliased(c: FlagContext) -> str | None:
    radar, apparent_delay, delay_rate, drift = c.radar, c.apparent_delay, c.delay_rate, c.drift
    edge = 2.0 * radar.delay_resolution
    near_wrap = apparent_delay < edge or apparent_delay > radar.max_delay - edge
    above_if = apparent_delay * radar.slope > radar.if_bandwidth
    fast_doppler = abs(delay_rate) > 0.9 * radar.max_delay_rate
    wrapped_doppler = drift is not None and \
        abs(drift.rate - delay_rate) > max(radar.max_delay_rate, 5.0 * drift.std)
    if not (near_wrap or above_if or fast_doppler or wrapped_doppler):
        return None
    why = []
    if near_wrap:
        why.append(f"the return sits within {edge * SPEED_OF_LIGHT / 2 * 100:.1f} cm of the range wrap (0 or "
                   f"{radar.max_range:.2f} m)")
    if above_if:
        why.append(f"its beat frequency {apparent_delay * radar.slope / 1e6:.2f} MHz is above the IF bandwidth "
                   f"{radar.if_bandwidth / 1e6:.2f} MHz")
    if fast_doppler:
        why.append(f"|v| = {abs(delay_rate) * SPEED_OF_LIGHT / 2:.2f} m/s is near the unambiguous "
                   f"{radar.max_velocity:.2f} m/s")
    if wrapped_doppler:
        span = 2 * radar.max_delay_rate
        unwrapped = delay_rate + span * round((drift.rate - delay_rate) / span)
        why.append(f"the delay drifts across the sweep at {drift.rate * SPEED_OF_LIGHT / 2:+.2f} m/s "
                   f"(±{drift.std * SPEED_OF_LIGHT / 2:.2f}) but the Doppler reads "
                   f"{delay_rate * SPEED_OF_LIGHT / 2:+.2f} m/s: the velocity is beyond ±{radar.max_velocity:.2f} m/s "
                   f"and wrapped, probably {unwrapped * SPEED_OF_LIGHT / 2:+.2f} m/s (shorten the chirp period)")
    return "; ".join(why) + (f": the true return may lie {radar.max_range:.2f} m (or one velocity "
                             "span) further; check with a second chirp configuration or the expected geometry")


@_rule("unresolved-peaks")
def _second_return_nearby(c: FlagContext) -> str | None:
    if c.unresolved is None:
        return None
    stat, thr = c.unresolved
    radar = c.radar
    moving = (f" (whether it stays at one delay or follows the radar's motion across the sweep at "
              f"{c.delay_rate * SPEED_OF_LIGHT / 2:+.2f} m/s)" if c.delay_rate != 0 else "")
    return (f"after removing the fitted RIS tone{moving} the residual within half a resolution cell is "
            f"{10 * np.log10(max(stat, 1e-30)):.1f} dB (threshold {10 * np.log10(thr):.1f} dB): a second "
            f"return lies within {radar.range_resolution * 100:.1f} cm / {radar.velocity_resolution:.2f} m/s "
            "and biases delay and AoD; move the radar or use more bandwidth/chirps")


@_rule("moving-clutter")
def _moving_clutter_removed(c: FlagContext) -> str | None:
    if c.clutter is None or not c.clutter.removed:
        return None
    echoes = "; ".join(f"{e.range_offset:+.2f} range bin, {e.doppler_offset:+.3f} Doppler cell "
                       f"({(e.delay_rate - c.delay_rate) * SPEED_OF_LIGHT / 2 * 1e3:+.0f} mm/s), "
                       f"{10 * np.log10(max(e.snr, 1e-30)):.0f} dB" for e in c.clutter.echoes)
    n = len(c.clutter.echoes)
    return (f"{n} hall echo{'es' if n > 1 else ''} moving with the radar within a cell of the RIS return "
            f"({echoes} over the noise, from {c.clutter.far_beams} far beams) "
            f"{'were' if n > 1 else 'was'} removed before the fit, each as one tone over the sweep (one amplitude, "
            "its range's drift and curvature fitted); a wall passed very close is removed less completely: "
            "compare with the fixes of neighbouring sweeps")


def _rungs(f: FloorLadder, rungs: int) -> str:
    return f"{rungs} rung{'s' if rungs > 1 else ''} ({rungs * f.spacing * 100:.1f} cm)"


@_rule("floor-leg")
def _floor_leg_taken(c: FlagContext) -> str | None:
    f = c.floor
    if f is None or f.steps_down == 0 or c.floor_moved:
        return None
    first = f.levels_db[RUNGS.index(-f.steps_down)]
    return (f"a RIS return {_rungs(f, f.steps_down)} earlier on the floor's ladder ({first:.1f} dB over its "
            "noise mean, "
            f"the estimate {f.levels_db[RUNGS.index(0)]:.1f} dB) is the straight leg: this estimate is the RIS's "
            f"return via the floor, its distance {f.steps_down * f.spacing * 100:.1f} cm too long (its 1σ includes "
            "it); the refined estimator takes the first arrival")


@_rule("first-arrival")
def _first_arrival_taken(c: FlagContext) -> str | None:
    f = c.floor
    if f is None or not c.floor_moved:
        return None
    return (f"the strongest RIS return was its echo via the floor, a rung of {f.spacing * 100:.1f} cm or two later; "
            "the estimate is the first arrival, the straight leg (floor's ladder "
            f"{', '.join(f'{v:.1f}' for v in f.levels_db)} "
            f"dB over noise at rungs {RUNGS}); its distance 1σ includes the {f.bias_std * 1e3:.1f} mm the "
            "floor's legs beside it may bias it by")


@_rule("before-ris-delay")
def _negative_distance(c: FlagContext) -> str | None:
    if not c.delay < c.loopback_delay:
        return None
    return (f"the delay {c.delay * 1e9:.3f} ns is shorter than the RIS loop-back delay τ_RB = "
            f"{c.loopback_delay * 1e9:.3f} ns: distance {c.distance:+.3f} m is negative and the position "
            "lies behind the panel; check τ_RB, or the return is the panel's structural reflection "
            "or an aliased one")


@_rule("elevation-assumed")
def _elevation_not_measured(c: FlagContext) -> str | None:
    if is_one_dimensional(c.sweep) and c.ue_height is None:
        return _sweep_plane_assumed(c)
    if c.ue_height is not None and not c.height_solved:
        return (f"ue_height={c.ue_height:.3f} m cannot be reached at distance {c.distance:.3f} m along the "
                f"measured azimuth: the position assumes el {_deg(float(c.aod[1]))}; check the height "
                "(world z) and the RIS pose")
    return None


def _sweep_plane_assumed(c: FlagContext) -> str:
    """The ``elevation-assumed`` message of a 1-D sweep without a height, with the error ±height_range makes."""
    pose, distance, aod, height_range = c.pose, c.distance, c.aod, c.height_range
    el_assumed = float(aod[1])
    if distance > 0:
        u = float(np.cos(el_assumed) * np.sin(aod[0]))
        base = position_at(pose, distance, float(aod[0]), el_assumed)
        worst = 0.0
        for sign in (-1.0, 1.0):
            el = el_assumed + sign * float(np.arcsin(min(height_range / distance, 1.0)))
            if abs(u) < np.cos(el):
                az = float(np.arcsin(u / np.cos(el)))
                worst = max(worst, float(np.linalg.norm(position_at(pose, distance, az, el) - base)))
        extra = (f"; a UE ±{height_range:.2f} m off that plane would be misplaced by up to {worst:.3f} m "
                 f"(mostly vertically)")
    else:
        extra = ""
    return (f"a 1-D sweep cannot see elevation: the position assumes the UE in the sweep plane "
            f"(el {_deg(el_assumed)}){extra}; give ue_height (the radar's known height) to solve it")


@_rule("unobservable")
def _angle_not_observable(c: FlagContext) -> str | None:
    std = c.std
    if std is None or not np.any(np.isinf(std.aod)):
        return None
    names = " and ".join(n for n, v in zip(("azimuth", "elevation"), std.aod) if np.isinf(v))
    angles = c.sweep.angles
    if np.ptp(angles[:, 0]) < 1e-12:
        why = (f"every beam is steered to az {_deg(angles[0, 0])} (an elevation-only sweep): the beams differ "
               "only in elevation, so a change of azimuth scales all of them alike and is taken by the "
               "return's unknown amplitude")
    elif abs(abs(float(c.aod[0])) - np.pi / 2) < np.deg2rad(2.0) or \
            np.any(np.abs(np.abs(angles[:, 0]) - np.pi / 2) < np.deg2rad(2.0)):
        why = (f"the estimate (az {_deg(c.aod[0])}) or the sweep's beams lie in or near the panel's plane "
               "(|az| ≈ 90°), where the beam pattern does not change with the angle")
    else:
        why = "the beams' pattern does not change along it at this direction"
    return (f"the sweep cannot observe the {names}: {why}. Its 1σ is infinite (result.json: null) and so is "
            "the position's along the axes it moves; the position is not reliable there. Sweep the beams "
            "in that angle too (a 2-D sweep) and keep them away from the panel's plane")


@_rule("pattern-mismatch")
def _pattern_does_not_fit(c: FlagContext) -> str | None:
    fit = c.pattern_fit
    if fit is None or not fit.mismatch:
        return None
    return (f"the per-beam powers depart from the RIS model's beam pattern beyond the noise (even with the AoD "
            f"drifting as a radar moving across the beam would): the fit's residual "
            f"is {fit.statistic:.1f}× what the noise leaves (threshold {fit.threshold:.2f}, "
            f"{fit.dof:.0f} effective degrees of freedom): the AoD is the best fit of a wrong model, its 1σ (and the "
            f"position's) is widened {np.sqrt(fit.statistic):.1f}×; check the RIS mode (relay or reflective), its "
            "rows, columns, element spacing and facing/yaw against the hardware")


@_rule("impulsive-samples")
def _impulses_zeroed(c: FlagContext) -> str | None:
    return c.impulses.describe() if c.impulses is not None and c.impulses.count else None
