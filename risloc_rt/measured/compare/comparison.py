"""Measured vs ray-traced: the numbers behind ``risloc compare`` (the page is :mod:`.comparison_page`).

The simulated side is the traced hall (:mod:`.traced_hall`) at the capture's radar position,
synthesised with eq. (1) for the capture's radar, sweep and RIS (calibrated when a calibration is
given: τ_RB, ζ, range offset), scaled to ADC counts by the receiver gain G (the calibration's
power offset; without one, ``G = (mean|y|² − σ²)/mean|s|²``, the measured signal power over the
simulated) and given white noise at the measured floor σ² (the chirp-to-chirp variance), so both
sides go through the same DSP (``dsp.delay_doppler_map`` and ``dsp.scan_beams``).

**Peaks.** Local maxima of the measured zero-Doppler range profile at the best beam, at least
``prominence_db`` (6 dB) prominent and ``floor_db`` (12 dB) above the profile's median, beyond
the range gate. Each is associated with the traced path that contributes most power at that beam
among those whose apparent range lies within 1.5 range cells (the label ``hall.path_table``
gives, e.g. ``ris_loopback: out LOS | back LOS``), or marked ``"unexplained"``. Its simulated
counterpart is the local maximum nearest to it within 1.5 cells of the *noise-free* simulated
profile (the model's prediction: the same paths, gain, gate and DSP without the added noise, so
that the residual carries the measured side's noise only, not a second, independent noise
draw); the **delay residual** is the measured minus the simulated peak range [mm] (peaks
interpolated by a parabola in dB), the **power residual** measured minus simulated peak power [dB].

**Delay σ.** Each explained peak states the 1σ of its measured range from the noise floor
(``delay_sigma_mm``): for a peak of power P [counts²] (a grid-centred tone of amplitude γ
reads |γ|² = P) in white noise σ² per sample, the peak of the windowed transform moves by

``var(ω) = Σ_n w_n² (n − c)² / (2 ρ (Σ_n w_n (n − c)²)²)``,  ``ρ = (P/σ²) · (Σ_k w_k)² / Σ_k w_k²``

[rad²/sample²] (first-order perturbation of the maximum of ``|Σ_n w_n y_n e^{jωn}|``; c the
window's centre, w_n and w_k the fast- and slow-time windows), and ``σ_d = σ_ω · N · ΔR / (2π)``
with ΔR the range cell. For rectangular windows it is the Cramér–Rao bound
``6/(ρ N (N² − 1))``; Hann on both axes widens σ by 1.53 (fast time) × 1.22 (slow time). Checked
by Monte Carlo against the peak picking used here (parabola in dB on the zero-padded grid): the
folded wall_1 echo of the emulated hall, 19 dB over the profile's noise floor, 1.93 mm by the
formula and 1.88 mm over 60 draws; ``tests/measured/test_compare.py`` checks a small radar. Near-by echoes are not in it (they are in the
noise-free prediction, which contains them); the ray tracer's own error is what the residual
beyond a few σ reveals.

**Calibration.** A calibration moves every simulated path by its range offset and the RIS's
paths by its τ_RB and ζ *relative to the RIS the model was traced with* (``model.scenario``):
a model traced with the calibrated RIS (``risloc compare --calibration``) is not moved twice,
and a model traced with the schedule's RIS is corrected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.signal

from dsp import delay_doppler_map, delay_profile
from dsp.spectrum import dft_windows

from ...hall.path_table import apparent_distance
from ...io.report import process_capture
from ...model.beat import beat_cube
from ...model.capture import Capture
from ...model.paths import PathSet, shift_paths
from ...model.ris import RisConfig, ris_response
from ..sweep.leakage import apply_range_gate, range_gate_basis
from .calibration_file import Calibration, apply_to_scenario, calibration_delay
from .traced_hall import HallModel

__all__ = ["Comparison", "compare_capture", "delay_sigma", "parabolic_peak"]

FORMAT = "risloc-comparison"


@dataclass(frozen=True)
class Comparison:
    """Both sides and the peak table. Profiles are zero-Doppler powers [counts²] on ``distance`` [m]."""

    measured: Capture
    simulated: Capture
    beam: int
    distance: np.ndarray
    profile_measured: np.ndarray
    profile_simulated: np.ndarray
    mean_profile_measured: np.ndarray
    mean_profile_simulated: np.ndarray
    ddm_measured: Any
    ddm_simulated: Any
    pave_measured: np.ndarray
    pave_simulated: np.ndarray
    peaks: list[dict[str, Any]]
    summary: dict[str, Any]
    info: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The ``comparison.json`` document (``docs/formats.md``).

        Returns
        -------
        dict
            The peak table and summary (distances m, residuals mm and dB, powers dB of counts²), the
            best beam and its angle [deg], P_ave of both sides per beam [dB].
        """
        return {"format": FORMAT, "version": 1, **self.info, "best_beam": self.beam,
                "best_beam_angle_deg": np.rad2deg(self.measured.sweep.angles[self.beam]).tolist(),
                "peaks": self.peaks, "summary": self.summary,
                "sweep": {"angle_deg": np.rad2deg(self.measured.sweep.angles[:, 0]).tolist(),
                          "pave_measured_db": _db(self.pave_measured).tolist(),
                          "pave_simulated_db": _db(self.pave_simulated).tolist()}}


