"""``dsp.delay_profile``: one delay-rate row of eq. (2DDFT) without the whole delay-Doppler map.

Oracles: eq. (2DDFT) summed term by term in the test (explicit exponentials, no FFT, nothing of
``dsp.spectrum`` but the window vector), a noiseless on-grid tone that reads |γ|² in its bin, and the
row of ``delay_doppler_map`` the profile stands for (the same row chosen, midway rates included).
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import BeamSweep, delay_doppler_map, delay_profile, window_vector
from risloc_rt.model.beat import beat_cube


def _direct_row(frame, radar, processing, q):
    """|z(τ_p, ν_q)|² for every p by eq. (2DDFT) written out: Σ_k Σ_n w_k w_n y e^{+j2π(qk/K_DFT + pn/N_DFT)}."""
    k_len, n_len = frame.shape
    w_k = window_vector(processing.window, k_len)
    w_n = window_vector(processing.window, n_len)
    p = np.arange(processing.n_dft)[:, None]
    n = np.arange(n_len)[None, :]
    fast = np.exp(2j * np.pi * p * n / processing.n_dft)  # [N_DFT, N]
    slow = np.exp(2j * np.pi * q * np.arange(k_len) / processing.k_dft)  # [K]
    z = fast @ ((slow * w_k) @ (frame * w_n))
    return np.abs(z) ** 2 / (w_k.sum() * w_n.sum()) ** 2


@pytest.mark.parametrize("window", ["hann", "boxcar"])
@pytest.mark.parametrize("q", [0, 3, 40])
def test_the_profile_is_the_direct_dft_row_for_every_beam(window, q, rng, make_processing, make_radar):
    radar = make_radar(num_samples=48, num_chirps=12)
    processing = make_processing(radar, window=window, n_dft=95, k_dft=47)
    cube = rng.normal(size=(3, 12, 48)) + 1j * rng.normal(size=(3, 12, 48))  # [√W], unit power per sample
    nu = radar.delay_rate_grid(processing.k_dft)[q]
    prof = delay_profile(cube, radar, processing, delay_rate=nu)
    assert prof.power.shape == (3, processing.n_dft)
    assert prof.delay_rate == nu
    np.testing.assert_array_equal(prof.delay, radar.delay_grid(processing.n_dft))
    for m in range(3):
        direct = _direct_row(cube[m], radar, processing, q)
        # both are sums of 576 unit-power terms: rounding is ~1e-13 of the row's largest value [W]
        assert np.max(np.abs(prof.power[m] - direct)) <= 1e-12 * direct.max()
    one = delay_profile(cube[1], radar, processing, delay_rate=nu)  # a frame gives [N_DFT]
    assert one.power.shape == (processing.n_dft,)
    np.testing.assert_allclose(one.power, prof.power[1], rtol=0, atol=1e-13 * prof.power[1].max())


def test_an_on_grid_tone_reads_its_power_in_its_bin(make_processing, make_radar, tone_paths):
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar)  # N_DFT = 127, K_DFT = 64
    p, q = 37, 5
    nu = radar.delay_rate_grid(processing.k_dft)[q]
    tau = radar.delay_grid(processing.n_dft)[p] - radar.carrier_frequency * nu / radar.slope
    gamma = 3e-4 * np.exp(0.7j)  # [√W]
    frame = beat_cube(tone_paths(gamma, tau, nu), radar=radar, sweep=BeamSweep(np.zeros((1, 2))), ris=None)[0]
    prof = delay_profile(frame, radar, processing, delay_rate=nu)
    assert int(np.argmax(prof.power)) == p
    assert prof.power[p] == pytest.approx(abs(gamma) ** 2, rel=1e-9)  # [W]
    assert prof.distance[p] == pytest.approx(radar.delay_grid(processing.n_dft)[p] * 299_792_458.0 / 2, rel=1e-15)


def test_the_row_is_the_maps_including_rates_between_rows(rng, make_processing, make_radar):
    radar = make_radar(num_samples=32, num_chirps=8)
    processing = make_processing(radar, n_dft=63, k_dft=30)
    frame = rng.normal(size=(8, 32)) + 1j * rng.normal(size=(8, 32))
    ddm = delay_doppler_map(frame, radar, processing)
    rows = ddm.delay_rate  # ascending
    step = rows[1] - rows[0]
    zero = int(np.flatnonzero(rows == 0.0)[0])
    # exactly midway between the rows -1 and 0 (the only adjacent pair whose FFT order is not ascending) and
    # between two others; beyond both ends; on a row; near zero
    asked = [-0.5 * rows[zero + 1], 0.5 * (rows[7] + rows[8]), 0.0, rows[3], rows[0] - 5 * step,
             rows[-1] + 5 * step, 0.3 * step]
    assert abs(asked[0] - rows[zero - 1]) == abs(asked[0] - rows[zero])  # a true tie
    for nu in asked:
        prof = delay_profile(frame, radar, processing, delay_rate=nu)
        row = int(np.argmin(np.abs(rows - nu)))
        assert prof.delay_rate == rows[row]
        assert np.max(np.abs(prof.power - ddm.profile(nu))) <= 1e-12 * ddm.power.max()


@pytest.mark.parametrize("frames, message", [
    (np.ones((2, 2, 8, 32), complex), "frames has 4 axes"),
    (np.ones(32, complex), "frames has 1 axes"),
    (np.ones((8, 31), complex), "K=8 chirps and N=32 samples"),
    (np.full((8, 32), np.nan + 0j), "frames"),
    (np.ones((8, 32)), "frames"),  # real samples are refused
])
def test_bad_frames_get_one_line_errors(frames, message, make_processing, make_radar):
    radar = make_radar(num_samples=32, num_chirps=8)
    processing = make_processing(radar, n_dft=63, k_dft=30)
    with pytest.raises((ValueError, TypeError), match=message) as err:
        delay_profile(frames, radar, processing)
    assert "\n" not in str(err.value)


def test_a_non_finite_rate_is_refused(make_processing, make_radar):
    radar = make_radar(num_samples=32, num_chirps=8)
    processing = make_processing(radar, n_dft=63, k_dft=30)
    with pytest.raises(ValueError, match="delay_rate"):
        delay_profile(np.ones((8, 32), complex), radar, processing, delay_rate=float("nan"))
