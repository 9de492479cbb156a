"""Run the DSP on captures and report estimates, errors and timings (``result.json``, console)."""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from dsp import (FLAG_CODES, SPEED_OF_LIGHT, Flag, Localization, ProcessingConfig, delay_doppler_map,
                 direction_from_angles, self_localize)

from .._files import atomic_write_bytes
from ..model.capture import Capture
from ..model.power_check import range_alias_flag
from ..model.scenario import Truth

__all__ = ["CaseResult", "process_capture", "report_capture", "estimation_errors", "write_result", "format_case",
           "RESULT_FORMAT", "json_safe", "facing_away_flag", "capture_flags", "significant", "run_environment",
           "format_environment"]

RESULT_FORMAT = "risloc-result"
RESULT_VERSION = 1


@dataclass(frozen=True)
class CaseResult:
    """One processed capture: the estimate, the truth (if known) and the time per stage.

    Attributes
    ----------
    name : str
    capture : Capture
    localization : Localization
    timing : dict of str -> float
        Seconds per stage (``"synthesis"``, ``"dsp"``, …).
    plots : dict of str -> str
        Plot files written for this case, relative to the output directory.
    uncertainty_budget : list of dict, optional
        A measured capture's uncertainty terms (``risloc_rt.measured.compare.uncertainty_budget``),
        plain JSON; ``localization.std`` is then their total.
    """

    name: str
    capture: Capture
    localization: Localization
    timing: dict[str, float] = field(default_factory=dict)
    plots: dict[str, str] = field(default_factory=dict)
    uncertainty_budget: list[dict[str, Any]] | None = None

    @property
    def truth(self) -> Truth | None:
        """The capture's ground truth, if any."""
        return self.capture.truth

    @property
    def errors(self) -> dict[str, Any] | None:
        """:func:`estimation_errors` against the truth, or ``None`` without one."""
        return None if self.truth is None else estimation_errors(self.localization, self.truth, self.capture)


#: The estimator ``risloc locate``/``demo`` and :func:`process_capture` use unless told otherwise.
DEFAULT_ESTIMATOR = "refined"


def process_capture(capture: Capture, *, processing: ProcessingConfig | None = None,
                    estimator: str = DEFAULT_ESTIMATOR, ue_height: float | None = None,
                    pfa: float | None = None, backend: Any = None,
                    floor_height: float | None = None) -> tuple[Localization, float]:
    """Run the shared DSP on a capture; returns the localization and the DSP time [s].

    Parameters
    ----------
    capture : Capture
    processing : ProcessingConfig, optional
        Overrides the capture's recommended processing.
    estimator : {"refined", "paper"}, default "refined"
        ``"refined"``: off-grid delay/Doppler from all beams and the AoD from a fit of the RIS beam
        pattern (``docs/estimation.md``); ``"paper"``: the seed paper's method, unchanged.
    ue_height : float, optional
        Known world z of the radar [m]; resolves the elevation a 1-D sweep cannot see.
    pfa : float, optional
        Detector false-alarm probability per capture (default ``dsp``'s, 1e-3).
    backend : dsp.ArrayBackend, optional
        Where the whole-cube work runs (``--device``: the detector and the estimators' reads of the cube,
        :func:`dsp.self_localize`); default NumPy.
    floor_height : float, optional
        World z of the floor [m] (a traced hall's: 0): the floor's ladder of the RIS return is read and
        the first arrival taken (:func:`dsp.self_localize`); None: no floor is modelled.

    Returns
    -------
    (Localization, float)
        With ``detection``, ``std`` and ``flags``; NaN estimates when nothing was detected. The
        flags include the link-budget check for range aliasing
        (:func:`risloc_rt.model.power_check.range_alias_flag`).
    """
    start = time.perf_counter()
    extra = {} if pfa is None else {"pfa": pfa}
    loc = self_localize(capture.cube, sweep=capture.sweep, radar=capture.radar,
                        processing=processing or capture.processing, pose=capture.ris.pose,
                        loopback_delay=capture.ris.loopback_delay, estimator=estimator,
                        pattern=capture.ris.beam_pattern(), ue_height=ue_height, backend=backend,
                        floor_height=floor_height, **extra)
    alias = range_alias_flag(loc, capture)
    if alias is not None and "aliased" not in loc.flag_codes:
        loc = replace(loc, flags=(*loc.flags, alias))
    away = facing_away_flag(capture)
    if away is not None:
        loc = replace(loc, flags=(*loc.flags, away))
    if loc.detected:
        loc = replace(loc, flags=(*loc.flags, *capture_flags(capture, loc)))
    return loc, time.perf_counter() - start


