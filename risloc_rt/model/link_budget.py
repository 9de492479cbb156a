"""Path gains of the seed paper's simulator (Sec. IV-B)."""

from __future__ import annotations

from typing import Any

import numpy as np

from dsp import RadarConfig
from dsp.validation import as_finite_array

from .phase import exact_fractional_cycles

__all__ = ["carrier_phase", "point_target_gain", "ris_loopback_gain", "one_way_free_space_gain"]


def carrier_phase(delay: Any, carrier_frequency: float) -> np.ndarray:
    """``exp(-j2π f_c τ)`` [unitless], with the cycle count wrapped in float64 first.

    Parameters
    ----------
    delay : float array [...]
        τ [s].
    carrier_frequency : float
        f_c [Hz].
    """
    tau = np.asarray(delay, dtype=float)
    frac = exact_fractional_cycles([(1.0, tau.ravel())], carrier_frequency).reshape(tau.shape)
    return np.exp(-2j * np.pi * frac)


def one_way_free_space_gain(distance: Any, wavelength: float) -> np.ndarray:
    """|γ_UR|² = λ² / (4π d)², one-way free-space power gain [unitless]."""
    d = as_finite_array(distance, "distance")
    if np.any(d <= 0):
        raise ValueError("distance must be > 0 m")
    return wavelength**2 / (4 * np.pi * d) ** 2


def point_target_gain(radar: RadarConfig, distance: Any, rcs: Any) -> np.ndarray:
    """|γ_l| of a point target: ``sqrt(P G_trx σ λ² / ((4π)³ d⁴))`` [√W].

    Parameters
    ----------
    radar : RadarConfig
    distance : float array [...]
        d_l, one-way radar-target distance [m].
    rcs : float array [...]
        σ, radar cross-section [m²].
    """
    d = as_finite_array(distance, "distance")
    s = as_finite_array(rcs, "rcs")
    if np.any(d <= 0):
        raise ValueError("target distance must be > 0 m (a target cannot sit on the radar)")
    if np.any(s < 0):
        raise ValueError("rcs must be >= 0 m²")
    power = radar.tx_power * radar.antenna_gain * s * radar.wavelength**2 / ((4 * np.pi) ** 3 * d**4)
    return np.sqrt(power)


def ris_loopback_gain(radar: RadarConfig, distance: Any, amplification: float) -> np.ndarray:
    """|γ_0| of the RIS loop-back: ``sqrt(P G_trx |γ_UR|² ζ |γ_RU|²)`` [√W], before the array response.

    Parameters
    ----------
    radar : RadarConfig
    distance : float array [...]
        d_0, UE-RIS distance [m].
    amplification : float
        ζ, linear [unitless].
    """
    g = one_way_free_space_gain(distance, radar.wavelength)
    return np.sqrt(radar.tx_power * radar.antenna_gain * g * amplification * g)

