"""Exact derivatives of the traced monostatic path gains with respect to the materials' ε_r, σ and S.

:func:`material_jacobian` traces one radar position with sionna-rt's ``PathSolver`` (transmitter
and receiver at the radar, the settings and conventions of
:func:`risloc_rt.hall.raytrace.trace_scene`) and differentiates every path's complex gain ``a``
with respect to the relative permittivity ε_r and the conductivity σ [S/m] of each named radio
material, by Dr.Jit forward-mode automatic differentiation through the solver. The result is a
:class:`MaterialJacobian`: the paths as the tracer reports them and the two complex Jacobians
``d_eps`` [P, Q] (per unit ε_r) and ``d_sigma`` [P, Q] (per S/m), and, for the materials named in
``scattering``, ``d_scattering`` [P, Q_s] (per unit of the scattering coefficient S).

How (sionna-rt 2.2.0, Mitsuba 3.9.1, Dr.Jit 1.5.0)
-------------------------------------------------
- The scene's materials are sionna-rt radio materials whose ``relative_permittivity`` and
  ``conductivity`` are ``mi.Float`` variables (an ITU material holds its frequency formula's
  values at the carrier). They are set to the requested values (by default the ITU values, so the
  gains equal :func:`~risloc_rt.hall.raytrace.trace_scene`'s), made opaque (a new value does not
  recompile the kernels) and, one at a time, marked as requiring gradients.
- The solver runs with ``loop_mode = "evaluated"``: in sionna-rt's default ``"symbolic"`` mode the
  forward derivative raises ``RuntimeError: ... jit_var_add(...): operands have incompatible
  sizes``.
- Dr.Jit refuses to keep the AD graph of a solve for a second traversal (``ad_traverse(): tried to
  forward-propagate derivatives across edge ... outside of the current dr.isolate_grad() scope``), so each
  differentiated parameter gets its own deterministic solve followed by one ``dr.forward_to(a)``. With diffuse
  reflection off, σ needs none (Conventions: ∂a/∂σ follows from ∂a/∂ε_r), so Q solves give both Jacobians;
  with it on, 2·Q. Each solve is sorted as the tracer sorts (sionna-rt's raw order of diffuse paths changes
  from solve to solve; the set does not), and the sorted paths and gains of all solves are checked to be
  identical.
- Dr.Jit computes in float32 (``*_mono_polarized`` variants): the gains and their derivatives
  carry float32 rounding (relative ~1e-6 of the largest terms).

Conventions
-----------
SI units. ``a`` is sionna-rt's ``Paths.a`` (V-polarised isotropic antennas at both ends, V-V),
*without* the propagation phase ``exp(-j2π f τ)``: ``|a|² = (λ/(4π L))² Π|Γ|²`` for a specular
path of unfolded length L. The complex relative permittivity is ``η = ε_r − jσ/(ε0 ω)``, so for
every path whose gain is a holomorphic function of η (specular reflection, refraction and
diffraction, measured to 3e-5) ``∂a/∂σ = −j/(ε0 ω) · ∂a/∂ε_r``; a diffusely reflected path's gain
is not (the identity fails by more than the derivative itself). So with diffuse reflection off (every
path specular, refracted or diffracted) ``d_sigma`` is ``−j/(ε0 ω)·d_eps`` (``sigma_by_identity``; a test
holds it against a σ pass of its own and against finite differences), and with it on both are computed
by AD.
"""

from __future__ import annotations

import math
import os
import time
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.constants

from dsp.validation import as_finite_array, positive

from ..traced import TracedPaths
from .result import TraceSettings
from .scene import LoadedScene, load_scene, scene_content_hash
from .tracer import paths_to_traced, solver_options

__all__ = ["MaterialJacobian", "material_jacobian", "material_objects", "DEFAULT_FREQUENCY"]

