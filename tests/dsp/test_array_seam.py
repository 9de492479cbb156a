"""The array seam (dsp/xp.py) and the batched detector (dsp.detect_batch) on NumPy and on array_api_strict.

Issue 21: the detector's whole-cube work and the receiver noise are written once against the array
API standard; CI has no GPU, so the device-generic code is proven on ``array_api_strict``, whose
virtual ``device1`` refuses anything outside the standard and every implicit host copy.

Oracles:

- the statistic of the sweep-CFAR written out in float64 with NumPy (the half-bin 2-D DFT of every
  beam, D = Σ_m |X_m - X̄|², its best beam window, the noise from the median of D over all cells,
  the candidates as the 3 × 3 local maxima above η, strongest first): both backends must give it
  within the precision ``detect_batch`` states — "with oversample=2 ... a cell's statistic is within
  ~1e-6 relative of its float64 value" (complex64 transforms, float64 running sums); the DFT bins
  (oversample 1) are computed in double and must agree to double precision;
- the two backends against each other: the same decisions (detected, cell, candidate cells in the
  same order, rejections) and the numbers within twice that precision (each is within it of the
  float64 value);
- NumPy's batch against single realizations: bit for bit (every step is elementwise or reduces along
  one realization's own axes);
- the receiver noise: its power σ² within the sampling error of its mean square;
- the memory estimate of the detector (dsp.budget.detect_memory) against the peak that tracemalloc
  sees NumPy allocate.

The cubes are study points of Table I's RF parameters and geometry (the paper's RIS, 13.38 m, the
relay RIS with its structural reflection) on a smaller radar and sweep — K = 16 chirps, N = 128
samples, 31 beams (±45° in 3° steps) — so each comparison takes a fraction of a second.
"""

from __future__ import annotations

import sys
import tracemalloc

import numpy as np
import pytest
import scipy.special

import dsp
from dsp import SPEED_OF_LIGHT, DeviceError, backend_for, cuda_available, numpy_backend, strict_backend
from dsp.budget import DEVICE_BATCH, HOST_BATCH, MEMORY_LIMIT_ENV, detect_batch_size, detect_memory
from dsp.sweep_window import sweep_windows
from risloc_rt.model import add_noise
from risloc_rt.model.beat import add_noise_batch
from risloc_rt.studies.kernel import prepare_point, run_rng
from risloc_rt.studies.params import complete_point

#: The documented environment variable (README), written out: a rename in the code must fail these tests.
DEVICE_ENV = "RISLOC_DEVICE"

#: The precision ``detect_batch`` states for its half-bin (complex64) statistic: ~1e-6 relative to the
#: float64 value. "~": a factor of 2 is allowed against float64; two backends, each within 1e-6 of it,
#: differ by at most 2e-6.
HALF_BIN_PRECISION = 1e-6
#: The DFT bins (oversample 1) are complex128 throughout: both backends agree to double precision
#: (a few hundred ulps over transforms of 2K·2N points and sums over M beams).
DFT_BIN_PRECISION = 1e-12

#: Table I's radar and geometry on a smaller cube: 31 beams × 16 chirps × 128 samples.
SMALL = {"num_chirps": 16, "num_samples": 128, "n_dft": 255, "k_dft": 64, "sweep_step_deg": 3.0}
#: Realizations per batch.
BATCH = 8

#: (name, transmit power [dBm] or None for noise alone, P_FA per capture)
CASES = {
    # post-integration SNR ~12 dB: the windowed statistic lands within a few dB of η, some runs detect, some not
    "near-threshold": (10.0, 1e-3),
    # ~32 dB: every run detects, the side lobes of the return are candidates too
    "high-snr": (30.0, 1e-3),
    # noise alone at 1e-3: nothing crosses η
    "noise-only": (None, 1e-3),
    # noise alone at P_FA = 0.9: several local maxima cross η, the sweep-modulation test orders and rejects them
    "noise-many-candidates": (None, 0.9),
}
#: (name, windowed by the beam pattern, oversample)
CONFIGS = {
    "windowed-half-bins": (True, 2),  # what a study runs
    "whole-sweep-dft-bins": (False, 1),
    "whole-sweep-half-bins": (False, 2),
}


