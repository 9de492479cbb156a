"""Per-beam DTFT magnitudes at one frequency, and the test for a second return beside the fitted tone.

All read the cube at the (off-grid) frequencies the estimators found (``docs/estimation.md``):
:func:`beam_dtft` gives |Z_m| for the AoD fit of the paper path and the amplitude;
:func:`residual_test` decides the ``unresolved-peaks`` flag, :func:`beam_values` gives the
windowed per-beam values the ``pattern-mismatch`` test fits (``docs/flags.md``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .radar import RadarConfig
from .dtft_subspace import as_cube, contract_beams, contract_samples, dtft_phasors, mean_of_beams

__all__ = ["beam_dtft", "beam_values", "drift_shifts", "residual_test"]


def beam_dtft(cube: Any, radar: RadarConfig, delay: float, delay_rate: float) -> tuple[np.ndarray, float, float]:
    """|Z_m| of every beam at (τ, ν): the un-windowed 2-D DTFT magnitude [M] [√W·K·N].

    Returns the magnitudes and the frequencies (f₁, f₂) [cycles/sample] they were taken at.
    """
    arr = as_cube(cube)
    m, k, n = arr.shape
    f1 = (delay * radar.slope + radar.carrier_frequency * delay_rate) * radar.sample_period
    f2 = delay_rate * radar.carrier_frequency * radar.chirp_interval
    en = dtft_phasors(f1, np.arange(n) - (n - 1) / 2.0, np.zeros(1))[0]
    ek = dtft_phasors(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0]
    return np.abs(contract_samples(arr, en) @ ek), float(f1), float(f2)


def residual_test(
    cube: Any,
    radar: RadarConfig,
    f1: float,
    f2: float,
    weights: Any,
    *,
    cell_noise: float,
    pfa: float = 1e-3,
    min_weight: float = 0.05,
    drift_rate: float = 0.0,
    beam_times: Any = None,
) -> tuple[float, float] | None:
    """Is there a second return within half a resolution cell of the fitted tone?

    The per-beam least-squares tone at (f₁, f₂) is removed and the residual of the Hann-windowed
    DTFT is evaluated at the 8 points ±½ un-padded bin around it, summed over the beams with
    |A_m| >= ``min_weight`` (static returns removed as in :func:`refine_estimate`). The window
    keeps returns that are resolved (two or more cells away, e.g. multipath legs of the loop-back)
    from leaking into the test through the rectangular window's -13 dB sidelobes. With one tone
    the residual is noise only: ``Σ_m |R_m|²/σ²_cell`` (σ²_cell of the windowed sum) is at most
    Gamma(M', 1) (less, as the fit removed part of it), and the test flags when its maximum
    exceeds the Gamma(M', 1) level of probability pfa/8.

    **A moving return** (``drift_rate`` ≠ 0, ``docs/moving-radar.md``): a radar that moves changes
    its range from frame to frame, so beam m's tone sits at the delay τ + ν_d (t_m − t̄), t_m its
    frame centre (``beam_times``) and t̄ = Σ A_m² t_m / Σ A_m² the pattern-weighted mean frame time
    (where the fitted f₁ refers to). The tone removed from beam m is then the one at
    f₁ + S T_s ν_d (t_m − t̄), its 3 × 3 samples taken around it (each beam's fast-time basis
    shifted by its own drift): the moved return is no longer left as a "second peak". The static
    template is subtracted in the same shifted basis, so it cancels as before.

    Parameters
    ----------
    cube : complex array [M, K, N]
    radar : RadarConfig
    f1, f2 : float
        Fitted beat frequencies [cycles/sample].
    weights : float array [M]
        |A_m(θ̂)|.
    cell_noise : float
        Noise power of one un-padded DFT cell, K·N·σ² [W·K·N].
    pfa : float
        False-flag probability.
    min_weight : float
        Beams with |A_m| >= ``min_weight`` · max |A| are tested [unitless].
    drift_rate : float, default 0
        ν_d, the rate at which the return's delay drifts across the sweep [s/s]; 0: the tone is
        the same in every beam (eq. (1)'s frozen geometry).
    beam_times : float array [M], optional
        Frame centre of each beam, ``RadarConfig.beam_times(M)`` [s]; needed when ``drift_rate`` ≠ 0.

    Returns
    -------
    (statistic, threshold) when the test fires, else None.
    """
    import scipy.signal
    import scipy.special

    arr = as_cube(cube)
    m, k, n = arr.shape
    w = np.asarray(weights, dtype=float)
    sel = np.flatnonzero(w >= min_weight * w.max())
    far = w < 0.1 * w.max()
    n_idx = np.arange(n) - (n - 1) / 2.0
    k_idx = np.arange(k) - (k - 1) / 2.0
    offs1 = np.array([-0.5, 0.0, 0.5]) / n
    offs2 = np.array([-0.5, 0.0, 0.5]) / k
    wn = scipy.signal.get_window("hann", n, fftbins=False)
    wk = scipy.signal.get_window("hann", k, fftbins=False)
    bn = dtft_phasors(f1, n_idx, offs1).T * wn[:, None]  # [N, 3]
    bk = dtft_phasors(f2, k_idx, offs2) * wk[None, :]  # [3, K]
    rate = float(drift_rate)
    if rate == 0.0:
        g = contract_samples(arr, bn, sel)  # [M', K, 3]
        if far.sum() >= 4:
            g = g - (mean_of_beams(arr, np.flatnonzero(far)) @ bn)[None]
    else:
        t = _checked_times(beam_times, m)
        shift = drift_shifts(radar, rate, t, w)[sel]  # [M'] cycles/sample
        template = mean_of_beams(arr, np.flatnonzero(far)) if far.sum() >= 4 else None  # [K, N]

        def drifted(f: float, offsets: np.ndarray) -> np.ndarray:
            """Beam m's samples against its own drifted tone f + shift_m + offsets, [M', K, J]."""
            basis = np.stack([dtft_phasors(f + d, n_idx, offsets).T for d in shift]) * wn[None, :, None]
            out = contract_beams(arr, basis, sel)  # one product per beam, no copy
            return out if template is None else out - np.matmul(template[None], basis)

        # The fitted f₁ is the compromise of a model without motion; re-centre it on the moved
        # tones (parabola through the summed power at ±h; h = 0.05 bin, twice): left ~0.02 bin off,
        # a 55 dB return would leave 25 dB of residual.
        h = 0.05 / n
        for _ in range(2):
            p = (np.abs(np.einsum("k,mkj->mj", bk[1], drifted(f1, np.array([-h, 0.0, h])))) ** 2).sum(axis=0)
            curv = p[0] - 2 * p[1] + p[2]
            if curv < 0:
                f1 += float(np.clip(0.5 * h * (p[0] - p[2]) / curv, -0.25 / n, 0.25 / n))
        g = drifted(f1, offs1)  # [M', K, 3]
    z = np.einsum("bk,mka->mab", bk, g)  # [M', 3, 3]
    # windowed DTFT of a unit tone at (f1, f2), seen at the offsets: the fitted tone's footprint
    kernel = np.outer(np.exp(-2j * np.pi * np.outer(offs1, n_idx)) @ wn,
                      np.exp(-2j * np.pi * np.outer(offs2, k_idx)) @ wk)  # [3, 3]
    resid = z - (z[:, 1, 1] / kernel[1, 1])[:, None, None] * kernel[None]
    window_noise = cell_noise * float(np.sum(wn**2) * np.sum(wk**2)) / (k * n)
    stat = (np.abs(resid) ** 2).sum(axis=0) / window_noise  # [3, 3]
    stat[1, 1] = 0.0
    thr = float(scipy.special.gammainccinv(sel.size, pfa / 8.0))
    best = float(stat.max())
    return (best, thr) if best > thr else None


def _checked_times(beam_times: Any, m: int) -> np.ndarray:
    if beam_times is None:
        raise ValueError("drift_rate != 0 needs beam_times (RadarConfig.beam_times(M)) [s]")
    t = np.asarray(beam_times, dtype=float)
    if t.shape != (m,):
        raise ValueError(f"beam_times has shape {t.shape}, expected ({m},): one frame time per beam")
    return t


def drift_shifts(radar: RadarConfig, drift_rate: float, beam_times: Any, weights: Any) -> np.ndarray:
    """Each beam's fast-time frequency offset from a delay drifting at ``drift_rate`` [M] [cycles/sample].

    ``S T_s ν_d (t_m − t̄)``, t̄ = Σ A_m² t_m / Σ A_m² the pattern-weighted mean frame time (where
    a tone fitted over the beams refers to); ``weights`` are |A_m| [M], ``beam_times`` t_m [M] [s].
    """
    t = np.asarray(beam_times, dtype=float)
    w2 = np.asarray(weights, dtype=float) ** 2
    t_mean = float(w2 @ t / np.sum(w2))
    return radar.slope * radar.sample_period * float(drift_rate) * (t - t_mean)


def beam_values(cube: Any, radar: RadarConfig, f1: float, f2: float, weights: Any, *, drift_rate: float = 0.0,
                beam_times: Any = None, windowed: bool = True) -> tuple[np.ndarray, float]:
    """The Hann-windowed 2-D DTFT of every beam at the fitted tone, and its noise per unit noise power.

    Beam m is read at (f₁ + S T_s ν_d (t_m − t̄), f₂) (:func:`drift_shifts`; ν_d = 0: the same tone in
    every beam). The Hann windows keep a return a few cells away (the panel's structure τ_RB
    earlier, 7 cells at Table I) out of the values: −60 dB there, where the un-windowed DTFT lets
    −27 dB through, the same complex offset in every beam, which a pattern fit would read as a
    pattern that does not fall to zero.

    Parameters
    ----------
    cube : complex array [M, K, N]
    radar : RadarConfig
    f1, f2 : float
        The fitted tone [cycles/sample].
    weights : float array [M]
        |A_m(θ̂)| (for t̄ only).
    drift_rate : float, default 0
        ν_d [s/s].
    beam_times : float array [M], optional
        Frame centres [s]; needed when ``drift_rate`` ≠ 0.
    windowed : bool, default True
        Hann windows on both axes; False: the un-windowed DTFT (all weights 1), the magnitudes the
        refined estimator's AoD fit reads (``dsp.estimators``, range migration).

    Returns
    -------
    values : complex array [M]
        Z_m [√W · Σw].
    noise_gain : float
        Σ_n w_n² · Σ_k w_k²: the variance of Z_m's noise is ``noise_gain · σ²`` (σ² per sample).
    """
    import scipy.signal

    arr = as_cube(cube)
    m, k, n = arr.shape
    wn = scipy.signal.get_window("hann", n, fftbins=False) if windowed else np.ones(n)
    wk = scipy.signal.get_window("hann", k, fftbins=False) if windowed else np.ones(k)
    n_idx = np.arange(n) - (n - 1) / 2.0
    ek = dtft_phasors(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0] * wk  # [K]
    rate = float(drift_rate)
    shift = np.zeros(m) if rate == 0.0 else drift_shifts(radar, rate, _checked_times(beam_times, m), weights)
    en = np.stack([dtft_phasors(f1 + float(shift[beam]), n_idx, np.zeros(1))[0] * wn for beam in range(m)])  # [M, N]
    rows = contract_beams(arr, en, np.arange(m))  # [M, K]: each beam against its own tone, on the cube's backend
    values = np.array([ek @ rows[beam] for beam in range(m)], dtype=complex)
    return values, float(np.sum(wn**2) * np.sum(wk**2))
