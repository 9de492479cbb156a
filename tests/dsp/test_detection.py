"""Detection of the RIS return (dsp/detection.py): stated false-alarm probability, Pd, sweep modulation.

Oracles: under white Gaussian noise the mean-removed beam energy of each un-padded DFT cell is
Gamma(M-1, 1) in units of the cell noise, independently per cell, so the sweep-CFAR's rate of
threshold crossings on noise-only cubes is its stated P_FA (binomial tolerance, 3σ); a return that
is the same in every beam cancels exactly, whatever its strength; a strong beam-dependent tone is
always detected in its cell.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special

import dsp

C = dsp.SPEED_OF_LIGHT
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
PATTERN = dsp.BeamPattern().for_wavelength(RADAR.wavelength)


def noise(shape, rng, power=1.0):
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * np.sqrt(power / 2)


@pytest.fixture
def ris_cube(tone):
    """The local cube factory, closing over the ``tone`` fixture."""

    def ris_cube(rng, *, distance=5.0, velocity=0.4, az=np.deg2rad(4.3), peak_snr=10 ** 2.5):
        """RIS tone across the sweep (amplitude β|A_m|, random phase per beam) + unit noise."""
        m, k, n = SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples
        tau, nu = 2 * distance / C + 1.78e-9, 2 * velocity / C
        amp = np.abs(PATTERN.amplitude([az, 0.0], SWEEP.angles)) * np.sqrt(peak_snr / (k * n))
        cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * tone(RADAR, tau, nu)[None]
        return cube + noise(cube.shape, rng), tau, nu

    return ris_cube


def test_threshold_gives_the_stated_probability_for_iid_gamma_cells():
    for pfa, m, cells in ((1e-3, 15, 1024), (0.1, 61, 76800)):
        eta = dsp.detection.sweep_cfar_threshold(pfa, m, cells)
        p_max = 1 - (1 - scipy.special.gammaincc(m - 1, eta)) ** cells
        assert p_max == pytest.approx(pfa, rel=1e-9)


def test_false_alarm_rate_on_noise_only_cubes_matches_the_stated_pfa():
    rng = np.random.default_rng(11)
    trials, pfa = 1500, 0.1
    shape = (SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples)
    crossed = detected = 0
    for _ in range(trials):
        det = dsp.detect(noise(shape, rng), RADAR, pfa=pfa)
        crossed += det.statistic >= det.threshold
        detected += det.detected
    tol = 3 * np.sqrt(pfa * (1 - pfa) / trials)
    assert abs(crossed / trials - pfa) < tol
    assert detected / trials < pfa + tol  # the sweep-modulation test can only remove crossings


@pytest.mark.parametrize("windowed", [False, True])
def test_static_clutter_of_any_strength_leaves_the_false_alarm_rate_unchanged(tone, windowed):
    # exact for the whole-sweep test; the windowed half-bin search stays below its bound
    rng = np.random.default_rng(12 + windowed)
    trials, pfa = 800, 0.1
    shape = (SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples)
    kw = dict(pattern=PATTERN, sweep=SWEEP, oversample=2) if windowed else {}
    crossed = 0
    for _ in range(trials):
        clutter = 1e3 * np.exp(2j * np.pi * rng.random()) * tone(RADAR, 2 * 4.0 / C, 0.0)  # 60 dB per sample
        det = dsp.detect(clutter[None] + noise(shape, rng), RADAR, pfa=pfa, **kw)
        crossed += det.statistic >= det.threshold
    tol = 3 * np.sqrt(pfa * (1 - pfa) / trials)
    assert crossed / trials < pfa + tol
    if not windowed:
        assert crossed / trials > pfa - tol


def test_strong_ris_return_is_detected_in_its_cell(ris_cube):
    rng = np.random.default_rng(13)
    for _ in range(20):
        cube, tau, nu = ris_cube(rng, distance=rng.uniform(2, 15), velocity=rng.uniform(-2, 2))
        det = dsp.detect(cube, RADAR)
        assert det.detected and det.beam_dependent
        # the cell centre is within half a resolution cell of the truth on both axes
        assert abs(det.delay - tau) <= 0.5 * RADAR.delay_resolution + RADAR.carrier_frequency / RADAR.slope * abs(
            det.delay_rate - nu)
        assert abs(det.delay_rate - nu) * C / 2 <= 0.5 * RADAR.velocity_resolution + 1e-12
        assert det.snr_db > det.threshold_db


def test_detection_probability_rises_with_snr(ris_cube):
    rng = np.random.default_rng(14)
    rates = []
    for snr_db in (0.0, 20.0):
        hits = sum(dsp.detect(ris_cube(rng, peak_snr=10 ** (snr_db / 10))[0], RADAR).detected for _ in range(40))
        rates.append(hits / 40)
    assert rates[0] < 0.2 and rates[1] == 1.0


def test_beam_independent_return_with_moving_phase_is_rejected_by_the_sweep_modulation_test(tone):
    # A clutter return of constant amplitude whose phase changes from frame to frame (a moving
    # radar) survives the mean removal, but its power does not follow the sweep.
    rng = np.random.default_rng(15)
    m = SWEEP.num_beams
    clutter = 30.0 * np.exp(2j * np.pi * rng.random(m))[:, None, None] * tone(RADAR, 2 * 6.0 / C, 0.0)[None]
    det = dsp.detect(clutter + noise(clutter.shape, rng), RADAR)
    assert det.statistic > det.threshold  # the sweep-CFAR fires...
    assert not det.detected and det.rejected >= 1  # ...but it is not the RIS


def test_to_dict_has_exactly_the_four_keys(ris_cube):
    det = dsp.detect(ris_cube(np.random.default_rng(1))[0], RADAR)
    assert set(det.to_dict()) == {"detected", "snr_db", "threshold_db", "false_alarm_probability"}
    assert det.to_dict()["false_alarm_probability"] == dsp.detection.DEFAULT_PFA


@pytest.mark.parametrize("cube, match", [
    (np.zeros((0, 16, 64), complex), "empty"),
    (np.zeros((15, 16, 64), complex), "all zeros"),
    (np.full((15, 16, 64), np.nan, complex), "NaN"),
    (np.ones((1, 16, 64), complex), "at least 2 beams"),
    (np.ones((15, 64, 16), complex), "K=16 chirps and N=64 samples"),
    (np.ones((16, 64), complex), r"\[M, K, N\]"),
])
def test_bad_cubes_get_one_line_errors(cube, match):
    with pytest.raises(ValueError, match=match):
        dsp.detect(cube, RADAR)


def test_pfa_must_be_a_probability(ris_cube):
    with pytest.raises(ValueError, match="pfa"):
        dsp.detect(ris_cube(np.random.default_rng(2))[0], RADAR, pfa=1.5)


# --- pattern-matched windows and the half-bin grid (dsp/sweep_window.py, oversample=2) ----------


def test_windowed_half_bin_search_keeps_its_false_alarm_bound():
    # Upper bound: the stated P_FA (union over windows and correlated half-bin cells). Lower
    # bound: one window on the un-padded cells alone, whose statistic is at least Gamma(L-1, 1).
    rng = np.random.default_rng(21)
    trials, pfa = 1500, 0.1
    shape = (SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples)
    crossed = 0
    for _ in range(trials):
        det = dsp.detect(noise(shape, rng), RADAR, pfa=pfa, pattern=PATTERN, sweep=SWEEP, oversample=2)
        crossed += det.statistic >= det.threshold
    rate, sd = crossed / trials, np.sqrt(pfa * (1 - pfa) / trials)
    assert rate <= pfa + 3 * sd
    un_padded = RADAR.num_chirps * RADAR.num_samples
    lower = 1 - (1 - scipy.special.gammaincc(det.integrated_beams - 1, det.threshold)) ** un_padded
    assert rate >= lower - 3 * np.sqrt(lower * (1 - lower) / trials)
    assert det.num_cells == 4 * un_padded


def test_windowed_half_bin_detection_needs_less_snr_than_the_whole_sweep(ris_cube):
    # 12 dB at the pattern peak, off-grid: the whole-sweep test on DFT bins detects ~10 %, the
    # windowed half-bin search (what self_localize uses) ~60 % (measured 4/40 and 24/40).
    rng = np.random.default_rng(22)
    hits = {"sweep": 0, "window": 0}
    for _ in range(40):
        cube = ris_cube(rng, peak_snr=10 ** (12.0 / 10))[0]
        hits["sweep"] += dsp.detect(cube, RADAR).detected
        hits["window"] += dsp.detect(cube, RADAR, pattern=PATTERN, sweep=SWEEP, oversample=2).detected
    assert hits["window"] >= hits["sweep"] + 10


def test_half_bin_grid_recovers_the_straddle_loss(tone):
    # A return exactly half a bin off on both axes loses 2 × 3.92 dB on the DFT grid (rectangular
    # window: |sinc(½)|² per axis) and nothing on the half-bin grid.
    rng = np.random.default_rng(23)
    k, n = RADAR.num_chirps, RADAR.num_samples
    f1, f2 = 20.5 / n, 3.5 / k
    nu = f2 / (RADAR.carrier_frequency * RADAR.chirp_interval)
    tau = (f1 / RADAR.sample_period - RADAR.carrier_frequency * nu) / RADAR.slope
    amp = np.abs(PATTERN.amplitude([np.deg2rad(4.3), 0.0], SWEEP.angles)) * np.sqrt(1e4 / (k * n))  # 40 dB
    cube = (amp * np.exp(2j * np.pi * rng.random(SWEEP.num_beams)))[:, None, None] * tone(RADAR, tau, nu)[None]
    cube = cube + noise(cube.shape, rng)
    snr = {os: dsp.detect(cube, RADAR, pattern=PATTERN, sweep=SWEEP, oversample=os).snr_db for os in (1, 2)}
    expected = -2 * 20 * np.log10(np.sinc(0.5))  # 7.84 dB; the discrete kernel differs by < 0.01 dB
    assert snr[2] - snr[1] == pytest.approx(expected, abs=0.3)


@pytest.mark.parametrize("kw, match", [
    ({"oversample": 3}, "oversample"),
    ({"pattern": PATTERN}, "both pattern and sweep"),
    ({"pattern": PATTERN, "sweep": dsp.BeamSweep.azimuth_grid(0.0, 0.1, 0.05)}, "sweep has 3 angles"),
])
def test_bad_window_arguments_get_one_line_errors(ris_cube, kw, match):
    with pytest.raises(ValueError, match=match):
        dsp.detect(ris_cube(np.random.default_rng(3))[0], RADAR, **kw)