@pytest.fixture(scope="module")
def points():
    """Prepared small Table I points by transmit power (noiseless cubes, shared by every run)."""
    return {p: prepare_point(complete_point({**SMALL, "tx_power_dbm": p, "estimator": "refined"}))
            for p in (10.0, 30.0)}


def noisy_cubes(prep, power, count=BATCH, seed=21):
    """``count`` noisy cubes [B, M, K, N] of the point (noise alone when ``power`` is None), run r's noise from run_rng."""
    clean = prep.cube if power is not None else np.zeros_like(prep.cube)
    return add_noise_batch(clean, prep.radar.noise_power, [run_rng(seed, 0, r) for r in range(count)])


def detector_options(prep, *, windowed, oversample, pfa):
    return dict(pfa=pfa, min_range=prep.processing.min_range, max_candidates=5,
                pattern=prep.pattern if windowed else None, sweep=prep.sweep if windowed else None,
                oversample=oversample)


def float64_reference(cube, prep, *, windowed, oversample, pfa, count=5):
    """The sweep-CFAR of one cube written out in float64 (docs/estimation.md, module notes of dsp/detection.py).

    Returns
    -------
    stat : float array [Kₒ, Nₒ]
        D (or its best window) over σ̂²_cell; -inf at delay bins nearer than min_range.
    noise_power : float
        σ̂² per beat sample [W]: median of D over all cells / median of Gamma(M-1, 1) / (K N).
    eta : float
    candidates : list of int
        Flat cells of the ``count`` strongest 3 × 3 (wrapping) local maxima at or above η.
    """
    radar = prep.radar
    m, k, n = cube.shape
    ko, no = k * oversample, n * oversample
    # Σ_k Σ_n y e^{+j2π(qk/Kₒ + pn/Nₒ)}: numpy's ifft with norm="forward" does not divide by the length
    x = np.fft.ifft(np.fft.ifft(cube, n=ko, axis=1, norm="forward"), n=no, axis=2, norm="forward")
    energy = np.abs(x - x.mean(axis=0)) ** 2  # [M, Kₒ, Nₒ]
    d = energy.sum(axis=0)
    cell_noise = float(np.median(d)) / float(scipy.special.gammaincinv(m - 1, 0.5))
    first = int(np.searchsorted(np.arange(no) / no,
                                2.0 * prep.processing.min_range / SPEED_OF_LIGHT * radar.slope * radar.sample_period))
    cell_pfa = -np.expm1(np.log1p(-pfa) / (ko * (no - first)))
    if windowed:
        windows = sweep_windows(prep.pattern.for_wavelength(radar.wavelength), prep.sweep, cell_pfa=cell_pfa)
        raw = energy[windows.beams].sum(axis=1).max(axis=0)  # [G, L, Kₒ, Nₒ] -> best window per cell
        eta = windows.threshold(cell_pfa)
    else:
        raw = d
        eta = float(scipy.special.gammainccinv(m - 1, cell_pfa))
    stat = raw / cell_noise
    stat[:, :first] = -np.inf
    local = stat >= eta
    for dq in (-1, 0, 1):
        for dp in (-1, 0, 1):
            if dq or dp:
                local &= stat >= np.roll(stat, (dq, dp), axis=(0, 1))
    flat = np.where(local, stat, -np.inf).ravel()
    order = np.argsort(-flat, kind="stable")[:count]  # strongest first, equal values: the lower cell first
    candidates = [int(c) for c in order if np.isfinite(flat[c])]
    return stat, cell_noise / (k * n), eta, candidates


# ---------------------------------------------------------------------------------------------- strict


def test_strict_device_refuses_an_implicit_host_copy():
    """The premise of every strict test below: an array on 'device1' cannot become a NumPy array
    behind the code's back, only through the explicit ArrayBackend.to_host."""
    backend = strict_backend("device1")
    x = backend.asarray(np.arange(6.0))
    with pytest.raises((RuntimeError, TypeError, ValueError)):
        np.asarray(x)
    with pytest.raises((RuntimeError, TypeError, ValueError)):
        np.array(x) + 1.0
    np.testing.assert_array_equal(backend.to_host(x), np.arange(6.0))


