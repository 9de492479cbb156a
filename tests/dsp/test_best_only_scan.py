"""``scan_beams(best_only=True)``: the paper's best beam without searching the beams that cannot win.

Oracles: Szegő's extremal function (two chirps and two samples, first and last: the closed form
``|z| = 4|cos(π(K-1)(ν-ν₀))|·|cos(π(N-1)(f-f₀))|`` gives its maximum 4 and every grid value), the
continuous maximum (a float64 grid 8× finer than native, polished by Nelder-Mead on the exact DTFT),
and the full scan (``best_only=False``), whose best beam and numbers the reduced scan must give bit
for bit. A beam is left out only when its bound is below a P_ave already found.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
import scipy.optimize

import dsp
from dsp import gridbound, gridscreen
from risloc_rt.model.beat import add_noise
from risloc_rt.model.scenario import paper_scenario
from risloc_rt.model.simulate import simulate

FIELDS = ("delay", "delay_rate", "peak_power", "average_power", "delay_bin", "doppler_bin")


def _bound(x: np.ndarray, length: int) -> float:
    """grid_bound of the windowed beam ``x`` (given in float64: cast to complex64 as the scan does)."""
    x32 = x.astype(np.complex64)
    return gridbound.grid_bound(x32, float(np.linalg.norm(x32.astype(np.complex128))), length)


def _slack(x: np.ndarray, length: int) -> float:
    """grid_bound's stated float32 allowance on |z| (its docstring): 50 u log₂(L L_f) √(L L_f) ‖x‖_F + 4u √(KN) ‖x‖_F."""
    k, n = x.shape
    u, cells = 2.0**-24, length * scipy.fft.next_fast_len(2 * n)
    return (50 * u * np.log2(cells) * np.sqrt(cells) + 4 * u * np.sqrt(k * n)) * float(np.linalg.norm(x))


def _fine_max(x: np.ndarray, over: int) -> float:
    """The continuous max |z|²: from the best cell of a float64 grid ``over`` times finer than native per
    axis, polished by Nelder-Mead on the exact DTFT |Σ x e^{-j2π(νk + fn)}|² (never below the grid's)."""
    k, n = x.shape
    z = scipy.fft.fft2(x, s=(over * k, over * n))
    power = z.real**2 + z.imag**2
    q, p = np.unravel_index(int(power.argmax()), power.shape)
    kk, nn = np.arange(k), np.arange(n)

    def minus(v):
        return -abs(np.exp(-2j * np.pi * v[0] * kk) @ x @ np.exp(-2j * np.pi * v[1] * nn)) ** 2

    res = scipy.optimize.minimize(minus, [q / (over * k), p / (over * n)], method="Nelder-Mead",
                                  options={"xatol": 1e-12, "fatol": 1e-14 * float(power.max()), "maxiter": 4000})
    return max(float(power.max()), -float(res.fun))


def test_szegos_extremal_function_attains_the_bound_on_both_axes():
    # K = 17, L = 64: the maxima of |cos(16π(ν-ν₀))| repeat every 1/16 = 4/64 cycles, so with ν₀
    # midway between two of the 64 Doppler bins every repeat is too: the grid's largest |z| is
    # 4·cos(π/8), exactly the cos α_ν the bound divides by. N = 3 does the same on the delay axis
    # (L_f = 6, repeats every 1/2 = 3/6, α_f = π/6). The bound must then be the maximum, 16,
    # up to its float32 slack; a smaller factor would put it below the maximum.
    k, n, length = 17, 3, 64
    assert scipy.fft.next_fast_len(2 * n) == 6
    nu0, f0 = 9.5 / length, 2.5 / 6
    x = np.zeros((k, n), complex)
    for kk in (0, k - 1):
        for nn in (0, n - 1):
            x[kk, nn] = np.exp(2j * np.pi * (nu0 * kk + f0 * nn))
    bound = _bound(x, length)
    assert bound >= 16.0
    # and no more than the slack (divided by cos α_f cos α_ν, as the grid value it is added to) above it:
    # 16.0101 for this 4-sample beam; the float32 grid value may exceed float64's by u, hence 2e-6
    assert bound <= (4.0 * (1 + 2e-6) + _slack(x, length) / (np.cos(np.pi / 8) * np.cos(np.pi / 6))) ** 2
    # the half-bin grid alone misses the maximum by the factor the bound restores (Table I: at most 4)
    z = scipy.fft.fft2(x, s=(length, 6))
    grid_max = float((np.abs(z) ** 2).max())
    assert grid_max == pytest.approx(16.0 * (np.cos(np.pi / 8) * np.cos(np.pi / 6)) ** 2, rel=1e-12)


