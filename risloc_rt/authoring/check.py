"""Validate a hall spec or a built scene folder before tracing it: :func:`check_scene`.

Each finding is an :class:`Issue` that names the object, says what is wrong in physical terms and
how to fix it. Errors make a scene unusable (or its result wrong); warnings flag physics the
simulator reproduces faithfully but that may surprise (grating lobes, echoes that fold back).
The rules, by :attr:`Issue.rule` (also listed in :data:`RULES`):

========================  =======  ==================================================================
rule                      level    finding
========================  =======  ==================================================================
``spec``                  error    the spec cannot be read (its :class:`SpecError`)
``scene.file``            error    the folder is not built, or ``scene.xml`` / a mesh cannot be read
``scene.stale``           error    the folder's ``scene.xml``/meshes differ from what its spec builds
``material.frequency``    error    an ITU material undefined at the carrier (or at sionna's 3.5 GHz load)
``mesh.degenerate``       error    zero-area or collinear faces
``mesh.non_manifold``     error    edges shared by three or more faces
``mesh.flipped``          error    a closed mesh with inward normals, or inconsistently wound faces
``mesh.units``            error    an imported mesh far larger than the hall (a file in millimetres)
``mesh.placement``        error    an imported mesh reaching below the floor, above the ceiling or
                                   out of the footprint
``hall.open``             error    floor, ceiling and walls do not close the hall
``position.outside``      error    a radar or RIS outside the hall
``position.inside``       error    a radar or RIS inside a closed object
``position.clearance``    error    a radar closer than 5 cm to a surface
``ris.clearance``         error    a RIS panel closer than 5 cm + its half-diagonal to a surface
``ris.facing_wall``       error    a surface less than 1 m in front of a RIS, or its boresight leaves
                                   the hall
``ris.radar_behind``      error    a radar behind the RIS plane
``ris.range``             error    a RIS loop-back beyond the radar's unambiguous range
``ris.sweep``             warning  a radar seen outside the beam sweep
``ris.los``               warning  the radar-RIS line of sight is blocked
``ris.grating_lobe``      warning  element spacing that puts a grating lobe in the sweep
``range.walls``           warning  a wall beyond the radar's unambiguous range
========================  =======  ==================================================================

(``ris.radar_behind`` and ``ris.range`` are warnings when the spec has several RIS: the radar may
use another one.)

This module reads the spec and the folder and checks the materials; the other rules are in
:mod:`.check_geometry` (meshes, closure) and :mod:`.check_radio` (placement, sweep, range), the
report types in :mod:`.issues`. Pure numpy/trimesh: nothing here imports sionna, mitsuba or drjit.
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from dsp import BeamSweep, RadarConfig

from ._parse import SpecError
from .build import build_scene, content_hash
from .check_geometry import import_issues, mesh_issues, open_issues
from .check_radio import RADAR_CLEARANCE, RIS_FREE_AHEAD, position_issues, range_issues, ris_issues
from .geometry import load_geometry
from .issues import RULES, CheckReport, Issue, name_list
from .materials import ITU_MATERIALS, LOAD_FREQUENCY, itu_valid, valid_at
from .spec import HallSpec, load_spec

__all__ = ["Issue", "CheckReport", "RULES", "check_scene", "RADAR_CLEARANCE", "RIS_FREE_AHEAD"]


# ---------------------------------------------------------------------------------------------
# Entry point


def check_scene(scene: HallSpec | str | Path, *, radar: RadarConfig | None = None,
                sweep: BeamSweep | None = None) -> CheckReport:
    """Validate a hall spec or a built scene folder.

    Parameters
    ----------
    scene : HallSpec, or path of a spec (TOML) or of a scene folder
        A spec is built into a temporary folder and that build is checked. A folder is checked as
        it is: its ``scene.xml`` and meshes against its ``spec.toml`` (including whether they are
        up to date with it).
    radar : dsp.RadarConfig, optional
        The radar whose unambiguous range ``c/(2·S·T_s)`` the range rules use (default Table I,
        21.82 m).
    sweep : dsp.BeamSweep, optional
        The RIS beam sweep (default the paper's, -45° … 45° in 1.5° steps).

    Returns
    -------
    CheckReport
        ``report.ok`` is False when any rule found an error; ``report.format()`` prints it.

    Raises
    ------
    FileNotFoundError
        When ``scene`` does not exist, or a folder has no ``spec.toml``.
    """
    radar = radar if radar is not None else RadarConfig()
    sweep = sweep if sweep is not None else BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    folder: Path | None = None
    if isinstance(scene, HallSpec):
        source = str(scene.source_path) if scene.source_path else scene.name
    else:
        path = Path(scene)
        if path.is_dir():
            folder, path = path, path / "spec.toml"
        if not path.is_file():
            raise FileNotFoundError(f"{str(path)!r} does not exist" + (
                "; a scene folder needs the spec.toml it was built from" if folder is not None else ""))
        source = str(folder if folder is not None else path)
    issues: list[Issue] = []
    try:
        spec = scene if isinstance(scene, HallSpec) else load_spec(path)
    except SpecError as exc:
        issues.append(_spec_issue(exc))
        return CheckReport(source=source, issues=tuple(issues))
    with tempfile.TemporaryDirectory(prefix="risloc-check-") as tmp:
        try:
            built = build_scene(spec, tmp)
        except SpecError as exc:
            issues.append(_spec_issue(exc))
            return CheckReport(source=source, issues=tuple(issues), spec=spec)
        xml = built.xml_path
        if folder is not None:
            xml = _folder_xml(folder, built.content_hash, issues)
            if xml is None:
                return CheckReport(source=source, issues=tuple(issues), spec=spec)
        try:
            geo = load_geometry(xml)
        except Exception as exc:  # trimesh and ElementTree raise many types for broken files
            issues.append(Issue("error", "scene.file", xml.name, f"cannot load {xml}: {exc}",
                                f"rebuild the folder: risloc scene build {folder or xml.parent}/spec.toml"))
            return CheckReport(source=source, issues=tuple(issues), spec=spec)
        issues += _material_issues(xml, spec.frequency)
    issues += mesh_issues(spec, geo)
    issues += import_issues(spec, geo)
    issues += open_issues(spec, geo)
    issues += position_issues(spec, geo)
    issues += ris_issues(spec, geo, radar, sweep)
    issues += range_issues(spec, geo, radar)
    return CheckReport(source=source, issues=tuple(issues), spec=spec)


def _spec_issue(exc: SpecError) -> Issue:
    rule = exc.code if exc.code in RULES else "spec"
    return Issue("error", rule, exc.key or "spec", exc.problem, exc.fix or "fix the spec")


def _folder_xml(folder: Path, expected_hash: str, issues: list[Issue]) -> Path | None:
    """The folder's scene.xml, adding scene.file / scene.stale issues; None when unusable."""
    xml = folder / "scene.xml"
    build = f"risloc scene build {folder / 'spec.toml'}"
    if not xml.is_file():
        issues.append(Issue("error", "scene.file", "scene.xml", f"{folder} is not built: it has no scene.xml",
                            f"build it: {build}"))
        return None
    try:
        current = content_hash(xml)
    except (OSError, ValueError, ET.ParseError) as exc:  # a missing mesh, a broken XML
        issues.append(Issue("error", "scene.file", "scene.xml", f"cannot read the scene: {exc}", f"rebuild it: {build}"))
        return None
    if current != expected_hash:
        issues.append(Issue("error", "scene.stale", "scene.xml",
                            f"scene.xml and its meshes in {folder} differ from what spec.toml builds (an edited spec, "
                            "or hand-edited files): the tracer would use other geometry than the spec describes",
                            f"rebuild it: {build}"))
    return xml


# ---------------------------------------------------------------------------------------------
# Materials


def _material_issues(xml: Path, frequency: float) -> list[Issue]:
    """ITU materials of the XML that sionna-rt cannot evaluate at the carrier or at its 3.5 GHz load frequency."""
    root = ET.parse(xml).getroot()
    users: dict[str, list[str]] = {}
    for shape in root.iter("shape"):
        ref = shape.find("ref")
        if ref is not None:
            sid = shape.get("id", "")
            users.setdefault(ref.get("id", ""), []).append(sid[5:] if sid.startswith("mesh-") else sid)
    out = []
    for bsdf in root.iter("bsdf"):
        if bsdf.get("type") != "itu-radio-material":
            continue
        node = bsdf.find("string[@name='type']")
        itu = node.get("value", "") if node is not None else ""
        bid = bsdf.get("id", "")
        objects = name_list(users.get(bid, [])) or bid
        valid = ", ".join(valid_at(frequency))
        if itu not in ITU_MATERIALS:
            out.append(Issue("error", "material.frequency", objects, f"material {bid!r} has unknown ITU type {itu!r}",
                             f"use an ITU type valid at {frequency / 1e9:g} GHz ({valid}) and rebuild"))
            continue
        for f, why in ((frequency, "the carrier"), (LOAD_FREQUENCY, "sionna-rt's load frequency")):
            if not itu_valid(itu, f):
                f32 = float(np.float32(f) / np.float32(1e9))
                out.append(Issue(
                    "error", "material.frequency", objects,
                    f"ITU material {itu!r} ({bid}) is undefined at {f / 1e9:.9g} GHz, {why} "
                    f"({f32:.9g} GHz in sionna-rt's float32 arithmetic; its ranges: "
                    + ", ".join(f"{r[0]:g}–{r[1]:g} GHz" for r in ITU_MATERIALS[itu]) + ")",
                    f"use one valid at {frequency / 1e9:g} GHz ({valid}), or a custom material "
                    "{permittivity, conductivity, thickness}, in the spec and rebuild (the builder freezes "
                    "types undefined at 3.5 GHz)"))
                break
    return out
