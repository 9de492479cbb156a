"""The first implementation of eq. (1), kept (and extended to TDM timing) as the synthesis oracle.

:func:`beat_cube_reference` is ``beat_cube`` as it was before the fast synthesis: one batched
product over all beams, per-path phases in exact rational arithmetic with ``fractions.Fraction``.
It is slow (Python loops over paths) and serves only to show that
:func:`risloc_rt.model.beat.beat_cube` computes the same cube
(``tests/model/test_synthesis_speed_equivalence.py``, ``tests/model/test_tdm_reference.py``,
``benchmarks/bench_synthesis.py``).

It reads the radar's timing from the fields of :class:`dsp.RadarConfig` itself, exactly (every
float converted to a rational): the chirp repetition interval T_c (``chirp_period``, or the ramp
duration T when it is None), the frame interval (``frame_period``, or K·T_c) and
``frames_per_beam``. Frame m of the cube is the first frame of beam m: its chirps start at
``s_m = m · frames_per_beam · frame_interval`` from the start of the sweep, chirp k at
``s_m + k T_c``; its centre is ``t_m = s_m + K T_c / 2`` (``RadarConfig.beam_times``).

With ``motion="sweep"`` each path moves to first order from the paths given, which hold at
``reference_time`` t_ref (default the middle of the sweep, the mean of the t_m):
``τ_l(t) = τ_l + ν_l (t - t_ref)``. Frame m, chirp k, sample n of path l then carries

    γ_l r_{m,l} · exp(-j2π f_c ν_l (s_m + k T_c - t_ref)) · exp(-j2π (S τ_l(t_m) + f_c ν_l) n T_s),

the carrier phase of γ_l (that of t_ref) moved to the chirp's start, the beat frequency at the
delay of the frame centre (no range migration within a frame, as eq. (1)).
"""

from __future__ import annotations

from fractions import Fraction
from typing import Literal

import numpy as np

from dsp import RadarConfig
from dsp.sweep import BeamSweep

from .paths import PathSet
from .phase import wrapped_tone
from .ris import RisConfig, ris_response

__all__ = ["beat_cube_reference", "fraction_cycles", "sweep_timing"]


def fraction_cycles(rate_terms: list[tuple[float, np.ndarray]], scale: float) -> np.ndarray:
    """``frac(scale · Σ_i c_i x_i)`` per path in exact rational arithmetic [L] [cycles].

    Each input float is converted to an exact rational, so the only rounding is the final
    conversion of a number in [0, 1): the result is correctly rounded.

    Parameters
    ----------
    rate_terms : list of (float, float array [L])
        Pairs (c_i, x_i) whose products are summed.
    scale : float
        Common factor (e.g. the sample period) [any unit making the result cycles].
    """
    k = Fraction(scale)
    coeffs = [(Fraction(c), np.asarray(x, dtype=float)) for c, x in rate_terms]
    n = coeffs[0][1].shape[0] if coeffs else 0
    out = np.empty(n)
    for j in range(n):
        total = k * sum((c * Fraction(float(x[j])) for c, x in coeffs), Fraction(0))
        out[j] = _fraction_part(total)
    return out


