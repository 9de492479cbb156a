"""Property: both bounded grid searches give the whole grid's cell for any sizes, window, range gate and beam.

Hypothesis draws the radar's K (1-12 chirps) and N (2-24 samples), the grids N_DFT (N to 3N) and K_DFT
(K to 6K, so the Doppler grid may be coarser or finer than the 2K-point plane), the window, a
``min_range`` gate, and beams mixed from tones (off-grid delay and Doppler), impulses, whole chirps,
noise and zeros at amplitudes 10⁻⁶ to 10⁶. Oracle: the whole float64 N_DFT × K_DFT transform of each
beam (``numpy.fft.ifft2``, ``grid_oracle.py``). The host's screened search
(``doppler_search="zoom"``) and the device search (array_api_strict's ``device1``) must both return a
cell whose power equals the grid maximum to 1e-10 relative — the oracle's cell, or one tied with it
within float64 rounding — and the oracle's P_ave at that cell.

200 examples by default (2 s); ``GRID_EXAMPLES=6000`` for a deeper run (38 s). At 1500 examples this
test found that the host's dense search let a column inside ``min_range`` win on a coarse Doppler
grid at large amplitude (``tests/dsp/test_dense_search.py``, the gated-columns regression test).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dsp
from dsp import BeamSweep, ProcessingConfig, RadarConfig, scan_beams
from grid_oracle import whole_grid  # registered by tests/dsp/conftest.py

STRICT = dsp.strict_backend("device1")
SETTINGS = settings(max_examples=int(os.environ.get("GRID_EXAMPLES", 200)), deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow])


@st.composite
def cases(draw):
    k = draw(st.integers(1, 12))
    n = draw(st.integers(2, 24))
    n_dft = draw(st.integers(n, 3 * n))
    k_dft = draw(st.integers(k, 6 * k))
    window = draw(st.sampled_from(["hann", "hamming", "boxcar", "blackman"]))
    gate = draw(st.sampled_from([0.0, 0.0, 0.2, 0.6]))  # share of the unambiguous range gated off
    seed = draw(st.integers(0, 2**32 - 1))
    beams = draw(st.integers(2, 4))
    kinds = draw(st.lists(st.sampled_from(["tones", "impulse", "chirp", "noise", "zero"]), min_size=beams,
                          max_size=beams))
    return k, n, n_dft, k_dft, window, gate, seed, kinds


def _beam(kind, radar, rng):
    k, n = radar.num_chirps, radar.num_samples
    scale = 10.0 ** rng.uniform(-6, 6)
    y = np.zeros((k, n), complex)
    if kind == "tones":
        for _ in range(rng.integers(1, 4)):
            f1, f2 = rng.uniform(0, 1), rng.uniform(-0.5, 0.5)  # cycles per sample and per chirp
            y += rng.uniform(0.1, 1) * np.exp(2j * np.pi * (rng.uniform() - np.arange(k)[:, None] * f2
                                                            - np.arange(n)[None, :] * f1))
        y += 0.1 * (rng.standard_normal((k, n)) + 1j * rng.standard_normal((k, n)))
    elif kind == "impulse":
        y[rng.integers(k), rng.integers(n)] = 1.0
    elif kind == "chirp":
        y[rng.integers(k)] = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    elif kind == "noise":
        y = rng.standard_normal((k, n)) + 1j * rng.standard_normal((k, n))
    return scale * y


@SETTINGS
@given(cases())
def test_host_and_device_searches_give_the_grid_maximum(case):
    k, n, n_dft, k_dft, window, gate, seed, kinds = case
    radar = RadarConfig(num_samples=n, num_chirps=k)
    min_range = gate * radar.max_range
    processing = ProcessingConfig(n_dft=n_dft, k_dft=k_dft, window=window, min_range=min_range)
    rng = np.random.default_rng(seed)
    cube = np.stack([_beam(kind, radar, rng) for kind in kinds])
    if not np.any(cube):
        cube[0, 0, 0] = 1.0  # a device cube must not be all zeros
    sweep = BeamSweep(np.zeros((cube.shape[0], 2)))
    try:
        host = scan_beams(cube, sweep, radar, processing)
    except ValueError as exc:  # a gate past every delay bin: both refuse it alike
        assert "min_range" in str(exc)
        with pytest.raises(ValueError, match="min_range"):
            scan_beams(STRICT.asarray(cube), sweep, radar, processing)
        return
    dev = scan_beams(STRICT.asarray(cube), sweep, radar, processing)
    grids, first, delays, gain = whole_grid(cube, radar, processing)
    for m, power in enumerate(grids):
        best = power[:, first:].max()  # the searchable cells
        for scan in (host, dev):
            q, p = int(scan.doppler_bin[m]), int(scan.delay_bin[m])
            assert p >= first
            # the grid maximum, or a cell tied with it to float64 rounding
            assert power[q, p] >= best * (1 - 1e-10) - 1e-300, (m, kinds[m], q, p)
            assert scan.peak_power[m] == pytest.approx(power[q, p] / gain**2, rel=1e-9, abs=1e-300)
            window_bins = np.abs(delays - delays[p]) <= processing.delta * (1 + 1e-9)
            assert scan.average_power[m] == pytest.approx(power[q, window_bins].mean() / gain**2, rel=1e-9,
                                                          abs=1e-300)
