"""The dense grid search of noise-only beams (``dsp.gridscreen._dense_beam``) and its two bounds.

Oracles: the whole float64 N_DFT × K_DFT grid (``numpy.fft.ifft2``, the paper's search), Szegő's
extremal column ``|g(ν)| = M·|cos(σ(ν - ν₀))|`` (two chirps, first and last, on one delay tone:
the closed form gives every value), and float64 transforms for the complex64 error bounds.

The search keeps every grid bin that Szegő's inequality cannot rule out: a plane value r at
distance t of the grid maximum m obeys ``r ≥ m·cos(σt + α₀)``. For the extremal column with its
maximum on a grid bin midway between two plane samples this holds with equality (up to α₀): the
maximum sits exactly half a Doppler grid bin (α₀/σ) outside each sample's excluded interval. The
float32 parts may err by at most their stated slack; below it, float64 decides.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import BeamSweep, scan_beams
from dsp import gridscreen
from dsp.radar import SPEED_OF_LIGHT
from dsp.spectrum import dft_windows
from risloc_rt.model.beat import add_noise


def _full_grid(y, w_k, w_n, n_dft, k_dft, first=0):
    """(q, p, |z|²) of the float64 grid maximum, ties to the first in (q, p) order: the paper's search."""
    z = np.fft.ifft2(y * np.outer(w_k, w_n), s=(k_dft, n_dft)) * (k_dft * n_dft)  # Σ x e^{+j2π(qk/K_DFT + pn/N_DFT)}
    power = z.real**2 + z.imag**2
    power[:, :first] = -1.0
    q, p = np.unravel_index(int(power.argmax()), power.shape)
    return int(q), int(p), float(power[q, p])


def _dense(y, processing, w_k, w_n, first=0, lower=-np.inf):
    """The dense search on one beam as ``screened_scan`` runs it; returns (q, p, |z|², plan, work)."""
    k, n = y.shape
    plan = gridscreen._DensePlan(k, n, processing.n_dft, processing.k_dft)
    work = gridscreen._DenseWork(plan)
    x32 = y.astype(np.complex64) * np.outer(w_k, w_n).astype(np.float32)
    q, p, value, krow = gridscreen._dense_beam(y, x32, plan, work, first, w_k, w_n, lower)
    np.testing.assert_array_equal(krow, gridscreen._dft_table(processing.k_dft, k, processing.k_dft)[q])
    return q, p, value, plan, work


