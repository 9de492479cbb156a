"""A scene folder with fitted materials: the hall's spec with named materials replaced, built, with provenance.

``risloc calibrate CAPTURE... --scene HALL --materials NAME,... --out DIR`` ends here
(``docs/calibration-materials.md``). The source scene's ``spec.toml`` is parsed, every place that
resolves to a fitted material (``[hall.materials]`` walls/floor/ceiling, an object's or imported
mesh's ``material``) gets a custom material ``{permittivity, conductivity, thickness, name}`` with
the fitted ε_r [unitless] and σ [S/m], the material's own thickness [m] and its own name, and its
``scattering_coefficient`` (the fitted S where it was fitted, else the source's own; left out at 0) (so the
fitted scene's materials keep the names sionna-rt knows them by, and ``--materials NAME`` works on
it again). The new spec is written as plain TOML (the source's comments are not kept; a header
names the source), checked to change exactly the named materials, and built with
:func:`risloc_rt.authoring.build.build_scene`: rebuilding the folder from its own ``spec.toml``
gives the same bytes.

**Atomic.** Everything (the build and :data:`PROVENANCE_NAME`) is written into a hidden temporary
folder beside the target and renamed into place at the end: a fit or a build that fails or is
killed leaves no half scene (at most a hidden ``.NAME.partial-*`` folder, never the target). An
existing target is refused unless ``force`` is given *and* it is a folder this module wrote (it
holds :data:`PROVENANCE_NAME`) or an empty one: a user's folder is never replaced.

**What the tracer can express.** sionna-rt's custom radio material accepts a real relative
permittivity ε_r ≥ 1, a conductivity σ ≥ 0 S/m, finite, and a scattering coefficient S in [0, 1];
anything else is one ``ValueError`` line naming the range (:func:`check_material_values`). The ITU-R P.2040 tables give ε_r and σ as
functions of frequency per material type, with no range of values, so no narrower range is
imposed here.

Pure Python: no ray tracer is imported.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .build import build_scene
from .scene_folder import scene_directory
from .spec import HallSpec, loads_spec

__all__ = ["PROVENANCE_NAME", "check_material_values", "check_fitted_target", "fitted_spec_text",
           "write_fitted_scene"]

#: The provenance file of a fitted scene folder (JSON: captures, their hashes, the fit's values, σ, ...).
PROVENANCE_NAME = "material-fit.json"
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def check_material_values(values: Mapping[str, Any]) -> dict[str, tuple[float, ...]]:
    """The fitted values as ``{name: (ε_r, σ)}`` or ``(ε_r, σ, S)``, refusing what sionna-rt's custom material cannot express.

    Parameters
    ----------
    values : mapping
        ``{material name: (ε_r [unitless], σ [S/m])}``, or ``(ε_r, σ, S [unitless])`` where the
        scattering coefficient was fitted.

    Returns
    -------
    dict
        The same, as floats.

    Raises
    ------
    ValueError
        Empty, not a pair or triple, NaN/inf, ε_r < 1, σ < 0 S/m or S outside [0, 1]: one line naming
        the material and the range.
    """
    if not values:
        raise ValueError("no fitted material values were given")
    out: dict[str, tuple[float, ...]] = {}
    for name, given in values.items():
        try:
            numbers = tuple(float(x) for x in given)
        except (TypeError, ValueError):
            numbers = ()
        if len(numbers) not in (2, 3):
            raise ValueError(f"material {name!r}: expected (eps_r, sigma [S/m]) or (eps_r, sigma, S), got {given!r}")
        eps, sigma = numbers[:2]
        if not (math.isfinite(eps) and eps >= 1.0 and math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"material {name!r}: eps_r={eps!r}, sigma={sigma!r} S/m cannot be ray traced: sionna-rt's "
                             "radio materials need a finite eps_r >= 1 and a finite sigma >= 0 S/m")
        if len(numbers) == 3 and not (math.isfinite(numbers[2]) and 0.0 <= numbers[2] <= 1.0):
            raise ValueError(f"material {name!r}: scattering coefficient S={numbers[2]!r} cannot be ray traced: "
                             "sionna-rt needs S in [0, 1]")
        out[str(name)] = numbers
    return out


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k, ensure_ascii=False)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise ValueError(f"spec value {v!r} of type {type(v).__name__} cannot be written back as TOML")


def _is_aot(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _emit(table: dict[str, Any], prefix: str, lines: list[str], *, top: bool) -> None:
    """Write ``table``'s scalars, then its sub-tables as ``[a.b]`` headers (top level: arrays of tables as ``[[a]]``)."""
    for k, v in table.items():
        if not isinstance(v, dict) and not (top and _is_aot(v)):
            lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in table.items():
        if isinstance(v, dict):
            lines += ["", f"[{prefix}{_key(k)}]"]
            _emit(v, f"{prefix}{_key(k)}.", lines, top=False)
    if top:
        for k, v in table.items():
            if _is_aot(v):
                for item in v:
                    lines += ["", f"[[{_key(k)}]]"]
                    for ik, iv in item.items():
                        lines.append(f"{_key(ik)} = {_value(iv)}")