def _db(x: np.ndarray) -> np.ndarray:
    return 10 * np.log10(np.maximum(np.asarray(x, float), 1e-300))


def parabolic_peak(distance: np.ndarray, db: np.ndarray, i: int) -> tuple[float, float]:
    """The parabolic peak through bins ``i - 1, i, i + 1`` of a profile (the peak tables' reading).

    Parameters
    ----------
    distance : float array [B]
        The profile's axis, evenly spaced [m].
    db : float array [B]
        The profile [dB].
    i : int
        A local maximum's bin.

    Returns
    -------
    (float, float)
        The peak's distance [m] and power [dB]; bin ``i`` itself at the profile's ends or where the
        three bins do not curve down.
    """
    if 0 < i < len(db) - 1:
        a, b, c = db[i - 1], db[i], db[i + 1]
        den = a - 2 * b + c
        if den < 0:
            p = 0.5 * (a - c) / den
            return float(distance[i] + p * (distance[1] - distance[0])), float(b - 0.25 * (a - c) * p)
    return float(distance[i]), float(db[i])


@dataclass(frozen=True)
class _SimulatedSide:
    """The traced hall synthesised for the capture: the capture with the simulated cube, the paths and RIS used
    (calibrated when a calibration is given), the measured noise [counts² per sample] and the gain G [counts² per W]."""

    capture: Capture
    paths: PathSet
    ris: RisConfig
    noise: float
    gain: float
    gain_source: str
    clean: np.ndarray
    gate: Any


def _recalibrated_ris_paths(paths: PathSet, traced: RisConfig, calibrated: RisConfig,
                            carrier_frequency: float) -> PathSet:
    """The RIS loop-back paths of ``paths`` (traced with ``traced``'s τ_RB and ζ) as the ``calibrated`` RIS gives them.

    Parameters
    ----------
    paths : PathSet
        L paths; those with RIS angles include the traced RIS's τ_RB in their delay and √ζ in their gain.
    traced, calibrated : RisConfig
        The RIS the paths were traced with, and the one wanted.
    carrier_frequency : float
        f_c [Hz]: a delay change turns the gain by ``exp(−j2π f_c Δτ)`` (eq. (1)'s carrier phase).

    Returns
    -------
    PathSet
        RIS paths later by ``Δτ = τ_RB' − τ_RB`` [s] and scaled by ``sqrt(ζ'/ζ)``; the others unchanged.
    """
    d_tau = calibrated.loopback_delay - traced.loopback_delay
    d_db = calibrated.amplification_db - traced.amplification_db
    if d_tau == 0.0 and d_db == 0.0:
        return paths
    via = paths.via_ris
    factor = np.where(via, 10 ** (d_db / 20) * np.exp(-2j * np.pi * carrier_frequency * d_tau), 1.0)
    return replace(paths, delay=paths.delay + np.where(via, d_tau, 0.0), gain=paths.gain * factor)