#: Carrier [Hz] used when none is given (the example halls' ``[scene] frequency``).
DEFAULT_FREQUENCY = 60e9
#: Names of the radios this module adds (the tracer's own are not public).
_TX, _RX = "jacobian_tx", "jacobian_rx"
#: Loaded scenes kept in memory, keyed by (content hash, frequency): the last one only. Every loaded scene's
#: radio materials stay in Dr.Jit's registry while it lives, and each solve dispatches over all of them: 5
#: Jacobians of paper_hall took 0.20-0.31 s alone and 0.42-1.12 s next to 1-4 other loaded halls, while loading
#: the hall again for each cost 0.62-0.70 s (`bench_material_gradients.py --alive`, 2026-11-28).
_SCENE_CACHE_SIZE = 1
_scenes: OrderedDict[tuple[str, float], tuple[LoadedScene, dict[str, tuple[float, float, float]]]] = OrderedDict()


@dataclass(frozen=True)
class MaterialJacobian:
    """Monostatic paths of one radar position and the derivatives of their gains w.r.t. materials.

    Attributes
    ----------
    paths : TracedPaths
        The monostatic paths exactly as :func:`risloc_rt.hall.raytrace.trace_scene` reports them
        for the same scene, position and settings (its ``monostatic``): round-trip ``delay`` [s],
        ``amplitude`` = ``a``, ``interactions``, ``objects``, ``vertices``, ``object_names``
        (sorted by delay, then depth, objects, interaction types, departure). ``delay_rate`` is 0
        (the radar is static here).
    materials : tuple of str
        The Q differentiated radio materials (sionna-rt names, e.g. ``"concrete-200mm"``), in the
        order of the Jacobians' columns.
    relative_permittivity : float array [Q]
        ε_r at which the derivatives were taken (as sionna-rt holds it: float32 values) [unitless].
    conductivity : float array [Q]
        σ at which the derivatives were taken (float32 values) [S/m].
    d_eps : complex array [P, Q]
        ``∂a_p/∂ε_r,q`` [1/unit ε_r].
    d_sigma : complex array [P, Q]
        ``∂a_p/∂σ_q`` [m/S].
    touches : bool array [P, Q]
        Path p interacts at least once with an object made of material q. A path that does not
        has exactly zero derivatives with respect to q.
    material_objects : dict
        ``{material: tuple of object names}`` for the Q materials (objects as in ``paths.object_names``).
    frequency : float
        Carrier [Hz] the scene was evaluated at.
    settings : TraceSettings
        Solver options used, as asked: unlike :func:`risloc_rt.hall.raytrace.trace_scene`, diffuse
        reflection is not turned on for a scattering material (the specular paths carry its
        √(1 − S²) either way; the diffuse ones change their set with S, see ``d_scattering``).
    scene_hash : str
        :func:`risloc_rt.hall.raytrace.scene_content_hash` of the traced scene.
    timing : dict
        Wall-clock seconds: ``load`` (0 when the scene was loaded before in this process),
        ``solve`` (all Q or 2·Q, + Q_s, solves and their forward derivatives), ``convert``, ``total``.
    scattering : tuple of str
        The Q_s materials (a subset of ``materials``, in their order) whose scattering coefficient
        was differentiated; empty by default.
    scattering_coefficient : float array [Q]
        S at which the derivatives were taken (float32 values) [unitless]; zeros when not given.
    d_scattering : complex array [P, Q_s]
        ``∂a_p/∂S_q`` [1/unit S] for the materials of ``scattering``. sionna-rt scales a specular
        reflection off a scattering material by √(1 − S²) and a diffuse one by S, so at S = 0 the
        specular part of this derivative is 0: the fit works in S² (see
        :mod:`risloc_rt.hall.material_fit`). With diffuse reflection on, sionna-rt samples each
        bounce's interaction type with probabilities set by S, so the *set* of diffuse paths
        changes with S (the specular set does not): the derivative holds at fixed paths.
    sigma_by_identity : bool
        ``d_sigma`` is ``−j/(ε0 ω)·d_eps`` (diffuse reflection off: every gain holomorphic in η, module
        notes) rather than a solve and forward pass of its own.
    """

    paths: TracedPaths
    materials: tuple[str, ...]
    relative_permittivity: np.ndarray
    conductivity: np.ndarray
    d_eps: np.ndarray
    d_sigma: np.ndarray
    touches: np.ndarray
    material_objects: dict[str, tuple[str, ...]]
    frequency: float
    settings: TraceSettings
    scene_hash: str
    timing: dict[str, float] = field(compare=False)
    scattering: tuple[str, ...] = ()
    scattering_coefficient: np.ndarray | None = None
    d_scattering: np.ndarray | None = None
    sigma_by_identity: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.paths, TracedPaths):
            raise TypeError(f"paths must be a TracedPaths, got {type(self.paths).__name__}")
        p, q = len(self.paths), len(self.materials)
        object.__setattr__(self, "scattering", tuple(str(m) for m in self.scattering))
        extra = [m for m in self.scattering if m not in self.materials]
        if extra:
            raise ValueError(f"scattering names {extra} outside materials {list(self.materials)}")
        qs = len(self.scattering)
        arrays = {
            "scattering_coefficient": np.zeros(q) if self.scattering_coefficient is None
            else np.array(self.scattering_coefficient, dtype=float).reshape(q),
            "d_scattering": np.zeros((p, qs), complex) if self.d_scattering is None
            else np.array(self.d_scattering, dtype=complex).reshape(p, qs),
            "relative_permittivity": np.array(self.relative_permittivity, dtype=float).reshape(q),
            "conductivity": np.array(self.conductivity, dtype=float).reshape(q),
            "d_eps": np.array(self.d_eps, dtype=complex).reshape(p, q),
            "d_sigma": np.array(self.d_sigma, dtype=complex).reshape(p, q),
            "touches": np.array(self.touches, dtype=bool).reshape(p, q),
        }
        for name, value in arrays.items():
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "materials", tuple(str(m) for m in self.materials))
        object.__setattr__(self, "frequency", float(self.frequency))

    @property
    def delay(self) -> np.ndarray:
        """Round-trip delay of each path [s], float [P]."""
        return self.paths.delay

    @property
    def a(self) -> np.ndarray:
        """Complex gain of each path (``Paths.a``, V-V, without ``exp(-j2π f τ)``) [unitless], complex [P]."""
        return self.paths.amplitude

    @property
    def seen(self) -> np.ndarray:
        """bool [Q]: material q is touched by at least one path."""
        return self.touches.any(axis=0)

    @property
    def unseen(self) -> tuple[str, ...]:
        """The named materials that no traced path touches (their derivatives are all zero)."""
        return tuple(m for m, s in zip(self.materials, self.seen) if not s)

    def path_materials(self, index: int) -> tuple[str, ...]:
        """The differentiated materials path ``index`` interacts with.

        Parameters
        ----------
        index : int
            Path index in ``paths`` (0 ≤ index < P).

        Returns
        -------
        tuple of str
            Material names, in the order of ``materials``.
        """
        return tuple(m for m, t in zip(self.materials, self.touches[index]) if t)


