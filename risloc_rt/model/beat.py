"""The FMCW beat-signal model, eq. (1) of the seed paper."""

from __future__ import annotations

import numpy as np

from dsp import RadarConfig
from dsp.sweep import BeamSweep

from .paths import PathSet
from .phase import exact_fractional_cycles, wrapped_tone
from .ris import RisConfig, ris_response

__all__ = ["beat_cube", "add_noise"]


def beat_cube(paths: PathSet, *, radar: RadarConfig, sweep: BeamSweep, ris: RisConfig | None) -> np.ndarray:
    """Noiseless beat cube of eq. (1) for every sweep beam.

    Parameters
    ----------
    paths : PathSet
        L round-trip paths; those with RIS angles get the RIS response of each beam.
    radar : RadarConfig
    sweep : BeamSweep
        M beams.
    ris : RisConfig or None
        Needed when any path goes through the RIS.

    Returns
    -------
    complex array [M, K, N]
        ``Y[m, k, n] = Σ_l γ_l r_{m,l} e^{-j2π(S τ_l + f_c ν_l) n T_s} e^{-j2π f_c ν_l k T}`` [√W],
        where r_{m,l} is :func:`risloc_rt.ris.ris_response` for RIS paths and 1 otherwise.
    """
    m = sweep.num_beams
    # Cycles per sample (S τ + f_c ν) T_s and per chirp f_c ν T, reduced modulo 1 exactly.
    fast = wrapped_tone(exact_fractional_cycles(
        [(radar.slope, paths.delay), (radar.carrier_frequency, paths.delay_rate)], radar.sample_period),
        radar.num_samples)  # [L, N]
    slow = wrapped_tone(exact_fractional_cycles(
        [(radar.carrier_frequency, paths.delay_rate)], radar.chirp_duration), radar.num_chirps)  # [L, K]
    via = paths.via_ris
    # Paths that do not pass through the RIS are the same in every beam: one [K, N] frame.
    common = (slow[~via].T * paths.gain[~via]) @ fast[~via]  # [K, L0] @ [L0, N]
    cube = np.broadcast_to(common, (m,) + common.shape).copy()
    if via.any():
        if ris is None:
            raise ValueError("the path set has RIS loop-back paths but no RisConfig was given")
        coef = paths.gain[via] * ris_response(
            ris, sweep, paths.ris_incidence[via], paths.ris_departure[via], wavelength=radar.wavelength)  # [M, L1]
        # [M, 1, L1] * [1, K, L1] -> [M, K, L1]; @ [L1, N] -> [M, K, N]
        cube += (coef[:, None, :] * slow[via].T[None, :, :]) @ fast[via]
    return cube


def add_noise(cube: np.ndarray, noise_power: float, rng: np.random.Generator) -> np.ndarray:
    """``cube + w`` with w ~ CN(0, σ²) i.i.d. per sample.

    Parameters
    ----------
    cube : complex array [M, K, N]
        [√W].
    noise_power : float
        σ² [W].
    rng : numpy.random.Generator
        Source of the noise.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    scale = np.sqrt(noise_power / 2.0)
    noise = rng.standard_normal(cube.shape + (2,))
    return cube + scale * (noise[..., 0] + 1j * noise[..., 1])
