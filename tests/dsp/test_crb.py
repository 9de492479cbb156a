"""Cramér–Rao bounds of the sweep (dsp/crb.py) against the textbook tone bound and Monte Carlo.

Oracles: for one beam the delay-rate and fast-time bounds are the single-tone frequency bound
6/((2π)² SNR N(N²-1)) (Rife & Boorstyn); every beam carries the same delay, so the sweep's delay
bound is the one-beam bound scaled by |A_best| / sqrt(Σ A_m²); the refined estimator, an ML
estimator, reaches the bound in Monte Carlo (RMSE/CRB within 1.1 + 3/√(2n), the issue's goal plus
the sampling spread of an RMSE over n trials).
"""

from __future__ import annotations

import numpy as np
import pytest

import dsp

C = dsp.SPEED_OF_LIGHT
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15, 1-D
PATTERN = dsp.BeamPattern().for_wavelength(RADAR.wavelength)


@pytest.fixture
def ris_cube(tone):
    """The local cube factory, closing over the ``tone`` fixture."""

    def ris_cube(rng, *, tau, nu, aod, peak_snr):
        m, k, n = SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples
        amp = np.abs(PATTERN.amplitude(aod, SWEEP.angles)) * np.sqrt(peak_snr / (k * n))
        cube = (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * tone(RADAR, tau, nu)[None]
        return cube + (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape)) * np.sqrt(0.5)

    return ris_cube


def test_single_beam_bound_is_the_textbook_tone_bound():
    aod = SWEEP.angles[7]  # exactly on beam 7: A = 1 there
    rho = 300.0
    one = np.arange(SWEEP.num_beams) == 7
    b = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho, beams=one)
    k, n = RADAR.num_chirps, RADAR.num_samples
    gamma = rho / (k * n)  # per-sample SNR
    var_f2 = dsp.tone_frequency_crb(gamma * n, k)  # slow time: K samples of N-fold integrated SNR
    var_f1 = dsp.tone_frequency_crb(gamma * k, n)
    fct = RADAR.carrier_frequency * RADAR.chirp_interval
    assert b.delay_rate == pytest.approx(np.sqrt(var_f2) / fct, rel=1e-12)
    s_ts = RADAR.slope * RADAR.sample_period
    var_tau = var_f1 / s_ts**2 + (RADAR.carrier_frequency / RADAR.slope) ** 2 * b.delay_rate**2
    assert b.delay == pytest.approx(np.sqrt(var_tau), rel=1e-12)
    assert b.distance == pytest.approx(b.delay * C / 2, rel=1e-12)


def test_sweep_combines_the_beams():
    aod = np.array([np.deg2rad(5.2), 0.0])
    a = PATTERN.amplitude(aod, SWEEP.angles)
    best = int(np.argmax(np.abs(a)))
    full = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=100.0)
    one = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=100.0,
                        beams=np.arange(SWEEP.num_beams) == best)
    assert full.delay == pytest.approx(one.delay * abs(a[best]) / np.sqrt(a @ a), rel=1e-12)
    assert full.delay < 0.8 * one.delay  # the best beam alone cannot reach the sweep's bound


def test_bounds_scale_as_one_over_root_snr_and_elevation_is_unseen_by_a_1d_sweep():
    aod = np.array([np.deg2rad(-3.1), 0.0])
    b1 = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=100.0)
    b2 = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=400.0)
    assert b1.distance / b2.distance == pytest.approx(2.0, rel=1e-12)
    assert b1.aod[0] / b2.aod[0] == pytest.approx(2.0, rel=1e-9)
    assert np.isnan(b1.aod[1])


def test_aod_fisher_information_matches_a_direct_derivative_of_the_likelihood_terms():
    # J_az = 2ρ [Σ A'² - (Σ A A')²/Σ A²], with A' by a coarser independent difference.
    aod = np.array([np.deg2rad(7.7), 0.0])
    rho = 50.0
    h = 1e-5
    a = PATTERN.amplitude(aod, SWEEP.angles)
    da = (PATTERN.amplitude(aod + [h, 0], SWEEP.angles) - PATTERN.amplitude(aod - [h, 0], SWEEP.angles)) / (2 * h)
    j = 2 * rho * (da @ da - (a @ da) ** 2 / (a @ a))
    b = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho)
    assert b.aod[0] == pytest.approx(1 / np.sqrt(j), rel=1e-6)


def _draw(ris_cube, rng, rho):
    """One off-grid truth (3-15 m, ±1 m/s, ±12°) and its noisy cube: (τ [s], ν, aod [rad, rad], cube)."""
    distance, velocity = rng.uniform(3, 15), rng.uniform(-1, 1)
    aod = np.array([np.deg2rad(rng.uniform(-12, 12)), 0.0])
    tau, nu = 2 * distance / C + 1.78e-9, 2 * velocity / C
    return tau, nu, aod, ris_cube(rng, tau=tau, nu=nu, aod=aod, peak_snr=rho)


