"""The static peaks of a capture read from the complex mean over the sweep's beams (``--profile sweep-mean``).

A static (beam-independent) echo of the hall is the same in every one of the sweep's M beams: the
radar does not move and the RIS's code does not touch it. Its power can therefore be read from the
**complex mean of the M beams' cubes**, ``ȳ = (1/M) Σ_m y_m`` [counts], processed as one frame
(its zero-Doppler range profile, ``dsp.delay_profile``: that row of ``dsp.delay_doppler_map``): the
static echo keeps its amplitude, the receiver noise (independent from beam to beam) drops to σ²/M
per sample, 10 log10 M ≈ 17.9 dB for 61 beams, and every path via the RIS keeps only its mean
response over the codebook ``(1/M) Σ_m r_m`` (the RIS loop-back's peak falls by ≈ 23 dB in the
default hall). So weaker static echoes (the floor, oblique triple bounces between the walls) rise
above the comparison's thresholds and every static peak's power σ falls by √M.

**Why the complex mean, not the power mean.** The power mean ``(1/M) Σ_m |Y_m|²`` also averages a
peak's power fluctuation (to first order ``var = 2PN/M``, the same as below), but its noise floor
stays at N: a peak must still stand 12 dB over the median of a profile whose median is the noise,
so no new echo crosses the thresholds (measured on the default hall: the same peaks as the best
beam, 2 static of 4), and the RIS paths enter with their full power at every beam. The complex mean
lowers the floor itself (18 dB) and suppresses what varies with the beam; measured on the same
capture: 3 static peaks (wall_1, the floor, the wall_0 > wall_1 > wall_2 triple bounce).

**Power σ of a peak of the mean.** ``ȳ`` at the peak's bin is ``s + n̄`` with ``n̄`` complex white
noise of power ``N/M`` per bin (N the single frame's, the comparison's floor σ² times the windows'
noise gain), so as for one frame (:func:`~.material_peaks.peak_power_sigma_db`)

    σ_noise = 10/ln 10 · sqrt(2 N / (M P)) = 4.34 dB · sqrt(2 / (M · SNR₁))

with SNR₁ = P/N the single frame's SNR; the model error ``model_sigma_db`` is added in quadrature.
Checked by a Monte Carlo of the whole processing (``tests/measured/test_material_sweep_mean.py``).

**The forward side, processed alike.** The noise-free simulated cube of the comparison (eq. (1) of
the traced paths for the same beams, scaled by the same G, range-gated as the capture) is averaged
over the same M beams and processed the same way; each peak's offset is that expected peak power
minus the engine's model power ``10 log10 Σ|a_p|²`` of the same peak (as in
:mod:`.material_peaks`). With a calibration the model must be traced with the calibrated RIS (as
``risloc calibrate`` does): the calibration's range offset then shifts every path.

**Which peaks.** Local maxima of the measured mean profile ``prominence_db`` prominent and
``floor_db`` over its median, beyond the range gate, each associated with the traced path of
largest power *in the mean* within 1.5 range cells (an RIS path counts with its mean response).
Left out, each with its reason: an unexplained peak; a peak whose strongest path goes via the RIS
(set by ζ and the RIS); the RIS panel's structural echo and its multipath (``ris_structure``: its
power is the panel's, which the material tracer does not model); a peak whose expected power
exceeds the coherent sum of its own static paths ``G (Σ|g_p|)²`` by more than
:data:`MAX_BLEND_DB` (it is mostly another echo's sidelobe or an RIS path's mean, which the
materials do not set); a peak with no monostatic path of the material tracer within ``window``
(each path weighted as the simulator weights it, :func:`~.material_peaks.path_weights`); a peak less
than :data:`MIN_SNR_DB` over the mean's noise floor (near the thresholds a peak is found only when the
noise adds to it: measured, single wall bounces at 10–11 dB SNR read 2.9 and 3.6 dB high).

**Observed power.** The measured peak of the mean minus the mean's noise floor, ``|s + n̄|² − N/M``
(the expected value of ``|s + n̄|²`` is ``P + N/M``; the expected side is noise-free).

**Repeats.** Captures of the same sweep from the same radar position (``repeats``: recorded one
after another, the radar not moved) hold the same static echoes with independent noise, so the
mean over all their beams, C captures of M beams each, lowers the floor by 10 log10(C·M): 16
captures add 12 dB, enough to lift the p-polarised floor > wall > ceiling bounce of the default hall
(4 dB over one sweep's mean floor) past :data:`MIN_SNR_DB` (``docs/calibration-materials.md``,
"Repeats"). Each repeat's beam mean is turned onto the first one's phase first (the phase of their
inner product, which the strong static echoes set: a common phase drift of the radar between
recordings, none in an emulated one); a radar moved by a fraction of the wavelength between them
would average its echoes away, which is why the radar must not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal

from dsp import SPEED_OF_LIGHT, delay_profile
from dsp.spectrum import dft_windows

from ...hall.material_fit import DEFAULT_WINDOW, Observation, assign_paths
from ...hall.path_table import apparent_distance
from ...hall.raytrace.material_gradients import material_jacobian
from ...model.beat import beat_cube
from ...model.paths import shift_paths
from ...model.ris import ris_response
from ..sweep.leakage import apply_range_gate, range_gate_basis
from .calibration_file import Calibration, apply_to_scenario, calibration_delay
from .comparison import Comparison, compare_capture, delay_sigma, parabolic_peak
from .material_peaks import DEFAULT_MODEL_SIGMA_DB, CapturePeaks, path_weights, peak_power_sigma_db
from .traced_hall import HallModel

__all__ = ["MAX_BLEND_DB", "MIN_SNR_DB", "SweepMeanProfiles", "sweep_mean_observation", "sweep_mean_power_sigma_db",
           "sweep_mean_profile", "sweep_mean_profiles", "sweep_mean_residuals", "joint_mean_frame",
           "weighted_power_residuals"]

#: A peak whose expected power exceeds the coherent sum of its own static paths by more than this [dB] is left out.
MAX_BLEND_DB: float = 1.0
#: A peak less than this far over the mean's noise floor [dB] is left out (threshold-selection and noise bias).
MIN_SNR_DB: float = 15.0
_DB = 10.0 / math.log(10.0)


@dataclass(frozen=True)
class SweepMeanProfiles:
    """The measured and the expected (noise-free) zero-Doppler profiles of the complex beam mean.

    Attributes
    ----------
    distance : numpy.ndarray
        Range axis [m].
    measured, expected : numpy.ndarray
        Powers [counts²] of the measured and of the noise-free simulated complex mean.
    noise_floor : float
        Noise power per bin of the mean [counts²]: the single frame's divided by ``beams``.
    beams : int
        M, the beams averaged.
    gain : float
        G, the comparison's receiver gain [counts² per W].
    """

    distance: np.ndarray
    measured: np.ndarray
    expected: np.ndarray
    noise_floor: float
    beams: int
    gain: float


def sweep_mean_power_sigma_db(peak_power: float, noise_floor: float, beams: int, model_sigma_db: float = 0.0) -> float:
    """1σ [dB] of a peak's power read from the complex mean of ``beams`` frames (module docstring).

    Parameters
    ----------
    peak_power : float
        P, the static echo's power in the profile [counts²].
    noise_floor : float
        N, the noise power per bin of *one* frame's profile [counts²].
    beams : int
        M >= 1, the frames averaged.
    model_sigma_db : float
        Added in quadrature [dB], >= 0.

    Returns
    -------
    float
        ``sqrt((10/ln10)² · 2N/(M P) + model_sigma_db²)`` [dB]; inf for P <= 0.
    """
    if isinstance(beams, bool) or int(beams) != beams or beams < 1:
        raise ValueError(f"beams={beams!r} must be an integer >= 1")
    return peak_power_sigma_db(peak_power, noise_floor / beams, model_sigma_db)


def joint_mean_frame(cubes: Any) -> np.ndarray:
    """The complex mean over every beam of one or several cubes of the same sweep, each cube's beam mean turned
    onto the first one's phase (module docstring, "Repeats").

    Parameters
    ----------
    cubes : array [M, K, N] or sequence of them
        One capture's cube, or the cubes of repeats [counts], all of one shape.

    Returns
    -------
    numpy.ndarray
        The mean frame [K, N] [counts].
    """
    if hasattr(cubes, "ndim") and np.ndim(cubes) == 3:
        cubes = [cubes]
    means = [np.asarray(c).mean(axis=0) for c in cubes]
    if not means or any(m.shape != means[0].shape for m in means):
        raise ValueError("repeats must be cubes of the same sweep and chirp: their shapes differ "
                         f"({[list(np.shape(c)) for c in cubes]})")
    first = means[0]
    turned = [first] + [m * np.exp(-1j * np.angle(np.vdot(first, m))) for m in means[1:]]
    return np.mean(turned, axis=0)


def sweep_mean_profile(cube: Any, radar: Any, processing: Any) -> np.ndarray:
    """Zero-Doppler range profile [counts²] of the complex mean over the beams of a cube (or of repeats).

    Parameters
    ----------
    cube : array [M, K, N], or a sequence of them
        M beams' frames of K chirps of N samples [counts]; several: repeats (:func:`joint_mean_frame`).
    radar : dsp.RadarConfig
    processing : dsp.ProcessingConfig

    Returns
    -------
    numpy.ndarray
        ``|DDM(mean_m cube[m])|²`` at zero Doppler on the processing's range axis [counts²].
    """
    return delay_profile(joint_mean_frame(cube), radar, processing).power


def _check_repeats(capture: Any, repeats: Any) -> list[Any]:
    """``repeats`` as a list, each of the capture's radar, sweep, RIS and cube shape (a one-line error else)."""
    repeats = list(repeats or ())
    for k, r in enumerate(repeats):
        same = (r.radar == capture.radar and np.shape(r.cube) == np.shape(capture.cube)
                and np.allclose(r.sweep.angles, capture.sweep.angles)
                and np.allclose(r.ris.pose.position, capture.ris.pose.position))
        if not same:
            raise ValueError(f"repeat {k + 1} is not a capture of the same radar, sweep and RIS as the first (its radar "
                             "configuration, sweep angles, RIS position or cube shape differ): give repeats of one "
                             "experiment only")
    return repeats


