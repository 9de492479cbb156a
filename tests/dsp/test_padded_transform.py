"""The detector's zero-padded 2-D transform (``ArrayBackend.padded_ifft2``) and its reused workspace.

NumPy casts the cube into the padded array and transforms it in place; the oracle is the definition,
``Σ_k Σ_n x e^{+j2π(qk/Q + pn/P)}`` evaluated with ``numpy.fft`` in float64 (to the precision of the
dtype asked for), and the two padded ``scipy.fft`` calls the detector made before (bit for bit: the
same pocketfft lines, whatever the threads). ``dsp.detect_batch`` with a workspace must give the
detections it gives without one.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft

import dsp
from dsp import numpy_backend, strict_backend


def _cube(shape, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def _definition(x, q, p):
    return np.fft.ifft(np.fft.ifft(x, n=q, axis=-2, norm="forward"), n=p, axis=-1, norm="forward")


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_numpy_is_the_two_padded_transforms_bit_for_bit_and_the_definition(threads, dtype):
    x = _cube((2, 3, 12, 20))
    q, p = 24, 40
    with dsp.limit_threads(threads):
        got = numpy_backend().padded_ifft2(x, (q, p), dtype=dtype)
        before = scipy.fft.ifft(scipy.fft.ifft(x.astype(dtype), n=q, axis=2, norm="forward", workers=threads),
                                n=p, axis=3, norm="forward", workers=threads)
        reused = np.full((2, 3, q, p), 7 + 7j, dtype=dtype)  # stale values in every cell, padding included
        again = numpy_backend().padded_ifft2(x, (q, p), dtype=dtype, out=reused)
    assert got.dtype == dtype and got.shape == (2, 3, q, p)
    np.testing.assert_array_equal(got, before)
    assert again is reused
    np.testing.assert_array_equal(again, before)
    # the definition in float64: float32 rounding of the input and of log2(QP) butterfly stages
    eps = np.finfo(dtype).eps
    ref = _definition(x, q, p)
    scale = np.sqrt(x.shape[-1] * x.shape[-2]) * np.abs(x).max()  # the transform's typical magnitude
    assert np.abs(got - ref).max() < 10 * eps * np.log2(q * p) * scale


def test_unpadded_and_three_dimensional_inputs():
    x = _cube((4, 8, 6), seed=1)
    got = numpy_backend().padded_ifft2(x, (8, 6), dtype=np.complex128)
    np.testing.assert_allclose(got, _definition(x, 8, 6), rtol=0, atol=1e-12 * np.abs(x).sum())


def test_a_wrong_workspace_is_one_line():
    x = _cube((1, 2, 4, 6))
    be = numpy_backend()
    for bad in (np.empty((1, 2, 8, 12), np.complex128), np.empty((1, 2, 8, 10), np.complex64),
                np.empty((1, 2, 12, 8), np.complex64).transpose(0, 1, 3, 2)):
        with pytest.raises(ValueError, match=r"out must be a C-contiguous complex64 array of shape \[1, 2, 8, 12\]"):
            be.padded_ifft2(x, (8, 12), dtype=np.complex64, out=bad)


def test_strict_namespace_gives_the_definition():
    import array_api_strict as xp

    backend = strict_backend("device1")
    x = _cube((2, 3, 8, 10), seed=2)
    got = backend.to_host(backend.padded_ifft2(backend.asarray(x), (16, 20), dtype=xp.complex128))
    np.testing.assert_allclose(got, _definition(x, 16, 20), rtol=0, atol=1e-12 * np.abs(x).sum())


def test_detect_batch_with_a_workspace_gives_the_same_detections():
    from risloc_rt.model.beat import add_noise_batch
    from risloc_rt.studies.kernel import prepare_point, run_rng
    from risloc_rt.studies.params import complete_point

    prep = prepare_point(complete_point({"num_chirps": 16, "num_samples": 128, "n_dft": 255, "k_dft": 64,
                                         "sweep_step_deg": 3.0, "tx_power_dbm": 10.0}))
    cubes = add_noise_batch(prep.cube, prep.radar.noise_power, [run_rng(4, 0, r) for r in range(3)],
                            stream="boxmuller")
    kw = dict(pfa=1e-3, min_range=prep.processing.min_range, pattern=prep.pattern, sweep=prep.sweep, oversample=2)
    m, k, n = prep.cube.shape
    workspace = np.full((3, m, 2 * k, 2 * n), np.nan, np.complex64)
    plain = dsp.detect_batch(cubes, prep.radar, **kw)
    reused = dsp.detect_batch(cubes, prep.radar, workspace=workspace, **kw)
    assert reused == plain
    assert any(d.detected for d in plain)
    assert np.isfinite(workspace).all()  # the transform went there