@pytest.mark.parametrize("kind", ["one tone off both grids", "three tones", "noise", "tone in noise", "impulse"])
def test_the_bound_is_above_the_maximum_and_within_6_db_of_it(kind):
    # A Table I-like beam shape at reduced size (K = 32 chirps, N = 100 samples), Hann-windowed as the
    # scan windows it. The bound must cover the continuous maximum (an 8x-finer float64 grid polished
    # by Nelder-Mead; the paper's N_DFT × K_DFT grid's maximum lies below it) and exceed it by at
    # most the factor 1/(cos α_f cos α_ν)² <= 4 (6 dB) plus the slack.
    k, n = 32, 100
    length = 64
    rng = np.random.default_rng(sum(map(ord, kind)))
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    x = np.zeros((k, n), complex)
    if kind == "one tone off both grids":
        x = np.exp(2j * np.pi * (0.25 / length * 2 + 0.3141 * kk + 0.2718 * nn + 0.13 / (2 * n) * nn))
    elif kind == "three tones":
        for _ in range(3):
            x = x + rng.normal() * np.exp(2j * np.pi * (rng.random() * kk + rng.random() * nn + rng.random()))
    elif kind == "noise":
        x = rng.normal(size=(k, n)) + 1j * rng.normal(size=(k, n))
    elif kind == "tone in noise":
        x = 0.2 * np.exp(2j * np.pi * (0.41 * kk + 0.77 * nn)) + 0.1 * (rng.normal(size=(k, n)) + 1j * rng.normal(size=(k, n)))
    else:  # one glitched sample: flat in both axes
        x[7, 42] = 3.0 - 4.0j
    x = x * np.outer(np.hanning(k + 1)[:-1], np.hanning(n + 1)[:-1]) if kind != "impulse" else x
    bound = _bound(x, length)
    fine = _fine_max(x, 8)
    # 1/(cos α_f cos α_ν)², α_f = π(N-1)/(2 L_f), α_ν = π(K-1)/(2L): the bound's factor, written out
    factor = 1.0 / (np.cos(np.pi * (n - 1) / (2 * scipy.fft.next_fast_len(2 * n)))
                    * np.cos(np.pi * (k - 1) / (2 * length))) ** 2
    assert factor <= 4.0
    assert bound >= fine
    # the float32 grid value may exceed float64's by u: 2e-6 instead of the bound's own 1e-6
    assert bound <= factor * (np.sqrt(fine) * (1 + 2e-6) + _slack(x, length)) ** 2


@pytest.mark.parametrize("kind, above", [("tone in noise", 1.15), ("two tones", 1.15), ("noise", 2.5)])
def test_a_level_refines_the_delays_near_the_maximum_and_still_bounds_it(kind, above):
    # With a level ``above`` times the maximum, grid_bound refines the few delay bins that could reach
    # it 4x on both axes (their part of the bound: 1/(cos(α_f/4) cos(α_ν/4))² = 1.08 here times the
    # maximum); the other delays keep the coarse bound, below the level. The bound must still cover
    # the continuous maximum (the refined delays and Dopplers are the 8x-finer grid itself: its
    # maximum is below it by up to ~0.1 %), and come back below the level where the coarse one (3.6-3.7x here)
    # is above it. (Noise has more than the 16 refined delay bins within 1.15x / 3.7 of its maximum:
    # there the level is 2.5x.)
    k, n, length = 32, 100, 64
    rng = np.random.default_rng(len(kind))
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    noise = rng.normal(size=(k, n)) + 1j * rng.normal(size=(k, n))
    if kind == "tone in noise":
        x = 0.3 * np.exp(2j * np.pi * (0.123 * kk + 0.456 * nn)) + 0.1 * noise
    elif kind == "noise":
        x = noise
    else:
        x = np.exp(2j * np.pi * (0.2 * kk + 0.3 * nn)) + 0.9 * np.exp(2j * np.pi * (0.7 * kk + 0.61 * nn))
    x = x * np.outer(np.hanning(k + 1)[:-1], np.hanning(n + 1)[:-1])
    fine = _fine_max(x, 8)
    level = above * fine
    refined = gridbound.grid_bound(x.astype(np.complex64), float(np.linalg.norm(x.astype(np.complex64))), length,
                                    level=level)
    assert fine <= refined < level < _bound(x, length)


