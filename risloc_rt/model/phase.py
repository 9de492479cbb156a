"""Accurate phases: cycle counts reduced modulo 1 before the exponential.

The cycle count of a beat tone is a product of float64 parameters, ``T_s (S τ + f_c ν)``; the
fraction of it that reaches ``exp`` must be known to ~1e-16 cycles, because it is then multiplied
by the sample index (up to 599). :func:`exact_fractional_cycles` evaluates it with error-free
transformations (Dekker's product and Knuth's sum in float64), vectorized over any array shape.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["exact_fractional_cycles", "wrapped_tone"]

#: Veltkamp's splitting constant 2^27 + 1: ``a = hi + lo`` with 26-bit halves.
_SPLITTER = 134217729.0


def wrapped_tone(frequency: Any, length: int) -> np.ndarray:
    """``exp(-j2π f i)`` for i = 0…length-1, phase wrapped in float64 [..., length].

    Parameters
    ----------
    frequency : float array [...]
        Tone frequency in cycles per sample (any magnitude) [cycles]; e.g. [L] or [M, L].
    length : int
        Number of samples.

    Returns
    -------
    complex array [..., length]
        One tone per entry of ``frequency``.

    Notes
    -----
    The frequency is first reduced modulo 1 (exact in float64), the product with the index is
    reduced again, and only the fractional cycle count reaches the exponential, so the phase
    error stays below ``length · 2⁻⁵²`` cycles however large f·i is.
    """
    f = np.asarray(frequency, dtype=np.float64)
    f = f - np.floor(f)
    cycles = f[..., None] * np.arange(length, dtype=np.float64)
    cycles -= np.round(cycles)
    return np.exp(-2j * np.pi * cycles)


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Veltkamp: ``a = hi + lo`` exactly, each half with at most 26 significant bits."""
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def _two_prod(a: Any, b: Any) -> tuple[np.ndarray, np.ndarray]:
    """Dekker: ``a·b = p + e`` exactly, p = fl(a·b) (no overflow or underflow assumed)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knuth: ``a + b = s + t`` exactly, s = fl(a + b)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def exact_fractional_cycles(rate_terms: list[tuple[float, Any]], scale: float) -> np.ndarray:
    """``frac(scale · Σ_i c_i x_i)`` element-wise, from the exact values of the float64 inputs [...].

    Parameters
    ----------
    rate_terms : list of (float, float array [...])
        Pairs (c_i, x_i) whose products are summed; the arrays broadcast together (e.g. [L] or
        [M, L]).
    scale : float
        Common factor (e.g. the sample period) [any unit making the result cycles].

    Returns
    -------
    float array [...]
        In [0, 1] (1.0 only where the exact fraction rounds up to it) [cycles].

    Notes
    -----
    Each product ``scale·c_i·x_i`` is expanded without error into four float64 pieces
    (``scale·c_i = k_h + k_l``, then ``k_h·x_i`` and ``k_l·x_i`` each by Dekker's product); each
    piece is reduced modulo 1 (exact) and summed with Knuth's error-free sum, the running sum
    reduced modulo 1 after every step. Only the accumulation of the low parts (each below 2⁻⁵³)
    and the final addition round, so the result is the correctly rounded fraction up to
    ~2⁻¹⁰⁰ cycles, or one unit in the last place in rare near-ties: the same number the exact
    rational computation of :func:`risloc_rt.model.beat_reference.fraction_cycles` gives, about
    10³ times faster for a few dozen paths. Inputs are assumed well inside float64's range
    (|x| < 1e290, no subnormal products that matter): true of every delay, rate and frequency
    of a radar.
    """
    scale = float(scale)
    hi: Any = np.float64(0.0)
    lo: Any = np.float64(0.0)
    for c, x in rate_terms:
        kh, kl = _two_prod(scale, float(c))
        x = np.asarray(x, dtype=np.float64)
        p, e = _two_prod(kh, x)
        q, f = _two_prod(kl, x)
        for piece in (p, e, q, f):
            piece = piece - np.round(piece)  # exact: the integer part is dropped
            s, t = _two_sum(hi, piece)
            hi = s - np.round(s)  # exact, |hi| <= 1/2
            lo = lo + t  # |t| <= 2^-53: its own rounding is ~2^-106
    # hi in [-1/2, 1/2]: move it to [0, 1) without rounding, then round hi + lo once.
    s, t = _two_sum(hi, np.where(hi < 0, 1.0, 0.0))
    out = np.asarray(s + (lo + t), dtype=np.float64)
    out = np.where(out < 0, out + 1.0, out)
    out = np.where(out > 1.0, out - 1.0, out)
    return out