def material_objects(loaded: LoadedScene) -> dict[str, tuple[str, ...]]:
    """``{radio material name: sorted object names}`` of a loaded scene.

    Parameters
    ----------
    loaded : LoadedScene
        From :func:`risloc_rt.hall.raytrace.load_scene`.

    Returns
    -------
    dict
        Every radio material of the scene, with the objects that use it (empty when none does).
    """
    out: dict[str, list[str]] = {name: [] for name in loaded.scene.radio_materials}
    for name, obj in loaded.scene.objects.items():
        out.setdefault(obj.radio_material.name, []).append(name)
    return {k: tuple(sorted(v)) for k, v in sorted(out.items())}


def _xml_path(scene: str | os.PathLike[str]) -> str:
    path = os.path.abspath(os.fspath(scene))
    if os.path.isdir(path):
        path = os.path.join(path, "scene.xml")
    return path


def _loaded(xml_path: str, frequency: float) -> tuple[LoadedScene, dict[str, tuple[float, float, float]], bool]:
    """The scene (loaded at most once per process) and its materials' own (ε_r, σ, S)."""
    key = (scene_content_hash(xml_path), frequency)
    if key in _scenes:
        _scenes.move_to_end(key)
        return (*_scenes[key], True)
    loaded = load_scene(xml_path, frequency=frequency)
    own = {}
    for name, mat in loaded.scene.radio_materials.items():
        if hasattr(mat, "relative_permittivity") and hasattr(mat, "conductivity"):
            own[name] = (float(mat.relative_permittivity[0]), float(mat.conductivity[0]),
                         float(mat.scattering_coefficient[0]))
    _scenes[(loaded.content_hash, frequency)] = (loaded, own)
    while len(_scenes) > _SCENE_CACHE_SIZE:
        _scenes.popitem(last=False)
    return loaded, own, False


