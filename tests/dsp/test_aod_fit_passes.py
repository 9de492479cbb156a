"""The AoD search's grid in passes (dsp.aod_fit.GRID_CELLS_PER_PASS): bounded memory at any declared RIS size.

Oracles: the single-pass fit (the same fit bit for bit in any number of passes), the noiseless pattern (a
UE on a beam's own direction is found within a null width), and tracemalloc's peak (under 64 MiB where the
grid in one pass took 1.1 GiB).
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import dsp
import dsp.aod_fit as aod_fit

WAVELENGTH = dsp.RadarConfig().wavelength
PAPER_SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))  # M = 61


def _fits(magnitudes, sweep, pattern, s2):
    return [aod_fit.fit_aod(magnitudes, sweep, pattern, noise_variance=nv) for nv in (None, s2)]


@pytest.mark.parametrize("two_d", [False, True])
def test_the_fit_is_the_same_bit_for_bit_in_any_number_of_passes(monkeypatch, two_d):
    rng = np.random.default_rng(11)
    pattern = dsp.BeamPattern.relay(num_rows=16, num_columns=4).for_wavelength(WAVELENGTH)
    if two_d:
        az, el = np.meshgrid(np.deg2rad(np.arange(-30.0, 31.0, 3.0)), np.deg2rad([-10.0, 0.0, 10.0]))
        sweep = dsp.BeamSweep(np.stack([az.ravel(), el.ravel()], axis=1))
    else:
        sweep = PAPER_SWEEP
    for _ in range(3 if two_d else 6):
        aod = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.1, 0.1) if two_d else 0.0])
        amp = np.abs(pattern.amplitude(aod, sweep.angles))
        s2 = 10 ** rng.uniform(-3, 0) * float(np.max(amp ** 2))
        noise = np.sqrt(s2 / 2) * (rng.standard_normal(amp.size) + 1j * rng.standard_normal(amp.size))
        mags = np.abs(amp + noise)
        one_pass = _fits(mags, sweep, pattern, s2)
        for cells in ((7,) if two_d else (1, 7)):  # directions per pass
            monkeypatch.setattr(aod_fit, "GRID_CELLS_PER_PASS", cells * sweep.num_beams)
            for a, b in zip(one_pass, _fits(mags, sweep, pattern, s2)):
                assert np.array_equal(a.aod, b.aod) and a.amplitude == b.amplitude
                assert a.direction_cosine == b.direction_cosine
                assert np.array_equal(a.candidates, b.candidates) and np.array_equal(a.twins, b.twins)
            monkeypatch.undo()


def test_a_capture_declaring_a_huge_ris_is_fitted_within_a_bounded_working_set():
    """Regression (benchmarks/fuzz.py, "declared sizes", seed 1128): a capture whose metadata declares a
    52 171 x 2 RIS. Its search grid (a null width / 8 per step) has 3 · 10⁵ directions; in one pass
    the 61 beams' amplitudes and their temporaries took 1.1 GiB, past the 512 MiB limit the fuzzer sets."""
    pattern = dsp.BeamPattern.relay(num_rows=52_171, num_columns=2).for_wavelength(WAVELENGTH)
    beam = 37
    truth = PAPER_SWEEP.angles[beam]  # the UE on a beam's own direction: that beam alone sees the main lobe
    mags = np.abs(pattern.amplitude(truth, PAPER_SWEEP.angles))
    tracemalloc.start()
    try:
        fit = aod_fit.fit_aod(mags, PAPER_SWEEP, pattern)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # a pass's arrays (2 MiB each) and their temporaries, not the grid's 140 MiB per array
    assert peak < 64 * 2**20, f"{peak / 2**20:.0f} MiB"
    u_true = np.sin(truth[0])
    assert abs(fit.direction_cosine - u_true) < pattern.null_width  # the physics: on its beam's main lobe