def _model_paths(model: HallModel, calibration: Calibration | None, carrier: float) -> tuple[Any, Any]:
    """The traced paths and RIS the comparison synthesises (calibrated: range offset applied; RIS must match)."""
    paths, ris = model.traced.paths, model.scenario.base.ris
    if calibration is None:
        return paths, ris
    if (ris.loopback_delay, ris.amplification_db) != (calibration.loopback_delay, calibration.amplification_db):
        raise ValueError("the sweep-mean profile needs the model traced with the calibrated RIS: pass "
                         "ris=replace(capture.ris, loopback_delay=..., amplification_db=...) to hall_model")
    ris = apply_to_scenario(model.scenario.base, calibration).ris
    return shift_paths(paths, calibration_delay(calibration), carrier), ris


def sweep_mean_profiles(capture: Any, model: HallModel, comparison: Comparison,
                        calibration: Calibration | None = None, repeats: Any = ()) -> SweepMeanProfiles:
    """Both sides' complex-mean profiles, the expected one noise-free with the comparison's G (module docstring).

    Parameters
    ----------
    capture : Capture
        The measured capture [ADC counts] (range-gated as imported).
    model : HallModel
        The traced hall at the capture's radar position.
    comparison : Comparison
        :func:`~.comparison.compare_capture` of the capture and model (its G and noise floor are used).
    calibration : Calibration, optional
        As given to the comparison.
    repeats : sequence of Capture
        Further captures of the same sweep from the same position (module docstring, "Repeats"): the
        measured mean is over all their beams, the floor divided by all of them.

    Returns
    -------
    SweepMeanProfiles
    """
    radar, processing = capture.radar, capture.processing
    paths, ris = _model_paths(model, calibration, radar.carrier_frequency)
    gain = 10 ** (float(comparison.summary["gain_db"]) / 10)
    clean = beat_cube(paths, radar=radar, sweep=capture.sweep, ris=ris).mean(axis=0) * math.sqrt(gain)
    leak = capture.provenance.get("leakage") or {}
    if leak.get("method") == "gate":
        clean = apply_range_gate(clean[None], range_gate_basis(radar, float(leak["gate_range"])))[0]
    expected = delay_profile(clean, radar, processing).power
    repeats = _check_repeats(capture, repeats)
    measured = sweep_mean_profile([capture.cube] + [r.cube for r in repeats], radar, processing)
    w_k, w_n, coherent = dft_windows(radar, processing)
    beams = int(np.asarray(capture.cube).shape[0]) * (1 + len(repeats))
    floor = float(comparison.summary["noise_counts2"]) * float(np.sum(w_k ** 2) * np.sum(w_n ** 2)) / coherent ** 2
    return SweepMeanProfiles(distance=np.asarray(comparison.distance), measured=measured, expected=expected,
                             noise_floor=floor / beams, beams=beams, gain=gain)


