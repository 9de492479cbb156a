"""Load a Mitsuba XML scene into sionna-rt at the carrier frequency, or fail with a clear reason.

A scene is ``scenes/<name>/<name>.xml`` plus the meshes it references (``meshes/*.ply``,
relative to the XML's folder). :func:`load_scene` turns every failure sionna-rt or Mitsuba can
raise into a :class:`SceneError` naming the file, the problem and the fix, and refuses a material
that is not defined at the carrier frequency (sionna-rt raises while setting
``scene.frequency`` but leaves the material at its old values, and a later solve would run
silently with them). :func:`scene_content_hash` is what the trace cache keys on.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Any

from dsp.validation import positive

from ...authoring.scene_folder import SceneError, scene_content_hash

__all__ = ["LoadedScene", "SceneError", "load_scene", "scene_content_hash"]

#: ITU-R P.2040 materials sionna-rt 2.2 defines at 60 GHz (for error messages).
_ITU_AT_60GHZ = "concrete, glass, metal, wood, plasterboard, ceiling_board, chipboard"


@dataclass(frozen=True)
class LoadedScene:
    """A sionna-rt scene loaded at one carrier frequency.

    Attributes
    ----------
    scene : sionna.rt.Scene
        The loaded scene (``merge_shapes=False``, so every shape is its own object). Mutable:
        :func:`risloc_rt.hall.raytrace.trace_scene` adds and removes radios on it.
    path : str
        Absolute path of the XML file.
    frequency : float
        Carrier frequency the materials were evaluated at [Hz].
    content_hash : str
        :func:`scene_content_hash` of the XML and its meshes.
    object_names : tuple of str
        Scene object names, sorted (the shape ids without sionna's ``mesh-`` prefix).
    materials : dict
        ``{name: (itu_type or "custom", relative_permittivity, conductivity [S/m], thickness [m])}``
        evaluated at ``frequency``; NaN for materials without these parameters (absorbers).
    """

    scene: Any = field(repr=False, compare=False)
    path: str
    frequency: float
    content_hash: str
    object_names: tuple[str, ...]
    materials: dict[str, tuple[str, float, float, float]] = field(compare=False)


def _one_line(exc: BaseException, limit: int = 400) -> str:
    """The last informative line of a (possibly multi-line, traceback-carrying) message."""
    text = str(exc).strip()
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if len(lines) > 1:
        text = f"{lines[0]} ... {lines[-1]}"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _load_error(xml_path: str, exc: BaseException) -> SceneError:
    msg = str(exc)
    if m := re.search(r'Plugin "([^"]+)" not found', msg):
        return SceneError(
            f"scene file {xml_path} uses an unknown Mitsuba plugin type {m.group(1)!r}; fix the type= "
            f"attribute (shapes: 'ply', 'obj'; materials: 'itu-radio-material', 'radio-material'). [{_one_line(exc)}]"
        )
    if m := re.search(r'Error while loading PLY file "([^"]+)"', msg):
        return SceneError(
            f"scene file {xml_path}: mesh {m.group(1)!r} cannot be read (missing or corrupt PLY); "
            f"regenerate the mesh (e.g. with trimesh's PLY export). [{_one_line(exc)}]"
        )
    if m := re.search(r'Invalid ITU material type "([^"]+)"', msg):
        return SceneError(
            f"scene file {xml_path}: unknown ITU material type {m.group(1)!r}; use an ITU-R P.2040 name "
            f"defined at the carrier (at 60 GHz: {_ITU_AT_60GHZ}) or a <bsdf type=\"radio-material\"> with "
            "relative_permittivity, conductivity and thickness"
        )
    if m := re.search(r"ITU material '([^']+)' are not defined for this frequency", msg):
        return SceneError(
            f"scene file {xml_path}: ITU material {m.group(1)!r} is not defined at sionna-rt's default "
            "3.5 GHz, at which it evaluates materials while loading, so it cannot be loaded from XML; "
            "replace it with a <bsdf type=\"radio-material\"> whose relative_permittivity, conductivity "
            "and thickness are the ITU-R P.2040 values at the carrier"
        )
    if "Missing property" in msg or "not a radio material" in msg or "ITU material names must" in msg:
        return SceneError(f"scene file {xml_path} has an invalid material definition: {_one_line(exc)}")
    return SceneError(f"scene file {xml_path} cannot be loaded by sionna-rt: {type(exc).__name__}: {_one_line(exc)}")


def _material_summary(scene: Any) -> dict[str, tuple[str, float, float, float]]:
    def num(value: Any) -> float:
        try:
            return float(value[0])
        except (TypeError, IndexError):
            return float(value)

    out: dict[str, tuple[str, float, float, float]] = {}
    for name, mat in sorted(scene.radio_materials.items()):
        kind = getattr(mat, "itu_type", None) or "custom"
        try:
            values = (num(mat.relative_permittivity), num(mat.conductivity), num(mat.thickness))
        except AttributeError:
            kind, values = type(mat).__name__, (math.nan, math.nan, math.nan)
        out[name] = (str(kind), *values)
    return out


def _set_frequency(scene: Any, xml_path: str, frequency: float) -> None:
    """``scene.frequency = frequency``, refusing any material undefined there (no silent fallback)."""
    try:
        scene.frequency = frequency
    except ValueError:
        # sionna stops at the first bad material and leaves the rest at their old values; find all.
        bad, types = [], set()
        for name, mat in sorted(scene.radio_materials.items()):
            try:
                mat.frequency_update()
            except ValueError:
                types.add(getattr(mat, "itu_type", "?"))
                bad.append(f"{name!r} (ITU type {getattr(mat, 'itu_type', '?')!r})")
        note = (" (sionna-rt stores the frequency as float32: 60e9 becomes 60.000002 GHz, just above "
                "marble's 60 GHz limit; 59.99e9 works.)") if "marble" in types else ""
        raise SceneError(
            f"scene file {xml_path}: material {', '.join(bad) or '?'} is not defined at "
            f"{frequency / 1e9:g} GHz (frequency={frequency:g} Hz) in ITU-R P.2040 / sionna-rt; "
            f"use a material valid there (at 60 GHz: {_ITU_AT_60GHZ}) or a <bsdf type=\"radio-material\"> "
            f"with explicit relative_permittivity, conductivity and thickness.{note}"
        ) from None


#: Largest extent a scene may have [m]: a larger one is almost always a hall in millimetres.
MAX_SCENE_EXTENT = 1000.0


def _check_extent(scene: Any, xml_path: str) -> None:
    """Refuse a scene larger than :data:`MAX_SCENE_EXTENT` (meshes written in millimetres)."""
    try:
        bbox = scene.mi_scene.bbox()
        extent = max(float(bbox.max[i]) - float(bbox.min[i]) for i in range(3))
    except Exception:  # noqa: BLE001 - an empty or unusual scene: nothing to check
        return
    if math.isfinite(extent) and extent > MAX_SCENE_EXTENT:
        raise SceneError(
            f"scene file {xml_path} spans {extent:.4g} m, more than the {MAX_SCENE_EXTENT:g} m of any hall: its meshes "
            "are not in metres (millimetres?); rebuild it from a spec with lengths in metres, or set scale = 0.001 "
            "for an imported mesh in millimetres")


def load_scene(xml_path: str | os.PathLike[str], *, frequency: float) -> LoadedScene:
    """Load a Mitsuba XML scene into sionna-rt with materials evaluated at ``frequency``.

    Parameters
    ----------
    xml_path : path-like
        The scene's XML file; meshes are resolved relative to its folder and must lie inside it.
    frequency : float
        Carrier frequency [Hz], > 0.

    Returns
    -------
    LoadedScene

    Raises
    ------
    SceneError
        Missing file, malformed XML, missing or corrupt mesh, a mesh reference leaving the
        scene's folder (``..``, an absolute path, a symbolic link out; checked before sionna-rt
        reads anything), unknown plugin or material type, or a material not defined at ``frequency``.
    """
    from .backend import ensure_backend

    xml_path = os.path.abspath(os.fspath(xml_path))
    frequency = positive(frequency, "frequency", "Hz")
    content_hash = scene_content_hash(xml_path)  # also checks the XML parses and its meshes exist
    ensure_backend()
    import sionna.rt as rt

    try:
        scene = rt.load_scene(xml_path, merge_shapes=False)
    except SceneError:
        raise
    except Exception as exc:  # Mitsuba raises RuntimeError, sionna ValueError/TypeError
        raise _load_error(xml_path, exc) from exc
    _check_extent(scene, xml_path)
    _set_frequency(scene, xml_path, frequency)
    return LoadedScene(
        scene=scene,
        path=xml_path,
        frequency=frequency,
        content_hash=content_hash,
        object_names=tuple(sorted(scene.objects)),
        materials=_material_summary(scene),
    )
