"""Per-beam DTFT magnitudes at one frequency, and the test for a second return beside the fitted tone.

Both read the cube at the (off-grid) frequencies the estimators found (``docs/estimation.md``):
:func:`beam_dtft` gives |Z_m| for the AoD fit of the paper path and the amplitude;
:func:`residual_test` decides the ``unresolved-peaks`` flag (``docs/flags.md``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .radar import RadarConfig
from .dtft_subspace import contract_samples, dtft_phasors

__all__ = ["beam_dtft", "residual_test"]


def beam_dtft(cube: Any, radar: RadarConfig, delay: float, delay_rate: float) -> tuple[np.ndarray, float, float]:
    """|Z_m| of every beam at (τ, ν): the un-windowed 2-D DTFT magnitude [M] [√W·K·N].

    Returns the magnitudes and the frequencies (f₁, f₂) [cycles/sample] they were taken at.
    """
    arr = np.asarray(cube, dtype=complex)
    m, k, n = arr.shape
    f1 = (delay * radar.slope + radar.carrier_frequency * delay_rate) * radar.sample_period
    f2 = delay_rate * radar.carrier_frequency * radar.chirp_interval
    en = dtft_phasors(f1, np.arange(n) - (n - 1) / 2.0, np.zeros(1))[0]
    ek = dtft_phasors(f2, np.arange(k) - (k - 1) / 2.0, np.zeros(1))[0]
    return np.abs((arr.reshape(m * k, n) @ en).reshape(m, k) @ ek), float(f1), float(f2)


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

    Returns
    -------
    (statistic, threshold) when the test fires, else None.
    """
    import scipy.signal
    import scipy.special

    arr = np.asarray(cube, dtype=complex)
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
    g = contract_samples(arr, bn, sel)  # [M', K, 3]
    if far.sum() >= 4:
        g = g - (arr.mean(axis=0, where=far[:, None, None]) @ bn)[None]
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