def _mean_contribution(paths: Any, ris: Any, capture: Any) -> np.ndarray:
    """Each path's power in the beam mean [W]: |g|², times |mean_m r_m|² for a path via the RIS."""
    power = np.abs(paths.gain) ** 2
    if paths.via_ris.any():
        r = ris_response(ris, capture.sweep, paths.ris_incidence[paths.via_ris], paths.ris_departure[paths.via_ris],
                         wavelength=capture.radar.wavelength)
        power = power.copy()
        power[paths.via_ris] *= np.abs(np.mean(r, axis=0)) ** 2
    return power


def _mean_peaks(capture: Any, model: HallModel, prof: SweepMeanProfiles, calibration: Calibration | None, *,
                prominence_db: float, floor_db: float) -> tuple[list[dict[str, Any]], list[tuple[float, str]]]:
    """The mean profile's static candidate peaks (distance, power, unfolded delay, expected power) and those left out."""
    radar = capture.radar
    paths, ris = _model_paths(model, calibration, radar.carrier_frequency)
    dist, cell = prof.distance, radar.range_resolution
    db_m = _DB * np.log(np.maximum(prof.measured, 1e-300))
    db_s = _DB * np.log(np.maximum(prof.expected, 1e-300))
    leak = capture.provenance.get("leakage") or {}
    gate = float(leak.get("gate_range") or 0.0) + 2 * cell
    found, _ = scipy.signal.find_peaks(db_m, prominence=prominence_db, height=np.median(db_m) + floor_db)
    found = [int(i) for i in found if gate <= dist[i] < radar.max_range - gate]
    sim_peaks, _ = scipy.signal.find_peaks(db_s)
    app = apparent_distance(paths, radar)
    power = _mean_contribution(paths, ris, capture)
    candidates, left = [], []
    for i in sorted(found, key=lambda j: -db_m[j]):
        d_m, p_m = parabolic_peak(dist, db_m, i)
        near = np.flatnonzero(np.abs(app - d_m) <= 1.5 * cell)
        if not near.size:
            left.append((d_m, "unexplained: no traced path within 1.5 range cells"))
            continue
        best = int(near[np.argmax(power[near])])
        label = paths.labels[best]
        if paths.via_ris[best]:
            left.append((d_m, f"via the RIS ({label}): its power is set by zeta and the RIS, not by the materials"))
            continue
        if label.startswith("ris_structure"):
            left.append((d_m, f"the RIS panel's structural echo ({label}): its power is the panel's, not the hall's "
                              "materials"))
            continue
        cand = sim_peaks[np.abs(dist[sim_peaks] - d_m) <= 1.5 * cell]
        j = int(cand[np.argmin(np.abs(dist[cand] - d_m))]) if cand.size else i
        d_s, p_s = parabolic_peak(dist, db_s, j)
        own = near[~paths.via_ris[near] & np.array([paths.labels[k].startswith("hall") for k in near])]
        own_db = _DB * math.log(prof.gain * float(np.sum(np.abs(paths.gain[own]))) ** 2 + 1e-300)
        if p_s > own_db + MAX_BLEND_DB:
            left.append((d_m, f"blended ({label}): the expected peak is {p_s - own_db:.1f} dB over its own static "
                              "paths (another echo's sidelobe or an RIS path's mean)"))
            continue
        tau = float(paths.delay[best]) + 2.0 * (d_m - float(app[best])) / SPEED_OF_LIGHT
        candidates.append({"distance_m": d_m, "label": label, "delay_s": tau, "power_db": p_m,
                           "expected_power_db": p_s, "expected_distance_m": d_s})
    return candidates, left


