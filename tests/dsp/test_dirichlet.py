"""``dsp.dirichlet``, the array factor's kernel, against the sum it stands for.

Oracle: the normalised sum of n unit phasors centred on the array, (1/n) Σ_k e^{j(k − (n−1)/2)x},
k = 0 … n−1, which is real and equals sin(n x/2) / (n sin(x/2)), with the limit (−1)^{j(n−1)} at
x = 2πj. The sum has n rounding errors of ~1e-16; 1e-12 is far above them and far below any wrong
sign, count or branch (those change the value by O(1/n)).
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp.pattern import dirichlet


def phasor_sum(x, n):
    k = np.arange(n) - (n - 1) / 2
    return np.mean(np.exp(1j * np.multiply.outer(np.asarray(x, float), k)), axis=-1)


@pytest.mark.parametrize("n", [1, 2, 4, 5, 16, 33])
def test_the_kernel_is_the_phasor_sum(n):
    rng = np.random.default_rng(n)
    j = np.arange(-3, 4)
    x = np.concatenate([rng.uniform(-20, 20, 500),
                        2 * np.pi * j,  # the removable singularities: the limit branch
                        2 * np.pi * j + 1e-13, 2 * np.pi * j - 3e-14,  # beside them, still that branch
                        2 * np.pi * j + 1e-6])  # just outside it
    ref = phasor_sum(x, n)
    assert np.max(np.abs(ref.imag)) < 1e-12
    np.testing.assert_allclose(dirichlet(x, n), ref.real, rtol=0, atol=1e-12)


def test_shape_and_scalars_are_kept():
    x = np.linspace(-1, 1, 12).reshape(3, 4)
    assert dirichlet(x, 16).shape == (3, 4)
    assert dirichlet(0.0, 16) == pytest.approx(1.0)
    assert dirichlet(2 * np.pi, 16) == pytest.approx(-1.0)  # (−1)^{j(n−1)}, j = 1, n = 16
