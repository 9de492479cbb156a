"""Trace a radar pose in a scene with sionna-rt and hand the paths over as numpy.

One ``PathSolver`` call per pose: the transmitter at the radar, and receivers at the radar
(round-trip, monostatic paths) and at every RIS point (one-way radar → RIS legs). sionna-rt's
per-receiver tensors are cut down to the valid paths, converted to float64/complex128, mapped from
the process-local object ids to names, sorted by delay, and returned as
:class:`~risloc_rt.hall.traced.TracedPaths`.
"""

from __future__ import annotations

import os
import time
from collections import OrderedDict
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from dsp import SPEED_OF_LIGHT
from dsp.validation import as_finite_array, positive

from ..traced import TracedPaths
from .result import TraceResult, TraceSettings
from .scene import LoadedScene, load_scene, scene_content_hash

if TYPE_CHECKING:  # pragma: no cover
    from .cache import TraceCache

__all__ = ["TraceResult", "TraceSettings", "paths_to_traced", "r_hat", "scene_scatters", "settings_for_scene", "solve_paths",
           "solver_options", "trace_scene"]

#: Name of the transmitter and of the monostatic receiver added to the scene.
RADAR_TX, RADAR_RX = "radar_tx", "radar_rx"
#: Radar → RIS legs kept per RIS point with diffuse reflection on (the strongest): every ordered
#: pair of legs is a loop-back candidate, and 10⁵ rays give ~3·10⁴ diffuse legs (10⁹ pairs).
MAX_DIFFUSE_LEGS = 256
#: Closest a RIS point may be to the radar [m] (sionna drops segments shorter than ~1 cm).
MIN_RIS_DISTANCE = 0.01
#: Loaded scenes kept in memory, keyed by (content hash, frequency): the last one only. Every loaded scene's
#: radio materials stay in Dr.Jit's registry while it lives, and each solve dispatches over all of them: 5
#: Jacobians of paper_hall took 0.20-0.31 s alone and 0.42-1.12 s next to 1-4 other loaded halls, while loading
#: the hall again for each cost 0.62-0.70 s (`bench_material_gradients.py --alive`, 2026-11-28).
_SCENE_CACHE_SIZE = 1
_scenes: OrderedDict[tuple[str, float], LoadedScene] = OrderedDict()


