"""The FMCW beat-signal model, eq. (1) of the seed paper."""

from __future__ import annotations

import threading
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

__all__ = ["beat_cube", "add_noise", "add_noise_batch", "NoiseStream", "NOISE_STREAMS"]

NoiseStream = Literal["standard", "fast", "boxmuller"]
#: The receiver-noise streams of :func:`add_noise` (and ``simulate(noise_stream=...)``).
NOISE_STREAMS = ("standard", "fast", "boxmuller")


def beat_cube(
    paths: PathSet | PathFrames,
    *,
    radar: RadarConfig,
    sweep: BeamSweep,
    ris: RisConfig | None,
    out: np.ndarray | None = None,
    noise: tuple[float, np.random.Generator] | None = None,
    workers: int | None = None,
    noise_stream: NoiseStream = "fast",
) -> np.ndarray:
    """Beat cube of eq. (1) for every sweep beam, noiseless or with a per-beam noise stream.

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
        (σ² [W], rng): add CN(0, σ²) receiver noise from the ``noise_stream`` stream of
        :func:`add_noise`, beam by beam while the beam is in cache. ``None``: noiseless.
    workers : int, optional
        Threads that synthesise beams concurrently (default: up to 2, the CPU count). The cube
        is the same, bit for bit, for any number of workers.
    noise_stream : {"fast", "boxmuller"}, default "fast"
        The per-beam stream of ``noise`` (:func:`add_noise`): the same numbers as
        ``add_noise(noiseless cube, σ², rng, stream=noise_stream)``.

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
    if noise_stream not in ("fast", "boxmuller"):
        raise ValueError(f"noise_stream={noise_stream!r}: the noise added during synthesis is per beam, "
                         "'fast' or 'boxmuller'; add the 'standard' stream with add_noise afterwards")
    noise_power, rng = noise
    streams = _noise_streams(rng, m_beams)
    add_beam_noise = _beam_noise(noise_stream)

    def noisy_beam(m: int) -> None:
        beam(m)
        add_beam_noise(cube[m], noise_power, streams[m], cube[m])

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


_WORD = np.float32(2.0**-32)  # one step of a 32-bit word on [0, 1)
_TURN = np.float32(2.0 * np.pi * 2.0**-32)  # one step of a 32-bit word on [0, 2π)


def _add_beam_noise_boxmuller(frame: np.ndarray, noise_power: float, rng: np.random.Generator, out: np.ndarray,
                              words: np.ndarray, noise: np.ndarray) -> None:
    """``out = frame + w``, w ~ CN(0, σ²) by Box–Muller from 32-bit words of ``rng`` (the boxmuller stream) [K, N].

    ``words`` (float32 [2·K·N]) and ``noise`` (complex64 [K·N]) are scratch space, reused between beams.
    Sample i is ``√(-σ² ln u_i) e^{jθ_i}`` with ``u_i = (a_i + ½)/2³²`` and ``θ_i = 2π b_i/2³²`` for
    the 32-bit words a_i = word i and b_i = word K·N + i of ``rng.bit_generator.random_raw(K·N)``.
    """
    n = frame.size
    words[...] = rng.bit_generator.random_raw(n).view(np.uint32)  # 2n words; float32 rounds a word to 24 bits
    radius, angle = words[:n], words[n:]
    radius += np.float32(0.5)
    radius *= _WORD  # u in (2⁻³³, 1]: a word of 2³² - 1 rounds to 2³², i.e. u = 1 and a zero radius
    np.log(radius, out=radius)
    np.negative(radius, out=radius)
    np.sqrt(radius, out=radius)  # |w|/σ = √(-ln u): |w|²/σ² ~ Exp(1), at most √(33 ln 2) = 4.78
    radius *= np.float32(np.sqrt(noise_power))
    angle *= _TURN
    parts = noise.view(np.float32).reshape(n, 2)  # [..., (re, im)]
    np.cos(angle, out=parts[:, 0])
    parts[:, 0] *= radius
    np.sin(angle, out=angle)
    np.multiply(angle, radius, out=parts[:, 1])
    np.add(frame, noise.reshape(frame.shape), out=out)


def _beam_noise(stream: str) -> Callable[[np.ndarray, float, np.random.Generator, np.ndarray], None]:
    """``add(frame, σ², rng, out)`` of a per-beam stream; the boxmuller stream's scratch space is per thread."""
    if stream == "fast":
        return _add_beam_noise
    local = threading.local()

    def add(frame: np.ndarray, noise_power: float, rng: np.random.Generator, out: np.ndarray) -> None:
        scratch = getattr(local, "scratch", None)
        if scratch is None or scratch[1].size != frame.size:  # a fresh 0.6 MB array per beam doubled its cost
            scratch = local.scratch = (np.empty(2 * frame.size, np.float32), np.empty(frame.size, np.complex64))
        _add_beam_noise_boxmuller(frame, noise_power, rng, out, *scratch)

    return add


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
    stream : {"standard", "fast", "boxmuller"}
        ``"standard"``: the real and imaginary parts of w[i] are the float64 normals 2i and 2i+1 of
        one ``rng.standard_normal`` call, scaled by sqrt(σ²/2): the same numbers for the same seed
        whether or not ``out`` is given. ``"fast"``: beam m draws float32 normals (NumPy's
        ziggurat) from its own child stream ``rng.spawn(M)[m]``, so beams are drawn concurrently
        (2-3x faster on two cores). ``"boxmuller"``: the same child streams, each sample made by
        Box–Muller from two 32-bit words in float32 (2-2.5x faster than ``"fast"`` on one core; what
        a CPU study draws). All three have the same distribution and give other numbers; the per-beam
        streams give the same numbers for any number of workers.
    workers : int, optional
        Threads of the per-beam streams (default ``dsp.threads.thread_count()``).

    Notes
    -----
    float32 normals have a 24-bit mantissa: each noise sample carries a relative rounding of
    6e-8, i.e. the noise power is exact to 1e-7 and the noise floor to 5e-7 dB, far below any
    Monte Carlo error. The boxmuller stream's sample i is √(-σ² ln u) (cos θ + j sin θ) with
    u = (a + ½)/2³², θ = 2π b/2³² for two independent uniform 32-bit words a, b: exact Box–Muller
    of uniforms on a 2⁻³² grid, then float32 (the word's rounding to 24 bits moves u by ≤ 2⁻²⁴
    relative, i.e. |w|²/σ² by ≤ 6e-8, and θ by ≤ 4e-7 rad; float32 log, sqrt, sin and cos add a few
    1e-7 relative). |w|²/σ² is Exp(1) cut at 33 ln 2 = 22.9 (each part at 6.8 standard deviations),
    which a Gaussian passes with probability 2⁻³³ per sample. All streams leave ``rng``'s own draw
    sequence in a new state.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    if stream not in NOISE_STREAMS:
        raise ValueError(f"stream={stream!r} must be 'standard' (float64, one draw), 'fast' (float32 ziggurat, "
                         "per-beam streams) or 'boxmuller' (float32 Box–Muller, per-beam streams)")
    cube = np.asarray(cube)
    if stream != "standard":
        frames = cube.reshape((-1,) + cube.shape[-2:]) if cube.ndim >= 2 else cube.reshape(1, 1, -1)
        result = np.empty(frames.shape, dtype=np.result_type(cube.dtype, np.complex64)) if out is None \
            else out.reshape(frames.shape)
        streams = _noise_streams(rng, frames.shape[0])
        add_beam_noise = _beam_noise(stream)
        _run_beams(lambda m: add_beam_noise(frames[m], noise_power, streams[m], result[m]), frames.shape[0], workers)
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
                    device_cube: Any = None, stream: NoiseStream = "fast") -> Any:
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
    stream : {"fast", "boxmuller"}, default "fast"
        The host's per-beam stream (:func:`add_noise`); not used on a GPU.

    Returns
    -------
    complex array [B, M, K, N] of ``backend``

    Notes
    -----
    On the host (NumPy, array_api_strict) copy b is :func:`add_noise` with ``stream`` on
    ``rngs[b]``: bit for bit the noise of a single run with that stream, whatever B (array_api_strict
    then receives the batch by one explicit copy). On a GPU (CuPy) the normals are drawn there
    (``ArrayBackend.device_normals``, float32, seeded from each ``rngs[b]``): other numbers, the same law.
    """
    backend = numpy_backend() if backend is None else backend
    if stream not in ("fast", "boxmuller"):
        raise ValueError(f"stream={stream!r}: a batch draws a per-beam stream, 'fast' or 'boxmuller'")
    b = len(rngs)
    if backend.name == "cupy":
        xp = backend.xp
        clean = backend.asarray(cube) if device_cube is None else device_cube
        scale = float(np.sqrt(noise_power / 2.0))
        return xp.stack([clean + scale * backend.device_normals(rng, tuple(cube.shape)) for rng in rngs])
    host = np.empty((b,) + tuple(cube.shape), dtype=np.complex128) if out is None else out[:b]
    for i, rng in enumerate(rngs):
        add_noise(cube, noise_power, rng, out=host[i], stream=stream)
    return host if backend.is_numpy else backend.asarray(host)