def _typical(x32: np.ndarray) -> float:
    """grid_bound's estimate of a noise beam's Σ_k |a_k| in one delay bin: √(π/4) Σ_k ‖x_k‖ (its docstring)."""
    return float(np.sqrt(np.pi / 4.0) * np.linalg.norm(x32.astype(np.complex128), axis=1).sum())


def test_the_chirp_sum_closes_the_delays_of_a_doppler_tone_and_attains_the_bound_on_the_delay_axis():
    # A tone in Doppler (every chirp, the same phase step) on Szegő's delay-axis extremal function (samples
    # 0 and N-1, N = 3, f₀ midway between two of the L_f = 6 delay bins): |a_k(f)| = 2|cos(2π(f-f₀))| in
    # every chirp, so Σ_k |a_k(f)| = max_ν |z(ν, f)| exactly and the maximum 2K lies between delay bins by
    # α_f = π/6. With a level 1 % above the maximum the chirp sum alone closes every delay bin, and the
    # bound is the maximum up to the sum's float32 slack; without the 1/cos α_f it would be 25 % below it.
    # The Doppler grid's bound (refined 4x) would be 3 % above it, above the level.
    k, n, length = 17, 3, 64
    nu0, f0 = 0.2, 2.5 / 6
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    x = np.zeros((k, n), complex)
    x[:, [0, n - 1]] = np.exp(2j * np.pi * (nu0 * kk + f0 * nn[:, [0, n - 1]]))
    x32 = x.astype(np.complex64)
    norm = float(np.linalg.norm(x32.astype(np.complex128)))
    peak = (2.0 * k) ** 2
    assert _fine_max(x, 8) == pytest.approx(peak, rel=1e-9)
    level = 1.01 * peak
    alpha_f = np.pi / 6
    assert _typical(x32) < np.sqrt(level) * np.cos(alpha_f)  # the sum is taken (grid_bound's test, written out)
    bound = gridbound.grid_bound(x32, norm, length, level=level)
    u = 2.0**-24
    l1_slack = (50 * u * np.log2(6) * np.sqrt(6 * k) + 4 * u * np.sqrt(k * n)) * norm
    # the grid's largest sum is 2K cos α_f (float32: up to u more), divided by cos α_f
    assert peak <= bound <= (2.0 * k * (1 + 2e-6) + l1_slack / np.cos(alpha_f)) ** 2
    assert bound < level
    # the Doppler grid's own bound, for comparison: above the level
    assert gridbound.grid_bound(x32, norm, length) > level


@pytest.mark.parametrize("seed", range(6))
def test_where_the_chirp_sum_closes_delays_the_bound_still_covers_the_maximum(seed):
    # A strong tone (random delay and Doppler) in weak noise, K = 32, N = 100, Hann-windowed; the level
    # 1.3-2x the continuous maximum: the chirp sum is taken (its typical value is below the level) and
    # closes the noise's delay bins, the Doppler grid is computed for the rest. The bound must cover
    # the continuous maximum and come back below the level.
    k, n, length = 32, 100, 64
    rng = np.random.default_rng(100 + seed)
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    x = np.exp(2j * np.pi * (rng.random() * kk + rng.random() * nn)) \
        + 0.05 * (rng.normal(size=(k, n)) + 1j * rng.normal(size=(k, n)))
    x = x * np.outer(np.hanning(k + 1)[:-1], np.hanning(n + 1)[:-1])
    x32 = x.astype(np.complex64)
    norm = float(np.linalg.norm(x32.astype(np.complex128)))
    fine = _fine_max(x, 8)
    level = (1.3 + 0.7 * rng.random()) * fine
    assert _typical(x32) < np.sqrt(level) * np.cos(np.pi * (n - 1) / (2 * scipy.fft.next_fast_len(2 * n)))
    bound = gridbound.grid_bound(x32, norm, length, level=level)
    assert fine <= bound < level


