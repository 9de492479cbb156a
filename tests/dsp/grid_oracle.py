"""The paper's grid search written out for the tests: the whole float64 N_DFT × K_DFT transform of each beam.

eq. (2DDFT): ``z(q, p) = Σ_k Σ_n w_k w_n y[k, n] e^{+j2π(qk/K_DFT + pn/N_DFT)}`` by ``numpy.fft.ifft2`` (not
the project's transforms); eq. (argmaxmap) over the delay bins at or beyond ``min_range``, ties to the first
cell in (q, p) order; eq. (P_ave) on the winning Doppler row. Only the windows come from the project
(``dsp.spectrum.dft_windows``): the searches under test share them by definition.
"""

from __future__ import annotations

import numpy as np

import dsp
from dsp.spectrum import dft_windows


def whole_grid(cube, radar, processing):
    """(|z|² [M, K_DFT, N_DFT] ungated, first searchable delay bin, the delay grid [s], the coherent gain)."""
    w_k, w_n, gain = dft_windows(radar, processing)
    delays = radar.delay_grid(processing.n_dft)
    first = int(np.searchsorted(delays, 2.0 * processing.min_range / dsp.SPEED_OF_LIGHT))
    z = np.fft.ifft2(np.asarray(cube) * np.outer(w_k, w_n), s=(processing.k_dft, processing.n_dft), axes=(-2, -1))
    z *= processing.k_dft * processing.n_dft
    return z.real**2 + z.imag**2, first, delays, gain


def grid_maxima(cube, radar, processing):
    """Per beam (q, p, |z|²/gain², P_ave/gain²) of the whole grid: the answer every search must give."""
    power, first, delays, gain = whole_grid(cube, radar, processing)
    out = []
    for grid in power:
        gated = grid.copy()
        gated[:, :first] = -1.0
        q, p = np.unravel_index(int(gated.argmax()), gated.shape)
        window = np.abs(delays - delays[p]) <= processing.delta * (1.0 + 1e-9)
        out.append((int(q), int(p), grid[q, p] / gain**2, grid[q, window].mean() / gain**2))
    q, p, peak, average = map(np.array, zip(*out))
    return q, p, peak, average