def test_szego_bound_is_met_with_equality_by_the_extremal_column(make_radar, make_processing):
    # Boxcar window, chirps 0 and K-1 only, one delay tone on fine bin p0: column p0 is
    # g(ν) = N(1 + e^{j2π(ν-ν₀)(K-1)}), |g| = 2N|cos(σ(ν-ν₀))|, σ = π(K-1), the case of equality
    # in Szegő's inequality. ν₀ = q0/K_DFT is a grid bin midway between plane samples r0/L and
    # (r0+1)/L (K_DFT = 14·L), so both samples are exactly 2N·cos(σ/(2L)). |g| repeats every
    # 1/(K-1) cycles; K_DFT is prime to K-1 = 15, so no repeat falls on a grid bin (no tie).
    radar = make_radar(num_samples=64, num_chirps=16)
    k, n = 16, 64
    plan_l = 32  # the plane's length for K = 16 (power of two >= 2K)
    processing = make_processing(radar, n_dft=127, k_dft=14 * plan_l, window="boxcar")
    k_dft, n_dft = processing.k_dft, processing.n_dft
    r0, p0 = 7, 40
    q0 = 7 * (2 * r0 + 1)
    nu0 = q0 / k_dft  # cycles per chirp
    y = np.zeros((k, n), complex)
    tone = np.exp(-2j * np.pi * p0 * np.arange(n) / n_dft)  # peaks on fine delay bin p0
    y[0] = tone
    y[k - 1] = np.exp(-2j * np.pi * nu0 * (k - 1)) * tone
    w_k, w_n = np.ones(k), np.ones(n)

    q, p, value, plan, work = _dense(y, processing, w_k, w_n)
    assert plan.length == plan_l
    # The grid maximum: |z|² = (2N)² exactly (physics: two unit chirps of N unit samples in phase).
    assert (q, p) == (q0, p0) == _full_grid(y, w_k, w_n, n_dft, k_dft)[:2]
    assert value == pytest.approx((2.0 * n) ** 2, rel=1e-12)

    # The two plane samples around ν₀ carry the closed-form value, to float32 accuracy.
    sigma, h = np.pi * (k - 1), 1.0 / plan_l
    end_value = 2.0 * n * np.cos(sigma * h / 2)
    b, a = np.argwhere(plan.column == p0)[0]
    np.testing.assert_allclose(work.amp[b, [r0, r0 + 1], a], end_value, rtol=1e-6)

    # Each sample excludes the open interval of half-width (arccos(r/m) - α₀)/σ around it. The
    # maximum, h/2 away, lies outside by exactly α₀/σ = 1/(2 K_DFT) cycles per chirp: half a
    # Doppler bin, c/(4 f_c T_c K_DFT) in radial velocity. Tolerance 1e-12 cycles per chirp.
    reach = gridscreen._exclusion(np.array([end_value]), 2.0 * n, 0.0, plan)[0]
    assert plan.alpha0 / sigma == pytest.approx(1.0 / (2 * k_dft), rel=1e-12)
    assert h / 2 - reach == pytest.approx(1.0 / (2 * k_dft), abs=1e-12)
    half_bin_speed = SPEED_OF_LIGHT / (4 * radar.carrier_frequency * radar.chirp_interval * k_dft)  # [m/s]
    assert (h / 2 - reach) * SPEED_OF_LIGHT / (2 * radar.carrier_frequency * radar.chirp_interval) == \
        pytest.approx(half_bin_speed, rel=1e-9)
    # Without the grid allowance α₀ the maximum would sit exactly on the excluded interval's edge:
    # no reach shorter than Szegő's would still be a bound (tolerance 1e-12 cycles per chirp).
    assert reach + plan.alpha0 / sigma == pytest.approx(h / 2, abs=1e-12)
    # The two-end test keeps the interval with one grid bin to spare (2α₀/σ = 1/K_DFT cycles).
    assert h - 2 * reach == pytest.approx(1.0 / k_dft, abs=1e-12)


@pytest.mark.parametrize("stronger", [0, 1])
def test_float64_decides_below_the_complex64_slack(make_radar, make_processing, stronger):
    # Two equal unit returns on grid cells far apart whose powers differ by 2e-7 relative: far
    # below the complex64 stage's slack (≈1e-5·‖x‖₁), far above float64 rounding (1e-13). Both
    # stay candidates and the float64 values pick the stronger, as the full grid does.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    k, n = 16, 64
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    cells = [(5, 20), (50, 90)]  # (q, p)
    amps = [1.0, 1.0]
    amps[stronger] *= 1 + 1e-7
    y = sum(a * np.exp(-2j * np.pi * (q * kk / processing.k_dft + p * nn / processing.n_dft))
            for a, (q, p) in zip(amps, cells))
    w_k, w_n, _ = dft_windows(radar, processing)
    q, p, value, plan, _ = _dense(y, processing, w_k, w_n)
    full = _full_grid(y, w_k, w_n, processing.n_dft, processing.k_dft)
    assert (q, p) == cells[stronger] == full[:2]
    assert value == pytest.approx(full[2], rel=1e-12)
    # The difference is indeed below what complex64 could resolve.
    l1 = float(np.abs(y * np.outer(w_k, w_n)).sum())
    assert 1e-7 * np.sqrt(full[2]) < plan.err_grid * l1


@pytest.mark.parametrize("n_dft", [127, 128, 150])  # prime (one product), 8·16 and 10·15 (P₂ even, odd)
@pytest.mark.parametrize("window", ["hann", "hamming", "boxcar", "blackman"])
def test_noise_only_beams_give_the_full_grid_answer(make_radar, make_processing, window, n_dft):
    # 25 beams per window of noise only, or noise with a return below it per sample, with and
    # without min_range: the dense search's cell is the full grid's, its value equal to 1e-12.
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=n_dft, k_dft=67, window=window)
    for plan in _noise_beams_match_the_full_grid(radar, processing, np.random.default_rng(sum(map(ord, window))), 25):
        assert plan.p1 * plan.p2 == n_dft