@pytest.mark.parametrize("config", list(CONFIGS))
@pytest.mark.parametrize("case", list(CASES))
def test_detect_batch_strict_equals_numpy_and_float64(points, case, config, monkeypatch, detect_with_candidates):
    """Same decisions on array_api_strict ('device1') as on NumPy; the numbers within the stated precision
    of each other and of the float64 sweep-CFAR."""
    power, pfa = CASES[case]
    windowed, oversample = CONFIGS[config]
    prep = points[10.0 if power is None else power]
    cubes = noisy_cubes(prep, power)
    options = detector_options(prep, windowed=windowed, oversample=oversample, pfa=pfa)
    rtol = HALF_BIN_PRECISION if oversample == 2 else DFT_BIN_PRECISION

    ref_dets, ref_cells, ref_stats = detect_with_candidates(cubes, prep, numpy_backend(), options, monkeypatch)
    dets, cells, stats = detect_with_candidates(cubes, prep, strict_backend("device1"), options, monkeypatch)

    # the case is what it claims to be
    detected = [d.detected for d in ref_dets]
    if case == "near-threshold":
        assert any(detected) and not all(detected), detected
        assert min(abs(d.snr_db - d.threshold_db) for d in ref_dets) < 3.0
    elif case == "high-snr":
        assert all(detected) and all(d.snr_db > d.threshold_db + 10.0 for d in ref_dets)
    elif case == "noise-only":
        assert not any(detected) and all(d.statistic < d.threshold for d in ref_dets)
    else:
        assert (ref_cells >= 0).sum() > len(ref_dets), "some realization must have several candidates"

    for i, (a, b) in enumerate(zip(ref_dets, dets)):
        where = f"realization {i}"
        # decisions: identical
        assert (b.detected, b.cell, b.rejected, b.beam_dependent) == (a.detected, a.cell, a.rejected,
                                                                        a.beam_dependent), where
        np.testing.assert_array_equal(cells[i], ref_cells[i], err_msg=f"{where}: candidate cells and order")
        assert (b.threshold, b.threshold_db, b.num_cells, b.integrated_beams) == \
               (a.threshold, a.threshold_db, a.num_cells, a.integrated_beams), where
        # the cell's delay and rate follow from the cell alone
        np.testing.assert_array_equal([b.delay, b.delay_rate], [a.delay, a.delay_rate], err_msg=where)
        # numbers: each backend within the precision of the float64 value, so within twice of each other
        assert b.statistic == pytest.approx(a.statistic, rel=2 * rtol), where
        assert b.noise_power == pytest.approx(a.noise_power, rel=2 * rtol), where
        dof = a.integrated_beams  # snr_db = 10 log10(D - dof): its error is 10/ln10 · ΔD/(D - dof)
        if a.statistic > dof:
            snr_tol = 10 / np.log(10) * 2 * rtol * a.statistic / (a.statistic - dof)
            assert abs(b.snr_db - a.snr_db) <= snr_tol, where
        finite = np.isfinite(ref_stats[i])
        np.testing.assert_array_equal(np.isfinite(stats[i]), finite, err_msg=where)
        np.testing.assert_allclose(stats[i][finite], ref_stats[i][finite], rtol=2 * rtol, err_msg=where)
        # P_m = |X_m|²/σ̂²: the transform's rounding is relative to its input's norm (a cell's noise), so
        # the beam powers agree within the precision in noise units as well as relatively
        assert b.beam_power.shape == a.beam_power.shape, where
        np.testing.assert_allclose(b.beam_power, a.beam_power, rtol=2 * rtol, atol=2 * rtol, err_msg=where)

        stat64, noise64, eta64, cand64 = float64_reference(cubes[i], prep, windowed=windowed, oversample=oversample,
                                                           pfa=pfa)
        assert a.threshold == pytest.approx(eta64, rel=1e-12), where
        assert [int(c) for c in ref_cells[i] if c >= 0] == cand64, f"{where}: the local maxima above η, strongest first"
        for det, cand_stats in ((a, ref_stats[i]), (b, stats[i])):
            assert det.noise_power == pytest.approx(noise64, rel=2 * rtol), where
            assert cand_stats[finite] == pytest.approx(stat64.ravel()[cand64], rel=2 * rtol), where
            expected = stat64[det.cell] if det.cell[0] >= 0 else stat64.max()
            assert det.statistic == pytest.approx(expected, rel=2 * rtol), where