def r_hat(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vector [..., 3] of zenith angle ``theta`` (from +z) and azimuth ``phi`` (from +x) [rad].

    Notes
    -----
    ``r̂(θ, φ) = (sin θ cos φ, sin θ sin φ, cos θ)``, sionna-rt's spherical unit vector.
    """
    theta = np.asarray(theta, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=-1)


def _scene_for(xml_path: str, frequency: float, content_hash: str) -> tuple[LoadedScene, bool]:
    """The loaded scene for (hash, frequency), loading it at most once per process."""
    key = (content_hash, frequency)
    if key in _scenes:
        _scenes.move_to_end(key)
        return _scenes[key], True
    loaded = load_scene(xml_path, frequency=frequency)
    if loaded.content_hash != content_hash:  # edited between hashing and loading: key on what loaded
        key = (loaded.content_hash, frequency)
    _scenes[key] = loaded
    while len(_scenes) > _SCENE_CACHE_SIZE:
        _scenes.popitem(last=False)
    return loaded, False


def _point(value: Any, name: str) -> np.ndarray:
    return as_finite_array(value, name, shape=(3,))


def _points(value: Any, name: str) -> np.ndarray:
    arr = as_finite_array(value, name, allow_empty=True)
    if arr.size == 0:
        return np.zeros((0, 3))
    return as_finite_array(arr, name, shape=(None, 3))


def _validate_poses(radar_position: Any, ris_positions: Any, radar_velocity: Any) -> tuple[np.ndarray, ...]:
    radar = _point(radar_position, "radar_position")
    ris = _points(ris_positions, "ris_positions")
    velocity = _point(radar_velocity, "radar_velocity")
    for i, p in enumerate(ris):
        d = float(np.linalg.norm(p - radar))
        if d < MIN_RIS_DISTANCE:
            raise ValueError(
                f"ris_positions[{i}]={p.tolist()} is {d:.3g} m from radar_position={radar.tolist()}; "
                f"it must be >= {MIN_RIS_DISTANCE} m away (sionna-rt drops shorter segments)"
            )
    return radar, ris, velocity


def solve_paths(
    loaded: LoadedScene,
    *,
    radar_position: np.ndarray,
    ris_positions: np.ndarray,
    radar_velocity: np.ndarray,
    settings: TraceSettings,
) -> Any:
    """Run sionna-rt's ``PathSolver`` once for the radar and every RIS point.

    Replaces the radios of ``loaded.scene`` with a transmitter ``radar_tx`` at the radar and
    receivers ``radar_rx`` (at the radar), ``ris_0``, ``ris_1``, ... (at the RIS points), all with
    isotropic 1 × 1 V-polarised arrays. The radar's transmitter and receiver move with
    ``radar_velocity``; the RIS receivers are static.

    Parameters
    ----------
    loaded : LoadedScene
        From :func:`risloc_rt.hall.raytrace.load_scene`.
    radar_position : float array [3]
        World frame [m].
    ris_positions : float array [R, 3]
        World frame [m]; R may be 0.
    radar_velocity : float array [3]
        [m/s].
    settings : TraceSettings

    Returns
    -------
    sionna.rt.Paths
        Receivers in the order ``radar_rx, ris_0, ...`` (the first axis of every tensor).
    """
    import mitsuba as mi
    import sionna.rt as rt

    scene = loaded.scene
    radar, ris, velocity = _validate_poses(radar_position, ris_positions, radar_velocity)
    old = list(scene.transmitters) + list(scene.receivers)
    if old:
        scene.remove(old)
    scene.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    scene.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    # mi.Point3f refuses numpy float64 scalars: pass Python floats.
    pos = mi.Point3f(*map(float, radar))
    vel = mi.Vector3f(*map(float, velocity))
    radios = [rt.Transmitter(name=RADAR_TX, position=pos, velocity=vel),
              rt.Receiver(name=RADAR_RX, position=pos, velocity=vel)]
    radios += [rt.Receiver(name=f"ris_{i}", position=mi.Point3f(*map(float, p))) for i, p in enumerate(ris)]
    scene.add(radios)
    solver = rt.PathSolver(deterministic=True)
    saved = {}
    if settings.scattering_coefficient is not None:
        for name, material in scene.radio_materials.items():
            if hasattr(material, "scattering_coefficient"):
                saved[name] = material.scattering_coefficient
                material.scattering_coefficient = settings.scattering_coefficient
    try:
        return _solve(solver, scene, settings)
    finally:
        for name, value in saved.items():  # the loaded scene is reused by later traces
            scene.radio_materials[name].scattering_coefficient = value


def scene_scatters(loaded: LoadedScene) -> tuple[str, ...]:
    """The radio materials of ``loaded`` with a scattering coefficient S > 0 (sorted names).

    Parameters
    ----------
    loaded : LoadedScene

    Returns
    -------
    tuple of str
        Empty for a scene of smooth surfaces (every example hall).
    """
    out = []
    for name, mat in sorted(loaded.scene.radio_materials.items()):
        s = getattr(mat, "scattering_coefficient", None)
        if s is not None and float(s[0] if hasattr(s, "__getitem__") else s) > 0.0:
            out.append(name)
    return tuple(out)


def settings_for_scene(settings: TraceSettings, loaded: LoadedScene) -> TraceSettings:
    """``settings`` with diffuse reflection turned on when a material of the scene scatters (S > 0).

    sionna-rt always lowers a scattering material's specular reflection by √(1 − S²); the power
    S² it takes away comes back only as diffuse paths. Tracing such a scene without them would lose
    that power silently, so a spec's ``scattering_coefficient`` turns them on (a scene without one
    is traced as asked).

    Parameters
    ----------
    settings : TraceSettings
        As asked.
    loaded : LoadedScene

    Returns
    -------
    TraceSettings
        ``settings`` itself, or a copy with ``diffuse_reflection=True``.
    """
    if settings.diffuse_reflection or settings.scattering_coefficient is not None or not scene_scatters(loaded):
        return settings
    return replace(settings, diffuse_reflection=True)


def solver_options(settings: TraceSettings) -> dict[str, Any]:
    """The keyword arguments of sionna-rt's ``PathSolver`` call for ``settings`` (every solve of the project's).

    Parameters
    ----------
    settings : TraceSettings

    Returns
    -------
    dict
        ``max_depth``, ``max_num_paths_per_src``, ``samples_per_src``, ``synthetic_array=True``,
        ``los=True``, the interaction switches and ``seed``.
    """
    return dict(max_depth=settings.max_depth, max_num_paths_per_src=settings.max_num_paths_per_src,
                samples_per_src=settings.samples_per_src, synthetic_array=True, los=True,
                specular_reflection=settings.specular_reflection, diffuse_reflection=settings.diffuse_reflection,
                refraction=settings.refraction, diffraction=settings.diffraction, seed=settings.seed)


def _solve(solver: Any, scene: Any, settings: TraceSettings) -> Any:
    """One deterministic solve, evaluated before returning (materials may change afterwards)."""
    paths = solver(scene, **solver_options(settings))
    paths.tau.numpy()  # Dr.Jit is lazy: evaluate while the materials are the ones asked for
    return paths


def paths_to_traced(
    paths: Any,
    loaded: LoadedScene,
    *,
    radar_position: np.ndarray,
    ris_positions: np.ndarray,
    radar_velocity: np.ndarray,
    max_depth: int | None = None,
) -> tuple[TracedPaths, ...]:
    """Convert a :func:`solve_paths` result to one :class:`TracedPaths` per receiver.

    Parameters
    ----------
    paths : sionna.rt.Paths
        From :func:`solve_paths` with the same positions (synthetic arrays, 1 × 1 V-V).
    loaded : LoadedScene
        The scene it was solved in (object ids are only valid in this process).
    radar_position, ris_positions, radar_velocity
        As given to :func:`solve_paths`.
    max_depth : int, optional
        ``settings.max_depth`` of the solve: the width D of the per-bounce arrays (sionna-rt
        returns one all-zero column for ``max_depth=0``). Default: as returned.

    Returns
    -------
    tuple of TracedPaths
        ``(monostatic, leg_0, leg_1, ...)``.

    Notes
    -----
    - Entries with ``valid`` False or ``tau < 0`` (padding across receivers) are dropped.
    - ``amplitude = a[rx, 0, 0, 0, :]`` (V-V), ``departure = r̂(θ_t, φ_t)``,
      ``arrival = r̂(θ_r, φ_r)`` (from the receiver toward where the wave comes from).
    - Delay rate, for static scatterers: the path length changes by ``-v_tx·k̂_dep`` per unit
      displacement of the transmitter and by ``-v_rx·k̂_arr`` of the receiver, so
      ``ν = dτ/dt = -(v_tx·departure + v_rx·arrival)/c``: ``-2 v·departure/c`` for a monostatic
      path whose departure and arrival coincide (every single bounce), ``-v·departure/c`` for a
      leg. This is sionna-rt's ``doppler = -ν f`` in float64.
    - Paths are sorted by delay, then depth, object names, interaction types and departure
      vector (stable), so the order does not depend on sionna-rt's process-local object ids.
    """
    radar, ris, velocity = _validate_poses(radar_position, ris_positions, radar_velocity)
    object_names = tuple(sorted(loaded.scene.objects))
    index_of = {name: i for i, name in enumerate(object_names)}
    id_to_index = {int(obj.object_id): index_of[name] for name, obj in loaded.scene.objects.items()}
    frequency = float(loaded.frequency)

    a_re, a_im = paths.a
    # a: [num_rx, num_rx_ant=1, num_tx=1, num_tx_ant=1, N] -> [num_rx, N] (V-V)
    amplitude = np.asarray(a_re.numpy(), np.float64)[:, 0, 0, 0, :] + 1j * np.asarray(a_im.numpy(), np.float64)[:, 0, 0, 0, :]
    # per-path tensors: [num_rx, num_tx=1, N] -> [num_rx, N]
    tau = np.asarray(paths.tau.numpy(), np.float64)[:, 0, :]
    valid = np.asarray(paths.valid.numpy(), bool)[:, 0, :]
    departure = r_hat(paths.theta_t.numpy()[:, 0, :], paths.phi_t.numpy()[:, 0, :])  # [num_rx, N, 3]
    arrival = r_hat(paths.theta_r.numpy()[:, 0, :], paths.phi_r.numpy()[:, 0, :])
    # interactions, objects: [D, num_rx, num_tx=1, N] -> [num_rx, N, D]; vertices -> [num_rx, N, D, 3]
    interactions = np.moveaxis(np.asarray(paths.interactions.numpy(), np.int64)[:, :, 0, :], 0, -1)
    raw_objects = np.moveaxis(np.asarray(paths.objects.numpy(), np.int64)[:, :, 0, :], 0, -1)
    vertices = np.moveaxis(np.asarray(paths.vertices.numpy(), np.float64)[:, :, 0, :, :], 0, 2)
    if max_depth is not None and interactions.shape[-1] != max_depth:
        width = interactions.shape[-1]
        if np.any(interactions[..., max_depth:] != 0):
            raise RuntimeError(f"sionna-rt returned paths deeper than max_depth={max_depth}")
        pad = max(max_depth - width, 0)
        interactions = np.pad(interactions[..., :max_depth], [(0, 0), (0, 0), (0, pad)])
        raw_objects = np.pad(raw_objects[..., :max_depth], [(0, 0), (0, 0), (0, pad)])
        vertices = np.pad(vertices[..., :max_depth, :], [(0, 0), (0, 0), (0, pad), (0, 0)])

    rx_positions = [radar, *ris]
    rx_velocities = [velocity] + [np.zeros(3)] * len(ris)
    if amplitude.shape[0] != len(rx_positions):
        raise RuntimeError(f"sionna-rt returned {amplitude.shape[0]} receivers, expected {len(rx_positions)}")
    out = []
    for r, (rx_pos, rx_vel) in enumerate(zip(rx_positions, rx_velocities)):
        keep = valid[r] & (tau[r] >= 0)
        inter = interactions[r][keep]
        objs = np.full(inter.shape, -1, dtype=np.int64)
        used = inter != 0
        raw = raw_objects[r][keep][used]
        unknown = sorted(set(raw.tolist()) - set(id_to_index))
        if unknown:
            raise RuntimeError(f"sionna-rt returned object ids {unknown} that are not in the scene")
        objs[used] = [id_to_index[i] for i in raw.tolist()]
        verts = vertices[r][keep].copy()
        verts[inter == 0] = np.nan  # unused slots hold garbage
        dep, arr = departure[r][keep], arrival[r][keep]
        rate = -(dep @ velocity + arr @ rx_vel) / SPEED_OF_LIGHT
        delay = tau[r][keep]
        depth = (inter != 0).sum(axis=1)
        # np.lexsort: the last key is the primary one.
        keys = [dep[:, 2], dep[:, 1], dep[:, 0]]
        keys += [inter[:, d] for d in reversed(range(inter.shape[1]))]
        keys += [objs[:, d] for d in reversed(range(objs.shape[1]))]
        keys += [depth, delay]
        order = np.lexsort(keys) if delay.size else np.arange(0)
        out.append(TracedPaths(
            tx_position=radar, rx_position=rx_pos, frequency=frequency,
            delay=delay[order], amplitude=amplitude[r][keep][order],
            departure=dep[order], arrival=arr[order], delay_rate=rate[order],
            interactions=inter[order], objects=objs[order], vertices=verts[order],
            object_names=object_names,
        ))
    return tuple(out)


def trace_scene(
    xml_path: str | os.PathLike[str],
    *,
    radar_position: Any,
    ris_positions: Any = (),
    radar_velocity: Any = (0.0, 0.0, 0.0),
    frequency: float,
    settings: TraceSettings | None = None,
    cache: TraceCache | None = None,
) -> TraceResult:
    """Trace the monostatic radar paths and the radar → RIS legs of one pose in one scene.

    Parameters
    ----------
    xml_path : path-like
        Mitsuba XML scene (meshes relative to its folder).
    radar_position : float array [3]
        Radar (transmitter and receiver) position, world frame [m].
    ris_positions : float array [R, 3]
        RIS reference points, world frame [m]; may be empty. Keep them >= 1 cm from any surface
        (sionna-rt drops segments shorter than about 1 cm).
    radar_velocity : float array [3]
        Radar velocity [m/s]; sets the delay rates.
    frequency : float
        Carrier frequency [Hz] the materials are evaluated at.
    settings : TraceSettings, optional
        Solver options (default ``TraceSettings()``).
    cache : TraceCache, optional
        On-disk cache: a hit returns the stored arrays bit for bit, a miss stores the result.

    Returns
    -------
    TraceResult

    Raises
    ------
    SceneError
        The scene cannot be loaded, or a material is undefined at ``frequency``.
    BackendError
        No usable Dr.Jit backend (see :func:`risloc_rt.hall.raytrace.ensure_backend`).
    ValueError, TypeError
        Positions or velocity not finite ``[3]`` / ``[R, 3]``, a RIS point within 1 cm of the
        radar, a bad frequency or settings.

    Notes
    -----
    The scene is loaded once per process for each (content hash, frequency) and reused, so moving
    the radios reloads nothing; Dr.Jit's kernels are cached on disk (``~/.drjit``), so only the
    first solve of each (max_depth, samples_per_src) on a machine compiles.
    """
    t_start = time.perf_counter()
    settings = TraceSettings() if settings is None else settings
    if not isinstance(settings, TraceSettings):
        raise TypeError(f"settings must be a TraceSettings, got {type(settings).__name__}")
    radar, ris, velocity = _validate_poses(radar_position, ris_positions, radar_velocity)
    frequency = positive(frequency, "frequency", "Hz")
    xml_path = os.path.abspath(os.fspath(xml_path))
    timing = dict.fromkeys(("hash", "cache_read", "load", "solve", "convert", "cache_write"), 0.0)

    scene_hash = scene_content_hash(xml_path)
    t = time.perf_counter()
    timing["hash"] = t - t_start
    key = None
    if cache is not None:
        from .cache import trace_key

        key = trace_key(scene_hash=scene_hash, radar_position=radar, ris_positions=ris,
                        radar_velocity=velocity, frequency=frequency, settings=settings)
        hit = cache.load(key)
        timing["cache_read"] = time.perf_counter() - t
        if hit is not None:
            return TraceResult(monostatic=hit.monostatic, legs=hit.legs, scene_hash=hit.scene_hash,
                               cache_hit=True, timing=timing, settings=hit.settings,
                               radar_velocity=hit.radar_velocity)

    from dsp.budget import check_memory

    check_memory(settings.memory_estimate(1 + len(ris)),
                 f"tracing with max_depth={settings.max_depth} (--depth), samples_per_src={settings.samples_per_src} "
                 f"(--samples), max_num_paths_per_src={settings.max_num_paths_per_src}",
                 fix="lower --depth (3 finds every path above the noise in the example halls) or --samples")
    t = time.perf_counter()
    loaded, _reused = _scene_for(xml_path, frequency, scene_hash)
    timing["load"] = time.perf_counter() - t
    settings = settings_for_scene(settings, loaded)
    t = time.perf_counter()
    paths = solve_paths(loaded, radar_position=radar, ris_positions=ris, radar_velocity=velocity,
                        settings=settings)
    # Dr.Jit evaluates lazily; pulling tau to the host forces the solve into this timer.
    paths.tau.numpy()
    timing["solve"] = time.perf_counter() - t
    t = time.perf_counter()
    traced = paths_to_traced(paths, loaded, radar_position=radar, ris_positions=ris, radar_velocity=velocity,
                             max_depth=settings.max_depth)
    if settings.diffuse_reflection:
        traced = (traced[0], *(leg.strongest(MAX_DIFFUSE_LEGS) for leg in traced[1:]))
    timing["convert"] = time.perf_counter() - t
    result = TraceResult(monostatic=traced[0], legs=traced[1:], scene_hash=loaded.content_hash,
                         cache_hit=False, timing=timing, settings=settings, radar_velocity=velocity)
    if cache is not None and key is not None and loaded.content_hash == scene_hash:
        t = time.perf_counter()
        cache.store(key, result)
        timing["cache_write"] = time.perf_counter() - t
        result = TraceResult(monostatic=result.monostatic, legs=result.legs, scene_hash=result.scene_hash,
                             cache_hit=False, timing=timing, settings=settings, radar_velocity=velocity)
    return result