def _measured(c: dict[str, Any], prof: SweepMeanProfiles, noise: float, capture: Any,
              model_sigma_db: float) -> dict[str, Any]:
    """A candidate peak's measured numbers: its power over the mean's floor [counts², dB], SNR [dB], power σ [dB],
    power and delay residuals against the expected peak [dB, mm] and the delay's σ [mm]."""
    signal = 10 ** (c["power_db"] / 10) - prof.noise_floor
    snr_db = 10 * math.log10(signal / prof.noise_floor) if signal > 0 else -math.inf
    power_db = 10 * math.log10(signal) if signal > 0 else -math.inf
    sigma = sweep_mean_power_sigma_db(signal, prof.noise_floor * prof.beams, prof.beams, model_sigma_db)
    return {"signal": signal, "snr_db": snr_db, "power_db": power_db, "sigma_db": sigma, "beams": prof.beams,
            "power_residual_db": power_db - c["expected_power_db"],
            "delay_residual_mm": 1e3 * (c["distance_m"] - c["expected_distance_m"]),
            "delay_sigma_mm": 1e3 * delay_sigma(max(signal, 1e-300), noise / prof.beams, capture.radar,
                                                capture.processing)}


def weighted_power_residuals(residual_db: Any, sigma_db: Any) -> tuple[float | None, float | None]:
    """How well a hall predicts peak powers, judged by each peak's own σ.

    A plain rms is set by the weakest peaks (σ 0.8–1 dB at 17–19 dB SNR, for the true hall too); weighted by
    1/σ², the well-measured peaks count as they should.

    Parameters
    ----------
    residual_db : float array [K]
        Measured − predicted power of each peak [dB].
    sigma_db : float array [K]
        Each peak's 1σ [dB], > 0.

    Returns
    -------
    weighted_rms_db : float or None
        sqrt(Σ r²/σ² / Σ 1/σ²) [dB]; None for no peak.
    chi2 : float or None
        Σ (r/σ)² [unitless]: for a hall that predicts every peak within its noise, χ² is distributed as
        χ²_K (mean K, sd √(2K)); None for no peak.
    """
    r = np.asarray(residual_db, dtype=float).reshape(-1)
    sd = np.asarray(sigma_db, dtype=float).reshape(-1)
    if r.size != sd.size:
        raise ValueError(f"residual_db and sigma_db must have one entry per peak; got {r.size} and {sd.size}")
    if not r.size:
        return None, None
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(sd)) and np.all(sd > 0)):
        raise ValueError("residual_db must be finite and sigma_db finite and > 0 [dB]")
    w = 1.0 / sd ** 2
    return float(np.sqrt(np.sum(w * r * r) / np.sum(w))), float(np.sum(w * r * r))


