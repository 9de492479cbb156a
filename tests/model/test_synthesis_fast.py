"""Threaded synthesis and the fast noise stream.

The deterministic cube must not depend on the number of threads (bit for bit) and must still
equal the exact rational reference (``beat_reference``) for long delays, where the phase of
``S τ n T_s`` reaches 8·10⁴ cycles within a chirp and a naive float64 phase would be off by
~1e-11 cycles. The fast noise
stream must be CN(0, σ²): its power, the balance of I and Q and the independence of beams are
checked against their sampling errors (5σ bounds, stated per assertion).
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT, BeamSweep
from risloc_rt.model.beat import add_noise, beat_cube
from risloc_rt.model.beat_reference import beat_cube_reference
from risloc_rt.model.motion import advance_paths
from risloc_rt.model.paths import PathSet


def _random_paths(rng, n, n_ris, *, max_range=20.0, moving=False):
    tau = 2 * rng.uniform(0.5, max_range, n) / SPEED_OF_LIGHT
    gain = np.exp(2j * np.pi * rng.random(n)) * 10 ** rng.uniform(-7, -4, n)
    angles = np.full((n, 2), np.nan)
    angles[:n_ris] = np.deg2rad(np.c_[rng.uniform(-40, 40, n_ris), rng.uniform(-5, 5, n_ris)])
    nu = rng.uniform(-2, 2, n) * 2 / SPEED_OF_LIGHT if moving else np.zeros(n)
    return PathSet(gain=gain, delay=tau, delay_rate=nu, ris_incidence=angles, ris_departure=angles,
                   labels=("p",) * n)


@pytest.mark.parametrize("moving", [False, True])
def test_cube_is_the_same_bit_for_bit_for_any_number_of_threads(moving, make_radar, make_ris, paper_sweep):
    radar, ris, sweep = make_radar(), make_ris(), paper_sweep()
    paths = _random_paths(np.random.default_rng(3), 40, 25, moving=moving)
    cubes = [beat_cube(paths, radar=radar, sweep=sweep, ris=ris, workers=w) for w in (1, 2, 5)]
    frames = advance_paths(paths, radar=radar, num_beams=sweep.num_beams)  # per-frame geometry
    framed = [beat_cube(frames, radar=radar, sweep=sweep, ris=ris, workers=w) for w in (1, 3)]
    for other in cubes[1:]:
        np.testing.assert_array_equal(other, cubes[0])
    np.testing.assert_array_equal(framed[1], framed[0])


def test_long_delays_still_equal_the_rational_reference(make_radar, make_ris):
    # Delays up to 3 km (S τ T_s ≈ 140 cycles per sample, 8·10⁴ at the last sample): the threaded
    # cube equals the Fraction-based reference to 1e-12 of Σ_l |γ_l r_{m,l}| (float64 rounding
    # of the tones' sum), so no phase is lost however long the delay.
    radar, ris = make_radar(), make_ris()
    sweep = BeamSweep(np.deg2rad([[-30.0, 0.0], [0.0, 0.0], [21.0, 0.0]]))
    rng = np.random.default_rng(11)
    for max_range in (20.0, 3000.0):
        paths = _random_paths(rng, 24, 12, max_range=max_range)
        new = beat_cube(paths, radar=radar, sweep=sweep, ris=ris, workers=2)
        old = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
        scale = np.abs(paths.gain).sum() * ris.num_elements
        assert np.abs(new - old).max() < 1e-12 * scale


def test_fused_noise_is_the_fast_stream_added_to_the_noiseless_cube(make_radar, make_ris, paper_sweep):
    radar, ris, sweep = make_radar(), make_ris(), paper_sweep()
    paths = _random_paths(np.random.default_rng(5), 10, 5)
    fused = beat_cube(paths, radar=radar, sweep=sweep, ris=ris, noise=(1e-9, np.random.default_rng(9)), workers=2)
    clean = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
    added = add_noise(clean, 1e-9, np.random.default_rng(9), stream="fast", workers=1)
    np.testing.assert_array_equal(fused, added)


def test_fast_noise_is_circular_gaussian_with_the_stated_power():
    sigma2 = 2.5e-10  # [W]
    shape = (61, 64, 128)  # 5·10⁵ samples
    w = add_noise(np.zeros(shape, complex), sigma2, np.random.default_rng(1), stream="fast")
    n = w.size
    # E|w|² = σ², std of the sample mean σ²/√n: 5σ bound.
    assert abs(np.mean(np.abs(w) ** 2) / sigma2 - 1) < 5 / np.sqrt(n)
    # I and Q carry σ²/2 each (std of their difference's mean: σ²/√(2n)·√2).
    assert abs((np.mean(w.real**2) - np.mean(w.imag**2)) / sigma2) < 5 / np.sqrt(n)
    # Uncorrelated I/Q and beams: |E[w_a w_b*]| / σ² has std 1/√(samples).
    per_beam = w[0].size
    assert abs(np.mean(w.real * w.imag)) / sigma2 < 5 / np.sqrt(2 * n)
    corr = np.abs(np.vdot(w[0], w[1])) / per_beam / sigma2
    assert corr < 5 / np.sqrt(per_beam)
    # Gaussian: the fourth moment E|w|⁴ = 2σ⁴ for a circular complex normal (std ≈ √20/√n·σ⁴).
    assert abs(np.mean(np.abs(w) ** 4) / sigma2**2 - 2) < 5 * np.sqrt(20 / n)


def test_fast_noise_does_not_depend_on_the_thread_count_and_follows_the_seed():
    cube = np.zeros((7, 16, 32), complex)
    a = add_noise(cube, 1.0, np.random.default_rng(4), stream="fast", workers=1)
    b = add_noise(cube, 1.0, np.random.default_rng(4), stream="fast", workers=4)
    c = add_noise(cube, 1.0, np.random.default_rng(5), stream="fast")
    np.testing.assert_array_equal(a, b)
    assert not np.any(a == c)


def test_unknown_noise_stream_is_refused():
    with pytest.raises(ValueError, match="stream='quick' must be 'standard'"):
        add_noise(np.zeros((1, 2, 2), complex), 1.0, np.random.default_rng(0), stream="quick")
