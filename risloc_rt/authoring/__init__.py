"""Declarative hall scenes: TOML spec -> Mitsuba XML + PLY meshes sionna-rt loads, and checks.

* :mod:`.spec` -- :func:`load_spec` reads a hall spec (schema in its docstring) into a frozen
  :class:`HallSpec`; :class:`SpecError` names the key path and the fix.
* :mod:`.objects`, :mod:`.radios`, :mod:`.materials` -- the parts of a spec (objects and meshes,
  RIS and radar, radio materials checked at the carrier frequency).
* :mod:`.build` -- :func:`build_scene` writes ``scene.xml``, ``meshes/*.ply`` and ``spec.toml``
  deterministically; ``python -m risloc_rt.authoring.build SPEC -o DIR``.
* :mod:`.geometry` -- :class:`HallGeometry` of a built scene: ``check_point`` for radar and RIS
  positions.
* :mod:`.check` -- :func:`check_scene` validates a spec or a built folder (mesh quality, closure,
  placement, materials, grating lobes, range) into a :class:`CheckReport`.
* :mod:`.show` -- :func:`show_scene` draws the plan and elevation (optionally traced paths) to a PNG.
* :mod:`.fitted_scene` -- a hall's spec with fitted materials, built atomically into a new scene
  folder with its provenance (``risloc calibrate --materials``).
* :mod:`.cli` -- ``risloc scene build|check|show`` (:func:`~.cli.add_scene_parser`).

Tutorial: ``docs/scene-authoring.md``.

Pure numpy/trimesh (and matplotlib for :mod:`.show`): nothing here imports sionna, mitsuba or drjit
(``risloc scene show --paths`` traces through :mod:`risloc_rt.hall`). The build, geometry, check and
show modules are imported on first use, so ``python -m risloc_rt.authoring.build`` runs cleanly.
"""

from __future__ import annotations

from typing import Any

from ._parse import SpecError
from .spec import HallSpec, load_spec, loads_spec

__all__ = ["SpecError", "HallSpec", "load_spec", "loads_spec", "BuiltScene", "build_scene", "HallGeometry",
           "load_geometry", "CheckReport", "Issue", "check_scene", "SceneFigure", "show_scene"]

_LAZY = {"BuiltScene": "build", "build_scene": "build", "HallGeometry": "geometry", "load_geometry": "geometry",
         "CheckReport": "check", "Issue": "check", "check_scene": "check", "SceneFigure": "show",
         "show_scene": "show"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