def test_refined_estimator_reaches_the_bound_in_monte_carlo(ris_cube):
    rng = np.random.default_rng(2024)
    trials, rho = 300, 10 ** 2.5  # 25 dB at the pattern peak
    err, crb_d, crb_az = [], [], []
    for _ in range(trials):
        tau, nu, aod, cube = _draw(ris_cube, rng, rho)
        det = dsp.detect(cube, RADAR)
        assert det.detected
        est = dsp.refine_estimate(cube, sweep=SWEEP, radar=RADAR, pattern=PATTERN,
                                  initial_delay=det.delay, initial_delay_rate=det.delay_rate)
        b = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho)
        err.append(((est.delay - tau) * C / 2, est.aod.aod[0] - aod[0]))
        crb_d.append(b.distance)
        crb_az.append(b.aod[0])
    e = np.array(err)
    rmse = np.sqrt(np.mean(e**2, axis=0))
    ratio = rmse / np.sqrt([np.mean(np.square(crb_d)), np.mean(np.square(crb_az))])
    spread = 3 / np.sqrt(2 * trials)
    assert np.all(ratio > 1 - spread), ratio  # nothing beats the bound
    assert np.all(ratio < 1.1 + spread), ratio
    bias_over_sd = np.abs(e.mean(axis=0)) / e.std(axis=0)
    assert np.all(bias_over_sd < 0.1 + 3 / np.sqrt(trials)), bias_over_sd


# ------------------------------------------------------------------ random per-beam phases
@pytest.mark.parametrize("u", [0.3, 1.0, 3.0])
def test_rician_information_factors_match_monte_carlo(u):
    """G = E[g(2ur)²], V = E[(g(2ur) r - u)²] for r = |u + CN(0, 1)|, g = I1/I0, by sampling."""
    import scipy.special

    rng = np.random.default_rng(5)
    n = 400_000
    r = np.abs(u + (rng.standard_normal(n) + 1j * rng.standard_normal(n)) * np.sqrt(0.5))
    g = scipy.special.i1e(2 * u * r) / scipy.special.i0e(2 * u * r)
    g_mc, v_mc = g**2, (g * r - u) ** 2
    g_tab, v_tab = dsp.rician_information(u**2)
    assert abs(g_tab - g_mc.mean()) < 5 * g_mc.std() / np.sqrt(n)
    assert abs(v_tab - v_mc.mean()) < 5 * v_mc.std() / np.sqrt(n)
    assert abs((g * r - u).mean()) < 5 * np.sqrt(v_mc.mean() / n)  # the amplitude score has zero mean


def test_rician_information_limits_and_continuity():
    rho = np.geomspace(1e-9, 1e6, 2000)
    g, v = dsp.rician_information(rho)
    assert np.all(np.diff(g) > 0) and np.all(np.diff(v) > 0)  # more SNR, more information
    np.testing.assert_allclose(g[:50] / rho[:50], 1.0, rtol=2e-3)  # square law far below the noise
    np.testing.assert_allclose(v[:50] / rho[:50], 1.0, rtol=2e-3)
    assert 1 - g[-1] < 1e-5 and 0.5 - v[-1] < 1e-5  # a learnable phase far above it
    for edge in (1e-6, 3600.0):  # the table's ends: no step into the expansions
        ge, ve = dsp.rician_information(np.array([edge * (1 - 1e-9), edge * (1 + 1e-9)]))
        assert abs(ge[1] / ge[0] - 1) < 2e-3 and abs(ve[1] / ve[0] - 1) < 2e-3
    with pytest.raises(ValueError, match="finite and >= 0"):
        dsp.rician_information(-1.0)


def test_random_phase_bound_is_the_fixed_one_above_the_noise_and_larger_near_it():
    aod = np.array([np.deg2rad(4.1), 0.0])
    for rho, most in ((1e5, 1.003), (10.0, None)):
        f = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho)
        r = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho, phases="random")
        assert r.distance >= f.distance and r.aod[0] >= f.aod[0] and r.velocity >= f.velocity
        if most is not None:
            assert r.distance / f.distance < most and r.aod[0] / f.aod[0] < most
        else:
            assert r.aod[0] / f.aod[0] > 1.15
    with pytest.raises(ValueError, match="phases='known'"):
        dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=10.0, phases="known")


@pytest.mark.slow
def test_refined_aod_reaches_the_random_phase_bound_at_low_snr(ris_cube):
    """13 dB at the pattern peak: most of the 15 beams are near the noise, so the AoD's fixed-phase
    CRB is not reachable (the pattern fit sees Rician magnitudes). Started at the true cell (no
    acquisition outliers), the ML AoD's RMSE lies at the random-phase bound and above the
    fixed-phase CRB by more than the sampling spread. (The distance is left out: in this small
    K = 16, N = 64 cube its RMSE/CRB is 1.2 at every SNR, phases or not: noted in docs/estimation.md.)"""
    rng = np.random.default_rng(99)
    trials, rho = 300, 10**1.3
    err, fixed, rand = [], [], []
    for _ in range(trials):
        tau, nu, aod, cube = _draw(ris_cube, rng, rho)
        est = dsp.refine_estimate(cube, sweep=SWEEP, radar=RADAR, pattern=PATTERN, initial_delay=tau,
                                  initial_delay_rate=nu)
        err.append(est.aod.aod[0] - aod[0])
        fixed.append(dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho).aod[0])
        rand.append(dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=PATTERN, aod=aod, peak_snr=rho,
                                  phases="random").aod[0])
    rmse = np.sqrt(np.mean(np.square(err)))
    over_random = rmse / np.sqrt(np.mean(np.square(rand)))
    over_fixed = rmse / np.sqrt(np.mean(np.square(fixed)))
    spread = 3 / np.sqrt(2 * trials)
    assert 1 - spread < over_random < 1.1 + spread, over_random
    assert over_fixed > 1 + spread, over_fixed