def _scans(cube, sweep, radar, processing):
    with dsp.limit_threads(1):
        return (dsp.scan_beams(cube, sweep, radar, processing),
                dsp.scan_beams(cube, sweep, radar, processing, best_only=True))


def _assert_same_best(full, best):
    m = full.best_beam
    assert best.best_beam == m
    for name in FIELDS:
        assert getattr(best, name)[m] == getattr(full, name)[m], name
    kept = ~best.bounded
    for name in FIELDS:  # every searched beam is the full scan's, bit for bit
        np.testing.assert_array_equal(getattr(best, name)[kept], getattr(full, name)[kept])
    b = best.bounded
    # the bounded beams: above their true numbers, below the best beam's P_ave, no cell
    assert np.all(best.peak_power[b] >= full.peak_power[b])
    assert np.all(best.average_power[b] >= full.average_power[b])
    assert np.all(best.average_power[b] < full.average_power[m])
    assert np.all(np.isnan(best.delay[b])) and np.all(best.delay_bin[b] == -1)


@pytest.mark.slow
@pytest.mark.parametrize("tx_power_dbm, least_bounded", [(-30.0, 0), (0.0, 0), (5.0, 50), (10.0, 50)])
def test_table_i_best_beam_is_the_full_scans_and_the_noise_beams_are_left_out(tx_power_dbm, least_bounded):
    # Table I (61 beams, 128 chirps, 600 samples, the paper's grid), the fast noise stream. At 5 and
    # 10 dBm the noise-only beams' bounds fall below the RIS beam's P_ave: measured 55 of 55 left out
    # at 5 dBm and 54 at 10 dBm (8 seeds, UE at 10.3°); at 0 dBm the best P_ave is within 1-3 dB of
    # their maxima and at -30 dBm no beam has a return: all searched.
    sc = paper_scenario(radar=dsp.RadarConfig(tx_power_dbm=tx_power_dbm))
    cap = simulate(sc, rng=np.random.default_rng(11), noise_stream="fast")
    full, best = _scans(cap.cube, cap.sweep, cap.radar, cap.processing)
    _assert_same_best(full, best)
    assert full.bounded is None
    assert int(best.bounded.sum()) >= least_bounded
    if least_bounded == 0:
        assert not best.bounded.any()


def test_random_sweeps_give_the_full_scans_best_beam_bit_for_bit(make_radar, make_processing, tone, monkeypatch):
    # 40 random 12-beam sweeps on a small radar (K = 16, N = 64): 1-4 beams with a tone of random delay,
    # Doppler and amplitude (0.1-10 times the noise's rms per sample: -20 to 20 dB per sample, 1024
    # samples) in unit noise, the others noise only. Whatever the bounds leave out, the best beam and
    # every searched beam must be the full scan's, bit for bit. The bounds taken are recorded: measured,
    # 370 of the 480 beams left out, every bound through the chirp sum (its condition written out as
    # grid_bound's docstring states it; the Doppler grid's part is Table I's test above at 5 dBm).
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-8.25, 8.25, 1.5]))
    assert sweep.num_beams == 12
    taken = []

    def recording(x32, norm, length, level=None):
        alpha_f = np.pi * (x32.shape[1] - 1) / (2 * scipy.fft.next_fast_len(2 * x32.shape[1]))
        taken.append(_typical(x32) < np.sqrt(level) * np.cos(alpha_f))
        return gridbound.grid_bound(x32, norm, length, level=level)

    monkeypatch.setattr(gridscreen, "grid_bound", recording)
    max_delay = 1.0 / (radar.slope * radar.sample_period)
    max_rate = 1.0 / (2.0 * radar.carrier_frequency * radar.chirp_interval)
    left_out = 0
    for seed in range(40):
        rng = np.random.default_rng(1000 + seed)
        cube = np.zeros((12, 16, 64), complex)
        for m in rng.choice(12, size=int(rng.integers(1, 5)), replace=False):
            amp = 10.0 ** rng.uniform(-1.0, 1.0)
            cube[m] = amp * tone(radar, rng.uniform(0.1, 0.9) * max_delay, rng.uniform(-0.4, 0.4) * max_rate)
        cube = add_noise(cube, 1.0, rng)
        full, best = _scans(cube, sweep, radar, processing)
        _assert_same_best(full, best)
        left_out += int(best.bounded.sum())
    assert left_out >= 200 and sum(taken) >= 200, (left_out, sum(taken), len(taken))


