"""The sionna-rt-facing layer: the only part of risloc-rt that imports sionna, mitsuba and drjit.

It loads Mitsuba XML scenes (:func:`load_scene`), traces a radar pose with one sionna-rt
``PathSolver`` call (:func:`trace_scene`), caches traces on disk (:class:`TraceCache`) and hands
the paths over as numpy (:class:`risloc_rt.hall.traced.TracedPaths`); :func:`material_jacobian`
gives every path's gain and its derivatives with respect to the named materials' ε_r and σ (Dr.Jit
automatic differentiation through the solver: ``docs/calibration-materials.md``).

Importing this package imports none of the heavy dependencies: the names below are loaded on
first use, and sionna-rt itself only inside the functions that need it, after
:func:`ensure_backend` has chosen a libLLVM that does not abort the process.
"""

from __future__ import annotations

from typing import TYPE_CHECKING
from ..._lazy import lazy_exports

_EXPORTS = {
    "BackendError": "backend",
    "backend_info": "backend",
    "ensure_backend": "backend",
    "find_libllvm": "backend",
    "LoadedScene": "scene",
    "SceneError": "scene",
    "load_scene": "scene",
    "scene_content_hash": "scene",
    "TraceResult": "result",
    "TraceSettings": "result",
    "trace_scene": "tracer",
    "TraceCache": "cache",
    "default_cache_dir": "cache",
    "trace_key": "cache",
    "MaterialJacobian": "material_gradients",
    "material_jacobian": "material_gradients",
}

__all__ = sorted(_EXPORTS)

if TYPE_CHECKING:  # pragma: no cover
    from .backend import BackendError, backend_info, ensure_backend, find_libllvm
    from .cache import TraceCache, default_cache_dir, trace_key
    from .result import TraceResult, TraceSettings
    from .scene import LoadedScene, SceneError, load_scene, scene_content_hash
    from .material_gradients import MaterialJacobian, material_jacobian
    from .tracer import trace_scene


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
