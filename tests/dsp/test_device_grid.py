"""The paper's grid search where the cube lives (``dsp.devicegrid``): the full grid's answer on a device.

Oracle: the whole float64 N_DFT × K_DFT transform of every beam on the host (``numpy.fft.ifft2``
in ``grid_oracle.py``, the paper's eq. (2DDFT) + eq. (argmaxmap) with ties to the first cell in (q, p)
order) and eq. (P_ave) on its row: ``mean |z(q, p')|²`` over the delay bins within ±Δ of the peak. The device is
array_api_strict's ``device1``, which refuses every implicit host copy and every operation outside
the array API standard, so what passes here is written for CuPy's namespace too
(``tests/gpu/test_gpu_grid.py`` runs it there).

On every beam the device search must pick the oracle's cell; the values are two float64 evaluations
of the same sums and agree to 1e-9 relative. The one tolerated difference is an exact tie (two
cells equal to 1e-12), where either cell is the grid maximum.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dsp
from dsp import BeamSweep, devicegrid, scan_beams
from dsp.spectrum import dft_windows
from risloc_rt.model import paper_scenario, simulate
from risloc_rt.model.beat import add_noise
from grid_oracle import grid_maxima  # registered by tests/dsp/conftest.py

STRICT = dsp.strict_backend("device1")


@pytest.fixture(autouse=True)
def whole_grid(monkeypatch):
    """The beams searched on their whole grid (zero and tiny beams; any other is a search that gave up)."""
    calls: list[int] = []
    original = devicegrid._Plan._whole_grid
    monkeypatch.setattr(devicegrid._Plan, "_whole_grid", lambda self, a: calls.append(1) or original(self, a))
    return calls


def _on_device(cube, radar, processing):
    """``scan_beams`` of the cube copied to device1 (one explicit copy)."""
    sweep = BeamSweep(np.zeros((cube.shape[0], 2)))
    return scan_beams(STRICT.asarray(cube), sweep, radar, processing)


def _compare(cube, radar, processing, *, allow_ties=False, whole_grid=None, expect_whole=0):
    scan = _on_device(cube, radar, processing)
    if whole_grid is not None:  # the bounded search decided every other beam itself
        assert len(whole_grid) == expect_whole
    q, p, peak, average = grid_maxima(cube, radar, processing)
    same = (scan.doppler_bin == q) & (scan.delay_bin == p)
    if allow_ties:  # a differing cell must be a tie: its power equals the maximum
        np.testing.assert_allclose(scan.peak_power[~same], peak[~same], rtol=1e-12)
    else:
        np.testing.assert_array_equal(scan.doppler_bin, q)
        np.testing.assert_array_equal(scan.delay_bin, p)
    np.testing.assert_allclose(scan.peak_power, peak, rtol=1e-9)
    np.testing.assert_allclose(scan.average_power[same], average[same], rtol=1e-9)
    return scan


@pytest.mark.parametrize("window", ["hann", "hamming", "boxcar"])
def test_random_multipath_beams_give_the_full_grid_cell(window, make_radar, make_processing, multipath_cube,
                                                        whole_grid):
    # 40 beams per window, each an independent draw: 1-6 returns with random delay, Doppler (up to
    # ±v_max) and amplitude (0-40 dB spread), plus noise from -20 to +30 dB per sample relative to the
    # strongest return: from clean to noise only after integration.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67, window=window)
    cube = multipath_cube(radar, 40, np.random.default_rng(sum(map(ord, window)) + 1))
    _compare(cube, radar, processing, whole_grid=whole_grid)


def test_table1_sizes_close_returns_near_ties_low_snr_noise_and_a_zero_beam(make_radar, make_processing,
                                                                           hard_table1_beams, whole_grid):
    # Table I's N, K, N_DFT, K_DFT: two returns 1.5 resolution cells apart; two equal returns far apart
    # whose powers differ by 1e-6 (either order); a return at -15 dB per sample; noise only; a zero beam.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    cube = hard_table1_beams(radar, processing, np.random.default_rng(11))
    scan = _compare(cube, radar, processing, whole_grid=whole_grid, expect_whole=1)  # the zero beam
    assert (scan.delay_bin[1], scan.delay_bin[2]) == (800, 200)  # the 1e-6 stronger return wins either way
    assert (scan.doppler_bin[5], scan.delay_bin[5]) == (0, 0)  # every cell of a zero beam ties at 0: the first


def test_a_noisy_table1_capture_gives_the_hosts_screened_answer(whole_grid):
    # The paper's relay scenario at 0 dBm (most beams noise only after integration, the dense search's
    # case): the device search and the host's screened search (doppler_search="zoom") on the same cube.
    scenario = paper_scenario("off-broadside", mode="relay")
    scenario = dataclasses.replace(scenario, radar=dataclasses.replace(scenario.radar, tx_power_dbm=0.0))
    capture = simulate(scenario, rng=np.random.default_rng(21))
    host = scan_beams(capture.cube, capture.sweep, capture.radar, capture.processing)
    dev = scan_beams(STRICT.asarray(capture.cube), capture.sweep, capture.radar, capture.processing)
    np.testing.assert_array_equal(dev.delay_bin, host.delay_bin)
    np.testing.assert_array_equal(dev.doppler_bin, host.doppler_bin)
    np.testing.assert_allclose(dev.peak_power, host.peak_power, rtol=1e-9)
    np.testing.assert_allclose(dev.average_power, host.average_power, rtol=1e-9)
    assert dev.best_beam == host.best_beam
    assert not whole_grid


def test_exact_ties_pick_a_maximum(make_radar, make_processing, grid_tone, whole_grid):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    cube = np.stack([grid_tone(radar, processing, 20, 5) + grid_tone(radar, processing, 90, 5),
                     grid_tone(radar, processing, 40, 3) + grid_tone(radar, processing, 40, 60)])
    scan = _compare(cube, radar, processing, allow_ties=True, whole_grid=whole_grid)
    for m, cells in enumerate([{(5, 20), (5, 90)}, {(3, 40), (60, 40)}]):
        assert (int(scan.doppler_bin[m]), int(scan.delay_bin[m])) in cells


def test_min_range_is_honoured(make_radar, make_processing, tone, whole_grid):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67, min_range=5.0)
    res = radar.max_delay / radar.num_samples
    near = 2 * 3.0 / dsp.SPEED_OF_LIGHT  # a 100x stronger return at 3 m, inside the excluded range
    cube = np.stack([10 * tone(radar, near, 0.0) + tone(radar, 40.4 * res, 2e-9),
                     add_noise(10 * tone(radar, near, 0.0), 1e-2, np.random.default_rng(2))])
    scan = _compare(cube, radar, processing, whole_grid=whole_grid)
    assert np.all(scan.distance > 5.0)


def test_szego_extremal_column_keeps_its_maximum(make_radar, make_processing, whole_grid):
    # Boxcar, chirps 0 and K-1 only, one delay tone on fine bin p0: |g(ν)| = 2N|cos(σ(ν - ν₀))|, the case
    # of equality in Szegő's inequality, with ν₀ a grid bin midway between two plane samples. The bound
    # leaves the maximum exactly half a grid bin outside each sample's excluded interval; the search
    # must still find it: |z|² = (2N)² (two unit chirps of N unit samples in phase).
    radar = make_radar(num_samples=64, num_chirps=16)
    k, n, plane = 16, 64, 32
    processing = make_processing(radar, n_dft=127, k_dft=14 * plane, window="boxcar")
    r0, p0 = 7, 40
    q0 = 7 * (2 * r0 + 1)
    y = np.zeros((k, n), complex)
    y[0] = np.exp(-2j * np.pi * p0 * np.arange(n) / processing.n_dft)
    y[k - 1] = np.exp(-2j * np.pi * q0 / processing.k_dft * (k - 1)) * y[0]
    scan = _compare(np.stack([y, 0.5 * y]), radar, processing, whole_grid=whole_grid)
    assert (scan.doppler_bin[0], scan.delay_bin[0]) == (q0, p0)
    assert scan.peak_power[0] * dft_windows(radar, processing)[2] ** 2 == pytest.approx((2.0 * n) ** 2, rel=1e-12)


def test_tiny_beams_and_the_full_search_on_the_whole_grid(make_radar, make_processing, tone, whole_grid):
    # A beam at 1e-130 (squares near underflow) is searched on its whole grid; doppler_search="full"
    # searches every beam there. Both give the oracle's cells.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    rng = np.random.default_rng(5)
    cube = np.stack([add_noise(tone(radar, 1e-8, 1e-9), 1.0, rng), 1e-130 * add_noise(tone(radar, 2e-8, 0.0), 0.1, rng)])
    _compare(cube, radar, processing, whole_grid=whole_grid, expect_whole=1)  # the tiny beam only
    _compare(cube, radar, dataclasses.replace(processing, doppler_search="full"), whole_grid=whole_grid,
             expect_whole=3)


def test_a_beam_without_a_positive_lower_bound_is_searched_on_its_whole_grid(make_radar, make_processing, tone,
                                                                              whole_grid, monkeypatch):
    # T = (largest grid value found) - slack; with a slack above every value no beam has a positive T, so
    # none can be pruned: each goes to its whole grid, with the oracle's cells.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    cube = add_noise(np.zeros((3, 16, 64), complex) + 0.5 * tone(radar, 3e-8, 1e-9), 1.0, np.random.default_rng(8))
    monkeypatch.setattr(devicegrid, "_SLACK", 10.0)
    _compare(cube, radar, processing, whole_grid=whole_grid, expect_whole=3)


def test_a_glitch_in_one_sample_goes_to_the_whole_grid(make_radar, make_processing, glitch_beams, whole_grid):
    # A beam whose energy is in one ADC sample (a glitch) is flat over the whole grid: Szegő's bound prunes
    # nothing, so it is searched on its whole grid (as on the host). One chirp (a burst) is flat in Doppler
    # only near its delay and noise is pruned: both stay with the bounded search.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    rng = np.random.default_rng(12)
    beams = glitch_beams(rng)
    cube = np.concatenate([beams, add_noise(beams[:1], 1.0, rng)])  # and the burst in noise
    _compare(cube, radar, processing, whole_grid=whole_grid, expect_whole=1)  # the impulse


def test_one_chirp_has_no_doppler_to_search(make_radar, make_processing, whole_grid):
    # K = 1: every Doppler bin of a column holds the same value (σ = 0): the first, q = 0, wins.
    radar = make_radar(num_samples=32, num_chirps=1)
    processing = make_processing(radar, n_dft=63, k_dft=5, window="boxcar")
    cube = add_noise(np.zeros((2, 1, 32), complex), 1.0, np.random.default_rng(8))
    scan = _compare(cube, radar, processing)
    assert np.all(scan.doppler_bin == 0)


def test_chunks_and_candidate_blocks_do_not_change_the_result(make_radar, make_processing, tone, monkeypatch):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    rng = np.random.default_rng(9)
    cube = add_noise(np.zeros((7, 16, 64), complex) + 0.2 * tone(radar, 1e-8, 2e-9), 1.0, rng)
    one = _on_device(cube, radar, processing)
    monkeypatch.setattr(devicegrid, "DEVICE_SCAN_BYTES", 3 * devicegrid.device_scan_bytes(16, 64, 127, 67))
    monkeypatch.setattr(devicegrid, "_CANDIDATE_BLOCK", 7)
    chunked = _on_device(cube, radar, processing)
    for name in ("delay_bin", "doppler_bin", "peak_power", "average_power"):
        np.testing.assert_array_equal(getattr(chunked, name), getattr(one, name))


def test_a_device_cube_with_bad_values_is_refused_where_it_lives(make_radar, make_processing):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    sweep = BeamSweep(np.zeros((2, 2)))
    bad = np.ones((2, 16, 64), complex)
    bad[1, 3, 4] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        scan_beams(STRICT.asarray(bad), sweep, radar, processing)
    with pytest.raises(ValueError, match="all zeros"):
        scan_beams(STRICT.asarray(np.zeros((2, 16, 64), complex)), sweep, radar, processing)
    with pytest.raises(ValueError, match="sweep has 2 angles"):
        scan_beams(STRICT.asarray(np.ones((3, 16, 64), complex)), sweep, radar, processing)


class _CupyLikeNamespace:
    """array_api_strict with CuPy's (before v14) narrower ``repeat``: counts held on the device are refused."""

    def __init__(self, xp):
        self._xp = xp

    def __getattr__(self, name):
        return getattr(self._xp, name)

    def repeat(self, x, repeats, /, *, axis=None):
        if not isinstance(repeats, int):
            raise ValueError("cupy.ndarray cannot be specified as `repeats` argument.")
        return self._xp.repeat(x, repeats, axis=axis)


def test_the_search_keeps_to_what_cupy_accepts(make_radar, make_processing, multipath_cube):
    # CuPy's repeat takes host counts only: the candidate bins are expanded by searchsorted instead, so a
    # namespace that refuses device counts gives the same cells.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    cube = multipath_cube(radar, 12, np.random.default_rng(31))
    backend = dsp.ArrayBackend("array_api_strict", _CupyLikeNamespace(STRICT.xp), STRICT.device)
    w_k, w_n, _ = dft_windows(radar, processing)
    q, p, *_ = devicegrid.device_scan(backend.asarray(cube), processing, 0, (w_k, w_n),
                                      radar.delay_grid(processing.n_dft), backend)
    oracle = grid_maxima(cube, radar, processing)
    np.testing.assert_array_equal(q, oracle[0])
    np.testing.assert_array_equal(p, oracle[1])