def _source_spec(scene: str | os.PathLike[str]) -> tuple[Path, str]:
    folder = scene_directory(scene)
    path = folder / "spec.toml"
    if not path.is_file():
        raise ValueError(f"scene {scene}: {path} does not exist; a fitted scene is made from the hall's spec (build "
                         "the scene with 'risloc scene build SPEC' first)")
    return folder, path.read_text(encoding="utf-8")


def fitted_spec_text(scene: str | os.PathLike[str], values: Mapping[str, Any], *, note: str = "") -> str:
    """The spec of ``scene`` with the named materials replaced by custom materials of the fitted values.

    Parameters
    ----------
    scene : path-like or str
        A scene name in ``scenes/`` or a scene folder holding its ``spec.toml``.
    values : mapping
        ``{material name: (ε_r [unitless], σ [S/m])}``, or ``(ε_r, σ, S)`` with a fitted scattering
        coefficient [unitless] (names as sionna-rt knows them, e.g. ``"concrete-200mm"``).
    note : str
        One line for the header comment (e.g. which captures the values come from).

    Returns
    -------
    str
        The new spec (TOML).

    Raises
    ------
    ValueError
        A value the tracer cannot express (:func:`check_material_values`); a name that is not a
        material of the spec; a material used where it cannot be rewritten (an RIS panel's, which
        the scene XML does not hold); a spec that then fails to load.
    """
    values = check_material_values(values)
    folder, text = _source_spec(scene)
    spec = loads_spec(text, base_dir=folder)
    known = spec.all_materials()
    for name in values:
        if name not in known:
            raise ValueError(f"{name!r} is not a material of {folder}/spec.toml; its materials: {', '.join(known)}")
    data = tomllib.loads(text)

    def custom(name: str) -> dict[str, Any]:
        eps, sigma, *rest = values[name]
        rough = rest[0] if rest else known[name].scattering_coefficient
        return {"permittivity": eps, "conductivity": sigma, "thickness": known[name].thickness, "name": name,
                **({"scattering_coefficient": rough} if rough > 0 else {})}

    shell = data["hall"]["materials"]
    for surface in ("walls", "floor", "ceiling"):
        if getattr(spec.materials, surface).name in values:
            shell[surface] = custom(getattr(spec.materials, surface).name)
    for key, parsed in (("objects", spec.objects), ("meshes", spec.meshes)):
        tables = data.get(key, [])
        for table, obj in zip(tables, parsed):
            if obj.material.name in values:
                table["material"] = custom(obj.material.name)
    lines = [f"# Fitted from scene {spec.name!r} ({folder}) by 'risloc calibrate --materials': "
             + ", ".join(f"{n}: eps_r {v[0]:.6g}, sigma {v[1]:.6g} S/m" + (f", S {v[2]:.6g}" if len(v) > 2 else "")
                         for n, v in values.items()),
             *([f"# {note}"] if note else []),
             "# Provenance (captures, sigma, correlation, identifiability): material-fit.json beside this file.", ""]
    _emit(data, "", lines, top=True)
    new = "\n".join(lines) + "\n"
    _check_rewrite(spec, loads_spec(new, base_dir=folder), values)
    return new