@pytest.mark.parametrize("count", [3, 5])
def test_strict_any_batch_size(points, count):
    """Any batch size works on a strict namespace: B = 3 and 5, whose host cell blocks (4096 // B cells) do not
    divide the 4·16·128 = 8192 half-bin cells — a last, partial block that must not be sliced past the end
    (an out-of-range slice stop is outside the array API: array_api_strict refuses it)."""
    prep = points[10.0]
    cubes = noisy_cubes(prep, 10.0, count=count)
    options = detector_options(prep, windowed=True, oversample=2, pfa=1e-3)
    backend = strict_backend("device1")
    ref = dsp.detect_batch(cubes, prep.radar, **options)
    got = dsp.detect_batch(backend.asarray(cubes), prep.radar, backend=backend, **options)
    assert [(d.detected, d.cell, d.rejected) for d in got] == [(d.detected, d.cell, d.rejected) for d in ref]
    assert [d.statistic for d in got] == pytest.approx([d.statistic for d in ref], rel=2 * HALF_BIN_PRECISION)
    assert [d.noise_power for d in got] == pytest.approx([d.noise_power for d in ref], rel=2 * HALF_BIN_PRECISION)


@pytest.mark.parametrize("config", ["windowed-half-bins", "whole-sweep-dft-bins"])
def test_numpy_batch_equals_single_realizations(points, config):
    """On NumPy a realization's Detection does not depend on the batch it is in: bit for bit against
    detect_batch of that realization alone and against the public dsp.detect."""
    windowed, oversample = CONFIGS[config]
    prep = points[10.0]
    cubes = noisy_cubes(prep, 10.0, count=5)  # 5: the last cell block of the batch is a partial one
    options = detector_options(prep, windowed=windowed, oversample=oversample, pfa=1e-3)
    batch = dsp.detect_batch(cubes, prep.radar, **options)
    assert any(d.detected for d in batch)
    for i in range(cubes.shape[0]):
        alone = dsp.detect_batch(cubes[i:i + 1], prep.radar, **options)[0]
        public = dsp.detect(cubes[i], prep.radar, **options)
        assert batch[i] == alone, f"realization {i}"
        assert batch[i] == public, f"realization {i}"


# ----------------------------------------------------------------------------------- receiver noise


def test_add_noise_batch_strict_equals_numpy_and_single_runs(points):
    """The host backends draw each copy as add_noise(stream="fast") on its own stream: bit for bit, whatever
    the batch; strict receives that batch by one explicit copy. The noise has power σ²."""
    prep = points[10.0]
    rngs = lambda: [run_rng(3, 1, r) for r in range(4)]  # noqa: E731 - fresh generators for each draw
    host = add_noise_batch(prep.cube, prep.radar.noise_power, rngs())
    backend = strict_backend("device1")
    on_device = add_noise_batch(prep.cube, prep.radar.noise_power, rngs(), backend=backend)
    assert on_device.shape == host.shape
    np.testing.assert_array_equal(backend.to_host(on_device), host)
    for i, rng in enumerate(rngs()):
        np.testing.assert_array_equal(host[i], add_noise(prep.cube, prep.radar.noise_power, rng, stream="fast"))
    # E|w|² = σ²; the mean square of n samples of |w|² (exponential: sd = mean) has relative sd 1/√n
    w = host - prep.cube
    assert np.mean(np.abs(w) ** 2) == pytest.approx(prep.radar.noise_power, rel=5 / np.sqrt(w.size))
    # independent copies: the correlation of two copies' noise is within 5/√n of 0
    assert abs(np.vdot(w[0], w[1])) / np.sqrt(np.vdot(w[0], w[0]).real * np.vdot(w[1], w[1]).real) < 5 / np.sqrt(w[0].size)