def _simulated_side(capture: Capture, model: HallModel, calibration: Calibration | None,
                    rng: np.random.Generator) -> _SimulatedSide:
    """eq. (1) of the traced paths for the capture's radar, sweep and RIS, scaled by G, with the measured noise floor,
    range-gated as the capture was (module docstring)."""
    y = np.asarray(capture.cube)
    M, K, N = y.shape
    radar = capture.radar
    scenario = model.scenario.base
    paths = model.traced.paths
    ris = scenario.ris
    if calibration is not None:
        scenario = apply_to_scenario(scenario, calibration)
        paths = _recalibrated_ris_paths(paths, ris, scenario.ris, radar.carrier_frequency)
        ris = scenario.ris
        paths = shift_paths(paths, calibration_delay(calibration), radar.carrier_frequency)
    clean = beat_cube(paths, radar=radar, sweep=capture.sweep, ris=ris)                    # [M, K, N] √W
    noise = float(np.sum(np.abs(y - y.mean(axis=1, keepdims=True)) ** 2) / (M * (K - 1) * N))
    if calibration is not None:
        gain = 10 ** (calibration.power_offset_db / 10)
        gain_source = "calibration"
    else:
        gain = max(float(np.mean(np.abs(y) ** 2)) - noise, 1e-30) / max(float(np.mean(np.abs(clean) ** 2)), 1e-300)
        gain_source = "signal power ratio"
    sim = clean * math.sqrt(gain)
    sim = sim + math.sqrt(noise / 2) * (rng.standard_normal(sim.shape) + 1j * rng.standard_normal(sim.shape))
    leak = capture.provenance.get("leakage") or {}
    gate = range_gate_basis(radar, float(leak["gate_range"])) if leak.get("method") == "gate" else None
    if gate is not None:
        sim = apply_range_gate(sim, gate)
    simulated = replace(capture, cube=sim, ris=ris,
                        provenance={"source": "simulation", "scene": str(model.scenario.scene_xml)})
    return _SimulatedSide(capture=simulated, paths=paths, ris=ris, noise=noise, gain=gain, gain_source=gain_source,
                          clean=clean, gate=gate)


def _expected_profile(side: _SimulatedSide, beam: int, radar: Any, processing: Any) -> np.ndarray:
    """The noise-free simulated zero-Doppler profile [counts²] at ``beam``: G·eq. (1), range-gated as the capture."""
    frame = side.clean[beam] * math.sqrt(side.gain)                                     # [K, N] counts
    if side.gate is not None:
        frame = apply_range_gate(frame[None], side.gate)[0]
    return delay_profile(frame, radar, processing).power


def delay_sigma(peak_power: float, noise: float, radar: Any, processing: Any) -> float:
    """1σ of a measured peak's range from white noise (module docstring, "Delay σ").

    Parameters
    ----------
    peak_power : float
        P, the peak's power in the normalised profile (a grid-centred tone of amplitude γ reads |γ|²) [counts²].
    noise : float
        σ², the noise power per ADC sample [counts²].
    radar : dsp.RadarConfig
        N samples, K chirps and the range cell ΔR.
    processing : dsp.ProcessingConfig
        Its window.

    Returns
    -------
    float
        σ_d [m]; infinite for P <= 0.
    """
    if not peak_power > 0 or not noise > 0:
        return math.inf if not peak_power > 0 else 0.0
    w_k, w_n, _ = dft_windows(radar, processing)
    n = np.arange(w_n.size) - 0.5 * (w_n.size - 1)
    rho = peak_power / noise * float(w_k.sum()) ** 2 / float(np.sum(w_k ** 2))
    var = float(np.sum(w_n ** 2 * n ** 2)) / (2.0 * rho * float(np.sum(w_n * n ** 2)) ** 2)   # [rad²/sample²]
    return math.sqrt(var) * w_n.size * radar.range_resolution / (2 * math.pi)