def _check_rewrite(old: HallSpec, new: HallSpec, values: Mapping[str, tuple[float, ...]]) -> None:
    """Exactly the named materials changed, to custom materials of the fitted values (else ValueError)."""
    before, after = old.all_materials(), new.all_materials()
    if list(before) != list(after):
        raise ValueError(f"rewriting the spec changed its materials from {list(before)} to {list(after)}")
    for name, mat in after.items():
        if name in values:
            eps, sigma, *rest = values[name]
            rough = rest[0] if rest else before[name].scattering_coefficient
            ok = mat.itu is None and (mat.permittivity, mat.conductivity, mat.scattering_coefficient) == (eps, sigma, rough)
        else:
            ok = mat == before[name]
        if not ok:
            raise ValueError(f"material {name!r} could not be rewritten in the spec (is it an RIS panel's?)")
    if new.object_names != old.object_names:
        raise ValueError("rewriting the spec changed its objects")


def check_fitted_target(out: str | os.PathLike[str], *, force: bool) -> Path:
    """Refuse an output folder a fitted scene may not be written to (call it before the fit).

    Parameters
    ----------
    out : path-like
        The target folder.
    force : bool
        Replace a folder this module wrote before (holding :data:`PROVENANCE_NAME`) or an empty one.

    Returns
    -------
    Path
        The target.

    Raises
    ------
    ValueError
        The target is a file; or it exists without ``force``; or it exists and is neither empty nor a fitted scene
        (then even with ``force``).
    """
    target = Path(out)
    if target.is_symlink() or (target.exists() and not target.is_dir()):
        raise ValueError(f"--out {target} is not a folder; name a new folder for the fitted scene")
    if target.exists():
        empty = not any(target.iterdir())
        ours = (target / PROVENANCE_NAME).is_file()
        if not (empty or ours):
            raise ValueError(f"--out {target} exists and is not a fitted scene folder (no {PROVENANCE_NAME}); "
                             "name a new folder (it is never replaced, even with --force)")
        if not force:
            raise ValueError(f"--out {target} exists; name a new folder, or give --force to replace it")
    if not target.parent.is_dir():
        raise ValueError(f"--out {target}: its parent folder {target.parent} does not exist")
    return target


def write_fitted_scene(scene: str | os.PathLike[str], out: str | os.PathLike[str], values: Mapping[str, Any],
                       provenance: Mapping[str, Any], *, force: bool = False, note: str = "") -> Path:
    """Build the fitted scene folder atomically: spec with the fitted materials, scene files, provenance.

    Parameters
    ----------
    scene : path-like or str
        The source hall (name in ``scenes/`` or folder with ``spec.toml``).
    out : path-like
        The folder to create (:func:`check_fitted_target` rules).
    values : mapping
        ``{material name: (ε_r [unitless], σ [S/m])}``, or ``(ε_r, σ, S)`` with a fitted scattering
        coefficient [unitless].
    provenance : mapping
        JSON-serialisable record of the fit, written as :data:`PROVENANCE_NAME` (NaN/inf become null).
    force : bool
        Replace an earlier fitted scene (or empty folder) at ``out``.
    note : str
        One line for the spec's header comment.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    ValueError
        As :func:`fitted_spec_text` and :func:`check_fitted_target`; a spec the builder refuses.
    """
    target = check_fitted_target(out, force=force)
    text = fitted_spec_text(scene, values, note=note)
    folder = scene_directory(scene)
    stage = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.partial-"))
    try:
        build_scene(loads_spec(text, base_dir=folder), stage)
        doc = json.dumps(_finite(dict(provenance)), indent=2, allow_nan=False) + "\n"
        (stage / PROVENANCE_NAME).write_text(doc, encoding="utf-8")
        os.chmod(stage, 0o755)
        if target.exists():
            check_fitted_target(target, force=force)
            old = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.old-"))
            os.rename(target, old / "x")
            os.rename(stage, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(stage, target)
    finally:
        if stage.exists():
            shutil.rmtree(stage, ignore_errors=True)
    return target


def _finite(x: Any) -> Any:
    """``x`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x
