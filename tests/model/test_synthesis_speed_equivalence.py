"""The fast synthesis equals the original one: risloc_rt/model/beat.py and phase.py.

Oracles: the original implementation, kept in ``risloc_rt.model.beat_reference`` (per-path phases
in exact rational arithmetic with ``fractions.Fraction``, one batched product over the beams);
eq. (1) frame by frame; the same noise stream as before for the same seed.

The bound. The new and the old cube use bit-identical tone frequencies (checked below), so the
two differ only in the rounding of the sums over paths (grouped by slow-time tone, a different
order of the products γ·r·s·f). Each of the L terms is a product of four complex factors, each
rounded to 2⁻⁵³, summed in some order, so |Y_new − Y_old| ≤ c·(L + 4)·2⁻⁵³·Σ_l |γ_l r_{m,l}| with
a small c; we demand ``8·(L + 4)·2⁻⁵³ ≈ 5e-14`` relative to Σ_l |γ_l r_{m,l}| for L = 48. In
physical units: an amplitude error 10⁻¹³ of the signal is a phase error below 10⁻¹³ rad and a
spurious component 260 dB below the paths, where the receiver noise of Table I sits ~11 dB
*above* a 13 m loop-back per sample and the traced hall's own model error is -93 dB
(docs/benchmarks.md): nothing the DSP can see.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import BeamSweep, RadarConfig
from risloc_rt.model.beat import add_noise, beat_cube
from risloc_rt.model.beat_reference import beat_cube_reference, fraction_cycles
from risloc_rt.model.paths import PathFrames, PathSet
from risloc_rt.model.phase import exact_fractional_cycles
from risloc_rt.model.ris import ris_response


def rel_bound(num_paths: int) -> float:
    """8·(L + 4)·2⁻⁵³: the allowed |Y_new − Y_old| per unit of Σ_l |γ_l r_{m,l}| (module doc)."""
    return 8 * (num_paths + 4) * 2.0**-53


def extreme_paths(radar: RadarConfig, rng: np.random.Generator, n: int, *, n_ris: int, shared_rates: int = 0) -> PathSet:
    """n paths (the first n_ris through the RIS) at extreme delays and delay rates.

    Delays fill the whole unambiguous range, a quarter of them in its last 1 %; rates are in the
    outer 10 % of ±max_delay_rate, except ``shared_rates`` paths that share a few rates (0 among
    them) so that the synthesis groups them.
    """
    tau = radar.max_delay * rng.random(n)
    tau[: n // 4] = radar.max_delay * (1 - 0.01 * rng.random(n // 4))
    nu = radar.max_delay_rate * (1 - 0.1 * rng.random(n)) * rng.choice([-1.0, 1.0], n)
    if shared_rates:
        nu[rng.choice(n, shared_rates, replace=False)] = rng.choice([0.0, nu[0], -3e-9], shared_rates)
    gain = (rng.standard_normal(n) + 1j * rng.standard_normal(n)) * 10 ** rng.uniform(-6, -3, n)
    inc = np.full((n, 2), np.nan)
    inc[:n_ris] = np.deg2rad(np.c_[rng.uniform(-50, 50, n_ris), rng.uniform(-10, 10, n_ris)])
    dep = inc + np.deg2rad(rng.uniform(-5, 5, (n, 2)))  # a wall between: departure ≠ incidence
    return PathSet(gain=gain, delay=tau, delay_rate=nu, ris_incidence=inc, ris_departure=dep, labels=("p",) * n)


def path_amplitude_sum(paths: PathSet, radar: RadarConfig, sweep: BeamSweep, ris) -> np.ndarray:
    """Σ_l |γ_l r_{m,l}| per beam [M] [√W]: the scale of the rounding of eq. (1)'s sum."""
    amp = np.tile(np.abs(paths.gain), (sweep.num_beams, 1))
    via = paths.via_ris
    if via.any():
        amp[:, via] *= np.abs(ris_response(ris, sweep, paths.ris_incidence[via], paths.ris_departure[via],
                                           wavelength=radar.wavelength))
    return amp.sum(axis=1)