def _fraction_part(x: Fraction) -> float:
    """``x - floor(x)`` rounded once to float64, in [0, 1] [cycles]."""
    return float(x - (x.numerator // x.denominator))


def sweep_timing(radar: RadarConfig, num_beams: int) -> tuple[Fraction, list[Fraction], Fraction]:
    """The sweep's clock in exact rationals, read from the radar's timing fields.

    Parameters
    ----------
    radar : RadarConfig
        ``chirp_duration``, ``chirp_period``, ``frame_period``, ``frames_per_beam``, ``num_chirps``.
    num_beams : int
        M.

    Returns
    -------
    (Fraction, list of Fraction [M], Fraction)
        T_c, the chirp repetition interval [s]; s_m, the start of beam m's (first) frame from
        the start of the sweep [s]; t_mid, the mean of the frame centres s_m + K T_c/2 [s].
    """
    t_c = Fraction(radar.chirp_duration if radar.chirp_period is None else radar.chirp_period)
    frame = radar.num_chirps * t_c if radar.frame_period is None else Fraction(radar.frame_period)
    beam = radar.frames_per_beam * frame
    starts = [m * beam for m in range(num_beams)]
    half_frame = radar.num_chirps * t_c / 2
    t_mid = sum(starts, Fraction(0)) / num_beams + half_frame
    return t_c, starts, t_mid


def beat_cube_reference(paths: PathSet, *, radar: RadarConfig, sweep: BeamSweep, ris: RisConfig | None,
                        motion: Literal["frozen", "sweep"] = "frozen",
                        reference_time: float | None = None) -> np.ndarray:
    """Noiseless beat cube of eq. (1) [M, K, N] [√W], the reference implementation.

    Parameters
    ----------
    paths : PathSet
        L paths; with ``motion="sweep"``, the paths at ``reference_time``.
    radar : RadarConfig
    sweep : BeamSweep
        M beams, one frame each.
    ris : RisConfig or None
        Needed when any path goes through the RIS.
    motion : {"frozen", "sweep"}, default "frozen"
        ``"frozen"``: eq. (1), the same paths in every frame,
        ``Y[m, k, n] = Σ_l γ_l r_{m,l} e^{-j2π(S τ_l + f_c ν_l) n T_s} e^{-j2π f_c ν_l k T_c}``.
        ``"sweep"``: each path's delay moves with its rate between frames (module docstring);
        its gain, rate and RIS angles are kept.
    reference_time : float, optional
        t_ref for ``motion="sweep"``, from the start of the sweep [s]; default the middle of the
        sweep, the mean of the frame centres.

    Returns
    -------
    complex array [M, K, N]
        [√W].

    Notes
    -----
    Every cycle count is computed exactly in rationals and reduced modulo 1 before it is
    rounded to float64; the per-chirp and per-sample phase ramps are then ``wrapped_tone``'s
    (error below K or N times 2⁻⁵² cycles).
    """
    if motion not in ("frozen", "sweep"):
        raise ValueError(f"motion={motion!r} must be 'frozen' (eq. (1)) or 'sweep' (first-order motion)")
    m_beams, k_chirps, n_samples = sweep.num_beams, radar.num_chirps, radar.num_samples
    t_c, starts, t_mid = sweep_timing(radar, m_beams)
    coef = np.broadcast_to(paths.gain.astype(complex), (m_beams, len(paths))).copy()  # [M, L]
    via = paths.via_ris
    if via.any():
        if ris is None:
            raise ValueError("the path set has RIS loop-back paths but no RisConfig was given")
        coef[:, via] *= ris_response(ris, sweep, paths.ris_incidence[via], paths.ris_departure[via],
                                     wavelength=radar.wavelength)  # [M, L1]
    slow = wrapped_tone(fraction_cycles([(radar.carrier_frequency, paths.delay_rate)], float(t_c)),
                        k_chirps)  # [L, K]: e^{-j2π f_c ν k T_c}
    if motion == "frozen":
        fast = wrapped_tone(fraction_cycles(
            [(radar.slope, paths.delay), (radar.carrier_frequency, paths.delay_rate)], radar.sample_period),
            n_samples)  # [L, N]
        return (coef[:, None, :] * slow.T[None, :, :]) @ fast  # [M, K, L] @ [L, N]
    t_ref = t_mid if reference_time is None else Fraction(float(reference_time))
    f_c, slope, t_s = Fraction(radar.carrier_frequency), Fraction(radar.slope), Fraction(radar.sample_period)
    half_frame = k_chirps * t_c / 2
    cube = np.empty((m_beams, k_chirps, n_samples), dtype=complex)
    for m, start in enumerate(starts):
        shift = np.empty(len(paths))  # f_c ν (s_m - t_ref) [cycles]
        beat = np.empty(len(paths))  # (S τ(t_m) + f_c ν) T_s [cycles per sample]
        for j in range(len(paths)):
            tau, nu = Fraction(float(paths.delay[j])), Fraction(float(paths.delay_rate[j]))
            shift[j] = _fraction_part(f_c * nu * (start - t_ref))
            beat[j] = _fraction_part((slope * (tau + nu * (start + half_frame - t_ref)) + f_c * nu) * t_s)
        weight = coef[m] * np.exp(-2j * np.pi * shift)  # [L]
        cube[m] = (slow.T * weight) @ wrapped_tone(beat, n_samples)  # [K, L] @ [L, N]
    return cube