def _noise_beams_match_the_full_grid(radar, processing, rng, trials):
    """``trials`` beams of noise, every other one with a return below the noise per sample, a third of them with
    min_range: each dense search's cell is the float64 full grid's, its value equal to 1e-12. Yields each plan."""
    k, n = radar.num_chirps, radar.num_samples
    w_k, w_n, _ = dft_windows(radar, processing)
    kk, nn = np.arange(k)[:, None], np.arange(n)[None, :]
    for trial in range(trials):
        y = add_noise(np.zeros((k, n), complex), 1.0, rng)
        if trial % 2:
            f2, f1 = rng.uniform(0, 1, 2)
            y += 10 ** (-rng.uniform(0, 15) / 20) * np.exp(2j * np.pi * (kk * f2 + nn * f1))
        first = 0 if trial % 3 else int(rng.integers(1, n - 4))
        q, p, value, plan, _ = _dense(y, processing, w_k, w_n, first)
        fq, fp, fvalue = _full_grid(y, w_k, w_n, processing.n_dft, processing.k_dft, first)
        assert (q, p) == (fq, fp)
        assert value == pytest.approx(fvalue, rel=1e-12)
        yield plan


def test_table1_noise_only_beams_and_the_error_bounds(make_radar, make_processing):
    # Table I sizes (K = 128, N = 600, N_DFT = 1199 = 11·109, K_DFT = 4793): two noise-only beams
    # and one with a return 30 dB above the noise (a large dynamic range for float32). The cell
    # is the full grid's; the complex64 plane and range transform stay inside their slack
    # (float64 transforms as the oracle), which is far below the noise maximum.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    w_k, w_n, _ = dft_windows(radar, processing)
    rng = np.random.default_rng(11)
    kk, nn = np.arange(128)[:, None], np.arange(600)[None, :]
    beams = [add_noise(np.zeros((128, 600), complex), 1.0, rng) for _ in range(2)]
    beams.append(add_noise(31.6 * np.exp(2j * np.pi * (0.137 * kk + 0.311 * nn)), 1.0, rng))
    for y in beams:
        q, p, value, plan, work = _dense(y, processing, w_k, w_n)
        fq, fp, fvalue = _full_grid(y, w_k, w_n, 1199, 4793)
        assert (q, p) == (fq, fp)
        assert value == pytest.approx(fvalue, rel=1e-12)
        x = y * np.outer(w_k, w_n)
        l1 = float(np.abs(x).sum())
        a64 = np.fft.ifft(x, n=1199, axis=1) * 1199  # [K, N_DFT]
        a32 = work.a.transpose(1, 0, 2).reshape(128, -1)[:, np.argsort(plan.column.ravel())]
        plane64 = np.abs(np.fft.ifft(a64, n=plan.length, axis=0) * plan.length)
        plane32 = work.amp.transpose(1, 0, 2).reshape(plan.length, -1)[:, np.argsort(plan.column.ravel())]
        err_a = np.abs(a32 - a64).sum(axis=0).max()  # Σ_k |Δa_k(p)|: what a grid value inherits
        err_plane = np.abs(plane32 - plane64).max()
        assert err_a <= plan.err_grid / 2 * l1
        assert err_plane <= plan.err_plane / 2 * l1
        assert plan.err_plane * l1 < 1e-2 * np.sqrt(fvalue)  # the slack: < 1 % of the maximum


def test_zero_and_subnormal_beams(make_radar, make_processing):
    # All zero: every cell ties at 0 and the first searchable one wins, as in the full search.
    # Amplitudes of 1e-40 are subnormal in float32: the float64 grid decides (same cell).
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=127, k_dft=67)
    w_k, w_n, _ = dft_windows(radar, processing)
    assert _dense(np.zeros((16, 64), complex), processing, w_k, w_n, 5)[:3] == (0, 5, 0.0)
    rng = np.random.default_rng(4)
    y = 1e-40 * add_noise(np.zeros((16, 64), complex), 1.0, rng)
    q, p, value, *_ = _dense(y, processing, w_k, w_n)
    fq, fp, fvalue = _full_grid(y, w_k, w_n, 127, 67)
    assert (q, p) == (fq, fp) and value == pytest.approx(fvalue, rel=1e-12)


