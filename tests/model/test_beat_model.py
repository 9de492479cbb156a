"""The beat-signal model, eq. (1): risloc_rt/beat.py, paths.py, link_budget.py, scenario.py.

Oracles: eq. (1) evaluated in exact rational arithmetic (``fractions.Fraction``) from the same
float64 parameters; the paper's link-budget formulas (Sec. IV-B); linearity of eq. (1) in the
paths; the statistics of CN(0, σ²) noise.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from dsp import BeamSweep, RadarConfig
from risloc_rt.model.beat import add_noise, beat_cube
from risloc_rt.model.phase import wrapped_tone
from risloc_rt.model.paths import PathSet
from risloc_rt.model.ris import ris_response
from risloc_rt.model.scenario import PAPER_RCS, analytic_paths
from risloc_rt.model.simulate import simulate

# Phase accuracy demanded of the synthesiser: |Y - Y_ref| / |γ| < 1e-12. A float64 frequency
# of ~1 cycle/sample is itself only known to 2⁻⁵³ relative, which over n = 599 samples is
# 2π·599·2⁻⁵³ ≈ 4e-13 rad, so 1e-12 leaves room for a correctly rounded frequency.
PHASE_TOL = 1e-12


def exact_phasor(cycles: Fraction) -> complex:
    """exp(-j2π·cycles) with the cycle count reduced modulo 1 exactly before the float trig."""
    frac = float(cycles - math.floor(cycles))  # in [0, 1): cos/sin of it are good to ~1e-16
    return complex(math.cos(2 * math.pi * frac), -math.sin(2 * math.pi * frac))


def reference_sample(radar: RadarConfig, gain: complex, tau: float, nu: float, n: int, k: int) -> complex:
    """Eq. (1) for one non-RIS path: γ e^{-j2π(Sτ + f_c ν) n T_s} e^{-j2π f_c ν k T}, exactly."""
    S, fc, Ts, T = (Fraction(x) for x in (radar.slope, radar.carrier_frequency, radar.sample_period,
                                          radar.chirp_duration))
    tau_f, nu_f = Fraction(tau), Fraction(nu)
    cycles = (S * tau_f + fc * nu_f) * Ts * n + fc * nu_f * T * k
    return gain * exact_phasor(cycles)


def one_beam() -> BeamSweep:
    return BeamSweep(np.zeros((1, 2)))


# ------------------------------------------------------------------------------ phase accuracy
@pytest.mark.parametrize("rate_sign", [1.0, -1.0])
def test_extreme_path_phase_at_the_largest_indices(rate_sign, tone_paths):
    radar = RadarConfig()  # Table I: the largest indices are n = 599, k = 127
    tau = radar.max_delay * (1 - 1e-6)
    nu = rate_sign * radar.max_delay_rate * (1 - 1e-3)
    gain = 0.6 - 0.8j
    cube = beat_cube(tone_paths(gain, tau, nu), radar=radar, sweep=one_beam(), ris=None)
    N, K = radar.num_samples, radar.num_chirps
    # The whole last chirp and the whole last sample column, corner included.
    for n in range(N):
        ref = reference_sample(radar, gain, tau, nu, n, K - 1)
        assert abs(cube[0, K - 1, n] - ref) < PHASE_TOL * abs(gain), f"n={n}"
    for k in range(K):
        ref = reference_sample(radar, gain, tau, nu, N - 1, k)
        assert abs(cube[0, k, N - 1] - ref) < PHASE_TOL * abs(gain), f"k={k}"


def test_phase_accuracy_over_many_extreme_paths(tone_paths):
    # The bound must hold for every extreme path, not just one: draw delays in the last 1 % of
    # the unambiguous delay and delay rates in the outer 10 % of ±max_delay_rate.
    radar = RadarConfig()
    rng = np.random.default_rng(7)
    taus = radar.max_delay * (1 - 0.01 * rng.random(1000))
    nus = radar.max_delay_rate * (1 - 0.1 * rng.random(1000)) * rng.choice([-1.0, 1.0], 1000)
    N, K = radar.num_samples, radar.num_chirps
    errors = []
    for tau, nu in zip(taus, nus):
        cube = beat_cube(tone_paths(1.0, tau, nu), radar=radar, sweep=one_beam(), ris=None)
        errors.append(abs(cube[0, K - 1, N - 1] - reference_sample(radar, 1.0, tau, nu, N - 1, K - 1)))
    errors = np.array(errors)
    worst = int(np.argmax(errors))
    assert errors[worst] < PHASE_TOL, (
        f"{np.count_nonzero(errors >= PHASE_TOL)} of {errors.size} paths exceed {PHASE_TOL}; worst "
        f"{errors[worst]:.3e} at tau={taus[worst]!r} s, nu={nus[worst]!r}"
    )


@pytest.mark.parametrize("frequency", [0.123456789, 1.0 - 2.0**-40, 123456.789, -98765.4321, 2.0**40 / 3])
@pytest.mark.parametrize("length", [600, 4096])
def test_wrapped_tone_matches_exact_reference(frequency, length):
    tone = wrapped_tone(np.array([frequency]), length)
    assert tone.shape == (1, length)
    f = Fraction(frequency)
    idx = np.unique(np.r_[0:8, length - 8:length, np.linspace(0, length - 1, 40).astype(int)])
    ref = np.array([exact_phasor(f * int(i)) for i in idx])
    # wrapped_tone's documented bound: length·2⁻⁵² cycles of phase error, plus ~1e-15 from the
    # float trig.
    bound = 2 * np.pi * length * 2.0**-52 + 1e-15
    np.testing.assert_array_less(np.abs(tone[0, idx] - ref), bound)


# ------------------------------------------------------------------------------ structure of eq. (1)
def test_beat_cube_is_linear_in_the_paths(make_radar, tone_paths):
    radar = make_radar()
    a = tone_paths([1e-3, 2e-4j], [20e-9, 55e-9], [0.0, 3e-8])
    b = tone_paths([5e-4 - 5e-4j], [80e-9], [-6e-8])
    sweep = BeamSweep(np.zeros((2, 2)))
    both = beat_cube(PathSet.concatenate([a, b]), radar=radar, sweep=sweep, ris=None)
    parts = beat_cube(a, radar=radar, sweep=sweep, ris=None) + beat_cube(b, radar=radar, sweep=sweep, ris=None)
    # Sums of O(1e-3) terms: rounding is ~1e-19.
    np.testing.assert_allclose(both, parts, rtol=0, atol=1e-15)
    assert both.shape == (2, radar.num_chirps, radar.num_samples)


def test_ris_path_carries_the_ris_response_of_each_beam(make_scenario, tone_paths):
    scenario = make_scenario(mode="relay", structure=False, yaw=np.deg2rad(-12.0))
    paths = analytic_paths(scenario)
    assert paths.via_ris.tolist() == [True]
    cube = beat_cube(paths, radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    # The same tone without the RIS: eq. (1) says Y_m = r_m · (that tone).
    bare = beat_cube(tone_paths(paths.gain, paths.delay, paths.delay_rate), radar=scenario.radar,
                     sweep=BeamSweep(np.zeros((1, 2))), ris=None)[0]
    r = ris_response(scenario.ris, scenario.sweep, paths.ris_incidence, paths.ris_departure,
                     wavelength=scenario.radar.wavelength)[:, 0]
    np.testing.assert_allclose(cube, r[:, None, None] * bare[None], rtol=1e-12, atol=0)


def test_ris_path_without_ris_config_is_rejected(make_scenario):
    scenario = make_scenario(structure=False)
    with pytest.raises(ValueError, match="RIS loop-back paths but no RisConfig"):
        beat_cube(analytic_paths(scenario), radar=scenario.radar, sweep=scenario.sweep, ris=None)


# ------------------------------------------------------------------------------ link budget
@pytest.mark.parametrize("mode", ["relay", "reflective"])
def test_analytic_paths_follow_the_paper_link_budget(mode, make_scenario):
    scenario = make_scenario(mode=mode, ue_velocity=(0.0, -2.5, 0.0))
    radar, ris = scenario.radar, scenario.ris
    paths = analytic_paths(scenario)
    d = 13.38
    assert paths.labels == ("ris_loopback", "ris_structure")
    # Sec. IV-B: |γ_0|² = P G |γ_UR|² ζ |γ_RU|², |γ_UR|² = λ²/(4π d)²; |γ_l|² = P G σ λ²/((4π)³ d⁴).
    one_way = radar.wavelength**2 / (4 * np.pi * d) ** 2
    p0 = radar.tx_power * radar.antenna_gain * one_way * ris.amplification * one_way
    p1 = radar.tx_power * radar.antenna_gain * PAPER_RCS * radar.wavelength**2 / ((4 * np.pi) ** 3 * d**4)
    np.testing.assert_allclose(paths.power, [p0, p1], rtol=1e-12)
    # Round trip 2d/c, plus τ_RB inside the RIS for the loop-back; 1e-20 s is float rounding.
    np.testing.assert_allclose(paths.delay, [2 * d / C + ris.loopback_delay, 2 * d / C], rtol=0, atol=1e-20)
    # The UE moves away from the RIS (−y) at 2.5 m/s: ν = 2v/c > 0 (receding) for both paths.
    np.testing.assert_allclose(paths.delay_rate, 2 * 2.5 / C, rtol=1e-12)
    # Carrier phase exp(-j2π f_c τ) in the gain. f_c τ ≈ 5·10³ cycles is known to ~1e-12 cycles
    # in float64, so 1e-9 is ample.
    expected_phase = np.exp(-2j * np.pi * np.mod(paths.delay * radar.carrier_frequency, 1.0))
    np.testing.assert_allclose(paths.gain / np.abs(paths.gain), expected_phase, atol=1e-9)
    np.testing.assert_allclose(paths.ris_incidence[0], scenario.truth.aod, atol=1e-15)
    assert np.isnan(paths.ris_incidence[1]).all()


# ------------------------------------------------------------------------------ noise and seeds
def test_noise_has_the_configured_power_and_is_circular(make_radar):
    radar = make_radar()
    sigma2 = radar.noise_power
    w = add_noise(np.zeros((50, 16, 128), complex), sigma2, np.random.default_rng(11))
    n = w.size  # 102400 samples: the sample mean of |w|² has relative std 1/sqrt(n) ≈ 0.3 %
    assert np.mean(np.abs(w) ** 2) == pytest.approx(sigma2, rel=5 / np.sqrt(n))
    assert np.mean(w.real**2) == pytest.approx(sigma2 / 2, rel=5 * np.sqrt(2 / n))
    assert np.mean(w.imag**2) == pytest.approx(sigma2 / 2, rel=5 * np.sqrt(2 / n))
    # Circular: E[w²] = 0; its sample mean has std σ²/sqrt(n).
    assert abs(np.mean(w**2)) < 5 * sigma2 / np.sqrt(n)


def test_seeded_simulation_is_bit_reproducible(make_scenario):
    scenario = make_scenario()
    a = simulate(scenario, rng=np.random.default_rng(123)).cube
    b = simulate(scenario, rng=np.random.default_rng(123)).cube
    c = simulate(scenario, rng=np.random.default_rng(124)).cube
    assert a.dtype == b.dtype == np.complex128
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()
    # Different seeds differ in the noise only: the signal cancels in a - c, leaving the
    # difference of two independent CN(0, σ²) draws (variance 2σ²). Over 61·16·128 = 125k
    # samples the sample mean's relative std is 0.3 %: allow 2 %.
    assert np.mean(np.abs(a - c) ** 2) == pytest.approx(2 * scenario.radar.noise_power, rel=0.02)


def test_noiseless_simulation_ignores_the_rng(make_scenario):
    scenario = make_scenario()
    a = simulate(scenario, rng=np.random.default_rng(1), noise=False).cube
    b = simulate(scenario, rng=np.random.default_rng(2), noise=False).cube
    assert a.tobytes() == b.tobytes()
    np.testing.assert_array_equal(a, beat_cube(analytic_paths(scenario), radar=scenario.radar,
                                               sweep=scenario.sweep, ris=scenario.ris))
