"""Threaded synthesis and the per-beam noise streams ("fast" and "boxmuller").

The deterministic cube must not depend on the number of threads (bit for bit) and must still
equal the exact rational reference (``beat_reference``) for long delays, where the phase of
``S τ n T_s`` reaches 8·10⁴ cycles within a chirp and a naive float64 phase would be off by
~1e-11 cycles. The per-beam noise streams must be CN(0, σ²): their power, the balance of I and Q
and the independence of beams are checked against their sampling errors (5σ bounds, stated per
assertion), and the Box–Muller stream against its definition (docs/conventions.md, "Receiver
noise") recomputed here in float64 from the child streams' words, and against the Gaussian CDF.
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


@pytest.mark.parametrize("stream", ["fast", "boxmuller"])
def test_fused_noise_is_the_stream_added_to_the_noiseless_cube(stream, make_radar, make_ris, paper_sweep):
    radar, ris, sweep = make_radar(), make_ris(), paper_sweep()
    paths = _random_paths(np.random.default_rng(5), 10, 5)
    fused = beat_cube(paths, radar=radar, sweep=sweep, ris=ris, noise=(1e-9, np.random.default_rng(9)), workers=2,
                      noise_stream=stream)
    clean = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
    added = add_noise(clean, 1e-9, np.random.default_rng(9), stream=stream, workers=1)
    np.testing.assert_array_equal(fused, added)


@pytest.mark.parametrize("stream", ["fast", "boxmuller"])
def test_per_beam_noise_is_circular_gaussian_with_the_stated_power(stream):
    sigma2 = 2.5e-10  # [W]
    shape = (61, 64, 128)  # 5·10⁵ samples
    w = add_noise(np.zeros(shape, complex), sigma2, np.random.default_rng(1), stream=stream)
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


@pytest.mark.parametrize("stream", ["fast", "boxmuller"])
def test_per_beam_noise_does_not_depend_on_the_thread_count_and_follows_the_seed(stream):
    cube = np.zeros((7, 16, 32), complex)
    a = add_noise(cube, 1.0, np.random.default_rng(4), stream=stream, workers=1)
    b = add_noise(cube, 1.0, np.random.default_rng(4), stream=stream, workers=4)
    c = add_noise(cube, 1.0, np.random.default_rng(5), stream=stream)
    np.testing.assert_array_equal(a, b)
    assert not np.any(a == c)
    other = add_noise(cube, 1.0, np.random.default_rng(4), stream="fast" if stream == "boxmuller" else "boxmuller")
    assert not np.any(a == other)  # the two streams are two streams


def test_boxmuller_samples_are_their_definition_from_the_child_streams_words():
    # The definition (docs/conventions.md, "Receiver noise"), in float64 here: beam m's child stream
    # rng.spawn(M)[m] gives K·N 64-bit words = 2·K·N 32-bit words a (the first K·N) and b (the rest);
    # sample i = sqrt(-σ² ln u) e^{jθ}, u = (a_i + 1/2)/2^32, θ = 2π b_i/2^32. float32 moves u by
    # <= 2^-24 relative (|w|²/σ² by <= 6e-8) and θ by <= 4e-7 rad, and rounds the sample (6e-8): the
    # tolerances below are those bounds with a 4x margin for float32's log, sin and cos.
    sigma2, shape = 3.0e-9, (5, 32, 48)
    cube = np.zeros(shape, complex)
    got = add_noise(cube, sigma2, np.random.default_rng(21), stream="boxmuller", workers=2)
    children = np.random.default_rng(21).spawn(shape[0])
    n = shape[1] * shape[2]
    for m, child in enumerate(children):
        words = child.bit_generator.random_raw(n).view(np.uint32).astype(np.float64)
        u, theta = (words[:n] + 0.5) / 2.0**32, 2 * np.pi * words[n:] / 2.0**32
        power = -np.log(u)  # |w|²/σ²
        w = got[m].ravel()
        np.testing.assert_allclose(np.abs(w) ** 2 / sigma2, power, rtol=1e-6, atol=2.5e-7)
        big = power > 1e-4  # the angle of a sample of radius 0.01σ and more
        phase_error = np.angle(w[big] * np.exp(-1j * theta[big]))
        assert np.abs(phase_error).max() < 2e-6  # rad
        assert big.sum() > 0.99 * n


def test_boxmuller_extreme_words_give_the_cut_and_zero_not_nan():
    # Words 0 and 2^32 - 1 are the ends of u's grid: u = 2^-33 gives the largest radius, √(33 ln 2)·σ; a word
    # rounding up to 2^32 in float32 gives u = 1 and a zero sample (not a NaN from a log of u > 1).
    from risloc_rt.model.beat import _add_beam_noise_boxmuller

    class Words:
        def __init__(self, words):
            self.words = np.asarray(words, dtype=np.uint32)

        def random_raw(self, n):
            return self.words.view(np.uint64)[:n]

    radius_words = [0, 2**32 - 1, 2**32 - 100, 2**24 + 1]  # 2**32 - 100 rounds up (float32 steps by 256 there)
    angle_words = [0, 2**30, 2**31, 3 * 2**30]  # θ = 0, π/2, π, 3π/2
    sigma2, n = 4.0, 4
    rng = type("Stub", (), {"bit_generator": Words(radius_words + angle_words)})()
    frame = np.zeros((1, n), complex)
    out = np.empty_like(frame)
    _add_beam_noise_boxmuller(frame, sigma2, rng, out, np.empty(2 * n, np.float32), np.empty(n, np.complex64))
    w = out[0]
    assert np.all(np.isfinite(w))
    cut = np.sqrt(33 * np.log(2) * sigma2)
    assert abs(w[0] - cut) < 1e-6 * cut  # θ = 0: all real
    assert w[1] == 0 and w[2] == 0  # words that round to 2^32 in float32: u = 1
    r3 = np.sqrt(-np.log((2**24 + 1.5) / 2.0**32) * sigma2)
    assert abs(w[3] - (-1j * r3)) < 1e-6 * r3  # 3π/2


def test_boxmuller_noise_passes_the_gaussian_cdf_and_its_tails():
    from scipy import stats

    sigma2 = 1.0e-8
    w = add_noise(np.zeros((61, 128, 300), complex), sigma2, np.random.default_rng(8), stream="boxmuller")
    parts = np.concatenate([w.real.ravel(), w.imag.ravel()]) / np.sqrt(sigma2 / 2)  # 4.7·10⁶ N(0, 1) samples
    # KS on 10⁶ of them resolves a CDF error of ~2e-3 at p = 1e-3 (a wrong scale by 0.5 % fails it)
    assert stats.kstest(parts[::4], "norm").pvalue > 1e-3
    # 4σ tails: P(|x| > 4) = 6.334e-5, binomial 5σ bound on the count
    expected = parts.size * 2 * stats.norm.sf(4.0)
    assert abs(np.sum(np.abs(parts) > 4.0) - expected) < 5 * np.sqrt(expected)
    # the radius: |w|²/σ² ~ Exp(1); P(> 10) = e^-10, and nothing beyond the cut 33 ln 2
    power = np.abs(w.ravel()) ** 2 / sigma2
    expected = power.size * np.exp(-10.0)
    assert abs(np.sum(power > 10.0) - expected) < 5 * np.sqrt(expected)
    assert power.max() <= 33 * np.log(2) * (1 + 1e-6)
    # Box–Muller's pair is independent, not only uncorrelated: E[I² Q²] = E[I²] E[Q²] (std ≈ √8/√n)
    i2, q2 = (w.real.ravel() ** 2, w.imag.ravel() ** 2)
    n = i2.size
    assert abs(np.mean(i2 * q2) / (np.mean(i2) * np.mean(q2)) - 1) < 5 * np.sqrt(8 / n)


def test_unknown_noise_stream_is_refused(make_radar, make_ris, paper_sweep):
    with pytest.raises(ValueError, match="stream='quick' must be 'standard'.*or 'boxmuller'"):
        add_noise(np.zeros((1, 2, 2), complex), 1.0, np.random.default_rng(0), stream="quick")
    paths = _random_paths(np.random.default_rng(5), 2, 1)
    with pytest.raises(ValueError, match="noise_stream='standard': the noise added during synthesis is per beam"):
        beat_cube(paths, radar=make_radar(), sweep=paper_sweep(), ris=make_ris(), noise=(1.0, np.random.default_rng(0)),
                  noise_stream="standard")