def capture_flags(capture: Capture, loc: Localization) -> tuple[Flag, ...]:
    """Flags a capture carries from its import: ``provenance["import_flags"]`` (e.g. ``schedule-mismatch``)
    and ``damaged-beams`` for beams whose frames hold zero-filled lost packets
    (``provenance["reader"]["damaged_beams"]``).

    Parameters
    ----------
    capture : Capture
    loc : Localization
        Its flags already present are not repeated; the best beam is named when damaged.

    Returns
    -------
    tuple of Flag
    """
    out: list[Flag] = []
    have = set(loc.flag_codes)
    for f in capture.provenance.get("import_flags") or ():
        if isinstance(f, dict) and f.get("code") in FLAG_CODES and f["code"] not in have:
            out.append(Flag(str(f["code"]), str(f.get("message", ""))))
            have.add(f["code"])
    damaged = sorted({int(m) for m in (capture.provenance.get("reader") or {}).get("damaged_beams") or ()})
    if damaged and "damaged-beams" not in have:
        best = loc.beam_index in damaged
        listed = ", ".join(str(m) for m in damaged[:8]) + (", …" if len(damaged) > 8 else "")
        out.append(Flag("damaged-beams", (
            f"{len(damaged)} of {capture.sweep.num_beams} beams ({listed}) hold zero-filled lost DCA1000 packets"
            + (f", the best beam {loc.beam_index} among them" if best else "")
            + ": their P_ave and phase are wrong; record again or check that they lie away from the best beam")))
    return tuple(out)


def facing_away_flag(capture: Capture) -> Flag | None:
    """The ``ris-facing-away`` flag when the capture's truth puts the radar behind (or in) the RIS plane.

    Parameters
    ----------
    capture : Capture

    Returns
    -------
    Flag or None
        None without a truth, or when the true radar position is in front of the panel
        (``normal · (p_UE - p_RIS) > 0``).
    """
    if capture.truth is None:
        return None
    pose = capture.ris.pose
    depth = float(pose.normal @ (np.asarray(capture.truth.ue_position, dtype=float) - pose.position))
    if depth > 0:
        return None
    return Flag("ris-facing-away",
                f"the true radar position is {abs(depth):.3f} m {'behind' if depth < 0 else 'in'} the RIS plane "
                f"(normal {np.round(pose.normal, 3).tolist()}): the RIS as given faces away from the radar, its "
                "beams cannot reach it and the estimate (always in front of the panel) cannot be right; check the "
                "capture's [ris] facing/normal")