def _material_list(materials: Any, available: Mapping[str, tuple[float, ...]], loaded: LoadedScene) -> tuple[str, ...]:
    if isinstance(materials, str):
        materials = [m.strip() for m in materials.split(",")]
    if not isinstance(materials, Sequence) or isinstance(materials, (bytes, bytearray)):
        raise TypeError(f"materials must be a name, 'a,b' or a sequence of names, got {type(materials).__name__}")
    names = tuple(materials)
    if not names:
        raise ValueError("materials is empty: name at least one of the scene's radio materials")
    for m in names:
        if not isinstance(m, str):
            raise TypeError(f"materials holds {m!r}: material names must be str")
    dup = sorted({m for m in names if names.count(m) > 1})
    if dup:
        raise ValueError(f"materials names {', '.join(map(repr, dup))} more than once")
    for m in names:
        if m not in available:
            raise ValueError(f"material {m!r} is not a radio material of scene {loaded.path}; "
                             f"its materials are {_describe(loaded, available)}")
    return names


def _describe(loaded: LoadedScene, available: Mapping[str, tuple[float, ...]]) -> str:
    return ", ".join(f"{name} ({loaded.materials.get(name, ('custom',))[0]})" for name in sorted(available)) or "none"


def _check_value(material: str, given: tuple[Any, ...]) -> tuple[float, ...]:
    out = []
    limits = (("relative_permittivity", 1.0, 3.0e38, ""), ("conductivity", 0.0, 3.0e38, " S/m"),
              ("scattering_coefficient", 0.0, 1.0, ""))
    for (what, low, high, unit), value in zip(limits, given):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError(f"values[{material!r}] {what}={value!r} must be a number")
        v = float(value)
        if not math.isfinite(v) or v < low or v > high:
            raise ValueError(f"values[{material!r}] {what}={v!r} is outside what sionna-rt accepts "
                             + (f"(a finite float32 >= {low:g}{unit})" if high > 1.0 else f"([{low:g}, {high:g}])"))
        out.append(v)
    return tuple(out)


def _values(values: Any, available: Mapping[str, tuple[float, float, float]],
            loaded: LoadedScene) -> dict[str, tuple[float, float, float]]:
    """``{material: (ε_r, σ, S)}`` asked; S is the scene's own where only (ε_r, σ) is given."""
    if values is None:
        return {}
    if not isinstance(values, Mapping):
        raise TypeError(f"values must be a mapping {{material: (relative_permittivity, conductivity [S/m]"
                        f"[, scattering_coefficient])}}, got {type(values).__name__}")
    out = {}
    for name, given in values.items():
        if name not in available:
            raise ValueError(f"values names material {name!r}, which is not a radio material of scene {loaded.path}; "
                             f"its materials are {_describe(loaded, available)}")
        try:
            given = tuple(given)
        except TypeError:
            given = ()
        if len(given) not in (2, 3):
            raise TypeError(f"values[{name!r}]={values[name]!r} must be a pair (relative_permittivity, conductivity "
                            "[S/m]) or a triple with the scattering coefficient S") from None
        checked = _check_value(name, given)
        out[name] = (checked[0], checked[1], checked[2] if len(checked) == 3 else available[name][2])
    return out


def _set_material(mat: Any, eps: float, sigma: float, scattering: float) -> None:
    """Give ``mat`` fresh opaque ε_r, σ and S variables (a new value then reuses the compiled kernels)."""
    import drjit as dr

    mat.relative_permittivity = eps
    mat.conductivity = sigma
    mat.scattering_coefficient = scattering
    dr.make_opaque(mat.relative_permittivity, mat.conductivity, mat.scattering_coefficient)


