"""The FMCW beat-signal model, eq. (1) of the seed paper."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Literal

import numpy as np

from dsp import RadarConfig
from dsp.sweep import BeamSweep
from dsp.threads import thread_count
from dsp.xp import ArrayBackend, numpy_backend

from .paths import PathFrames, PathSet
from .phase import exact_fractional_cycles, wrapped_tone
from .ris import RisConfig, ris_response

__all__ = ["beat_cube", "add_noise", "add_noise_batch", "NoiseStream"]

NoiseStream = Literal["standard", "fast"]


def beat_cube(
    paths: PathSet | PathFrames,
    *,
    radar: RadarConfig,
    sweep: BeamSweep,
    ris: RisConfig | None,
    out: np.ndarray | None = None,
    noise: tuple[float, np.random.Generator] | None = None,
    workers: int | None = None,
) -> np.ndarray:
    """Beat cube of eq. (1) for every sweep beam, noiseless or with the fast noise stream.

    Parameters
    ----------
    paths : PathSet or PathFrames
        L round-trip paths; those with RIS angles get the RIS response of each beam. A
        :class:`PathSet` is the same in every frame (frozen geometry); a :class:`PathFrames`
        gives frame m its own delays, rates, gains and RIS angles (a moving radar).
    radar : RadarConfig
    sweep : BeamSweep
        M beams.
    ris : RisConfig or None
        Needed when any path goes through the RIS.
    out : complex128 array [M, K, N], optional
        Written in place and returned (saves allocating 75 MB per Table I cube in Monte Carlo
        loops).
    noise : (float, numpy.random.Generator), optional
        (σ² [W], rng): add CN(0, σ²) receiver noise from the ``"fast"`` stream of
        :func:`add_noise`, beam by beam while the beam is in cache. ``None``: noiseless.
    workers : int, optional
        Threads that synthesise beams concurrently (default: up to 2, the CPU count). The cube
        is the same, bit for bit, for any number of workers.

    Returns
    -------
    complex array [M, K, N]
        ``Y[m, k, n] = Σ_l γ_l r_{m,l} e^{-j2π(S τ_l + f_c ν_l) n T_s} e^{-j2π f_c ν_l k T_c}``
        [√W], where r_{m,l} is :func:`risloc_rt.model.ris.ris_response` for RIS paths and 1 otherwise,
        T_c = ``radar.chirp_interval`` (T for back-to-back chirps), and γ, τ, ν, r those of
        frame m for a :class:`PathFrames`.

    Notes
    -----
    Each path is a separable 2-D tone: frame m is ``Σ_l c_{m,l} s_l f_lᵀ`` with the slow-time
    tone s_l [K], the fast-time tone f_l [N] and c_{m,l} = γ_l r_{m,l}. Paths whose slow-time
    tones are equal (the same cycles per chirp, e.g. every path of a static radar, ν = 0) are
    summed first, ``h_g = Σ_{l∈g} c_{m,l} f_l``, so the frame is one product
    ``[s_g]ᵀ [K, G] @ [h_g] [G, N]`` with G ≤ L distinct slow tones: a static hall costs one
    outer product per beam whatever its number of paths. Per-path cycles per sample and per
    chirp are reduced modulo 1 exactly (:func:`risloc_rt.model.phase.exact_fractional_cycles`)
    before the exponential.
    """
    m_beams = sweep.num_beams
    k_chirps, n_samples = radar.num_chirps, radar.num_samples
    framed = isinstance(paths, PathFrames)
    if framed and paths.num_frames != m_beams:
        raise ValueError(f"the PathFrames has {paths.num_frames} frames but the sweep has {m_beams} beams; "
                         "build one frame per beam")
    if not isinstance(paths, (PathSet, PathFrames)):
        raise TypeError(f"paths must be a PathSet or PathFrames, got {type(paths).__name__}")
    shape = (m_beams, k_chirps, n_samples)
    if out is None:
        cube = np.empty(shape, dtype=np.complex128)
    else:
        if not (isinstance(out, np.ndarray) and out.shape == shape and out.dtype == np.complex128
                and out.flags.c_contiguous and out.flags.writeable):
            raise ValueError(f"out must be a writeable C-contiguous complex128 array of shape {list(shape)}")
        cube = out
    if len(paths) == 0:
        cube[...] = 0
        return cube
    if framed and _frames_are_equal(paths):
        paths, framed = paths.frame(0), False  # a static geometry: exactly the PathSet's cube
    # Cycles per sample (S τ + f_c ν) T_s and per chirp f_c ν T_c, reduced modulo 1 exactly:
    # [L] for a PathSet, [M, L] for a PathFrames.
    fast_cycles = exact_fractional_cycles(
        [(radar.slope, paths.delay), (radar.carrier_frequency, paths.delay_rate)], radar.sample_period)
    slow_cycles = exact_fractional_cycles([(radar.carrier_frequency, paths.delay_rate)], radar.chirp_interval)
    coef = _coefficients(paths, radar=radar, sweep=sweep, ris=ris)  # [M, L]
    if framed:
        def beam(m: int) -> None:
            _frame(cube[m], slow_cycles[m], wrapped_tone(fast_cycles[m], n_samples), coef[m], k_chirps)
    else:
        beam = _static(cube, slow_cycles, wrapped_tone(fast_cycles, n_samples), coef)
    if noise is None:
        _run_beams(beam, m_beams, workers)
        return cube
    noise_power, rng = noise
    streams = _noise_streams(rng, m_beams)

    def noisy_beam(m: int) -> None:
        beam(m)
        _add_beam_noise(cube[m], noise_power, streams[m], cube[m])

    _run_beams(noisy_beam, m_beams, workers)
    return cube


def _run_beams(beam: Callable[[int], None], num_beams: int, workers: int | None) -> None:
    """Call ``beam(m)`` for every beam, on up to ``workers`` threads (numpy releases the GIL)."""
    workers = thread_count() if workers is None else int(workers)
    if workers <= 1 or num_beams < 2:
        for m in range(num_beams):
            beam(m)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for _ in pool.map(beam, range(num_beams)):
            pass


def _noise_streams(rng: np.random.Generator, num_beams: int) -> list[np.random.Generator]:
    """One child stream per beam, spawned from ``rng``'s seed sequence (``Generator.spawn``)."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    try:
        return rng.spawn(num_beams)
    except TypeError:  # a Generator built from a bare bit generator without a seed sequence
        return [np.random.default_rng(s) for s in rng.integers(0, 2**63, size=num_beams)]


