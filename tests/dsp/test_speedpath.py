"""The screened grid search (``doppler_search="zoom"``) returns the paper's full-grid answer.

Oracle: the full N_DFT × K_DFT transform of every beam (``doppler_search="full"``, the paper's
eq. (2DDFT) + (argmaxmap)). On every cube the two must pick the same delay and Doppler bins and the
same best beam, and their peak and P_ave values must agree to 1e-9 relative (two float64
evaluations of the same DFT sums). The only tolerated difference is an exact tie: two cells whose
powers are equal up to float64 rounding (1e-12 relative), where either is the grid maximum.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import BeamSweep, scan_beams
from dsp import gridscreen
from dsp.gridscreen import scalloping_loss_db
from risloc_rt.model.beat import add_noise


def _compare(cube, radar, processing, *, allow_ties=False, monkeypatch=None):
    """Both searches on ``cube``; returns (zoom scan, full scan, beams the screen left to the dense search)."""
    dense: list[int] = []
    if monkeypatch is not None:
        original = gridscreen._dense_beam
        monkeypatch.setattr(gridscreen, "_dense_beam", lambda *a: dense.append(1) or original(*a))
    sweep = BeamSweep(np.zeros((cube.shape[0], 2)))
    zoom = scan_beams(cube, sweep, radar, dataclasses.replace(processing, doppler_search="zoom"))
    full = scan_beams(cube, sweep, radar, dataclasses.replace(processing, doppler_search="full"))
    same = (zoom.delay_bin == full.delay_bin) & (zoom.doppler_bin == full.doppler_bin)
    if allow_ties:
        # A differing cell must be a tie: its power equals the full search's maximum.
        np.testing.assert_allclose(zoom.peak_power[~same], full.peak_power[~same], rtol=1e-12)
    else:
        np.testing.assert_array_equal(zoom.delay_bin, full.delay_bin)
        np.testing.assert_array_equal(zoom.doppler_bin, full.doppler_bin)
    np.testing.assert_allclose(zoom.peak_power, full.peak_power, rtol=1e-9)
    np.testing.assert_allclose(zoom.average_power[same], full.average_power[same], rtol=1e-9)
    assert zoom.best_beam == full.best_beam or np.isclose(zoom.average_power[zoom.best_beam],
                                                          full.average_power[full.best_beam], rtol=1e-12)
    return zoom, full, len(dense)


@pytest.mark.parametrize("window", ["hann", "hamming", "boxcar"])
def test_random_multipath_cubes_give_the_full_grid_answer(window, make_radar, make_processing, monkeypatch,
                                                          multipath_cube):
    # 40 beams per window, each an independent draw: 1-6 returns with random delay, Doppler
    # (up to ±v_max) and amplitude (0-40 dB spread), plus noise from -20 to +30 dB per sample
    # relative to the strongest return, i.e. from clean to noise-only after integration.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67, window=window)
    cube = multipath_cube(radar, 40, np.random.default_rng(sum(map(ord, window))))
    *_, dense = _compare(cube, radar, processing, monkeypatch=monkeypatch)
    assert 0 < dense < 30  # the screen decides most beams; noise-dominated ones go dense


def test_table1_sizes_two_close_returns_and_low_snr(make_radar, make_processing, monkeypatch, hard_table1_beams):
    # Table I's N, K, N_DFT, K_DFT on 6 beams: two returns 1.5 resolution cells apart (they
    # interfere between native delay samples), equal-power returns far apart with 1e-6 relative
    # power difference, a return at -15 dB per sample, noise only and an all-zero beam.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    cube = hard_table1_beams(radar, processing, np.random.default_rng(7))
    # Beam 5 all zero: every cell ties at 0 and the first searchable one wins.
    zoom, full, dense = _compare(cube, radar, processing, monkeypatch=monkeypatch)
    assert dense == 2  # beams 4 (noise only) and 5 (zero): the screen cannot prune
    assert (zoom.delay_bin[1], zoom.delay_bin[2]) == (800, 200)  # the 1e-6 stronger return wins either way
    assert zoom.delay_bin[5] == 0 and zoom.doppler_bin[5] == 0


def test_exact_ties_pick_a_maximum(make_radar, make_processing, grid_tone):
    # Two unit tones on grid cells: the same power to rounding; the full search takes the first in
    # (Doppler, delay) FFT order, the screened one a cell equal to it within 1e-12.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    cube = np.stack([grid_tone(radar, processing, 20, 5) + grid_tone(radar, processing, 90, 5),
                     grid_tone(radar, processing, 40, 3) + grid_tone(radar, processing, 40, 60),
                     grid_tone(radar, processing, 30, 0) + grid_tone(radar, processing, 31, 0)])
    zoom, full, _ = _compare(cube, radar, processing, allow_ties=True)
    for m, cells in enumerate([{(5, 20), (5, 90)}, {(3, 40), (60, 40)}]):
        assert (int(zoom.doppler_bin[m]), int(zoom.delay_bin[m])) in cells


def test_min_range_is_honoured_by_the_screen(make_radar, make_processing, tone):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67, min_range=5.0)
    res = radar.max_delay / radar.num_samples
    near = 2 * 3.0 / 299792458.0  # a 100x stronger return at 3 m, inside the excluded range
    cube = (10 * tone(radar, near, 0.0) + tone(radar, 40.4 * res, 2e-9))[None]
    zoom, *_ = _compare(cube, radar, processing)
    assert zoom.distance[0] > 5.0


@pytest.mark.parametrize(("window", "offset", "loss_db"), [("boxcar", 0.5, 3.9224), ("hann", 0.5, 1.4236),
                                                             ("hann", 0.0, 0.0)])
def test_scalloping_loss_is_the_window_response_between_bins(window, offset, loss_db):
    # Closed forms for large N: boxcar |sinc(1/2)|² = (2/π)² → 3.92 dB; Hann at half a bin:
    # (8/(3π))² ... = 1.42 dB.
    assert scalloping_loss_db(window, 4096, offset) == pytest.approx(loss_db, abs=2e-3)


def test_threads_do_not_change_the_result(make_radar, make_processing, tone):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    rng = np.random.default_rng(3)
    cube = add_noise(np.zeros((9, 16, 64), complex) + 0.3 * tone(radar, 1e-8, 2e-9), 1.0, rng)
    windows = (np.hanning(17)[:-1], np.hanning(65)[:-1])
    runs = [gridscreen.screened_scan(cube, processing, 0, windows, lambda p: np.array([p]), workers=w) for w in (1, 3)]
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
