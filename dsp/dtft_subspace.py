"""The exact 2-D DTFT of every beam near one frequency, from one pass over the cube.

The refined estimator (:mod:`dsp.refine`) evaluates ``Z_m(f₁, f₂) = Σ_k Σ_n y[m,k,n]
e^{j2π(f₁ n + f₂ k)}`` (centred indices) and its derivatives many times, always within half a
DFT bin of the detected cell. Re-reading the cube for each evaluation (a 75 MB pass at Table I
sizes) dominated its cost. Within ±½ bin of a centre c, the vectors ``e_δ[n] = e^{j2π δ n}``
span a subspace of very low dimension (their time-bandwidth product is 1): with U [N, r] its
orthonormal basis (the first discrete prolate spheroidal sequences of that band, real), ``e_δ = U Uᴴ e_δ`` to a relative error below ``tolerance``, so

    Z_m(c + δ) = Σ_i Σ_l H[m, i, l] a_i(δ₁) b_l(δ₂),
    H[m, i, l] = Σ_k Σ_n y[m,k,n] e^{j2π(c₁ n + c₂ k)} U₁[n, i] U₂[k, l],
    a(δ₁) = U₁ᴴ e_δ₁,   b(δ₂) = U₂ᴴ e_δ₂,

one matrix product over the cube, then sums over r² numbers per beam. r = 11 per axis for the
default tolerance 1e-10 (N = 600 and K = 128 alike); derivatives in f use
``a⁽ʳ⁾(δ) = U₁ᴴ ((j2πn)^r ∘ e_δ)``. The error is tested against the direct sum.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .xp import backend_of, is_host_array

__all__ = ["SubspaceDtft", "as_cube", "band_basis", "dtft_phasors", "contract_samples", "contract_beams", "contract_chirps",
           "mean_of_beams", "DEFAULT_TOLERANCE"]

#: Relative error of e_δ's projection on the basis (singular-value cut-off).
DEFAULT_TOLERANCE = 1e-10

_ZERO = np.zeros(1)


def dtft_phasors(f: float, idx: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """exp(j2π (f + offsets) idx), phases reduced modulo 1 cycle first (exact for large f·idx).

    Parameters
    ----------
    f : float
        Frequency [cycles/sample].
    idx : float array [L]
        Sample indices (centred or not) [samples].
    offsets : float array [J]
        Frequency offsets added to ``f`` [cycles/sample].

    Returns
    -------
    complex array [J, L]
    """
    ph = np.outer(f + offsets, idx)
    return np.exp(2j * np.pi * (ph - np.round(ph)))


def as_cube(cube: Any) -> Any:
    """A beat cube for the contractions below: host data as complex128 NumPy, a device array as it is."""
    return np.asarray(cube, dtype=complex) if is_host_array(cube) else cube


def _runs(beams: np.ndarray) -> list[tuple[int, int, int]]:
    """Runs of consecutive beam indices: (position in ``beams``, first beam, one past the last)."""
    starts = np.concatenate([[0], np.flatnonzero(np.diff(beams) != 1) + 1])
    stops = np.concatenate([starts[1:], [beams.size]])
    return [(int(a), int(beams[a]), int(beams[b - 1]) + 1) for a, b in zip(starts, stops)]


def contract_samples(cube: Any, basis: np.ndarray, beams: np.ndarray | None = None) -> np.ndarray:
    """``cube[beams] @ basis``: the fast-time samples of the selected beams against P vectors.

    The pass over the cube runs where the cube lives (:mod:`dsp.xp`: NumPy, or a device array's own
    library); the result is small and comes back to the host.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W], a NumPy array or a device array (CuPy, array_api_strict).
    basis : complex array [N, P] or [N]
        The vectors (host data; copied to the cube's device explicitly).
    beams : int array [M'], optional
        Increasing beam indices (default all).

    Returns
    -------
    complex ndarray [M', K, P] (or [M', K] for a single vector), on the host

    One 2-D product per contiguous run of beams (a view of the cube, no copy): a single BLAS
    call is far faster than numpy's stacked matmul when other processes share the cores.
    """
    backend = backend_of(cube)
    xp = backend.xp
    m, k, n = cube.shape
    vec = backend.asarray(np.ascontiguousarray(basis))
    beams = np.arange(m) if beams is None else np.asarray(beams)
    parts = []
    for _, lo, hi in _runs(beams):
        flat = xp.reshape(cube[lo:hi, ...], ((hi - lo) * k, n)) @ vec
        parts.append(xp.reshape(flat, (hi - lo, k) + tuple(vec.shape[1:])))
    return backend.to_host(parts[0] if len(parts) == 1 else xp.concat(parts, axis=0))


def contract_beams(cube: Any, bases: np.ndarray, beams: np.ndarray) -> np.ndarray:
    """``cube[beams[i]] @ bases[i]`` for each selected beam: every beam against its own vectors.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W], on the host or a device.
    bases : complex array [M', N, P] or [M', N]
        Beam i's vectors (host data).
    beams : int array [M']
        The beams.

    Returns
    -------
    complex ndarray [M', K, P] (or [M', K]), on the host
    """
    backend = backend_of(cube)
    xp = backend.xp
    vecs = backend.asarray(np.asarray(bases))
    rows = [cube[int(beam), ...] @ vecs[i, ...] for i, beam in enumerate(np.asarray(beams))]  # one product per beam
    return backend.to_host(xp.stack(rows, axis=0))


def mean_of_beams(cube: Any, beams: np.ndarray) -> np.ndarray:
    """The mean of the selected beams' samples [K, N] (a static-return template), on the host.

    Parameters
    ----------
    cube : complex array [M, K, N]
        On the host or a device [√W].
    beams : int array
        The beams averaged (in increasing order).
    """
    backend = backend_of(cube)
    total = None
    for beam in np.asarray(beams):  # beam by beam, in order: the sum is the same on every backend
        total = cube[int(beam), ...] if total is None else total + cube[int(beam), ...]
    return backend.to_host(total / len(beams))


def contract_chirps(cube: Any, vector: np.ndarray, beams: np.ndarray) -> np.ndarray:
    """``Σ_k vector[k] cube[b, k, :]`` for the selected beams [M', N] (a slow-time DTFT), on the host.

    Parameters
    ----------
    cube : complex array [M, K, N]
        On the host or a device [√W].
    vector : complex array [K]
    beams : int array [M']
    """
    backend = backend_of(cube)
    xp = backend.xp
    vec = backend.asarray(np.asarray(vector))
    rows = [vec @ cube[int(beam), ...] for beam in np.asarray(beams)]  # [N] each
    return backend.to_host(xp.stack(rows, axis=0))


@functools.lru_cache(maxsize=16)
def band_basis(size: int, tolerance: float = DEFAULT_TOLERANCE) -> np.ndarray:
    """Orthonormal basis [size, r] of e^{j2πδn}, |δ| <= ½/size, n centred; read-only, real.

    The first r discrete prolate spheroidal sequences of half-bandwidth W = ½/size
    (``scipy.signal.windows.dpss``, NW = ½): the orthonormal sequences most concentrated in the
    band, so they span e_δ for |δ| <= W best. r is the smallest count that projects every e_δ of
    a 257-point grid over the bin with a relative error below ``tolerance`` (11 for 1e-10).

    They come from a symmetric tridiagonal eigenproblem (no matrix-matrix BLAS), so the basis is
    the same to the last bit whatever BLAS's thread count: an SVD basis was not, and a study's
    cached basis then depended on what the process had run before.
    """
    import scipy.signal

    size = int(size)
    if size < 2:
        return np.ones((size, size))
    idx = np.arange(size) - (size - 1) / 2.0
    deltas = np.linspace(-0.5, 0.5, 257) / size
    e = np.exp(2j * np.pi * np.outer(idx, deltas))  # [size, 257], each column of norm sqrt(size)
    count = min(size, 24)
    tapers = np.asarray(scipy.signal.windows.dpss(size, 0.5, Kmax=count, norm=2), dtype=float)  # [count, size]
    coeffs = np.einsum("kn,nd->kd", tapers, e)  # einsum without BLAS: deterministic [count, 257]
    r = count
    for r_try in range(1, count + 1):
        resid = e - np.einsum("kn,kd->nd", tapers[:r_try], coeffs[:r_try])
        if np.sqrt((np.abs(resid) ** 2).sum(axis=0)).max() <= tolerance * np.sqrt(size):
            r = r_try
            break
    basis = np.ascontiguousarray(tapers[:r].T)
    basis.setflags(write=False)
    return basis


class SubspaceDtft:
    """Projections of a beat cube around (c₁, c₂) [cycles/sample], valid within ±½ DFT bin.

    Parameters
    ----------
    cube : complex array [M, K, N]
        Beat samples [√W].
    f1, f2 : float
        Centre: fast- and slow-time frequency [cycles/sample].
    tolerance : float
        Relative projection error of the basis.

    Attributes
    ----------
    moments : complex array [M, r₁, r₂]
        H[m, i, l] [√W].
    centre : (float, float)
        (c₁, c₂) [cycles/sample].
    """

    def __init__(self, cube: np.ndarray, f1: float, f2: float, *, tolerance: float = DEFAULT_TOLERANCE) -> None:
        m, k, n = cube.shape
        self.shape = (m, k, n)
        self.centre = (float(f1), float(f2))
        self._n_idx = np.arange(n) - (n - 1) / 2.0
        self._k_idx = np.arange(k) - (k - 1) / 2.0
        self._u1 = band_basis(n, tolerance)
        self._u2 = band_basis(k, tolerance)
        b1 = dtft_phasors(f1, self._n_idx, _ZERO)[0][:, None] * self._u1  # [N, r₁]
        b2 = dtft_phasors(f2, self._k_idx, _ZERO)[0][:, None] * self._u2  # [K, r₂]
        g = contract_samples(cube, b1)  # the one pass over the cube (on its backend) [M, K, r₁]
        self.moments = np.einsum("mki,kl->mil", g, b2)

    def covers(self, f1: float, f2: float) -> bool:
        """(f₁, f₂) lies within the ±½-bin region where the basis holds."""
        _, k, n = self.shape
        return abs(f1 - self.centre[0]) * n <= 0.5 + 1e-9 and abs(f2 - self.centre[1]) * k <= 0.5 + 1e-9

    @staticmethod
    def _coefficients(basis: np.ndarray, idx: np.ndarray, deltas: np.ndarray, derivative: int) -> np.ndarray:
        """Uᴴ ((j2π idx)^r ∘ e_δ) for each δ [len(deltas), r]."""
        e = np.exp(2j * np.pi * np.outer(deltas, idx))  # |δ idx| <= ¼: no phase reduction needed
        if derivative:
            e = e * (2j * np.pi * idx) ** derivative
        return e @ basis.conj()

    def coefficients(self, f1: Any, f2: Any, derivative: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(a, b): coefficient rows for the fast- and slow-time frequencies [len(f), r]."""
        d1 = np.atleast_1d(np.asarray(f1, dtype=float)) - self.centre[0]
        d2 = np.atleast_1d(np.asarray(f2, dtype=float)) - self.centre[1]
        return (self._coefficients(self._u1, self._n_idx, d1, derivative),
                self._coefficients(self._u2, self._k_idx, d2, derivative))

    def evaluate(self, f1: float, f2: float, *, beams: np.ndarray | None = None, order: int = 0,
                 template: np.ndarray | None = None) -> np.ndarray:
        """Z and its derivatives at (f₁, f₂).

        Parameters
        ----------
        f1, f2 : float
            Frequencies within ±½ bin of the centre [cycles/sample].
        beams : int array, optional
            Beams to evaluate (default all).
        order : {0, 2}
            0: Z only, [M']; 2: the derivatives up to second order per axis, [M', 3, 3] with
            ``out[:, a, b] = ∂^{a+b} Z / ∂f₁^a ∂f₂^b``.
        template : complex array [r₁, r₂], optional
            Moments subtracted from every beam first (a static-return template).
        """
        h = self.moments if beams is None else self.moments[beams]
        if template is not None:
            h = h - template[None]
        if order == 0:
            a, b = self.coefficients(f1, f2)
            return np.einsum("mil,i,l->m", h, a[0], b[0])
        rows = [self.coefficients(f1, f2, r) for r in range(3)]
        a = np.concatenate([r[0] for r in rows])  # [3, r₁]
        b = np.concatenate([r[1] for r in rows])  # [3, r₂]
        return np.einsum("mil,ai,bl->mab", h, a, b)
