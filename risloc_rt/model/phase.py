"""Accurate phases: cycle counts reduced modulo 1 before the exponential."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

__all__ = ["exact_fractional_cycles", "wrapped_tone"]


def wrapped_tone(frequency: np.ndarray, length: int) -> np.ndarray:
    """``exp(-j2π f i)`` for i = 0…length-1, phase wrapped in float64 [L, length].

    Parameters
    ----------
    frequency : float array [L]
        Tone frequency in cycles per sample (any magnitude) [cycles].
    length : int
        Number of samples.

    Notes
    -----
    The frequency is first reduced modulo 1 (exact in float64), the product with the index is
    reduced again, and only the fractional cycle count reaches the exponential, so the phase
    error stays below ``length · 2⁻⁵²`` cycles however large f·i is.
    """
    f = np.asarray(frequency, dtype=np.float64)
    f = f - np.floor(f)
    cycles = np.outer(f, np.arange(length, dtype=np.float64))
    cycles -= np.round(cycles)
    return np.exp(-2j * np.pi * cycles)


def exact_fractional_cycles(rate_terms: list[tuple[float, np.ndarray]], scale: float) -> np.ndarray:
    """``frac(scale · Σ_i c_i x_i)`` per path, computed exactly from the float64 inputs [L].

    Parameters
    ----------
    rate_terms : list of (float, float array [L])
        Pairs (c_i, x_i) whose products are summed per path.
    scale : float
        Common factor (e.g. the sample period) [any unit making the result cycles].

    Notes
    -----
    Each input float is converted to an exact rational, so the only rounding is the final
    conversion of a number in [0, 1): the per-sample frequency reaching :func:`wrapped_tone` is
    correctly rounded, whatever the magnitude of the terms.
    """
    k = Fraction(scale)
    coeffs = [(Fraction(c), np.asarray(x, dtype=float)) for c, x in rate_terms]
    n = coeffs[0][1].shape[0] if coeffs else 0
    out = np.empty(n)
    for j in range(n):
        total = k * sum((c * Fraction(float(x[j])) for c, x in coeffs), Fraction(0))
        out[j] = float(total - (total.numerator // total.denominator))
    return out