def test_threads_do_not_change_the_reduced_scan(make_radar, make_processing, tone):
    # Four beams with a return and eight noise-only ones: the rounds of the deferred beams are fixed,
    # so 1 and 3 threads give the same beams left out and the same numbers.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    rng = np.random.default_rng(5)
    cube = np.zeros((12, 16, 64), complex)
    cube[:4] = 3.0 * tone(radar, 1e-8, 2e-9)
    cube = add_noise(cube, 1.0, rng)
    windows = (np.hanning(17)[:-1], np.hanning(65)[:-1])
    runs = [gridscreen.screened_scan(cube, processing, 0, windows, lambda p: np.array([p]), workers=w, best_only=True)
            for w in (1, 3)]
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
    assert np.count_nonzero(runs[0][1] < 0) >= 1  # some beam was left out
    full = gridscreen.screened_scan(cube, processing, 0, windows, lambda p: np.array([p]), workers=1)
    assert int(np.argmax(runs[0][3])) == int(np.argmax(full[3]))


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["paper", "refined"])
def test_self_localize_without_a_scan_gives_the_same_estimate(estimator):
    # The studies' call (scan=False): the paper's estimator reads only the best beam, so its position,
    # σ and flags are those of the full scan; the result keeps no scan.
    sc = paper_scenario(radar=dsp.RadarConfig(tx_power_dbm=10.0))
    cap = simulate(sc, rng=np.random.default_rng(3), noise_stream="fast")
    kw = dict(sweep=cap.sweep, radar=cap.radar, processing=cap.processing, pose=cap.ris.pose,
              loopback_delay=cap.ris.loopback_delay, estimator=estimator, pattern=cap.ris.beam_pattern())
    with_scan = dsp.self_localize(cap.cube, **kw)
    without = dsp.self_localize(cap.cube, scan=False, **kw)
    assert with_scan.scan is not None and without.scan is None
    np.testing.assert_array_equal(without.position, with_scan.position)
    assert without.beam_index == with_scan.beam_index
    assert without.flag_codes == with_scan.flag_codes
    assert without.std == with_scan.std


def test_a_device_cube_and_the_full_search_search_every_beam(make_radar, make_processing, tone):
    # best_only is the host screen's: on a device (array_api_strict here) and with doppler_search="full"
    # every beam is searched, and the scan says so (bounded all False).
    radar = make_radar(num_samples=32, num_chirps=8)
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-3.0, 3.0, 1.5]))
    rng = np.random.default_rng(2)
    cube = add_noise(np.zeros((5, 8, 32), complex) + tone(radar, 1e-8, 0.0), 0.1, rng)
    scan = dsp.scan_beams(cube, sweep, radar, make_processing(radar, n_dft=63, k_dft=31, doppler_search="full"),
                          best_only=True)
    assert scan.bounded is not None and not scan.bounded.any()
    strict = dsp.strict_backend("CPU_DEVICE")
    scan = dsp.scan_beams(strict.asarray(cube), sweep, radar, make_processing(radar, n_dft=63, k_dft=31),
                          best_only=True)
    assert not scan.bounded.any()


def test_best_only_must_be_a_bool(make_radar, make_processing):
    radar = make_radar(num_samples=32, num_chirps=8)
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-3.0, 3.0, 1.5]))
    with pytest.raises(TypeError, match="best_only"):
        dsp.scan_beams(np.ones((5, 8, 32), complex), sweep, radar, make_processing(radar), best_only="yes")