# ------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize("bad, match", [
    ({"cubes": "3d"}, r"\[B, M, K, N\]"),
    ({"cubes": "5d"}, r"\[B, M, K, N\]"),
    ({"sweep": "other"}, r"31 beams but the sweep has 61 angles"),
    ({"pfa": 0.0}, r"pfa"),
    ({"pfa": 1.0}, r"pfa"),
    ({"pfa": -0.1}, r"pfa"),
    ({"pfa": float("nan")}, r"pfa"),
    ({"pfa": "1e-3"}, r"pfa"),
    ({"oversample": 3}, r"oversample"),
    ({"pattern_only": True}, r"pattern and sweep"),
    ({"min_range": 1e3}, r"min_range"),
])
def test_detect_batch_input_errors_are_one_line(points, bad, match):
    prep = points[10.0]
    cubes = noisy_cubes(prep, 10.0, count=1)
    options = detector_options(prep, windowed=True, oversample=2, pfa=1e-3)
    if bad.get("cubes") == "3d":
        cubes = cubes[0]
    elif bad.get("cubes") == "5d":
        cubes = cubes[None]
    if bad.get("sweep") == "other":
        options["sweep"] = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    if bad.get("pattern_only"):
        options["sweep"] = None
    for key in ("pfa", "oversample", "min_range"):
        if key in bad:
            options[key] = bad[key]
    with pytest.raises(ValueError, match=match) as err:
        dsp.detect_batch(cubes, prep.radar, **options)
    assert "\n" not in str(err.value)


# --------------------------------------------------------------------------------------- backends


@pytest.fixture
def no_cupy(monkeypatch):
    """This process without CuPy (``import cupy`` raises ImportError), whatever is installed."""
    monkeypatch.setitem(sys.modules, "cupy", None)
    monkeypatch.delenv(DEVICE_ENV, raising=False)
    ok, why = cuda_available()
    assert not ok and "CuPy" in why
    return why


def test_cpu_is_numpy(monkeypatch):
    monkeypatch.delenv(DEVICE_ENV, raising=False)
    for choice in ("cpu", "CPU", None):  # None: $RISLOC_DEVICE unset -> cpu
        backend = backend_for(choice)
        assert backend.name == "numpy" and backend.is_numpy
        assert isinstance(backend.asarray([1.0, 2.0]), np.ndarray)


def test_auto_without_cupy_is_numpy(no_cupy, monkeypatch):
    assert backend_for("auto").is_numpy
    monkeypatch.setenv(DEVICE_ENV, "auto")
    assert backend_for().is_numpy


def test_cuda_without_cupy_says_how_to_fix_it(no_cupy, monkeypatch):
    with pytest.raises(DeviceError) as err:
        backend_for("cuda")
    msg = str(err.value)
    assert "\n" not in msg
    assert "CuPy" in msg and "--device cpu" in msg
    assert "setup.sh --gpu" in msg or "[gpu]" in msg  # how to get CuPy
    monkeypatch.setenv(DEVICE_ENV, "cuda")
    with pytest.raises(DeviceError, match=r"\$RISLOC_DEVICE") as err:
        backend_for()
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("name", ["tpu", "gpu", "", "cuda:0"])
def test_unknown_device_names_the_choices(name):
    with pytest.raises(DeviceError) as err:
        backend_for(name)
    msg = str(err.value)
    assert "\n" not in msg and repr(name) in msg and "device" in msg
    assert all(choice in msg for choice in ("cpu", "cuda", "auto"))


@pytest.mark.parametrize("value", ["gpu", "numpy", "cuda0"])
def test_bad_environment_variable_is_named(monkeypatch, value):
    monkeypatch.setenv(DEVICE_ENV, value)
    with pytest.raises(DeviceError) as err:
        backend_for()
    msg = str(err.value)
    assert "\n" not in msg and f"${DEVICE_ENV}" in msg and repr(value) in msg
    assert backend_for("cpu").is_numpy  # an explicit choice does not read the variable


def test_device_error_is_a_value_error():
    assert issubclass(DeviceError, ValueError)


@pytest.mark.parametrize("length", [1, 2, 7, 8])
@pytest.mark.parametrize("axis", [0, 1, -1])
def test_strict_median_equals_numpy_median(length, axis):
    """The strict namespace has no median: a sort and the mean of the two middle values (even counts)."""
    rng = np.random.default_rng(length)
    shape = [3, 5, 4]
    shape[axis] = length
    x = rng.standard_normal(shape)
    x.flat[::7] = 0.25  # repeated values
    backend = strict_backend("device1")
    got = backend.to_host(backend.median(backend.asarray(x), axis=axis))
    np.testing.assert_array_equal(got, np.median(x, axis=axis))
    np.testing.assert_array_equal(numpy_backend().median(x, axis=axis), np.median(x, axis=axis))