def _add_beam_noise(frame: np.ndarray, noise_power: float, rng: np.random.Generator, out: np.ndarray) -> None:
    """``out = frame + w``, w ~ CN(0, σ²) from float32 normals of ``rng`` (the fast stream) [K, N]."""
    w = rng.standard_normal(frame.shape + (2,), dtype=np.float32)  # [..., (re, im)]
    w *= np.float32(np.sqrt(noise_power / 2.0))
    np.add(frame, w.view(np.complex64)[..., 0], out=out)


def _static(cube: np.ndarray, slow_cycles: np.ndarray, fast: np.ndarray, coef: np.ndarray) -> Callable[[int], None]:
    """``beam(m)`` writing ``cube[m] = Σ_l coef_{m,l} s_l f_lᵀ``, tones shared by all beams, grouped by slow tone.

    cube [M, K, N] (written by ``beam``), slow_cycles [L], fast [L, N] (tones), coef [M, L].
    """
    keys, group = np.unique(slow_cycles, return_inverse=True)  # G distinct slow tones
    slow = wrapped_tone(keys, cube.shape[1])  # [G, K]
    h = np.empty((cube.shape[0], keys.size, fast.shape[1]), dtype=np.complex128)  # [M, G, N]
    for g in range(keys.size):
        members = np.flatnonzero(group == g)
        np.matmul(coef[:, members], fast[members], out=h[:, g])  # [M, L_g] @ [L_g, N]
    if keys.size == 1:
        def single(m: int) -> None:
            np.multiply(slow[0][:, None], h[m], out=cube[m])  # [K, 1] * [1, N]
        return single
    # Groups of paths that all miss the RIS are the same in every beam: one [K, N] frame.
    fixed = np.array([np.all(coef[:, group == g] == coef[:1, group == g]) for g in range(keys.size)])
    varying = ~fixed
    common = slow[fixed].T @ h[0, fixed] if fixed.any() and varying.any() else None  # [K, N]
    slow_t = slow[varying].T if common is not None else slow.T  # [K, G1]
    h = h[:, varying] if common is not None else h  # [M, G1, N]

    def grouped(m: int) -> None:
        np.matmul(slow_t, h[m], out=cube[m])  # [K, G1] @ [G1, N]
        if common is not None:
            cube[m] += common
    return grouped