def test_noise_only_beams_are_routed_to_the_dense_search(make_radar, make_processing, monkeypatch):
    # Table I sizes: noise-only beams go to the dense search (early), beams with a return above
    # the per-chirp noise stay with the screen; every cell is the full search's either way.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    rng = np.random.default_rng(5)
    kk, nn = np.arange(128)[:, None], np.arange(600)[None, :]
    cube = np.stack([add_noise(np.zeros((128, 600), complex), 1.0, rng),
                     add_noise(3.0 * np.exp(2j * np.pi * (0.21 * kk + 0.4 * nn)), 1.0, rng),
                     add_noise(np.zeros((128, 600), complex), 1.0, rng)])
    dense = []
    original = gridscreen._dense_beam
    monkeypatch.setattr(gridscreen, "_dense_beam", lambda *a: dense.append(1) or original(*a))
    sweep = BeamSweep(np.zeros((3, 2)))
    zoom = scan_beams(cube, sweep, radar, processing)
    assert len(dense) == 2
    w_k, w_n, gain = dft_windows(radar, processing)
    for m in range(3):
        fq, fp, fvalue = _full_grid(cube[m], w_k, w_n, 1199, 4793)
        assert (int(zoom.doppler_bin[m]), int(zoom.delay_bin[m])) == (fq, fp)
        assert zoom.peak_power[m] == pytest.approx(fvalue / gain**2, rel=1e-12)


def test_one_chirp_has_no_doppler_to_search(make_radar, make_processing):
    # K = 1: every Doppler bin of a column holds the same value (σ = 0), so the first, q = 0, wins
    # in the full search's order and the delay bin is the range spectrum's maximum.
    radar = make_radar(num_samples=32, num_chirps=1)
    processing = make_processing(radar, n_dft=63, k_dft=5, window="boxcar")
    w_k, w_n, _ = dft_windows(radar, processing)
    y = add_noise(np.zeros((1, 32), complex), 1.0, np.random.default_rng(8))
    q, p, value, *_ = _dense(y, processing, w_k, w_n)
    assert (q, p) == _full_grid(y, w_k, w_n, 63, 5)[:2]
    assert q == 0


def test_a_glitch_in_one_sample_goes_to_the_whole_grid(make_radar, make_processing, glitch_beams, monkeypatch):
    # Regression: a beam whose energy is in one ADC sample (a glitch) has |z| flat over the whole grid,
    # so Szegő's bound rules nothing out and ~K_DFT·N_DFT candidate bins were evaluated (Table I: 7.3 s
    # and 4.6 GB per beam). Such a beam is now searched on its whole float64 grid
    # (gridscreen.whole_grid_bins), with the full search's cell. A beam whose energy is in one chirp
    # (an interference burst) is flat in Doppler only near its delay: it stays with the bounded search.
    radar = make_radar(num_samples=600, num_chirps=128)
    processing = make_processing(radar, n_dft=1199, k_dft=4793)
    cube = glitch_beams(np.random.default_rng(12))
    whole = []
    original = gridscreen._full_beam
    monkeypatch.setattr(gridscreen, "_full_beam", lambda *a: whole.append(1) or original(*a))
    zoom = scan_beams(cube, BeamSweep(np.zeros((2, 2))), radar, processing)
    assert len(whole) == 1  # the impulse
    w_k, w_n, gain = dft_windows(radar, processing)
    for m in range(2):
        fq, fp, fvalue = _full_grid(cube[m], w_k, w_n, 1199, 4793)
        assert (int(zoom.doppler_bin[m]), int(zoom.delay_bin[m])) == (fq, fp)
        assert zoom.peak_power[m] == pytest.approx(fvalue / gain**2, rel=1e-12)


