"""The first implementation of eq. (1), kept as a reference for tests and benchmarks.

:func:`_beat_cube_reference` is ``beat_cube`` as it was before the fast synthesis (one batched
product over all beams, per-path phases in exact rational arithmetic with ``fractions.Fraction``,
the slow-time phase on the ramp duration T). It is slow (Python loops over paths) and serves
only to show that :func:`risloc_rt.model.beat.beat_cube` computes the same cube
(``tests/model/test_synthesis_speed_equivalence.py``, ``benchmarks/bench_synthesis.py``).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from dsp import RadarConfig
from dsp.sweep import BeamSweep

from .paths import PathSet
from .phase import wrapped_tone
from .ris import RisConfig, ris_response

__all__: list[str] = []


def fraction_cycles(rate_terms: list[tuple[float, np.ndarray]], scale: float) -> np.ndarray:
    """``frac(scale · Σ_i c_i x_i)`` per path in exact rational arithmetic [L] (the reference).

    Each input float is converted to an exact rational, so the only rounding is the final
    conversion of a number in [0, 1): the result is correctly rounded.
    """
    k = Fraction(scale)
    coeffs = [(Fraction(c), np.asarray(x, dtype=float)) for c, x in rate_terms]
    n = coeffs[0][1].shape[0] if coeffs else 0
    out = np.empty(n)
    for j in range(n):
        total = k * sum((c * Fraction(float(x[j])) for c, x in coeffs), Fraction(0))
        out[j] = float(total - (total.numerator // total.denominator))
    return out


def _beat_cube_reference(paths: PathSet, *, radar: RadarConfig, sweep: BeamSweep,
                         ris: RisConfig | None) -> np.ndarray:
    """Noiseless beat cube of eq. (1) [M, K, N] [√W], the original implementation.

    ``Y[m, k, n] = Σ_l γ_l r_{m,l} e^{-j2π(S τ_l + f_c ν_l) n T_s} e^{-j2π f_c ν_l k T}``, with the
    slow-time phase on the ramp duration T (back-to-back chirps).
    """
    m = sweep.num_beams
    fast = wrapped_tone(fraction_cycles(
        [(radar.slope, paths.delay), (radar.carrier_frequency, paths.delay_rate)], radar.sample_period),
        radar.num_samples)  # [L, N]
    slow = wrapped_tone(fraction_cycles(
        [(radar.carrier_frequency, paths.delay_rate)], radar.chirp_duration), radar.num_chirps)  # [L, K]
    via = paths.via_ris
    common = (slow[~via].T * paths.gain[~via]) @ fast[~via]  # [K, L0] @ [L0, N]
    cube = np.broadcast_to(common, (m,) + common.shape).copy()
    if via.any():
        if ris is None:
            raise ValueError("the path set has RIS loop-back paths but no RisConfig was given")
        coef = paths.gain[via] * ris_response(
            ris, sweep, paths.ris_incidence[via], paths.ris_departure[via], wavelength=radar.wavelength)  # [M, L1]
        cube += (coef[:, None, :] * slow[via].T[None, :, :]) @ fast[via]
    return cube
