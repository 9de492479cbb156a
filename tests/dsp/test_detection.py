"""Detection of the RIS return (dsp/detection.py): stated false-alarm probability, Pd, sweep modulation.

Oracles: under white Gaussian noise the mean-removed beam energy of each un-padded DFT cell is
Gamma(M-1, 1) in units of the cell noise, independently per cell, so the sweep-CFAR's number of
threshold crossings on n noise-only cubes is Binomial(n, P_FA) (its 99.9 % interval written out in
:func:`binomial_interval`); with a return the cell's statistic is a noncentral chi-square of known
noncentrality, which bounds the detections of a weak return by the union over cells
(:func:`cell_noncentrality`); a return that is the same in every beam cancels exactly,
whatever its strength; a strong beam-dependent tone is always detected in its cell."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special
from scipy import stats

import dsp

C = dsp.SPEED_OF_LIGHT
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
PATTERN = dsp.BeamPattern().for_wavelength(RADAR.wavelength)


def noise(shape, rng, power=1.0):
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * np.sqrt(power / 2)


def binomial_interval(trials, p, tail=1e-3):
    """(lo, hi) counts with P(K < lo) <= tail/2 and P(K > hi) <= tail/2 for K ~ Binomial(trials, p).

    The number of noise-only cubes (of ``trials``) in which the detector crosses a threshold whose
    false-alarm probability per cube is p; written out as the binomial quantiles, not a normal
    approximation.
    """
    return int(stats.binom.ppf(tail / 2, trials, p)), int(stats.binom.isf(tail / 2, trials, p))


@pytest.fixture
def ris_cube(tone):
    """The local cube factory, closing over the ``tone`` fixture."""

    def ris_cube(rng, *, distance=5.0, velocity=0.4, az=np.deg2rad(4.3), peak_snr=10 ** 2.5, signal=False):
        """RIS tone across the sweep (amplitude β|A_m|, random phase per beam) + unit noise:
        (cube, τ, ν), and the noiseless tone cube last if ``signal``."""
        m, k, n = SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples
        tau, nu = 2 * distance / C + 1.78e-9, 2 * velocity / C
        amp = np.abs(PATTERN.amplitude([az, 0.0], SWEEP.angles)) * np.sqrt(peak_snr / (k * n))
        cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * tone(RADAR, tau, nu)[None]
        noisy = cube + noise(cube.shape, rng)
        return (noisy, tau, nu, cube) if signal else (noisy, tau, nu)

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
    lo, hi = binomial_interval(trials, pfa)
    assert lo <= crossed <= hi, (crossed, lo, hi)
    assert detected <= hi  # the sweep-modulation test can only remove crossings


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
    lo, hi = binomial_interval(trials, pfa)
    assert crossed <= hi, (crossed, hi)
    if not windowed:
        assert crossed >= lo, (crossed, lo)


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


def cell_noncentrality(signal):
    """λ_c = 2 Σ_m |S_m,c - S̄_c|² / σ²_cell for every un-padded DFT cell [K, N] [unitless].

    S the 2-D DFT of each beam of the noiseless ``signal`` [M, K, N] (unit noise per sample, so
    σ²_cell = K N). Under noise plus this signal, twice the whole-sweep statistic of cell c,
    2 D_c = 2 Σ_m |X_m,c - X̄_c|² / σ²_cell, is χ'²(2(M-1), λ_c): the mean removal projects the M
    beams onto an (M-1)-dimensional complex subspace.
    """
    _, k, n = signal.shape
    x = np.fft.fft2(signal, axes=(1, 2))
    return 2 * np.sum(np.abs(x - x.mean(axis=0)) ** 2, axis=0) / (k * n)


def cfar_threshold(pfa=dsp.detection.DEFAULT_PFA):
    """η with 1 - (1 - Q(M-1, η))^C = P_FA over all C = K·N cells (Q the regularised upper
    incomplete gamma function): at most the detector's, which searches C or fewer cells."""
    m, k, n = SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples
    return scipy.special.gammainccinv(m - 1, -np.expm1(np.log1p(-pfa) / (k * n)))


