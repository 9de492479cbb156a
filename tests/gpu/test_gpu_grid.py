"""The paper's grid search (``dsp.devicegrid``) and the impulse screen (``dsp.impulses``) on an NVIDIA GPU (CuPy) against the host (issue 21, item 3).

Skipped, with the reason, where there is no GPU (``dsp.cuda_available()``); run with
``./setup.sh --gpu && .venv/bin/python -m pytest -m gpu``. The same code runs in CI on
array_api_strict (``tests/dsp/test_device_grid.py``).

Oracles: the host's screened search (``scan_beams`` on NumPy, ``doppler_search="zoom"``; itself equal
to the whole float64 grid, ``tests/dsp/test_speedpath.py``) on the same noisy Table I cubes, and the
whole float64 grid of ``numpy.fft`` on random multipath beams: the same cells on every beam, values
within 1e-9 relative (two float64 evaluations of the same sums, cuFFT's and pocketfft's).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dsp
from dsp import BeamSweep, scan_beams
from dsp.spectrum import dft_windows
from risloc_rt.model import paper_scenario, simulate

GPU_OK, GPU_WHY = dsp.cuda_available()
pytestmark = [pytest.mark.gpu, pytest.mark.skipif(not GPU_OK, reason=f"no GPU: {GPU_WHY}")]


@pytest.fixture(scope="module")
def gpu():
    backend = dsp.backend_for("cuda")
    assert backend.name == "cupy"
    return backend


@pytest.mark.parametrize("tx_dbm", [0.0, 10.0, 20.0])
def test_table1_captures_give_the_hosts_cells_on_the_gpu(gpu, tx_dbm):
    scenario = paper_scenario("off-broadside", mode="relay")
    scenario = dataclasses.replace(scenario, radar=dataclasses.replace(scenario.radar, tx_power_dbm=tx_dbm))
    for seed in range(4):
        capture = simulate(scenario, rng=np.random.default_rng(1000 + seed))
        args = (capture.sweep, capture.radar, capture.processing)
        host = scan_beams(capture.cube, *args)
        dev = scan_beams(gpu.asarray(capture.cube), *args)
        np.testing.assert_array_equal(dev.delay_bin, host.delay_bin)
        np.testing.assert_array_equal(dev.doppler_bin, host.doppler_bin)
        np.testing.assert_allclose(dev.peak_power, host.peak_power, rtol=1e-9)
        np.testing.assert_allclose(dev.average_power, host.average_power, rtol=1e-9)


def test_random_multipath_beams_and_glitches_give_the_full_grid_cell_on_the_gpu(gpu, make_radar, make_processing,
                                                                               multipath_cube, glitch_beams):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    cube = multipath_cube(radar, 160, np.random.default_rng(77))
    dev = scan_beams(gpu.asarray(cube), BeamSweep(np.zeros((cube.shape[0], 2))), radar, processing)
    w_k, w_n, gain = dft_windows(radar, processing)
    z = np.fft.ifft2(cube * np.outer(w_k, w_n), s=(processing.k_dft, processing.n_dft)) \
        * (processing.k_dft * processing.n_dft)
    power = (z.real**2 + z.imag**2).reshape(cube.shape[0], -1)
    q, p = np.divmod(power.argmax(axis=1), processing.n_dft)
    np.testing.assert_array_equal(dev.doppler_bin, q)
    np.testing.assert_array_equal(dev.delay_bin, p)
    np.testing.assert_allclose(dev.peak_power, power.max(axis=1) / gain**2, rtol=1e-9)
    # an interference burst and a glitch at Table I sizes (the glitch on its whole grid there): the host's cells
    table = make_radar(num_samples=600, num_chirps=128)
    table_processing = make_processing(table, n_dft=1199, k_dft=4793)
    beams = glitch_beams(np.random.default_rng(12))
    sweep = BeamSweep(np.zeros((2, 2)))
    host = scan_beams(beams, sweep, table, table_processing)
    dev = scan_beams(gpu.asarray(beams), sweep, table, table_processing)
    np.testing.assert_array_equal(dev.delay_bin, host.delay_bin)
    np.testing.assert_array_equal(dev.doppler_bin, host.doppler_bin)


def test_paper_estimator_on_the_gpu_takes_the_hosts_beam_and_cells(gpu):
    capture = simulate(paper_scenario("off-broadside", mode="relay"), rng=np.random.default_rng(4))
    kw = dict(sweep=capture.sweep, radar=capture.radar, processing=capture.processing, pose=capture.ris.pose,
              loopback_delay=capture.ris.loopback_delay, estimator="paper", pattern=capture.ris.beam_pattern())
    host = dsp.self_localize(capture.cube, **kw)
    dev = dsp.self_localize(capture.cube, backend=gpu, **kw)
    assert dev.beam_index == host.beam_index and dev.flag_codes == host.flag_codes
    np.testing.assert_array_equal(dev.scan.delay_bin, host.scan.delay_bin)
    np.testing.assert_array_equal(dev.scan.doppler_bin, host.scan.doppler_bin)
    assert dev.distance == pytest.approx(host.distance, abs=1e-9)


def test_impulsive_samples_are_found_on_the_gpu_as_on_the_host(gpu, impulse_screen_matches_host):
    capture = simulate(paper_scenario("off-broadside", mode="relay"), rng=np.random.default_rng(4))
    impulse_screen_matches_host(capture.cube, capture.radar.noise_power, gpu)