@pytest.mark.parametrize("scale", [1.0, 1e6])
def test_gated_columns_never_win_at_any_scale(make_radar, make_processing, scale):
    # Regression (found by tests/dsp/test_grid_search_property.py): on a Doppler grid as coarse as
    # K_DFT = K the exclusion reaches past π/2, so the candidate threshold T·cos(·) is 0 less the slack;
    # the plane's columns inside min_range were marked -1, which passed it once the float32 slack
    # exceeded 1 (here at amplitude 1e6: slack ≈ 5e-6·‖x‖₁ ≈ 40), and such a column won. They are now -inf.
    # Boxcar, N = 2, N_DFT = 2: delay column 0 is y₀ + y₁, column 1 is y₀ - y₁. With y₁ = y₀(1 - 10⁻³e^{jφ})
    # nearly all the energy is in column 0, which min_range excludes: the maximum is in column 1.
    radar = make_radar(num_samples=2, num_chirps=4)
    processing = make_processing(radar, n_dft=2, k_dft=4, min_range=0.2 * radar.max_range, window="boxcar")
    w_k, w_n, _ = dft_windows(radar, processing)
    rng = np.random.default_rng(3)
    y0 = scale * (rng.standard_normal(4) + 1j * rng.standard_normal(4))
    y = np.stack([y0, y0 * (1 - 1e-3 * np.exp(2j * np.pi * rng.uniform(size=4)))], axis=1)  # [K, N]
    first = 1
    q, p, value, *_ = _dense(y, processing, w_k, w_n, first=first)
    fq, fp, fvalue = _full_grid(y, w_k, w_n, 2, 4, first=first)
    assert fp == first and (q, p) == (fq, fp)
    assert value == pytest.approx(fvalue, rel=1e-12)


@pytest.mark.parametrize("n_dft", [127, 150])
def test_the_plain_dft_split_gives_the_full_grid_answer(make_radar, make_processing, monkeypatch, n_dft):
    # P₁ = 1, P₂ = N_DFT: stage 1 is the whole N_DFT x N DFT matrix and stage 2 a unit twiddle (the split a
    # prime N_DFT gets when its own, P₁ = N_DFT, would not fit DENSE_PLAN_BYTES). Its cell is the full grid's.
    monkeypatch.setattr(gridscreen, "_dense_split", lambda n, n_dft: 1)
    radar = make_radar(num_samples=64, num_chirps=16)
    processing = make_processing(radar, n_dft=n_dft, k_dft=67, window="hann")
    for plan in _noise_beams_match_the_full_grid(radar, processing, np.random.default_rng(n_dft), 12):
        assert (plan.p1, plan.p2) == (1, n_dft)


def test_a_prime_dft_length_builds_its_plan_within_the_table_budget(make_radar, make_processing):
    """Regression (benchmarks/fuzz.py, declared sizes, seed 2611): a capture declaring N_DFT = 13 763 (prime) on
    K = 8, N = 32. The split P₁ = N_DFT built a 13 763² stage-2 table and its complex128 factors: 7.2 GB, past
    the 512 MiB limit the fuzzer sets. P₁ = 1 now; the noise beam's cell is still the full grid's."""
    import tracemalloc

    radar = make_radar(num_samples=32, num_chirps=8)
    processing = make_processing(radar, n_dft=13_763, k_dft=38, window="hann")
    w_k, w_n, _ = dft_windows(radar, processing)
    y = add_noise(np.zeros((8, 32), complex), 1.0, np.random.default_rng(4))
    tracemalloc.start()
    try:
        q, p, value, plan, _ = _dense(y, processing, w_k, w_n)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert plan.p1 == 1 and peak < gridscreen.DENSE_PLAN_BYTES + 32 * 2**20, f"{peak / 2**20:.0f} MiB"
    fq, fp, fvalue = _full_grid(y, w_k, w_n, 13_763, 38)
    assert (q, p) == (fq, fp)
    assert value == pytest.approx(fvalue, rel=1e-12)


def test_a_prime_dft_length_whose_smallest_tables_exceed_the_limit_is_one_line(monkeypatch):
    # N_DFT = 100 003 (prime) on N = 600 samples: no split fits DENSE_PLAN_BYTES, and the smallest (P₁ = 1, an
    # N_DFT x N matrix: 805 MiB while it is built) exceeds a 512 MiB limit. A BudgetError naming n_dft, before any
    # table is allocated.
    import tracemalloc

    from dsp.budget import BudgetError

    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "512M")  # the documented variable, written out
    tracemalloc.start()
    try:
        with pytest.raises(BudgetError, match=r"processing\.n_dft=100003 .* needs about") as err:
            gridscreen._DensePlan(2, 600, 100_003, 8)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "\n" not in str(err.value) and peak < 2**20
    # the premise, counted by hand: P₁ = 1's stage-1 table alone, (N_DFT // 2 + 1) x N cells of an int64 phase index
    # and float64 cos and sin, is 720 MB > 512 MiB
    assert (100_003 // 2 + 1) * 600 * (8 + 8 + 8) > 512 * 2**20 > gridscreen.DENSE_PLAN_BYTES