def test_detection_probability_rises_with_snr(ris_cube):
    """0 dB at the pattern peak: the threshold crossings are (almost all) false alarms. The
    whole-sweep statistic crosses η when D_c >= η in some cell, so a capture crosses with
    probability at most Σ_c P(χ'²(2(M-1), λ_c) >= 2η) (:func:`cell_noncentrality`; the
    union over all K·N cells, P_FA plus the signal's share; the detector's median estimate of σ²,
    ~3 % off, moves this by far less than the margins here). The count in 40 captures is then at
    most the binomial quantile that Binomial(40, largest bound) exceeds with probability < 1e-3: 1;
    detections, which also need the sweep-modulation test, are at most the crossings.
    20 dB: every capture is detected, and the premise is checked: the strongest cell alone misses η
    with probability below 1e-3/40 per capture."""
    rng = np.random.default_rng(14)
    trials, m = 40, SWEEP.num_beams
    eta = cfar_threshold()
    crossed, detected, bound = 0, 0, []
    for _ in range(trials):
        cube, _, _, signal = ris_cube(rng, peak_snr=1.0, signal=True)
        det = dsp.detect(cube, RADAR)
        crossed += det.statistic >= det.threshold
        detected += det.detected
        bound.append(np.sum(stats.ncx2.sf(2 * eta, 2 * (m - 1), cell_noncentrality(signal).ravel())))
    p_max = max(bound)
    assert p_max < 2e-3, p_max  # the premise: at 0 dB a detection is essentially a false alarm
    k_max = int(stats.binom.isf(1e-3, trials, p_max))
    assert crossed <= k_max and detected <= crossed, (crossed, detected, k_max)
    for _ in range(trials):
        cube, _, _, signal = ris_cube(rng, peak_snr=100.0, signal=True)
        assert stats.ncx2.cdf(2 * eta, 2 * (m - 1), cell_noncentrality(signal).max()) < 1e-3 / trials
        assert dsp.detect(cube, RADAR).detected


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
    assert crossed <= binomial_interval(trials, pfa)[1], crossed
    un_padded = RADAR.num_chirps * RADAR.num_samples
    lower = 1 - (1 - scipy.special.gammaincc(det.integrated_beams - 1, det.threshold)) ** un_padded
    assert crossed >= binomial_interval(trials, lower)[0], (crossed, lower)
    assert det.num_cells == 4 * un_padded


def test_windowed_half_bin_detection_needs_less_snr_than_the_whole_sweep(ris_cube):
    """12 dB at the pattern peak, off-grid: the windowed half-bin search (what self_localize uses)
    detects more than the whole-sweep test on DFT bins, on the same 40 cubes. The margin is a paired
    sign test written out: of the d cubes where exactly one detector fires, b are the windowed
    search's. If it were no more sensitive to the return, each such cube would be its with
    probability at most ½, except for its own false alarms, at most k_FA of the 40 (the binomial
    quantile of P_FA = 1e-3, its stated upper bound: 1). So P(Binomial(d - k_FA, ½) >= b - k_FA) must
    be below 1e-3 (measured: 22 of 22 discordant cubes, 1 vs 23 detections: 5e-7)."""
    rng = np.random.default_rng(22)
    trials = 40
    b = c = 0
    for _ in range(trials):
        cube = ris_cube(rng, peak_snr=10 ** (12.0 / 10))[0]
        sweep = dsp.detect(cube, RADAR).detected
        window = dsp.detect(cube, RADAR, pattern=PATTERN, sweep=SWEEP, oversample=2).detected
        b += window and not sweep
        c += sweep and not window
    k_fa = int(stats.binom.isf(1e-3, trials, dsp.detection.DEFAULT_PFA))
    p_value = stats.binom.sf(b - k_fa - 1, b + c - k_fa, 0.5) if b > k_fa else 1.0  # P(X >= b - k_FA)
    assert p_value < 1e-3, (b, c, p_value)


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