def sweep_mean_residuals(capture: Any, model: HallModel, comparison: Comparison,
                         calibration: Calibration | None = None, *, model_sigma_db: float = DEFAULT_MODEL_SIGMA_DB,
                         prominence_db: float = 6.0, floor_db: float = 12.0, repeats: Any = ()) -> dict[str, Any]:
    """The sweep mean's static peaks measured against the traced hall, for ``risloc compare``'s page.

    The peaks :func:`sweep_mean_observation` would use, chosen without the material tracer (the same
    thresholds, association, blend test and :data:`MIN_SNR_DB`), each with its power residual (the
    measured peak of the mean, its floor taken off, minus the noise-free expected peak) and delay
    residual, and their σ.

    Parameters
    ----------
    capture : Capture
        The measured capture [ADC counts].
    model : HallModel
        The traced hall at the capture's radar position (with the calibrated RIS when a calibration is given).
    comparison : Comparison
        :func:`~.comparison.compare_capture` of the two (its G and noise floor are used).
    calibration : Calibration, optional
        As given to the comparison.
    model_sigma_db : float
        Model error in quadrature with each peak's noise σ [dB].
    prominence_db, floor_db : float
        Peak thresholds on the mean profile [dB] (prominence, height above its median).
    repeats : sequence of Capture
        Further captures of the same sweep from the same position, averaged in (module docstring, "Repeats").

    Returns
    -------
    dict
        ``beams`` (M, over all repeats); ``peaks``: per static peak ``distance_m`` [m], ``label``, ``snr_db``, ``sigma_db`` [dB],
        ``power_residual_db`` [dB], ``delay_residual_mm``, ``delay_sigma_mm`` [mm]; ``left_out``: ``distance_m`` and
        ``reason`` of every other peak of the mean; ``power_residual_rms_db`` [dB] and ``delay_residual_rms_mm`` [mm]
        over ``peaks``, ``power_residual_weighted_rms_db`` [dB] and ``power_chi2`` (each residual over its σ:
        :func:`weighted_power_residuals`) (None without any).
    """
    prof = sweep_mean_profiles(capture, model, comparison, calibration, repeats)
    candidates, left = _mean_peaks(capture, model, prof, calibration, prominence_db=prominence_db, floor_db=floor_db)
    noise = float(comparison.summary["noise_counts2"])
    peaks = []
    for c in candidates:
        m = _measured(c, prof, noise, capture, model_sigma_db)
        if m["snr_db"] < MIN_SNR_DB:
            left.append((c["distance_m"], f"{c['label']}: {m['snr_db']:.1f} dB over the mean's noise floor, below "
                                          f"{MIN_SNR_DB:g} dB"))
            continue
        peaks.append({"distance_m": c["distance_m"], "label": c["label"],
                      **{k: m[k] for k in ("snr_db", "sigma_db", "power_residual_db", "delay_residual_mm",
                                           "delay_sigma_mm")}})
    peaks.sort(key=lambda p: p["distance_m"])

    def rms(key: str) -> float | None:
        return float(np.sqrt(np.mean([p[key] ** 2 for p in peaks]))) if peaks else None

    weighted, chi2 = weighted_power_residuals([p["power_residual_db"] for p in peaks], [p["sigma_db"] for p in peaks])
    return {"beams": prof.beams, "peaks": peaks,
            "left_out": [{"distance_m": d, "reason": r} for d, r in sorted(left)],
            "power_residual_rms_db": rms("power_residual_db"), "delay_residual_rms_mm": rms("delay_residual_mm"),
            "power_residual_weighted_rms_db": weighted, "power_chi2": chi2}


