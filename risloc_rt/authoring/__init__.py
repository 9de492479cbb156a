"""Declarative hall scenes: TOML spec -> Mitsuba XML + PLY meshes sionna-rt loads, and checks.

* :mod:`.spec` -- :func:`load_spec` reads a hall spec (schema in its docstring) into a frozen
  :class:`HallSpec`; :class:`SpecError` names the key path and the fix.
* :mod:`.objects`, :mod:`.radios`, :mod:`.materials` -- the parts of a spec (objects and meshes,
  RIS and radar, radio materials checked at the carrier frequency).
* :mod:`.build` -- :func:`build_scene` writes ``scene.xml``, ``meshes/*.ply`` and ``spec.toml``
  deterministically; ``python -m risloc_rt.authoring.build SPEC -o DIR``.
* :mod:`.geometry` -- :class:`HallGeometry` of a built scene: ``check_point`` for radar and RIS
  positions.

Pure numpy/trimesh: nothing here imports sionna, mitsuba or drjit. The build and geometry modules
are imported on first use, so ``python -m risloc_rt.authoring.build`` runs cleanly.
"""

from __future__ import annotations

from typing import Any

from ._parse import SpecError
from .spec import HallSpec, load_spec, loads_spec

__all__ = ["SpecError", "HallSpec", "load_spec", "loads_spec", "BuiltScene", "build_scene", "HallGeometry",
           "load_geometry"]

_LAZY = {"BuiltScene": "build", "build_scene": "build", "HallGeometry": "geometry", "load_geometry": "geometry"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