# ------------------------------------------------------------------------------------------ budget


TABLE_I_SHAPE = (61, 128, 600)


def test_detect_batch_size_respects_the_memory_limit(monkeypatch):
    one = detect_memory(TABLE_I_SHAPE, whole_cells=False)
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "1K")  # less than one realization: still one at a time
    assert detect_batch_size(TABLE_I_SHAPE) == 1
    for b in range(1, HOST_BATCH + 1):  # exactly b realizations fit: b of them, never more than the limit allows
        monkeypatch.setenv(MEMORY_LIMIT_ENV, str(b * one + one // 2))
        assert detect_batch_size(TABLE_I_SHAPE) == b
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "1T")  # room for many: the host's cap
    assert detect_batch_size(TABLE_I_SHAPE) == HOST_BATCH


def test_detect_batch_size_caps_at_the_runs(monkeypatch):
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "1T")
    assert [detect_batch_size(TABLE_I_SHAPE, runs=r) for r in (1, 2, 3, 100)] == [min(r, HOST_BATCH) for r in (1, 2, 3, 100)]
    assert detect_batch_size(TABLE_I_SHAPE, free_bytes=1 << 50, runs=5) == 5


def test_detect_batch_size_on_a_gpu_uses_its_free_memory():
    one = detect_memory(TABLE_I_SHAPE, whole_cells=True)
    # 80 % of the free memory is used: 5 realizations fit in free = 5.5 · one / 0.8
    assert detect_batch_size(TABLE_I_SHAPE, free_bytes=int(5.5 * one / 0.8)) == 5
    assert detect_batch_size(TABLE_I_SHAPE, free_bytes=int(0.5 * one)) == 1
    assert detect_batch_size(TABLE_I_SHAPE, free_bytes=1 << 50) == DEVICE_BATCH
    # the whole-cell statistics (M + 1 running sums of every cell) cost more per realization than the host's blocks
    assert one > detect_memory(TABLE_I_SHAPE, whole_cells=False)


def test_detect_memory_bounds_what_numpy_allocates():
    """The estimate per realization is an upper bound of the detector's peak: what tracemalloc sees NumPy
    allocate (the noisy cubes included) stays below B × detect_memory, and above the cubes themselves."""
    prep = prepare_point(complete_point({"num_chirps": 32, "num_samples": 256, "n_dft": 511, "k_dft": 128,
                                         "tx_power_dbm": 10.0}))
    b = 2
    options = detector_options(prep, windowed=True, oversample=2, pfa=1e-3)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        cubes = noisy_cubes(prep, 10.0, count=b)
        dsp.detect_batch(cubes, prep.radar, **options)
        peak = tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()
    estimate = b * detect_memory(prep.cube.shape, whole_cells=False)
    assert cubes.nbytes < peak <= estimate, (peak, estimate)


def test_a_cupy_array_is_a_device_array_without_array_namespace(monkeypatch):
    """Regression (found on an H200): CuPy 14's ndarray has no ``__array_namespace__``, and ``is_host_array``
    took it for host data, so ``self_localize`` called ``np.asarray`` on it (CuPy refuses: 'use .get()').
    Here a stand-in module named ``cupy`` whose ndarray, like CuPy's, has no ``__array_namespace__``."""
    import sys
    import types

    from dsp.xp import is_host_array

    fake = types.ModuleType("cupy")

    class ndarray:  # noqa: N801 - CuPy's class name
        def __array__(self, *args, **kwargs):
            raise TypeError("Implicit conversion to a NumPy array is not allowed. Please use `.get()`")

    fake.ndarray = ndarray
    monkeypatch.setitem(sys.modules, "cupy", fake)
    assert not hasattr(ndarray(), "__array_namespace__")
    assert not is_host_array(ndarray())
    for host in (np.zeros(3), np.complex64(1), [1.0, 2.0], (1, 2), 3, 2.5, 1j):
        assert is_host_array(host)
    assert not is_host_array(dsp.strict_backend("device1").asarray(np.zeros(2)))