# ------------------------------------------------------------------------------ exact phases
def test_vectorized_fractional_cycles_equal_the_rational_ones_bit_for_bit():
    # The per-sample and per-chirp cycle counts of 4000 extreme paths, and 20 000 adversarial
    # inputs over 30 orders of magnitude: every result is the same float as the exact rational
    # computation's (which rounds once, correctly).
    radar = RadarConfig()
    rng = np.random.default_rng(3)
    n = 4000
    tau = np.r_[radar.max_delay * (1 - 0.01 * rng.random(n)), 0.0, radar.max_delay]
    nu = np.r_[radar.max_delay_rate * (1 - 0.1 * rng.random(n)) * rng.choice([-1.0, 1.0], n), 0.0, -1e-300]
    cases = [([(radar.slope, tau), (radar.carrier_frequency, nu)], radar.sample_period),
             ([(radar.carrier_frequency, nu)], radar.chirp_duration),
             ([(1.0, tau)], radar.carrier_frequency)]
    for _ in range(20):
        c1, c2, scale = 10 ** rng.uniform(-3, 14), -(10 ** rng.uniform(-3, 14)), 10 ** rng.uniform(-9, 2)
        x1 = rng.standard_normal(1000) * 10 ** rng.uniform(-12, 3, 1000)
        x2 = rng.standard_normal(1000) * 10 ** rng.uniform(-12, 3, 1000)
        cases.append(([(c1, x1), (c2, x2)], scale))
    for terms, scale in cases:
        fast = exact_fractional_cycles(terms, scale)
        np.testing.assert_array_equal(fast, fraction_cycles(terms, scale))
        assert np.all((fast >= 0) & (fast <= 1))


def test_fractional_cycles_keep_the_shape_of_their_inputs():
    radar = RadarConfig()
    rng = np.random.default_rng(4)
    tau = radar.max_delay * rng.random((7, 5))
    nu = radar.max_delay_rate * rng.uniform(-1, 1, (7, 5))
    terms = [(radar.slope, tau), (radar.carrier_frequency, nu)]
    out = exact_fractional_cycles(terms, radar.sample_period)
    assert out.shape == (7, 5)
    flat = fraction_cycles([(radar.slope, tau.ravel()), (radar.carrier_frequency, nu.ravel())], radar.sample_period)
    np.testing.assert_array_equal(out.ravel(), flat)


# ------------------------------------------------------------------------------ the cube
@pytest.mark.parametrize("seed, n, n_ris, shared", [(11, 48, 33, 0), (12, 48, 33, 20), (13, 30, 0, 10), (14, 5, 5, 5)])
def test_fast_cube_equals_the_reference_on_extreme_path_sets(seed, n, n_ris, shared, make_radar, make_ris):
    radar = make_radar()
    rng = np.random.default_rng(seed)
    paths = extreme_paths(radar, rng, n, n_ris=n_ris, shared_rates=shared)
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 7.5]))
    ris = make_ris()
    new = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
    old = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
    scale = path_amplitude_sum(paths, radar, sweep, ris)[:, None, None]
    err = np.abs(new - old) / scale
    assert err.max() < rel_bound(n), f"max |ΔY|/Σ|γr| = {err.max():.3e} (bound {rel_bound(n):.3e})"


def test_fast_cube_equals_the_reference_for_table1_and_48_hall_like_paths(make_ris):
    # Table I frames (K = 128, N = 600; 9 of the 61 beams, enough to cover the RIS response)
    # with 48 paths like the paper hall's (33 RIS loop-backs, 15 echoes at 3-20 m, all ν = 0
    # for a radar at rest), and the same with a moving radar's rates (every path its own ν).
    radar = RadarConfig()
    rng = np.random.default_rng(21)
    sweep, ris = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 11.25])), make_ris()
    tau = 2 * rng.uniform(3.0, 20.0, 48) / 299_792_458.0
    gain = np.exp(2j * np.pi * rng.random(48)) * 10 ** rng.uniform(-7, -4, 48)
    angles = np.full((48, 2), np.nan)
    angles[:33] = np.deg2rad(np.c_[rng.uniform(-40, 40, 33), rng.uniform(-5, 5, 33)])
    for nu in (np.zeros(48), rng.uniform(-1.3e-8, 1.3e-8, 48)):
        paths = PathSet(gain=gain, delay=tau, delay_rate=nu, ris_incidence=angles, ris_departure=angles,
                        labels=("hall",) * 48)
        new = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
        old = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
        err = np.abs(new - old) / path_amplitude_sum(paths, radar, sweep, ris)[:, None, None]
        assert err.max() < rel_bound(48), f"max |ΔY|/Σ|γr| = {err.max():.3e}"