def _peak_table(capture: Capture, side: _SimulatedSide, beam: int, dist: np.ndarray, db_m: np.ndarray,
                db_s: np.ndarray, *, prominence_db: float, floor_db: float) -> list[dict[str, Any]]:
    """The measured profile's peaks [m, dB], strongest first, each with its traced path and simulated counterpart
    (module docstring, "Peaks"); ``db_s`` is the noise-free simulated profile [dB]."""
    radar, paths = capture.radar, side.paths
    leak = capture.provenance.get("leakage") or {}
    gate = float(leak.get("gate_range") or 0.0) + 2 * radar.range_resolution
    found, _ = scipy.signal.find_peaks(db_m, prominence=prominence_db, height=np.median(db_m) + floor_db)
    found = [int(i) for i in found if gate <= dist[i] < radar.max_range - gate]
    app = apparent_distance(paths, radar)
    contribution = np.abs(paths.gain) ** 2
    if paths.via_ris.any():
        r = ris_response(side.ris, capture.sweep, paths.ris_incidence[paths.via_ris],
                         paths.ris_departure[paths.via_ris], wavelength=radar.wavelength)[beam]
        contribution = contribution.copy()
        contribution[paths.via_ris] *= np.abs(r) ** 2
    cell = radar.range_resolution
    w_k, w_n, coherent = dft_windows(radar, capture.processing)
    floor = side.noise * float(np.sum(w_k ** 2) * np.sum(w_n ** 2)) / coherent ** 2   # the profile's noise [counts²]
    sim_peaks, _ = scipy.signal.find_peaks(db_s)                   # local maxima of the noise-free simulated profile
    peaks: list[dict[str, Any]] = []
    for i in sorted(found, key=lambda j: -db_m[j]):
        d_m, p_m = parabolic_peak(dist, db_m, i)
        near = np.flatnonzero(np.abs(app - d_m) <= 1.5 * cell)
        entry: dict[str, Any] = {"distance_m": d_m, "power_db": p_m}
        if near.size:
            best = near[np.argmax(contribution[near])]
            cand = sim_peaks[np.abs(dist[sim_peaks] - d_m) <= 1.5 * cell]
            j = int(cand[np.argmin(np.abs(dist[cand] - d_m))]) if cand.size else i
            d_s, p_s = parabolic_peak(dist, db_s, j)
            sigma = delay_sigma(10 ** (p_m / 10) - floor, side.noise, radar, capture.processing)
            entry.update(label=paths.labels[best], explained=True, path_distance_m=float(app[best]),
                         simulated_distance_m=d_s, simulated_power_db=p_s,
                         delay_residual_mm=1e3 * (d_m - d_s), delay_sigma_mm=1e3 * sigma if math.isfinite(sigma) else None,
                         power_residual_db=p_m - p_s)
        else:
            entry.update(label="unexplained", explained=False, path_distance_m=None, simulated_distance_m=None,
                         simulated_power_db=None, delay_residual_mm=None, delay_sigma_mm=None, power_residual_db=None)
        peaks.append(entry)
    return peaks


