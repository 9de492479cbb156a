"""Does the measured SNR fit the link budget at the estimated distance? A check for range aliasing.

A return beyond the unambiguous range ``R_max = c/(2 S T_s)`` folds back to ``d̂ = d − k R_max``
and the DSP alone cannot tell: the structural reflection and the re-transmission fold together.
Its power can: the RIS loop-back falls as ``d⁻⁴`` (``|γ_0|² = P G |γ_UR|² ζ |γ_RU|²``, Sec. IV-B),
so a UE at 25.4 m seen at 3.6 m arrives 34 dB weaker than the link budget predicts there. When the
measured sweep-integrated SNR (from the fitted amplitude) lies more than :data:`ALIAS_MARGIN_DB` below the prediction at d̂ and
closer to the prediction at one of ``d̂ + k R_max`` (k = 1 … 3), :func:`range_alias_flag` raises
``aliased``. The check needs a trustworthy power model (transmit power, antenna gain, ζ, noise):
:func:`power_model_trusted` says whether a capture has one (simulations do; measurements only once
calibrated, provenance ``"calibrated": true``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dsp import SPEED_OF_LIGHT, Flag, Localization

from .link_budget import ris_loopback_gain
from .ris import RisConfig, ris_response

__all__ = ["ALIAS_MARGIN_DB", "expected_loopback_snr_db", "measured_loopback_snr_db", "power_model_trusted",
           "range_alias_flag"]

#: The measured SNR must fall this far below the link budget at d̂ before an alias is suspected [dB].
ALIAS_MARGIN_DB = 10.0


def expected_loopback_snr_db(capture: Any, distance: float, aod: Any) -> float:
    """Sweep-integrated SNR of the RIS loop-back the link budget predicts [dB].

    ``|γ_0(d)|² Σ_m |r_m(θ)|² N K / σ²``: the quantity :func:`measured_loopback_snr_db` reads off an
    estimate.

    Parameters
    ----------
    capture : Capture
        Radar (P, G, σ², N, K), RIS (ζ, array) and sweep.
    distance : float
        UE-RIS distance [m].
    aod : float array [2]
        RIS-frame AoD [rad].
    """
    radar, ris, sweep = capture.radar, capture.ris, capture.sweep
    gain = float(ris_loopback_gain(radar, distance, ris.amplification))
    angle = np.asarray(aod, float).reshape(1, 2)
    r = ris_response(ris, sweep, angle, angle, wavelength=radar.wavelength)[:, 0]
    snr = gain**2 * float(np.sum(np.abs(r) ** 2)) * radar.num_samples * radar.num_chirps / radar.noise_power
    return float(10 * np.log10(max(snr, 1e-300)))


def measured_loopback_snr_db(loc: Localization, capture: Any) -> float:
    """Sweep-integrated SNR of the RIS return an estimate measured [dB].

    ``ρ̂ Σ_m A_m(θ̂)²``: the post-integration SNR at the pattern peak from the fitted amplitude
    (``loc.std.peak_snr_db``, off-grid, so without straddle loss) times the pattern energy of the
    sweep at the estimated AoD — the same quantity as :func:`expected_loopback_snr_db`. Falls back
    to ``loc.detection.snr_db`` (integrated over the detector's window only) without an uncertainty.
    """
    if loc.std is None or not np.isfinite(loc.std.peak_snr_db):
        return float(loc.detection.snr_db)
    pattern = capture.ris.beam_pattern().for_wavelength(capture.radar.wavelength)
    energy = float(np.sum(pattern.amplitude(np.nan_to_num(np.asarray(loc.aod, float)), capture.sweep.angles) ** 2))
    return float(loc.std.peak_snr_db + 10 * np.log10(max(energy, 1e-300)))


def power_model_trusted(capture: Any) -> bool:
    """True for simulated captures and for measured ones marked ``"calibrated": true`` in their provenance."""
    prov = capture.provenance
    return prov.get("source") == "simulation" or bool(prov.get("calibrated", False))


def range_alias_flag(loc: Localization, capture: Any, *, margin_db: float = ALIAS_MARGIN_DB,
                     max_folds: int = 3) -> Flag | None:
    """An ``aliased`` flag when the measured power points to a return beyond the unambiguous range.

    Parameters
    ----------
    loc : dsp.Localization
        A detected estimate (its SNR, ``loc.distance``, ``loc.aod``).
    capture : Capture
    margin_db : float
        How far below the prediction at d̂ the measurement must lie [dB].
    max_folds : int
        Aliases ``d̂ + k R_max`` tried, k = 1 … max_folds.

    Returns
    -------
    Flag or None
    """
    if loc.detection is None or not loc.detected or not np.isfinite(loc.distance) or loc.distance <= 0:
        return None
    if not isinstance(capture.ris, RisConfig) or not power_model_trusted(capture):
        return None
    measured = measured_loopback_snr_db(loc, capture)
    aod = np.nan_to_num(np.asarray(loc.aod, float))
    here = expected_loopback_snr_db(capture, loc.distance, aod)
    if measured >= here - margin_db:
        return None
    span = capture.radar.max_range
    folds = [(k, loc.distance + k * span) for k in range(1, max_folds + 1)]
    predicted = [(k, d, expected_loopback_snr_db(capture, d, aod)) for k, d in folds]
    k, d, there = min(predicted, key=lambda item: abs(item[2] - measured))
    if abs(there - measured) >= here - measured:
        return None
    return Flag("aliased",
                f"the measured SNR {measured:.1f} dB is {here - measured:.1f} dB below the {here:.1f} dB the link budget "
                f"predicts at d̂ = {loc.distance:.3f} m, and close to the {there:.1f} dB it predicts at "
                f"d̂ + {k}·R_max = {d:.3f} m (R_max = {span:.2f} m, τ_RB c/2 = "
                f"{capture.ris.loopback_delay * SPEED_OF_LIGHT / 2:.3f} m): the return is probably aliased from beyond "
                "the unambiguous range; raise the sample rate or lower the slope, or check the power calibration")