def _frames_are_equal(paths: PathFrames) -> bool:
    """Whether every frame holds the same paths (bit for bit), e.g. a radar at rest."""
    def same(x: np.ndarray) -> bool:
        first = x[:1]
        return bool(np.all((x == first) | (np.isnan(x) & np.isnan(first)))) if x.dtype.kind == "f" \
            else bool(np.all(x == first))

    return all(same(x) for x in (paths.gain, paths.delay, paths.delay_rate, paths.ris_incidence, paths.ris_departure))


def _coefficients(paths: PathSet | PathFrames, *, radar: RadarConfig, sweep: BeamSweep,
                  ris: RisConfig | None) -> np.ndarray:
    """c_{m,l} = γ_{m,l} r_{m,l} (r = 1 for paths that miss the RIS) [M, L] [√W]."""
    m_beams, via = sweep.num_beams, paths.via_ris
    coef = np.empty((m_beams, len(paths)), dtype=np.complex128)
    coef[...] = paths.gain  # [L] or [M, L]
    if not via.any():
        return coef
    if ris is None:
        raise ValueError("the path set has RIS loop-back paths but no RisConfig was given")
    if isinstance(paths, PathFrames):
        # Frame m sees its own RIS angles through beam m: the diagonal blocks of the response to
        # every (frame, path) pair, [M, M·L1] -> [M, M, L1] -> [M, L1].
        n_via = int(via.sum())
        inc = paths.ris_incidence[:, via].reshape(-1, 2)
        dep = paths.ris_departure[:, via].reshape(-1, 2)
        r = ris_response(ris, sweep, inc, dep, wavelength=radar.wavelength).reshape(m_beams, m_beams, n_via)
        r = r[np.arange(m_beams), np.arange(m_beams)]
    else:
        r = ris_response(ris, sweep, paths.ris_incidence[via], paths.ris_departure[via],
                         wavelength=radar.wavelength)  # [M, L1]
    coef[:, via] *= r
    return coef


def _frame(out: np.ndarray, slow_cycles: np.ndarray, fast: np.ndarray, coef: np.ndarray, num_chirps: int) -> None:
    """``out[K, N] = Σ_l coef_l s_l f_lᵀ``, the paths grouped by equal slow-time tone.

    slow_cycles [L] (cycles per chirp in [0, 1]), fast [L, N] (tones), coef [L].
    """
    keys, group = np.unique(slow_cycles, return_inverse=True)  # G distinct slow tones
    weighted = coef[:, None] * fast  # [L, N]
    if keys.size == slow_cycles.size:
        h = np.empty_like(weighted)
        h[group] = weighted  # [G = L, N], in the order of keys
    else:
        order = np.argsort(group, kind="stable")
        starts = np.searchsorted(group[order], np.arange(keys.size))
        h = np.add.reduceat(weighted[order], starts, axis=0)  # [G, N]
    slow = wrapped_tone(keys, num_chirps)  # [G, K]
    if keys.size == 1:
        np.multiply(slow[0][:, None], h[0][None, :], out=out)
    else:
        np.matmul(slow.T, h, out=out)  # [K, G] @ [G, N]