def report_capture(name: str, capture: Capture, *, out_dir: Path | None, processing: ProcessingConfig,
                   timing: dict[str, float], budget: Callable[[Capture, Localization], tuple[Localization, Any]]
                   | None = None, **options: Any) -> CaseResult:
    """Localize ``capture`` and, with ``out_dir``, draw its figures under ``out_dir/name/``.

    The figures are the delay-Doppler map of the chosen beam with its three largest peaks, P_ave
    over the sweep, and the range profile at the estimated Doppler. ``timing`` (seconds per
    stage) gains ``"dsp"`` and, with figures, ``"plots"``. ``options`` go to :func:`process_capture`
    (``estimator``, ``ue_height``, ``pfa``, ``backend``). ``budget(capture, loc) -> (loc, budget or None)``
    (``risloc_rt.measured.compare.apply_budget`` for measured captures) replaces the σ by the
    uncertainty budget's total; its ``to_list()`` goes to :attr:`CaseResult.uncertainty_budget`.
    """
    loc, dsp_time = process_capture(capture, processing=processing, **options)
    terms = None
    if budget is not None:
        loc, made = budget(capture, loc)
        terms = None if made is None else made.to_list()
    timing = {**timing, "dsp": dsp_time}
    plots: dict[str, str] = {}
    if out_dir is not None:
        from . import plots as plotting

        start = time.perf_counter()
        frame = capture.cube[loc.beam_index]
        ddm = delay_doppler_map(frame, capture.radar, processing)
        peaks = ddm.peaks(3, min_delay=2 * processing.min_range / SPEED_OF_LIGHT)
        az = np.rad2deg(loc.aod[0])
        files = {
            "delay_doppler": plotting.plot_delay_doppler(
                ddm, peaks, out_dir / name / "delay_doppler.png",
                title=f"{name}: delay-Doppler map, beam {loc.beam_index} (φ = {az:+.1f}°), 3 largest peaks"),
            "sweep": plotting.plot_sweep(loc, out_dir / name / "aod_sweep.png", truth=capture.truth,
                                         title=f"{name}: P_ave over the RIS sweep"),
            "range_profile": plotting.plot_range_profile(
                ddm, loc, out_dir / name / "range_profile.png", loopback_delay=capture.ris.loopback_delay,
                truth=capture.truth, title=f"{name}: range profile at ν ≈ ν̂, beam {loc.beam_index}"),
        }
        plots = {k: str(v.relative_to(out_dir)) for k, v in files.items()}
        timing["plots"] = time.perf_counter() - start
    return CaseResult(name=name, capture=capture, localization=loc, timing=timing, plots=plots,
                      uncertainty_budget=terms)


def estimation_errors(loc: Localization, truth: Truth, capture: Capture) -> dict[str, Any]:
    """Estimate minus truth: distance [m], velocity [m/s], AoD [rad] per axis, angle between the
    estimated and true directions [rad], and the position error norm [m]."""
    true_dir = capture.ris.pose.to_world(direction_from_angles(truth.aod))
    cosang = float(np.clip(loc.direction @ true_dir, -1.0, 1.0))
    return {
        "distance": loc.distance - truth.distance,
        "velocity": loc.velocity - truth.velocity,
        "aod": (loc.aod - truth.aod).tolist(),
        "angle": float(np.arccos(cosang)),
        "position": float(np.linalg.norm(loc.position - truth.ue_position)),
    }


def _estimate_dict(loc: Localization, budget: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    return {
        "beam_index": loc.beam_index,
        "aod": loc.aod.tolist(),
        "delay": loc.delay,
        "distance": loc.distance,
        "delay_rate": loc.delay_rate,
        "velocity": loc.velocity,
        "position": loc.position.tolist(),
        "estimator": loc.estimator,
        "reference_time": loc.reference_time,
        "std": None if loc.std is None else loc.std.to_dict(),
        "uncertainty_budget": budget,
        "alternatives": [a.to_dict() for a in loc.alternatives],
    }


def case_dict(case: CaseResult) -> dict[str, Any]:
    """The JSON object of one case (see ``docs/formats.md``; ``"sweep"`` is null for a localization made without the
    per-beam scan, ``dsp.self_localize(scan=False)``)."""
    scan = case.localization.scan
    return {
        "name": case.name,
        "source": case.capture.provenance.get("source"),
        "provenance": case.capture.provenance,
        "detection": None if case.localization.detection is None else case.localization.detection.to_dict(),
        "estimate": _estimate_dict(case.localization, case.uncertainty_budget),
        "flags": [f.to_dict() for f in case.localization.flags],
        "truth": None if case.truth is None else case.truth.to_dict(),
        "error": case.errors,
        "sweep": None if scan is None else {
            "angles": scan.angles.tolist(),
            "average_power": scan.average_power.tolist(),
            "peak_delay": scan.delay.tolist(),
            "peak_delay_rate": scan.delay_rate.tolist(),
        },
        "timing": case.timing,
        "plots": case.plots,
    }


def json_safe(value: Any, *, where: str = "$", nonfinite: list[str] | None = None) -> Any:
    """``value`` as plain JSON: NaN and ±inf become ``null``, numpy scalars and arrays plain Python.

    Parameters
    ----------
    value : any JSON-like value (dicts, lists, numbers, strings, numpy values)
    where : str
        Path of ``value`` in the document (``$.cases[0].estimate``), for the report.
    nonfinite : list of str, optional
        Collects the path of every value that was NaN or infinite.
    """
    if isinstance(value, dict):
        return {k: json_safe(v, where=f"{where}.{k}", nonfinite=nonfinite) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v, where=f"{where}[{i}]", nonfinite=nonfinite) for i, v in enumerate(value)]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        if np.isfinite(value):
            return float(value)
        if nonfinite is not None:
            nonfinite.append(where)
        return None
    return value


