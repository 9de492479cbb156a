"""Delay-Doppler processing: eqs. (2DDFT), (argmaxmap), (P_ave) in dsp/spectrum.py and dsp/beamscan.py.

Oracles: a noiseless tone whose (range-Doppler-coupled) delay and delay rate sit on grid points
lands exactly in those bins with |z|² = |γ|² (the DSP divides by the window's coherent gain);
Parseval's theorem for the zero-padded 2-D DFT; the "zoom" Doppler search returns the same grid
maximum as the paper's full search.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from dsp import BeamSweep, RisPose, delay_doppler_map, localize, scan_beams, window_vector
from risloc_rt.model.beat import add_noise, beat_cube

# A tone exactly on a grid point: every DFT term is γ·w up to rounding, so |z|² = |γ|² to ~1e-15;
# 1e-9 relative is the tolerance.
POWER_RTOL = 1e-9
GAMMA = 3e-4 * np.exp(0.7j)  # [√W]


def on_grid_tone(radar, processing, p: int, q: int):
    """(τ, ν) whose DFT peak is at delay bin p and Doppler bin q (FFT order).

    Eq. (1)'s fast-time frequency is S τ + f_c ν: the peak is at τ + f_c ν / S, so τ is pulled
    back by f_c ν / S to land on τ_p.
    """
    nu = radar.delay_rate_grid(processing.k_dft)[q]
    tau = radar.delay_grid(processing.n_dft)[p] - radar.carrier_frequency * nu / radar.slope
    assert tau >= 0
    return tau, nu


def tone_frame(tone_paths, radar, tau, nu, gain=GAMMA):
    return beat_cube(tone_paths(gain, tau, nu), radar=radar, sweep=BeamSweep(np.zeros((1, 2))), ris=None)


TONE_CASES = [
    # (p, q): delay bin and Doppler bin (FFT order; q > K_DFT/2 is a negative delay rate)
    pytest.param(37, 0, id="static"),
    pytest.param(37, 5, id="receding"),
    pytest.param(90, 64 - 9, id="approaching"),
    pytest.param(3, 31, id="near-max-rate"),
]


@pytest.mark.parametrize("p, q", TONE_CASES)
def test_on_grid_tone_lands_in_its_bins_in_the_delay_doppler_map(p, q, make_processing, make_radar, tone_paths):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar)  # N_DFT = 127, K_DFT = 64
    tau, nu = on_grid_tone(radar, processing, p, q)
    dd = delay_doppler_map(tone_frame(tone_paths, radar, tau, nu)[0], radar, processing)
    assert dd.power.shape == (processing.k_dft, processing.n_dft)
    row, col = np.unravel_index(int(np.argmax(dd.power)), dd.power.shape)
    assert col == p
    assert dd.delay[col] == radar.delay_grid(processing.n_dft)[p]
    assert dd.delay_rate[row] == nu  # the map's Doppler axis is ascending (fft-shifted)
    assert np.all(np.diff(dd.delay_rate) > 0)
    assert dd.power[row, col] == pytest.approx(abs(GAMMA) ** 2, rel=POWER_RTOL)
    assert dd.velocity[row] == pytest.approx(nu * C / 2, rel=1e-12)
    np.testing.assert_array_equal(dd.peaks(1), [[row, col]])


@pytest.mark.parametrize("search", ["zoom", "full"])
@pytest.mark.parametrize("p, q", TONE_CASES)
def test_on_grid_tone_lands_in_its_bins_in_scan_beams(p, q, search, make_processing, make_radar, tone_paths):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, doppler_search=search)
    tau, nu = on_grid_tone(radar, processing, p, q)
    scan = scan_beams(tone_frame(tone_paths, radar, tau, nu), BeamSweep(np.zeros((1, 2))), radar, processing)
    assert scan.delay_bin.tolist() == [p]
    assert scan.doppler_bin.tolist() == [q]
    assert scan.delay[0] == radar.delay_grid(processing.n_dft)[p]
    assert scan.delay_rate[0] == nu
    assert scan.peak_power[0] == pytest.approx(abs(GAMMA) ** 2, rel=POWER_RTOL)
    # localize undoes the range-Doppler coupling: τ̂ = τ_p - f_c ν / S is the path's own τ
    # (to float rounding of ~1e-22 s), velocity ν c / 2.
    loc = localize(scan, radar=radar, pose=RisPose(np.zeros(3), np.array([0.0, 1.0, 0.0])), loopback_delay=0.0)
    assert loc.delay == pytest.approx(tau, abs=1e-20)
    assert loc.velocity == pytest.approx(nu * C / 2, rel=1e-12)


@pytest.mark.parametrize("window", ["hann", "hamming", "blackman", "boxcar"])
def test_peak_power_is_normalised_by_the_coherent_gain_of_any_window(window, make_processing, make_radar, tone_paths):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, window=window)
    tau, nu = on_grid_tone(radar, processing, 20, 3)
    dd = delay_doppler_map(tone_frame(tone_paths, radar, tau, nu)[0], radar, processing)
    assert dd.power.max() == pytest.approx(abs(GAMMA) ** 2, rel=POWER_RTOL)


def test_hann_is_the_papers_sin_squared_window():
    a = np.arange(10)
    np.testing.assert_allclose(window_vector("hann", 10), np.sin(a * np.pi / 10) ** 2, atol=1e-15)


@pytest.mark.parametrize("window", ["hann", "boxcar"])
def test_parseval_for_the_zero_padded_map(window, rng, make_processing, make_radar):
    # Σ_{p,q} |Z|² = N_DFT·K_DFT·Σ|w y|² for the unnormalised transform; the map is |Z|²/gain².
    radar = make_radar(num_samples=32, num_chirps=8)
    processing = make_processing(radar, window=window, n_dft=50, k_dft=24)
    frame = rng.normal(size=(8, 32)) + 1j * rng.normal(size=(8, 32))
    w = np.outer(window_vector(window, 8), window_vector(window, 32))
    gain = w.sum()  # Σw_K·Σw_N for separable windows
    dd = delay_doppler_map(frame, radar, processing)
    expected = processing.n_dft * processing.k_dft * np.sum(np.abs(w * frame) ** 2) / gain**2
    assert dd.power.sum() == pytest.approx(expected, rel=1e-12)


def test_scan_beams_agrees_with_the_full_map_on_noise(rng, make_processing, make_radar):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, delta=1.5e-9)  # ±1.5 ns: several delay bins in P_ave
    cube = add_noise(np.zeros((4, 16, 64), complex), 1.0, rng)
    scan = scan_beams(cube, BeamSweep(np.zeros((4, 2))), radar, processing)
    rates = radar.delay_rate_grid(processing.k_dft)
    for m in range(4):
        dd = delay_doppler_map(cube[m], radar, processing)
        row, col = np.unravel_index(int(np.argmax(dd.power)), dd.power.shape)
        assert scan.delay_bin[m] == col
        assert dd.delay_rate[row] == rates[scan.doppler_bin[m]]
        assert scan.peak_power[m] == pytest.approx(dd.power[row, col], rel=1e-9)
        window = np.abs(dd.delay - dd.delay[col]) <= processing.delta
        assert window.sum() > 1
        assert scan.average_power[m] == pytest.approx(dd.power[row, window].mean(), rel=1e-9)


def test_min_range_skips_near_returns(make_processing, make_radar, tone_paths):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar)
    grid = radar.delay_grid(processing.n_dft)
    near, far = grid[10], grid[60]  # 1.7 m and 10.3 m
    paths = tone_paths([1e-2, 1e-4], [near, far], [0.0, 0.0])
    cube = beat_cube(paths, radar=radar, sweep=BeamSweep(np.zeros((1, 2))), ris=None)
    sweep = BeamSweep(np.zeros((1, 2)))
    assert scan_beams(cube, sweep, radar, processing).delay_bin[0] == 10
    # Exclude everything closer than 5 m: the weaker, farther tone is the peak.
    gated = dataclasses.replace(processing, min_range=5.0)
    for search in ("zoom", "full"):
        scan = scan_beams(cube, sweep, radar, dataclasses.replace(gated, doppler_search=search))
        assert scan.delay_bin[0] == 60
        # |γ|² of the far tone; the near tone's Hann sidelobes 25 resolution cells away are
        # ~100 dB below its own 1e-4 W, i.e. ~1e-3 of the far tone's 1e-8 W: allow 1 %.
        assert scan.peak_power[0] == pytest.approx(1e-8, rel=1e-2)
    dd = delay_doppler_map(cube[0], radar, processing)
    assert dd.peaks(1, min_delay=2 * 5.0 / C)[0, 1] == 60


@pytest.mark.parametrize("velocity", [2.5, -7.3])
def test_zoom_and_full_search_agree_on_a_noisy_table1_capture(velocity, paper_run):
    scenario, _ = paper_run("off-broadside", "relay")
    # Seven beams: four around the UE (21°) and three far ones where noise and the structural
    # reflection dominate. The UE moves along the RIS-UE line (off-grid Doppler).
    subset = BeamSweep(np.deg2rad([[18.0, 0.0], [19.5, 0.0], [21.0, 0.0], [22.5, 0.0],
                                   [-45.0, 0.0], [-10.5, 0.0], [40.5, 0.0]]))
    away = -np.array([0.0, 1.0, 0.0])  # from the RIS (at +y) toward and past the UE (origin)
    scenario = dataclasses.replace(scenario, sweep=subset, ue_velocity=velocity * away)
    from risloc_rt.model.simulate import simulate

    cube = simulate(scenario, rng=np.random.default_rng(31)).cube
    zoom = scan_beams(cube, subset, scenario.radar, dataclasses.replace(scenario.processing, doppler_search="zoom"))
    full = scan_beams(cube, subset, scenario.radar, dataclasses.replace(scenario.processing, doppler_search="full"))
    np.testing.assert_array_equal(zoom.delay_bin, full.delay_bin)
    np.testing.assert_array_equal(zoom.doppler_bin, full.doppler_bin)
    # Same grid points, two evaluations of the same DFT (matrix product vs FFT): 1e-9 relative.
    np.testing.assert_allclose(zoom.peak_power, full.peak_power, rtol=1e-9)
    np.testing.assert_allclose(zoom.average_power, full.average_power, rtol=1e-9)
    # And the estimate is physical. At the UE beam the SNR is ≈ -11 dB per sample + 48.9 dB of
    # N·K integration - 3.5 dB of Hann loss ≈ 34 dB, so the Doppler error's std is ~1 % of the
    # resolution 1/(K f_c T); allow a tenth of it (the K_DFT grid step, 1/37 of it, is finer than
    # the noise-driven error, so half a grid step would be too strict).
    resolution = 1 / (scenario.radar.num_chirps * scenario.radar.carrier_frequency * scenario.radar.chirp_duration)
    assert full.delay_rate[2] == pytest.approx(2 * velocity / C, abs=0.1 * resolution)