def add_noise(cube: np.ndarray, noise_power: float, rng: np.random.Generator, *, out: np.ndarray | None = None,
              stream: NoiseStream = "standard", workers: int | None = None) -> np.ndarray:
    """``cube + w`` with w ~ CN(0, σ²) i.i.d. per sample.

    Parameters
    ----------
    cube : complex array [M, K, N]
        [√W].
    noise_power : float
        σ² [W].
    rng : numpy.random.Generator
        Source of the noise.
    out : complex128 array [M, K, N], optional
        Where to write the result; may be ``cube`` itself (in place, no copy).
    stream : {"standard", "fast"}
        ``"standard"``: the real and imaginary parts of w[i] are the float64 normals 2i and 2i+1 of
        one ``rng.standard_normal`` call, scaled by sqrt(σ²/2): the same numbers for the same seed
        whether or not ``out`` is given. ``"fast"``: beam m draws float32 normals from its own
        child stream ``rng.spawn(M)[m]``, so beams are drawn concurrently (2-3x faster on two
        cores); the same distribution, other numbers, the same for any number of workers.
    workers : int, optional
        Threads of the ``"fast"`` stream (default ``dsp.threads.thread_count()``).

    Notes
    -----
    float32 normals have a 24-bit mantissa: each noise sample carries a relative rounding of
    6e-8, i.e. the noise power is exact to 1e-7 and the noise floor to 5e-7 dB, far below any
    Monte Carlo error. Both streams leave ``rng``'s own draw sequence in a new state.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    if stream not in ("standard", "fast"):
        raise ValueError(f"stream={stream!r} must be 'standard' (float64, one draw) or 'fast' (float32, per-beam streams)")
    cube = np.asarray(cube)
    if stream == "fast":
        frames = cube.reshape((-1,) + cube.shape[-2:]) if cube.ndim >= 2 else cube.reshape(1, 1, -1)
        result = np.empty(frames.shape, dtype=np.result_type(cube.dtype, np.complex64)) if out is None \
            else out.reshape(frames.shape)
        streams = _noise_streams(rng, frames.shape[0])
        _run_beams(lambda m: _add_beam_noise(frames[m], noise_power, streams[m], result[m]), frames.shape[0], workers)
        return result.reshape(cube.shape) if out is None else out
    scale = np.sqrt(noise_power / 2.0)
    noise = rng.standard_normal(cube.shape + (2,))  # [..., (re, im)]
    noise *= scale
    w = noise.view(np.complex128)[..., 0]  # the same memory read as complex: re + j im
    if out is None:
        return cube + w
    np.add(cube, w, out=out)
    return out


def add_noise_batch(cube: np.ndarray, noise_power: float, rngs: list[np.random.Generator], *,
                    backend: ArrayBackend | None = None, out: np.ndarray | None = None,
                    device_cube: Any = None) -> Any:
    """B noisy copies of one noiseless cube, copy b with the noise of ``rngs[b]``, on an array backend.

    Parameters
    ----------
    cube : complex array [M, K, N]
        The noiseless cube, on the host [√W].
    noise_power : float
        σ² [W].
    rngs : list of numpy.random.Generator
        One stream per realization (a study's ``SeedSequence(seed, spawn_key=(point, run))``).
    backend : dsp.xp.ArrayBackend, optional
        Where the result lives (default NumPy).
    out : complex128 array [B', M, K, N], B' >= B, optional
        Host scratch space (NumPy and array_api_strict backends): the first B entries are written.
    device_cube : array of ``backend``, optional
        ``cube`` already on the device (CuPy): reused, not copied again.

    Returns
    -------
    complex array [B, M, K, N] of ``backend``

    Notes
    -----
    On the host (NumPy, array_api_strict) copy b is :func:`add_noise` with ``stream="fast"`` on
    ``rngs[b]``: bit for bit the noise of a single run with that stream, whatever B (array_api_strict
    then receives the batch by one explicit copy). On a GPU (CuPy) the normals are drawn there
    (``ArrayBackend.device_normals``, float32, seeded from each ``rngs[b]``): other numbers, the same law.
    """
    backend = numpy_backend() if backend is None else backend
    b = len(rngs)
    if backend.name == "cupy":
        xp = backend.xp
        clean = backend.asarray(cube) if device_cube is None else device_cube
        scale = float(np.sqrt(noise_power / 2.0))
        return xp.stack([clean + scale * backend.device_normals(rng, tuple(cube.shape)) for rng in rngs])
    host = np.empty((b,) + tuple(cube.shape), dtype=np.complex128) if out is None else out[:b]
    for i, rng in enumerate(rngs):
        add_noise(cube, noise_power, rng, out=host[i], stream="fast")
    return host if backend.is_numpy else backend.asarray(host)