def write_result(out_dir: str | os.PathLike[str], cases: list[CaseResult],
                 device: dict[str, Any] | None = None, fused: dict[str, Any] | None = None) -> Path:
    """Write ``out_dir/result.json`` for ``cases``; returns its path.

    ``device`` (:func:`run_environment`: what ran the DSP and the ray tracer) becomes the document's
    ``"device"`` object; without it the key is left out. ``fused`` (the captures of several RISs
    fused, :func:`risloc_rt.io.fused.fused_dict`) becomes ``"fused"``. The file is strict JSON: a value that is not
    finite (an estimate of a capture where nothing was detected, say) is written as ``null`` and its
    path listed under ``"nonfinite"``. It is written to a unique temporary file in ``out_dir`` and
    renamed, so concurrent writers leave one complete file and an interrupted write leaves none.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nonfinite: list[str] = []
    doc = json_safe({
        "format": RESULT_FORMAT,
        "version": RESULT_VERSION,
        "units": "SI: m, s, m/s, rad; delay_rate s/s; average_power W",
        **({} if device is None else {"device": device}),
        "cases": [case_dict(c) for c in cases],
        **({} if fused is None else {"fused": fused}),
    }, nonfinite=nonfinite)
    doc["nonfinite"] = nonfinite
    return atomic_write_bytes(out / "result.json", (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode())


def run_environment(backend: Any = None) -> dict[str, Any]:
    """What ran this process's numbers: the DSP's device and library, and the ray tracer's Mitsuba variant.

    Parameters
    ----------
    backend : dsp.ArrayBackend, optional
        The DSP's backend (default NumPy).

    Returns
    -------
    dict
        ``dsp``: :meth:`dsp.ArrayBackend.describe` (``device``, ``library``, ``hardware``, ``detail``);
        ``trace``: the Mitsuba variant sionna-rt ran on in this process (``llvm_ad_mono_polarized``: the
        CPU, ``cuda_ad_mono_polarized``: the GPU), or None when this process traced nothing (a capture
        file, the analytic scenario, or only cached traces). Nothing is initialised to find out: the
        variant is read only where :func:`risloc_rt.hall.raytrace.ensure_backend` has already set it
        (Mitsuba is imported by nothing else).
    """
    if backend is None:
        from dsp import numpy_backend

        backend = numpy_backend()
    trace = None
    if "mitsuba" in sys.modules:
        from ..hall.raytrace.backend import BackendError, ensure_backend

        try:
            trace = ensure_backend()  # the variant already chosen: returned, nothing initialised
        except BackendError:  # mitsuba imported but no variant usable: nothing was traced
            trace = None
    return {"dsp": backend.describe(), "trace": trace}


def format_environment(env: dict[str, Any]) -> str:
    """One console line for :func:`run_environment`'s dict: ``device: dsp cpu (numpy 2.4.6, CPU, BLAS ...); trace ...``.

    Parameters
    ----------
    env : dict
        ``{"dsp": ArrayBackend.describe(), "trace": variant or None}``.

    Returns
    -------
    str
        The DSP part as :meth:`dsp.ArrayBackend.summary`; ``; trace VARIANT`` only where a hall was traced.
    """
    from dsp.xp import describe_line

    return f"device: dsp {describe_line(env['dsp'])}" + (f"; trace {env['trace']}" if env.get("trace") else "")


def significant(value: float, digits: int = 2) -> str:
    """``value`` with ``digits`` significant digits, positional (a 1σ of 2.03e-5 m prints ``0.00002``, never ``0.00``).

    Parameters
    ----------
    value : float
    digits : int, default 2

    Returns
    -------
    str
    """
    return np.format_float_positional(float(value), precision=digits, unique=False, fractional=False, trim="-")


def format_case(case: CaseResult) -> str:
    """Human-readable table of truth, estimate ± 1σ and error for one case (degrees for angles),
    then the detection and the flags. A 1σ that is infinite (the sweep cannot observe the quantity,
    flag ``unobservable``) prints as ``± unobservable``; one that was not estimated (NaN) is left out."""
    loc, truth, err = case.localization, case.truth, case.errors
    std = loc.std
    fmt3 = lambda v: "[" + ", ".join(f"{x:+.3f}" for x in v) + "]"  # noqa: E731
    deg = lambda v: "[" + ", ".join(f"{x:+.2f}" for x in np.rad2deg(v)) + "]°"  # noqa: E731
    pm = lambda value, sigma, f: (value if sigma is None or np.isnan(sigma) else  # noqa: E731
                                  f"{value} ± unobservable" if np.isinf(sigma) else f"{value} ± {f(sigma)}")
    rows = [("quantity", "truth", "estimate", "error")]
    rows.append(("distance [m]", f"{truth.distance:.4f}" if truth else "-",
                 pm(f"{loc.distance:.4f}", std and std.distance, significant),
                 f"{err['distance']:+.4f}" if err else "-"))
    rows.append(("velocity [m/s]", f"{truth.velocity:+.3f}" if truth else "-",
                 pm(f"{loc.velocity:+.3f}", std and std.velocity, significant),
                 f"{err['velocity']:+.3f}" if err else "-"))
    rows.append(("AoD [az, el]", deg(truth.aod) if truth else "-",
                 pm(deg(loc.aod), std and std.aod[0], lambda x: f"{significant(np.rad2deg(x))}° az"),
                 f"{np.rad2deg(err['angle']):.2f}°" if err else "-"))
    rows.append(("position [m]", fmt3(truth.ue_position) if truth else "-",
                 pm(fmt3(loc.position), std and std.peb, significant),
                 f"{err['position']:.4f} m" if err else "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    beams = loc.scan.num_beams if loc.scan is not None else case.capture.sweep.num_beams  # scan=False: no scan
    head = f"== {case.name} ({loc.estimator} estimator, best beam {loc.beam_index} of {beams})"
    lines = [head] + ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    det = loc.detection
    if det is not None:
        lines.append(f"  detection: {'RIS return detected' if det.detected else 'NOTHING DETECTED: no position'}, "
                     f"SNR {det.snr_db:.1f} dB against a threshold of {det.threshold_db:.1f} dB "
                     f"(false-alarm probability {det.false_alarm_probability:.0e} per capture)")
    lines += [f"  flag {f.code}: {f.message}" for f in loc.flags]
    for quantity in ("distance", "velocity", "aod_az", "position"):
        terms = [t for t in case.uncertainty_budget or () if t["quantity"] == quantity]
        if terms:
            lines.append(f"  1σ budget, {quantity}: " + ", ".join(
                f"{t['name']} {'not known' if t['value'] is None else significant(t['value'])}"
                + ("" if t["value"] is not None else "" if t.get("bound") is None else
                   f" (may bias by ~{significant(t['bound'])})") + f" {t['unit']}" for t in terms))
    if case.timing:
        lines.append("  time: " + ", ".join(f"{k} {v:.2f} s" for k, v in case.timing.items()))
    return "\n".join(lines)
