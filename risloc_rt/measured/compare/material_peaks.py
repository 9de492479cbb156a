"""The peaks of a measured capture as the material fit's :class:`~risloc_rt.hall.material_fit.Observation`.

``risloc calibrate CAPTURE... --materials`` (``docs/calibration-materials.md``) fits the hall's
materials to the powers of the peaks :func:`~.comparison.compare_capture` explains; this module
turns one capture's peak table into the engine's observation.

**Which peaks.** The explained peaks of the comparison (measured zero-Doppler range profile at the
best beam, each associated with the traced path contributing most power near it) whose strongest
path does not go via the RIS: an RIS path's power is set by ζ and the RIS's response, not by the
hall's materials (left out, with the reason). A kept peak must also have at least one traced
*monostatic* path of the material tracer
(:func:`risloc_rt.hall.raytrace.material_gradients.material_jacobian`) within ``window`` of its
delay, else it is left out.

**Delay.** The measured peak's round-trip delay as the tracer reports delays [s]: the range axis
folds at the unambiguous range and carries the radar's range offset, so the delay is the
associated traced path's own delay plus the measured distance's difference from that path's
apparent distance, ``τ = τ_path + 2 (d_measured − d_path,apparent)/c`` (the path's apparent
distance already includes the calibration's range offset when one is given).

**Power and its known offset.** The observed power is the measured peak's power [dB of ADC
counts², the comparison's parabolic peak value]. The link budget from the material tracer's
|a|² to that power is taken per peak from the comparison's own forward model at the scene's
materials: ``offset_k = P_simulated,k − 10 log10 Σ_{p∈k} |a_p|²`` (the noise-free simulated peak
of eq. (1) at the same beam, minus the engine's model power of the same peak). It holds the radar's
receiver gain G (the calibration's power offset when given, else the comparison's G estimate), the
antenna pattern toward that path, the DSP gains and the coherent merging of the peak's paths —
everything the materials do not change. So the fit starts from exactly the comparison's power
residuals (``observed − model = P_measured − P_simulated``) and moves each peak's model power by
``10 log10 (Σ w|a(θ)|² / Σ w|a(θ₀)|²)``, each path weighted as the simulator weights it
(:func:`path_weights`: the antenna pattern toward its departure and arrival, 0 for a pruned path;
the material tracer's own gains are isotropic).

The same peaks read from the complex mean over the sweep's beams (more static echoes, each with a
smaller σ) are :func:`risloc_rt.measured.compare.sweep_mean_peaks.sweep_mean_observation`.

**Power σ.** A peak of power P [counts²] in the profile's complex white noise of power N per bin
(the comparison's noise floor σ² per sample times the windows' noise gain) reads
``|s + n|² = P + 2 Re(s* n) + |n|²``; to first order its variance is ``2 P N``, so its 1σ in dB is

    σ_noise = 10/ln 10 · sqrt(2 N / P) = 4.34 dB · sqrt(2 / SNR)

(0.19 dB at 30 dB SNR, 0.06 dB at 40 dB). The peak's SNR is the measured peak over the floor.
This is the measurement's own noise only; the ray tracer's model error (incoherent vs coherent
sums of a peak's paths, diffuse speckle, geometry) is not in it, so ``model_sigma_db`` (default
0.3 dB) is added in quadrature: ``σ = sqrt(σ_noise² + model_sigma_db²)``. χ² per degree of freedom
well above 1 after the fit says that this model σ is too small.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp import SPEED_OF_LIGHT
from dsp.spectrum import dft_windows

from ...hall.material_fit import DEFAULT_WINDOW, Observation, assign_paths
from ...hall.multipath import monostatic_paths
from ...hall.path_table import apparent_distance
from ...hall.raytrace.material_gradients import material_jacobian
from .calibration_file import Calibration
from .comparison import Comparison, compare_capture
from .traced_hall import HallModel

__all__ = ["CapturePeaks", "DEFAULT_MODEL_SIGMA_DB", "capture_observation", "path_weights", "peak_power_sigma_db"]

#: Model error added in quadrature to every peak's noise σ [dB] (module docstring, "Power σ").
DEFAULT_MODEL_SIGMA_DB: float = 0.3
_DB = 10.0 / math.log(10.0)


@dataclass(frozen=True)
class CapturePeaks:
    """One capture's peaks for the material fit.

    Attributes
    ----------
    observation : Observation
        Radar position [m], peak delays [s], measured powers [dB counts²], 1σ [dB], per-peak offsets [dB].
    comparison : Comparison
        The comparison the peaks come from (at the scene's materials).
    used : tuple of dict
        The kept peaks: ``distance_m`` [m], ``label``, ``delay_s`` [s], ``power_db`` [dB],
        ``offset_db`` [dB], ``sigma_db`` [dB], ``snr_db`` [dB], ``paths`` (monostatic paths in the window).
    left_out : tuple of (float, str)
        Measured distance [m] and reason of every peak not used.
    """

    observation: Observation
    comparison: Comparison
    used: tuple[dict[str, Any], ...]
    left_out: tuple[tuple[float, str], ...]


def peak_power_sigma_db(peak_power: float, noise_floor: float, model_sigma_db: float = 0.0) -> float:
    """1σ of a peak's power [dB] from its SNR, with a model error in quadrature (module docstring).

    Parameters
    ----------
    peak_power : float
        P, the peak's signal power in the profile [counts²] (measured peak minus the floor).
    noise_floor : float
        N, the profile's noise power per bin [counts²].
    model_sigma_db : float
        Added in quadrature [dB], >= 0.

    Returns
    -------
    float
        ``sqrt((10/ln10)² · 2N/P + model_sigma_db²)`` [dB]; inf for P <= 0.
    """
    if not peak_power > 0:
        return math.inf
    return math.sqrt(_DB ** 2 * 2.0 * noise_floor / peak_power + model_sigma_db ** 2)


def path_weights(traced: Any, model: HallModel) -> np.ndarray:
    """The weight of each monostatic path of the material tracer in the simulator: antenna pattern, 0 where pruned.

    The material tracer's gains ``a_p`` are those of isotropic antennas; the simulator
    (:func:`risloc_rt.hall.multipath.monostatic_paths`) multiplies each by the radar's antenna
    gain toward its departure and arrival and then drops the paths far below the noise floor. Two
    paths of one peak can differ by 20 dB there (a double bounce returning from behind the radar
    beside a triple bounce of the same delay), so the fit weights each path as the capture sees it.

    Parameters
    ----------
    traced : TracedPaths
        The material tracer's monostatic paths (``material_jacobian(...).paths``).
    model : HallModel
        The traced hall at the same radar position (its antenna, radar and kept paths).

    Returns
    -------
    numpy.ndarray
        ``w_p = |g_p|² / |a_p|²`` [W, the transmit power times the antenna gains] for every path the
        simulator keeps (same label, delay within 10 fs), else 0; shape [P].
    """
    conv = monostatic_paths(traced, radar=model.scenario.base.radar, antenna=model.scenario.antenna)
    a2 = np.abs(np.asarray(traced.amplitude)) ** 2
    kept = model.traced.paths
    static = [(float(d), label) for d, label, via in zip(kept.delay, kept.labels, kept.via_ris) if not via]
    present = np.array([any(lab == label and abs(d - dk) < 1e-14 for dk, lab in static)
                        for d, label in zip(conv.delay, conv.labels)], dtype=bool)
    ok = present & (a2 > 0)
    weight = np.zeros(a2.size)
    weight[ok] = np.abs(conv.gain[ok]) ** 2 / a2[ok]
    return weight


def _path_delay(model: HallModel, label: str, path_distance: float, radar: Any) -> float | None:
    """The unshifted delay [s] of the non-RIS traced path ``label`` whose apparent distance is nearest ``path_distance``."""
    paths = model.traced.paths
    idx = [i for i, name in enumerate(paths.labels) if name == label and not paths.via_ris[i]]
    if not idx:
        return None
    app = apparent_distance(paths, radar)
    best = min(idx, key=lambda i: abs(app[i] - path_distance))
    return float(paths.delay[best])


def capture_observation(capture: Any, model: HallModel, materials: Any, *,
                        calibration: Calibration | None = None, settings: Any = None,
                        window: float = DEFAULT_WINDOW, model_sigma_db: float = DEFAULT_MODEL_SIGMA_DB,
                        comparison: Comparison | None = None, prominence_db: float = 6.0,
                        floor_db: float = 12.0) -> CapturePeaks:
    """The material fit's observation of one capture at a known radar position (module docstring).

    Parameters
    ----------
    capture : Capture
        The measured capture [ADC counts].
    model : HallModel
        The traced hall at the capture's radar position (:func:`~.traced_hall.hall_model`); its scene
        (``model.scenario.scene_xml``) is the one the material tracer traces.
    materials : str or sequence of str
        The materials to fit (the tracer's derivatives are not used here; the names are checked).
    calibration : Calibration, optional
        The capture's radar/RIS calibration (applied to the comparison: G, range offset, τ_RB, ζ).
    settings : TraceSettings, optional
        The material tracer's settings (use the model's).
    window : float
        Delay window explaining a peak [s] (as for the fit).
    model_sigma_db : float
        Model error in quadrature with each peak's noise σ [dB], >= 0.
    comparison : Comparison, optional
        A comparison already made (else :func:`~.comparison.compare_capture`).
    prominence_db, floor_db : float
        The comparison's peak thresholds [dB] (prominence, height above the profile's median), when it is made here.

    Returns
    -------
    CapturePeaks

    Raises
    ------
    ValueError
        No explained peak is left (the reasons of each), or a bad ``model_sigma_db``.
    """
    if not (isinstance(model_sigma_db, (int, float)) and math.isfinite(model_sigma_db) and model_sigma_db >= 0):
        raise ValueError(f"model_sigma_db={model_sigma_db!r} must be finite and >= 0 [dB]")
    # the material tracer first: an unknown material name is refused before the (slower) comparison
    jac = material_jacobian(model.scenario.scene_xml, model.ue_position, materials, settings=settings)
    comp = comparison if comparison is not None else compare_capture(
        capture, model, calibration=calibration, prominence_db=prominence_db, floor_db=floor_db)
    radar = capture.radar
    w_k, w_n, coherent = dft_windows(radar, capture.processing)
    floor = float(comp.summary["noise_counts2"]) * float(np.sum(w_k ** 2) * np.sum(w_n ** 2)) / coherent ** 2
    ris_labels = {label for label, via in zip(model.traced.paths.labels, model.traced.paths.via_ris) if via}
    candidates, left = [], []
    for p in comp.peaks:
        if not p["explained"]:
            left.append((p["distance_m"], "unexplained: no traced path within 1.5 range cells"))
        elif p["label"] in ris_labels:
            left.append((p["distance_m"], f"via the RIS ({p['label']}): its power is set by zeta and the RIS, not by "
                                          "the materials"))
        else:
            tau = _path_delay(model, p["label"], p["path_distance_m"], radar)
            if tau is None:
                left.append((p["distance_m"], f"its path {p['label']!r} is not among the model's static paths"))
            else:
                candidates.append((p, tau + 2.0 * (p["distance_m"] - p["path_distance_m"]) / SPEED_OF_LIGHT))
    delays = np.array([t for _, t in candidates])
    assign = assign_paths(jac.delay, delays, window)
    weight = path_weights(jac.paths, model)
    used = []
    for k, (p, tau) in enumerate(candidates):
        members = (assign == k) & (weight > 0)
        if not members.any():
            left.append((p["distance_m"], f"no monostatic path of the material tracer within {window * 1e9:.3g} ns"))
            continue
        model_db = _DB * math.log(float(np.sum(weight[members] * np.abs(jac.a[members]) ** 2)))
        signal = 10 ** (p["power_db"] / 10) - floor
        used.append({"distance_m": p["distance_m"], "label": p["label"], "delay_s": tau, "power_db": p["power_db"],
                     "offset_db": p["simulated_power_db"] - model_db,
                     "sigma_db": peak_power_sigma_db(signal, floor, model_sigma_db),
                     "snr_db": 10 * math.log10(signal / floor) if signal > 0 else -math.inf,
                     "paths": int(members.sum())})
    used = [u for u in used if math.isfinite(u["sigma_db"])]
    if not used:
        reasons = "; ".join(f"{d:.3f} m: {r}" for d, r in left) or "the comparison found no peak"
        raise ValueError(f"no peak of this capture can constrain the materials ({reasons})")
    obs = Observation(model.ue_position, [u["delay_s"] for u in used], [u["power_db"] for u in used],
                      [u["sigma_db"] for u in used], offset_db=[u["offset_db"] for u in used], path_weight=weight)
    return CapturePeaks(observation=obs, comparison=comp, used=tuple(used), left_out=tuple(left))
