"""The marginal (random-phase) likelihood of the refined estimator (dsp/refine.py, dsp/aod_fit.py).

Oracles: the Bessel helpers against their definitions (derivatives by finite differences, the
series at both ends); the amplitude that maximises the marginal likelihood against a brute-force
search; the noise power read from the cube against the σ² that synthesised it; at high SNR the
marginal and profiled estimates of the same cube agree to a small fraction of the CRB, and at low
per-beam SNR the marginal one has the lower AoD error over the same cubes (Monte Carlo, fixed seed).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special

import dsp
from dsp.aod_fit import _marginal_amplitude, _marginal_objective, bessel_ratio, bessel_ratio_slope, log_i0
from dsp.refine import _Evaluator

C = dsp.SPEED_OF_LIGHT
RADAR = dsp.RadarConfig(num_samples=64, num_chirps=16)
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-21.0, 21.0, 3.0]))  # M = 15
RELAY = dsp.BeamPattern().for_wavelength(RADAR.wavelength)
KN = RADAR.num_chirps * RADAR.num_samples


def noisy_cube(tone, rng, *, tau, nu, aod, peak_snr, noise_power=1.0):
    """RIS tone with a random phase per beam plus CN(0, σ²) noise; ρ = K N β²/σ² [linear]."""
    beta = np.sqrt(peak_snr * noise_power / KN)
    a = np.abs(RELAY.amplitude(aod, SWEEP.angles))
    ph = np.exp(1j * rng.uniform(0, 2 * np.pi, SWEEP.num_beams))
    cube = (beta * a * ph)[:, None, None] * tone(RADAR, tau, nu)[None]
    w = rng.standard_normal((2,) + cube.shape)
    return cube + (w[0] + 1j * w[1]) * np.sqrt(noise_power / 2)


def refine(cube, tau0, nu0, **kw):
    return dsp.refine_estimate(cube, sweep=SWEEP, radar=RADAR, pattern=RELAY, initial_delay=tau0,
                               initial_delay_rate=nu0, **kw)


def test_bessel_helpers_match_their_definitions():
    x = np.array([1e-9, 1e-3, 0.3, 1.0, 4.0, 20.0, 99.0, 101.0, 800.0])
    # log I0 against scipy's unscaled I0 where that does not overflow
    mid = x < 700
    np.testing.assert_allclose(log_i0(x[mid]), np.log(scipy.special.i0(x[mid])), rtol=1e-12, atol=1e-15)
    # g = d/dx log I0, g' = dg/dx (central differences, where they are accurate)
    xd = x[x >= 0.3]
    h = 1e-5 * xd
    np.testing.assert_allclose(bessel_ratio(xd), (log_i0(xd + h) - log_i0(xd - h)) / (2 * h), rtol=1e-6)
    np.testing.assert_allclose(bessel_ratio_slope(xd), (bessel_ratio(xd + h) - bessel_ratio(xd - h)) / (2 * h),
                               rtol=1e-5)
    # below: the series g = x/2 − x³/16, g' = 1/2 − 3x²/16
    xs = x[x < 0.3]
    np.testing.assert_allclose(bessel_ratio(xs), xs / 2 - xs**3 / 16, rtol=1e-9)
    np.testing.assert_allclose(bessel_ratio_slope(xs), 0.5 - 3 * xs**2 / 16, rtol=1e-6)
    # the ends: square law near 0, the profiled criterion's slope far away; no overflow
    assert bessel_ratio(1e-6) == pytest.approx(5e-7, rel=1e-9)
    assert bessel_ratio_slope(0.0) == 0.5
    assert log_i0(1e6) == pytest.approx(1e6 - 0.5 * np.log(2 * np.pi * 1e6), abs=1e-6)
    assert np.isfinite(log_i0(1e300)) and bessel_ratio(1e300) == 1.0 and np.isfinite(bessel_ratio_slope(1e300))


def test_marginal_amplitude_is_the_maximum_of_the_likelihood():
    rng = np.random.default_rng(4)
    a = np.abs(RELAY.amplitude([0.07, 0.0], SWEEP.angles))
    s2 = 2.0
    for b_true in (0.5, 2.0, 30.0):
        r = np.abs(b_true * a * np.exp(1j * rng.uniform(0, 6.3, a.size))
                   + rng.standard_normal(a.size) * np.sqrt(s2 / 2) + 1j * rng.standard_normal(a.size) * np.sqrt(s2 / 2))
        b_hat = float(_marginal_amplitude(a, r, s2))
        grid = np.linspace(0.0, 2 * (a @ r) / (a @ a), 200001)
        like = log_i0(2 * grid[:, None] * a * r / s2).sum(axis=1) - grid**2 * (a @ a) / s2
        assert b_hat == pytest.approx(grid[np.argmax(like)], abs=2 * (grid[1] - grid[0]))
        val, b2 = _marginal_objective(a[None], r, s2)
        assert float(b2[0]) == b_hat and float(val[0]) == pytest.approx(like.max(), abs=1e-9 * abs(like.max()) + 1e-9)
    # magnitudes below the noise floor: no tone, b = 0 (the profiled b would be Σar/Σa² > 0)
    r = 0.2 * np.sqrt(s2) * np.ones(a.size)
    assert float(_marginal_amplitude(a, r, s2)) < 1e-9 * (a @ r) / (a @ a)


def test_noise_power_is_read_from_the_cube(tone):
    rng = np.random.default_rng(11)
    tau, nu = 2 * 7.3 / C, 2 * 0.3 / C
    aod = np.array([np.deg2rad(2.0), 0.0])
    for sigma2 in (0.5, 3.0):
        # a tone 40 dB above the noise at the pattern peak: its energy must not count as noise
        cube = noisy_cube(tone, rng, tau=tau, nu=nu, aod=aod, peak_snr=1e4, noise_power=sigma2)
        f1 = (RADAR.slope * tau + RADAR.carrier_frequency * nu) * RADAR.sample_period
        f2 = RADAR.carrier_frequency * nu * RADAR.chirp_interval
        ev = _Evaluator(cube.astype(complex), f1, f2)
        # median of M beams of σ²·Gamma(r²-1)/(r²-1): relative spread ~ 1.25·sqrt(1/(r²-1))/sqrt(M) < 5 %
        assert ev.noise_power(f1, f2) == pytest.approx(sigma2, rel=0.15)
        ev.far = np.abs(RELAY.amplitude(aod, SWEEP.angles)) < 0.1
        assert ev.noise_power(f1, f2) == pytest.approx(sigma2, rel=0.15)
        # ... and without removing the tone the same median would be far off: the oracle bites
        h = ev.proj.moments
        raw = np.median((np.abs(h) ** 2).sum(axis=(1, 2))) / (h.shape[1] * h.shape[2])
        assert raw > 1.5 * sigma2


def test_high_snr_marginal_equals_profiled_to_a_small_fraction_of_the_crb(tone):
    rng = np.random.default_rng(7)
    for snr_db in (30.0, 40.0):
        tau, nu = 2 * rng.uniform(3, 18) / C, 2 * rng.uniform(-1, 1) / C
        aod = np.array([np.deg2rad(rng.uniform(-12, 12)), 0.0])
        rho = 10 ** (snr_db / 10)
        cube = noisy_cube(tone, rng, tau=tau, nu=nu, aod=aod, peak_snr=rho)
        bound = dsp.sweep_crb(radar=RADAR, sweep=SWEEP, pattern=RELAY, aod=aod, peak_snr=rho)
        m = refine(cube, tau, nu)
        p = refine(cube, tau, nu, likelihood="profile")
        known = refine(cube, tau, nu, noise_power=1.0)
        assert abs(m.delay - p.delay) < 0.1 * bound.delay
        assert abs(m.aod.aod[0] - p.aod.aod[0]) < 0.1 * bound.aod[0]
        assert abs(known.delay - m.delay) < 0.02 * bound.delay
        assert abs(known.aod.aod[0] - m.aod.aod[0]) < 0.02 * bound.aod[0]
        assert m.amplitude == pytest.approx(np.sqrt(rho / KN), rel=0.1)


def test_marginal_likelihood_beats_the_profiled_one_at_low_per_beam_snr(tone):
    """Peak SNR 14 dB, 15 beams: the beams off the main lobe are near the noise floor, where
    |Z_m| is mostly Rayleigh noise. Same cubes for both criteria; paired squared errors."""
    rng = np.random.default_rng(2024)
    rho = 10 ** 1.4
    err = {"marginal": [], "profile": []}
    for _ in range(100):
        tau, nu = 2 * rng.uniform(3, 18) / C, 2 * rng.uniform(-1, 1) / C
        aod = np.array([np.deg2rad(rng.uniform(-12, 12)), 0.0])
        cube = noisy_cube(tone, rng, tau=tau, nu=nu, aod=aod, peak_snr=rho)
        for lk in err:
            est = refine(cube, tau, nu, likelihood=lk)
            err[lk].append(est.aod.aod[0] - aod[0])
    e_m, e_p = np.square(err["marginal"]), np.square(err["profile"])
    assert np.sqrt(e_m.mean()) < 0.95 * np.sqrt(e_p.mean())  # AoD RMSE at least 5 % lower
    diff = e_m - e_p
    assert diff.mean() < -2 * diff.std(ddof=1) / np.sqrt(diff.size)  # and not by chance


def test_refine_validates_the_likelihood_arguments(tone):
    cube = np.zeros((SWEEP.num_beams, RADAR.num_chirps, RADAR.num_samples), complex)
    with pytest.raises(ValueError, match="likelihood"):
        refine(cube, 1e-8, 0.0, likelihood="bayes")
    with pytest.raises(ValueError, match="noise_power"):
        refine(cube, 1e-8, 0.0, noise_power=0.0)
    with pytest.raises(ValueError, match="noise_variance"):
        dsp.fit_aod(np.ones(SWEEP.num_beams), SWEEP, RELAY, noise_variance=-1.0)


def test_marginal_pattern_fit_recovers_a_noiseless_pattern_between_beams():
    aod = np.array([np.deg2rad(1.5), 0.0])  # halfway between the beams at 0° and 3°
    mags = 7.0 * np.abs(RELAY.amplitude(aod, SWEEP.angles))
    # s² far below every magnitude: the marginal likelihood is the profiled one, maximal at the truth
    fit = dsp.fit_aod(mags, SWEEP, RELAY, noise_variance=1e-12)
    assert abs(fit.aod[0] - aod[0]) < 1e-7  # [rad]
    assert fit.amplitude == pytest.approx(7.0, rel=1e-6)
    # s² comparable with the magnitudes: b̂ shrinks towards the noise floor's share (b̂ < Σar/Σa²)
    noisy = dsp.fit_aod(mags, SWEEP, RELAY, noise_variance=25.0)
    assert noisy.amplitude < 7.0