def test_frames_synthesise_each_beam_from_its_own_paths(make_radar, make_ris):
    # A PathFrames is eq. (1) frame by frame: beam m of the cube is the one-beam cube of frame m.
    radar = make_radar()
    rng = np.random.default_rng(5)
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-30.0, 30.0, 10.0]))
    ris = make_ris()
    # The same 12 paths (6 through the RIS) with other delays, rates, gains and angles per frame.
    frames = [extreme_paths(radar, rng, 12, n_ris=6, shared_rates=4) for _ in range(sweep.num_beams)]
    pf = PathFrames.from_frames(frames, radar.beam_times(sweep.num_beams))
    cube = beat_cube(pf, radar=radar, sweep=sweep, ris=ris)
    for m in range(sweep.num_beams):
        one = BeamSweep(sweep.angles[m:m + 1])
        ref = beat_cube_reference(pf.frame(m), radar=radar, sweep=one, ris=ris)[0]
        scale = path_amplitude_sum(pf.frame(m), radar, one, ris)[0]
        assert np.abs(cube[m] - ref).max() / scale < rel_bound(12), f"beam {m}"


def test_identical_frames_give_the_static_cube_bit_for_bit(make_radar, make_ris):
    radar = make_radar()
    sweep = BeamSweep.azimuth_grid(*np.deg2rad([-30.0, 30.0, 10.0]))
    paths = extreme_paths(radar, np.random.default_rng(6), 10, n_ris=4)
    static = beat_cube(paths, radar=radar, sweep=sweep, ris=make_ris())
    framed = beat_cube(PathFrames.repeat(paths, radar.beam_times(sweep.num_beams)), radar=radar, sweep=sweep,
                       ris=make_ris())
    assert static.tobytes() == framed.tobytes()


def test_frames_must_match_the_sweep(make_radar):
    radar = make_radar()
    paths = extreme_paths(radar, np.random.default_rng(8), 3, n_ris=0)
    pf = PathFrames.repeat(paths, radar.beam_times(4))
    with pytest.raises(ValueError, match="4 frames but the sweep has 2 beams"):
        beat_cube(pf, radar=radar, sweep=BeamSweep(np.zeros((2, 2))), ris=None)


def test_out_argument_is_filled_in_place(make_radar):
    radar = make_radar()
    paths = extreme_paths(radar, np.random.default_rng(9), 6, n_ris=0, shared_rates=3)
    sweep = BeamSweep(np.zeros((3, 2)))
    out = np.full((3, radar.num_chirps, radar.num_samples), np.nan + 0j)
    res = beat_cube(paths, radar=radar, sweep=sweep, ris=None, out=out)
    assert res is out
    np.testing.assert_array_equal(out, beat_cube(paths, radar=radar, sweep=sweep, ris=None))
    with pytest.raises(ValueError, match="out must be"):
        beat_cube(paths, radar=radar, sweep=sweep, ris=None, out=np.zeros((3, 2, 2), complex))


def test_empty_path_set_gives_a_zero_cube(make_radar):
    radar = make_radar()
    cube = beat_cube(PathSet.empty(), radar=radar, sweep=BeamSweep(np.zeros((2, 2))), ris=None)
    assert cube.shape == (2, radar.num_chirps, radar.num_samples) and not cube.any()


# ------------------------------------------------------------------------------ noise
def test_noise_is_the_same_stream_as_before():
    # The original add_noise: scale·(n[..., 0] + 1j·n[..., 1]) of one standard_normal call.
    cube = np.ones((2, 3, 4), complex)
    sigma2 = 1e-9
    n = np.random.default_rng(17).standard_normal(cube.shape + (2,))
    before = cube + np.sqrt(sigma2 / 2) * (n[..., 0] + 1j * n[..., 1])
    np.testing.assert_array_equal(add_noise(cube, sigma2, np.random.default_rng(17)), before)
    inplace = cube.copy()
    add_noise(inplace, sigma2, np.random.default_rng(17), out=inplace)
    np.testing.assert_array_equal(inplace, before)