def compare_capture(capture: Capture, model: HallModel, *, calibration: Calibration | None = None,
                    rng: np.random.Generator | None = None, prominence_db: float = 6.0,
                    floor_db: float = 12.0) -> Comparison:
    """Compare ``capture`` with the traced hall ``model`` (module docstring).

    Parameters
    ----------
    capture : Capture
        The measured capture [ADC counts].
    model : HallModel
        The traced hall at the capture's radar position (:func:`~.traced_hall.hall_model`).
    calibration : Calibration, optional
        Applied to the simulated side (τ_RB, ζ, range offset; its power offset as G).
    rng : numpy.random.Generator, optional
        The simulated side's noise (default: seed 0).
    prominence_db, floor_db : float
        A measured peak stands this far above its surroundings and above the profile's median [dB].

    Returns
    -------
    Comparison
        Both captures, the best beam's and the sweep-mean zero-Doppler profiles [counts²] on
        ``distance`` [m], the delay-Doppler maps, P_ave of both, the peak table and the summary.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    y = np.asarray(capture.cube)
    radar, processing = capture.radar, capture.processing
    side = _simulated_side(capture, model, calibration, rng)
    simulated, sim = side.capture, side.capture.cube
    loc_m, _ = process_capture(capture)
    loc_s, _ = process_capture(simulated)
    beam = int(loc_m.beam_index)
    ddm_m = delay_doppler_map(y[beam], radar, processing)
    ddm_s = delay_doppler_map(sim[beam], radar, processing)
    dist = ddm_m.distance
    prof_m, prof_s = ddm_m.profile(0.0), ddm_s.profile(0.0)
    mean_m = np.mean(delay_profile(y, radar, processing).power, axis=0)  # every beam's zero-Doppler row, not its map
    mean_s = np.mean(delay_profile(sim, radar, processing).power, axis=0)
    expected = _expected_profile(side, beam, radar, processing)
    peaks = _peak_table(capture, side, beam, dist, _db(prof_m), _db(expected), prominence_db=prominence_db,
                        floor_db=floor_db)
    explained = [p for p in peaks if p["explained"]]
    rms = (lambda xs: float(np.sqrt(np.mean(np.square(xs)))) if xs else None)
    pave_m, pave_s = loc_m.scan.average_power, loc_s.scan.average_power
    summary = {
        "peaks": len(peaks), "explained": len(explained), "unexplained": len(peaks) - len(explained),
        "delay_residual_rms_mm": rms([p["delay_residual_mm"] for p in explained]),
        "delay_residual_max_sigma": max((abs(p["delay_residual_mm"]) / p["delay_sigma_mm"] for p in explained
                                         if p["delay_sigma_mm"]), default=None),
        "power_residual_rms_db": rms([p["power_residual_db"] for p in explained]),
        "power_residual_mean_db": float(np.mean([p["power_residual_db"] for p in explained])) if explained else None,
        "pave_rms_difference_db": float(np.sqrt(np.mean((_db(pave_m) - _db(pave_s)) ** 2))),
        "pave_peak_beam_measured": int(np.argmax(pave_m)), "pave_peak_beam_simulated": int(np.argmax(pave_s)),
        "noise_counts2": side.noise, "gain_db": float(10 * np.log10(side.gain)), "gain_source": side.gain_source,
        "estimate_position_m": None if loc_m.position is None else [float(v) for v in loc_m.position],
        "estimate_distance_m": None if loc_m.distance is None else float(loc_m.distance),
    }
    info = {"scene": str(model.scenario.scene_xml.parent), "ue_position_m": [float(v) for v in model.ue_position],
            "ue_source": model.ue_source, "calibrated": calibration is not None,
            "units": "distance m, residuals mm and dB, powers dB of ADC counts^2"}
    return Comparison(measured=capture, simulated=simulated, beam=beam, distance=dist, profile_measured=prof_m,
                      profile_simulated=prof_s, mean_profile_measured=mean_m, mean_profile_simulated=mean_s,
                      ddm_measured=ddm_m, ddm_simulated=ddm_s, pave_measured=pave_m, pave_simulated=pave_s,
                      peaks=peaks, summary=summary, info=info)
