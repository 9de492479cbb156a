"""The one-pass DTFT of the refined estimator (dsp/dtft_subspace.py).

Oracle: the direct sum Σ_k Σ_n y e^{j2π(f₁n + f₂k)} and its analytic derivatives, at random
frequencies within ±½ bin of the centre, on white-noise cubes (the hardest case: no tone to
dominate the sum). Errors are stated relative to the noise's own DTFT magnitude, √(K N).
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp.dtft_subspace import SubspaceDtft, band_basis


def direct(y, f1, f2, r1=0, r2=0):
    m, k, n = y.shape
    ni, ki = np.arange(n) - (n - 1) / 2, np.arange(k) - (k - 1) / 2
    a = (2j * np.pi * ni) ** r1 * np.exp(2j * np.pi * f1 * ni)
    b = (2j * np.pi * ki) ** r2 * np.exp(2j * np.pi * f2 * ki)
    return np.einsum("mkn,n,k->m", y, a, b)


@pytest.mark.parametrize("shape", [(3, 128, 600), (2, 16, 64), (2, 7, 33)])
def test_projection_matches_the_direct_sum_within_half_a_bin(shape):
    rng = np.random.default_rng(sum(shape))
    y = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    m, k, n = shape
    c1, c2 = 0.3127, -0.0413
    proj = SubspaceDtft(y, c1, c2)
    scale = np.sqrt(k * n)
    for _ in range(30):
        f1 = c1 + rng.uniform(-0.5, 0.5) / n
        f2 = c2 + rng.uniform(-0.5, 0.5) / k
        assert proj.covers(f1, f2)
        np.testing.assert_allclose(proj.evaluate(f1, f2), direct(y, f1, f2), rtol=0, atol=1e-8 * scale)
        d = proj.evaluate(f1, f2, order=2, beams=np.array([m - 1]))
        for a in range(3):
            for b in range(3):
                if a + b > 2:
                    continue
                ref = direct(y[m - 1:], f1, f2, a, b)
                # derivative scale: the RMS of (2πn)^a (2πk)^b times √(KN)
                s = scale * (2 * np.pi) ** (a + b) * (n / np.sqrt(12)) ** a * (k / np.sqrt(12)) ** b
                np.testing.assert_allclose(d[:, a, b], ref, rtol=0, atol=1e-6 * s)


def test_outside_the_bin_is_not_covered_and_the_basis_is_small():
    y = np.ones((1, 128, 600), dtype=complex)
    proj = SubspaceDtft(y, 0.1, 0.0)
    assert not proj.covers(0.1 + 0.51 / 600, 0.0)
    assert not proj.covers(0.1, 0.51 / 128)
    # time-bandwidth product 1: a handful of vectors span the whole bin to 1e-10
    assert band_basis(600).shape[1] <= 12 and band_basis(128).shape[1] <= 12
    assert not band_basis(600).flags.writeable