def sweep_mean_observation(capture: Any, model: HallModel, materials: Any, *,
                           calibration: Calibration | None = None, settings: Any = None,
                           window: float = DEFAULT_WINDOW, model_sigma_db: float = DEFAULT_MODEL_SIGMA_DB,
                           comparison: Comparison | None = None, prominence_db: float = 6.0,
                           floor_db: float = 12.0, repeats: Any = ()) -> CapturePeaks:
    """The material fit's observation of one capture from its sweep-mean static peaks (module docstring).

    Parameters
    ----------
    capture : Capture
        The measured capture [ADC counts].
    model : HallModel
        The traced hall at the capture's radar position (with the calibrated RIS when a calibration is given).
    materials : str or sequence of str
        The materials to fit (names checked by the material tracer first).
    calibration : Calibration, optional
        The capture's radar/RIS calibration (G, range offset).
    settings : TraceSettings, optional
        The material tracer's settings (use the model's).
    window : float
        Delay window explaining a peak [s] (as for the fit).
    model_sigma_db : float
        Model error in quadrature with each peak's noise σ [dB], >= 0.
    comparison : Comparison, optional
        A comparison already made (else :func:`~.comparison.compare_capture`); its G and noise floor are used.
    prominence_db, floor_db : float
        Peak thresholds on the mean profile [dB] (prominence, height above its median).
    repeats : sequence of Capture
        Further captures of the same sweep from the same position, averaged in (module docstring, "Repeats");
        the comparison (G, noise floor) is the first capture's.

    Returns
    -------
    CapturePeaks
        ``used`` entries as :func:`~.material_peaks.capture_observation`'s (``snr_db`` over the mean's floor), with
        ``beams`` (M), ``power_residual_db`` [dB] and ``delay_residual_mm`` [mm] (measured minus expected peak of the
        mean) and ``delay_sigma_mm`` (the comparison's delay σ at the mean's noise σ²/M) added.

    Raises
    ------
    ValueError
        No peak is left (the reasons of each), a bad ``model_sigma_db``, or a calibration without the
        calibrated RIS in the model.
    """
    if not (isinstance(model_sigma_db, (int, float)) and math.isfinite(model_sigma_db) and model_sigma_db >= 0):
        raise ValueError(f"model_sigma_db={model_sigma_db!r} must be finite and >= 0 [dB]")
    jac = material_jacobian(model.scenario.scene_xml, model.ue_position, materials, settings=settings)
    comp = comparison if comparison is not None else compare_capture(
        capture, model, calibration=calibration, prominence_db=prominence_db, floor_db=floor_db)
    prof = sweep_mean_profiles(capture, model, comp, calibration, repeats)
    candidates, left = _mean_peaks(capture, model, prof, calibration, prominence_db=prominence_db, floor_db=floor_db)
    assign = assign_paths(jac.delay, np.array([c["delay_s"] for c in candidates]), window)
    noise = float(comp.summary["noise_counts2"])
    weight = path_weights(jac.paths, model)
    used = []
    for k, c in enumerate(candidates):
        members = (assign == k) & (weight > 0)
        if not members.any():
            left.append((c["distance_m"], f"no monostatic path of the material tracer within {window * 1e9:.3g} ns"))
            continue
        model_db = _DB * math.log(float(np.sum(weight[members] * np.abs(jac.a[members]) ** 2)))
        m = _measured(c, prof, noise, capture, model_sigma_db)
        if m["snr_db"] < MIN_SNR_DB:
            left.append((c["distance_m"], f"{c['label']}: {m['snr_db']:.1f} dB over the mean's noise floor, below "
                                          f"{MIN_SNR_DB:g} dB (its power is biased by the threshold and the noise)"))
            continue
        used.append({"distance_m": c["distance_m"], "label": c["label"], "delay_s": c["delay_s"],
                     "power_db": m["power_db"], "offset_db": c["expected_power_db"] - model_db,
                     "sigma_db": m["sigma_db"], "snr_db": m["snr_db"], "paths": int(members.sum()),
                     **{k: m[k] for k in ("beams", "power_residual_db", "delay_residual_mm", "delay_sigma_mm")}})
    if not used:
        reasons = "; ".join(f"{d:.3f} m: {r}" for d, r in left) or "the sweep-mean profile has no peak"
        raise ValueError(f"no sweep-mean peak of this capture can constrain the materials ({reasons})")
    obs = Observation(model.ue_position, [u["delay_s"] for u in used], [u["power_db"] for u in used],
                      [u["sigma_db"] for u in used], offset_db=[u["offset_db"] for u in used], path_weight=weight)
    return CapturePeaks(observation=obs, comparison=comp, used=tuple(used), left_out=tuple(left))