class _Arrays:
    """Stand-in for ``sionna.rt.Paths`` handing :func:`paths_to_traced` numpy arrays."""

    def __init__(self, paths: Any, a: tuple[np.ndarray, np.ndarray]) -> None:
        self._paths = paths
        self.a = tuple(_Numpy(x) for x in a)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._paths, name)


class _Numpy:
    def __init__(self, value: np.ndarray) -> None:
        self._value = value

    def numpy(self) -> np.ndarray:
        return self._value


def _sorted(paths: Any, value: tuple[np.ndarray, np.ndarray], loaded: LoadedScene,
            kwargs: dict[str, Any]) -> tuple[TracedPaths, np.ndarray]:
    """The monostatic paths of one solve as the tracer sorts them, and each one's raw index.

    sionna-rt's raw path order is not reproducible for diffuse reflection (the set is), so every
    solve is sorted on its own: the same conversion with each raw path's index as its "gain"
    gives the permutation.
    """
    (traced,) = paths_to_traced(_Arrays(paths, value), loaded, **kwargs)
    index = np.broadcast_to(np.arange(value[0].shape[-1], dtype=np.float64), value[0].shape)
    (order,) = paths_to_traced(_Arrays(paths, (index, np.zeros_like(index))), loaded, **kwargs)
    return traced, np.rint(order.amplitude.real).astype(np.int64)


def _same(a: TracedPaths, b: TracedPaths) -> bool:
    """Two solves found the same paths with the same gains."""
    return (len(a) == len(b) and np.array_equal(a.delay, b.delay) and np.array_equal(a.interactions, b.interactions)
            and np.array_equal(a.objects, b.objects) and np.array_equal(a.amplitude, b.amplitude))


def material_jacobian(
    scene: str | os.PathLike[str],
    radar_position: Any,
    materials: str | Sequence[str],
    *,
    values: Mapping[str, tuple[float, ...]] | None = None,
    frequency: float = DEFAULT_FREQUENCY,
    settings: TraceSettings | None = None,
    scattering: Sequence[str] = (),
    derivatives: bool = True,
    sigma_by_identity: bool = True,
) -> MaterialJacobian:
    """Trace a monostatic radar and differentiate every path's gain w.r.t. named materials' ε_r, σ (and S).

    Parameters
    ----------
    scene : path-like
        A scene folder (``scenes/<name>/`` with ``scene.xml``) or the XML file itself.
    radar_position : float array [3]
        Radar (transmitter and receiver) position, world frame [m].
    materials : str or sequence of str
        Radio materials to differentiate, by sionna-rt name (``LoadedScene.materials``' keys, the
        XML's bsdf id without ``mat-``, e.g. ``"concrete-200mm"``): a list or ``"a,b"``.
    values : mapping, optional
        ``{material: (relative_permittivity [unitless], conductivity [S/m])}`` at which to trace
        and differentiate, or a triple adding the scattering coefficient S [unitless]; any radio
        material of the scene may be given. Materials not given keep the scene's own values
        (ITU-R P.2040 at ``frequency`` for ITU materials; the spec's S). sionna-rt accepts
        ε_r ≥ 1, σ ≥ 0 and S in [0, 1].
    frequency : float
        Carrier [Hz] the materials are evaluated at (default 60 GHz).
    settings : TraceSettings, optional
        Solver options (default ``TraceSettings()``), as for
        :func:`risloc_rt.hall.raytrace.trace_scene`; ``scattering_coefficient`` is applied to
        every material for this call, as there. Diffuse reflection is traced only when asked
        (``trace_scene`` turns it on for a scene whose materials scatter; here the paths then
        match its specular ones).
    scattering : sequence of str
        Materials among ``materials`` whose scattering coefficient S is differentiated too
        (``d_scattering``); not with ``settings.scattering_coefficient``, which overrides every S.
    derivatives : bool
        ``False``: one solve without automatic differentiation, the gains only (every derivative
        array is 0): for a search over values (1/(Q + Q_s) of the cost).
    sigma_by_identity : bool
        With diffuse reflection off, take ``d_sigma`` as ``−j/(ε0 ω)·d_eps`` (exact for gains holomorphic in η,
        module notes), saving Q of the solves; ``False``: a solve of its own for each σ (to check the identity).
        Ignored with diffuse reflection on.

    Returns
    -------
    MaterialJacobian
        The paths (identical to ``trace_scene(...).monostatic`` at the same values) and ``d_eps``,
        ``d_sigma`` [P, Q], ``d_scattering`` [P, Q_s].

    Raises
    ------
    ValueError, TypeError
        A material not in the scene (the message lists its materials), named twice, or an empty
        list; a value outside what sionna-rt accepts; a bad position, frequency or settings.
    SceneError
        The scene cannot be loaded (see :func:`risloc_rt.hall.raytrace.load_scene`).
    BackendError
        No usable Dr.Jit backend.
    RuntimeError
        The solves did not return the same paths (cannot happen with the deterministic solver).

    Notes
    -----
    Cost: Q + Q_s solves (2·Q + Q_s with diffuse reflection on, or ``sigma_by_identity=False``) with
    ``loop_mode="evaluated"``, each followed by one forward-mode derivative. The scene's materials are
    restored to their own values afterwards (the loaded scene is cached per process, keyed by content hash and
    frequency).
    """
    t0 = time.perf_counter()
    settings = TraceSettings() if settings is None else settings
    if not isinstance(settings, TraceSettings):
        raise TypeError(f"settings must be a TraceSettings, got {type(settings).__name__}")
    radar = as_finite_array(radar_position, "radar_position", shape=(3,))
    frequency = positive(frequency, "frequency", "Hz")
    xml_path = _xml_path(scene)
    loaded, own, cached = _loaded(xml_path, frequency)
    t_load = 0.0 if cached else time.perf_counter() - t0
    names = _material_list(materials, own, loaded)
    asked = _values(values, own, loaded)
    rough = _scattering_list(scattering, names, settings)

    import drjit as dr
    import mitsuba as mi
    import sionna.rt as rt

    sc = loaded.scene
    mats = sc.radio_materials
    t1 = time.perf_counter()
    old = list(sc.transmitters) + list(sc.receivers)
    if old:
        sc.remove(old)
    sc.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    sc.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    pos = mi.Point3f(*map(float, radar))
    sc.add([rt.Transmitter(name=_TX, position=pos), rt.Receiver(name=_RX, position=pos)])
    solver = rt.PathSolver(deterministic=True)
    solver.loop_mode = "evaluated"  # "symbolic" cannot carry forward derivatives (see module notes)

    saved_s = {}
    traced: TracedPaths | None = None
    grads: dict[tuple[str, str], np.ndarray] = {}
    kwargs = dict(radar_position=radar, ris_positions=np.zeros((0, 3)), radar_velocity=np.zeros(3),
                  max_depth=settings.max_depth)
    t_convert = 0.0
    try:
        for name in own:
            _set_material(mats[name], *asked.get(name, own[name]))
        if settings.scattering_coefficient is not None:
            for name, mat in mats.items():
                if hasattr(mat, "scattering_coefficient"):
                    saved_s[name] = mat.scattering_coefficient
                    mat.scattering_coefficient = settings.scattering_coefficient
        at = np.array([[float(mats[n].relative_permittivity[0]), float(mats[n].conductivity[0]),
                        float(mats[n].scattering_coefficient[0])] for n in names])
        by_identity = bool(sigma_by_identity) and not settings.diffuse_reflection
        kinds = ("relative_permittivity",) if by_identity else ("relative_permittivity", "conductivity")
        wanted = [(n, k) for n in names for k in kinds]
        wanted += [(n, "scattering_coefficient") for n in rough]
        if not derivatives:
            wanted = [(names[0], None)]
        for name, kind in wanted:
            param = getattr(mats[name], kind) if kind is not None else None
            if param is not None:
                dr.enable_grad(param)
            try:
                paths = solver(sc, **solver_options(settings))
                a_re, a_im = paths.a
                if param is not None:
                    dr.set_grad(param, 1.0)
                    dr.forward_to(a_re, a_im)
                    g = np.asarray(dr.grad(a_re).numpy(), np.float64) + 1j * np.asarray(dr.grad(a_im).numpy(), np.float64)
                value = (np.asarray(dr.detach(a_re).numpy()), np.asarray(dr.detach(a_im).numpy()))
                if param is None:
                    g = np.zeros(value[0].shape, complex)
            finally:
                if param is not None:
                    dr.disable_grad(param)
            t = time.perf_counter()
            this, order = _sorted(paths, value, loaded, kwargs)
            t_convert += time.perf_counter() - t
            if traced is None:
                traced = this
            elif not _same(this, traced):
                raise RuntimeError("sionna-rt returned different paths for two solves of the same scene and "
                                   "position (the deterministic solver should make them identical)")
            grads[(name, kind)] = g[0, 0, 0, 0, :][order]
        t_solve = time.perf_counter() - t1 - t_convert
    finally:
        for name, value in saved_s.items():
            mats[name].scattering_coefficient = value
        for name in own:
            _set_material(mats[name], *own[name])
    assert traced is not None  # names is never empty
    t2 = time.perf_counter()
    p_count = len(traced)
    def column(name: str, kind: str) -> np.ndarray:
        return grads.get((name, kind), np.zeros(p_count, complex))

    d_eps = np.stack([column(n, "relative_permittivity") for n in names], axis=1).reshape(p_count, len(names))
    if by_identity and derivatives:  # η = ε_r − jσ/(ε0 ω): ∂a/∂σ = ∂a/∂η·∂η/∂σ = −j/(ε0 ω)·∂a/∂ε_r
        d_sigma = d_eps * (-1j / (scipy.constants.epsilon_0 * 2 * math.pi * frequency))
    else:
        d_sigma = np.stack([column(n, "conductivity") for n in names], axis=1).reshape(p_count, len(names))
    objects_of = material_objects(loaded)
    index_of = {obj: i for i, obj in enumerate(traced.object_names)}
    touches = np.zeros((len(traced), len(names)), dtype=bool)
    used = traced.interactions != 0
    for q, name in enumerate(names):
        ids = [index_of[o] for o in objects_of.get(name, ())]
        touches[:, q] = (np.isin(traced.objects, ids) & used).any(axis=1)
    t_convert += time.perf_counter() - t2
    return MaterialJacobian(
        paths=traced, materials=names, relative_permittivity=at[:, 0], conductivity=at[:, 1],
        d_eps=d_eps, d_sigma=d_sigma, touches=touches,
        material_objects={n: objects_of.get(n, ()) for n in names}, frequency=frequency, settings=settings,
        scene_hash=loaded.content_hash,
        timing={"load": t_load, "solve": t_solve, "convert": t_convert, "total": time.perf_counter() - t0},
        scattering=rough, scattering_coefficient=at[:, 2], sigma_by_identity=by_identity and derivatives,
        d_scattering=np.stack([column(n, "scattering_coefficient") for n in rough], axis=1).reshape(p_count, len(rough))
        if rough else None,
    )


def _scattering_list(scattering: Any, names: tuple[str, ...], settings: TraceSettings) -> tuple[str, ...]:
    """The materials whose S is differentiated, in the order of ``names``."""
    if isinstance(scattering, str):
        scattering = [m.strip() for m in scattering.split(",") if m.strip()]
    if not isinstance(scattering, Sequence):
        raise TypeError(f"scattering must be a sequence of material names, got {type(scattering).__name__}")
    unknown = [m for m in scattering if m not in names]
    if unknown:
        raise ValueError(f"scattering names {', '.join(map(repr, unknown))}, not among the differentiated materials "
                         f"({', '.join(names)})")
    if scattering and settings.scattering_coefficient is not None:
        raise ValueError(f"settings.scattering_coefficient={settings.scattering_coefficient:g} (--diffuse) gives every "
                         "material one S, so S cannot be differentiated per material: leave it out")
    return tuple(n for n in names if n in scattering)
