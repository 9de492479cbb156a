"""``risloc scene check``: every validation rule, triggered by a crafted spec, mesh or scene folder.

The base scene is a clean 12 m × 8 m × 4 m concrete hall with the RIS at [10, 4, 1.2] facing a
radar 8 m away at [2, 4, 1.2]; each test changes one thing and checks the rule that fires, the object
it names and the numbers in its message (from geometry: distances, areas, volumes, angles).

Tolerances: meshes are stored as float32 (spacing 1e-6 m at 12 m), so the printed distances
(3 decimals) and areas (3 decimals) are exact for the round numbers used here.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from dsp import SPEED_OF_LIGHT, RadarConfig, RisPose
from risloc_rt.authoring import loads_spec
from risloc_rt.authoring.build import build_scene, ply_bytes
from risloc_rt.authoring.check import RULES, CheckReport, check_scene
from risloc_rt.cli import main as risloc_main
from risloc_rt.authoring.geometry import load_geometry
from risloc_rt.authoring.shapes import wall_mesh

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(d.name for d in (REPO / "scenes").iterdir() if (d / "spec.toml").is_file())

SHELL = 'walls = "concrete"\nfloor = "concrete"\nceiling = "concrete"'
HALL = "size = [12.0, 8.0]\nheight = 4.0"
RIS = '[[ris]]\nname = "ris0"\nposition = [10.0, 4.0, 1.2]\nfacing = [2.0, 4.0, 1.2]\n'
RADAR = "[radar]\npositions = [[2.0, 4.0, 1.2]]\n"
WAVELENGTH = SPEED_OF_LIGHT / 60e9


def make_toml(extra: str = "", *, hall: str = HALL, materials: str = SHELL, ris: str = RIS, radar: str = RADAR) -> str:
    """The base spec with ``extra`` ([[objects]]/[[meshes]] tables) and any section replaced."""
    return f'[scene]\nname = "t"\n\n[hall]\n{hall}\n\n[hall.materials]\n{materials}\n\n{extra}\n{ris}\n{radar}'


def check(tmp_path: Path, extra: str = "", **kw: str) -> CheckReport:
    """Check the base spec, changed by ``extra`` and ``kw``, written to ``tmp_path/spec.toml``."""
    path = tmp_path / "spec.toml"
    path.write_text(make_toml(extra, **kw))
    return check_scene(path)


def only(report: CheckReport, rule: str):
    """The single issue of ``rule`` (fails listing every issue when there is not exactly one)."""
    found = report.by_rule(rule)
    assert len(found) == 1, report.format()
    return found[0]


def mesh_toml(name: str, **kw: str) -> str:
    lines = [f'[[meshes]]\nfile = "{name}"\nmaterial = "metal"'] + [f"{k} = {v}" for k, v in kw.items()]
    return "\n".join(lines) + "\n"


def box_at(center, extents=(1.0, 1.0, 1.0)) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(center)
    return box


def build_folder(tmp_path: Path, text: str | None = None) -> Path:
    folder = tmp_path / "scene"
    build_scene(loads_spec(text or make_toml(), base_dir=tmp_path), folder)
    return folder


def drop_shape(folder: Path, name: str) -> None:
    """Remove ``mesh-<name>`` from the folder's scene.xml (a hand-edited, broken scene)."""
    xml = folder / "scene.xml"
    text, n = re.subn(rf'    <shape type="ply" id="mesh-{name}">.*?</shape>\n', "", xml.read_text(), flags=re.S)
    assert n == 1
    xml.write_text(text)


# --- clean scenes ---------------------------------------------------------------------------


def test_the_base_hall_is_clean(tmp_path):
    report = check(tmp_path)
    assert report.issues == () and report.ok
    assert report.format() == f"{tmp_path / 'spec.toml'}: ok: 0 error(s), 0 warning(s)"


def test_doors_and_windows_do_not_open_the_hall(tmp_path):
    # The panels stand 1 cm inside the wall plane; the slit around them is not an opening.
    report = check(tmp_path, '[[objects]]\nkind = "door"\nwall = 0\noffset = 4.0\nsize = [1.0, 2.1]\n'
                             '[[objects]]\nkind = "window"\nwall = 1\noffset = 2.0\nsize = [2.0, 1.0]\n')
    assert report.issues == (), report.format()


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_scenes_pass_without_errors(name):
    for target in (REPO / "scenes" / name, REPO / "scenes" / name / "spec.toml"):
        report = check_scene(target)
        assert report.ok, report.format()
        assert report.rules <= {"range.walls"}, report.format()  # walls beyond 21.82 m are allowed


def test_paper_hall_warns_of_the_far_wall_at_its_folded_distance():
    report = check_scene(REPO / "scenes" / "paper_hall")
    issue = only(report, "range.walls")
    # The radar at x = 6 m, wall_1 at x = 30 m: 24 m away, beyond c/(2 S T_s); the echo folds back.
    limit = RadarConfig().max_range
    assert issue.object == "wall_1" and issue.level == "warning"
    assert "radar.positions[0] (24.00 m)" in issue.message
    assert f"to an apparent {24.0 - limit:.2f} m" in issue.message and f"{limit:.2f} m unambiguous range" in issue.message


# --- the spec and the folder -----------------------------------------------------------------


def test_unreadable_spec_is_one_error_naming_the_key(tmp_path):
    issue = only(check(tmp_path, hall=HALL + '\ncolour = "red"'), "spec")
    assert issue.object == "hall.colour" and issue.message == "unknown key" and "valid keys" in issue.fix


def test_folder_without_scene_xml_is_not_built(tmp_path):
    folder = tmp_path / "unbuilt"
    folder.mkdir()
    (folder / "spec.toml").write_text(make_toml())
    issue = only(check_scene(folder), "scene.file")
    assert "is not built: it has no scene.xml" in issue.message and "risloc scene build" in issue.fix


def test_folder_with_a_missing_mesh_cannot_be_read(tmp_path):
    folder = build_folder(tmp_path)
    (folder / "meshes" / "wall_1.ply").unlink()
    issue = only(check_scene(folder), "scene.file")
    assert "references 'meshes/wall_1.ply'" in issue.message and "does not exist" in issue.message


def test_folder_out_of_date_with_its_spec_is_stale(tmp_path):
    folder = build_folder(tmp_path)
    assert check_scene(folder).issues == ()
    (folder / "spec.toml").write_text(make_toml(hall="size = [12.0, 8.0]\nheight = 4.5"))
    issue = only(check_scene(folder), "scene.stale")
    assert "differ from what spec.toml builds" in issue.message and "risloc scene build" in issue.fix


def test_missing_folder_raises():
    with pytest.raises(FileNotFoundError, match="does not exist"):
        check_scene("no/such/folder")


# --- materials -----------------------------------------------------------------------------


def test_spec_material_undefined_at_the_carrier(tmp_path):
    issue = only(check(tmp_path, materials=SHELL.replace('floor = "concrete"', 'floor = {itu = "brick"}')),
                 "material.frequency")
    assert issue.object == "hall.materials.floor.itu"
    assert "'brick' is defined for 1–40 GHz, 110–330 GHz only, not at 60 GHz" in issue.message


def test_scene_xml_material_undefined_in_float32_at_60_ghz(tmp_path):
    # Marble is tabulated up to 60 GHz, but sionna-rt compares float32(60e9)/1e9 = 60.0000038 GHz.
    folder = build_folder(tmp_path)
    xml = folder / "scene.xml"
    xml.write_text(xml.read_text().replace('value="concrete"', 'value="marble"'))
    issue = only(check_scene(folder), "material.frequency")
    assert issue.object.startswith("floor, ceiling, wall_0, wall_1")
    assert "'marble'" in issue.message and "60.0000038 GHz in sionna-rt's float32" in issue.message
    assert "1–60 GHz" in issue.message


def test_scene_xml_material_undefined_at_the_load_frequency(tmp_path):
    folder = build_folder(tmp_path)
    xml = folder / "scene.xml"
    xml.write_text(xml.read_text().replace('value="concrete"', 'value="floorboard"'))
    issue = only(check_scene(folder), "material.frequency")
    assert "undefined at 3.5 GHz, sionna-rt's load frequency" in issue.message and "freezes" in issue.fix


# --- meshes --------------------------------------------------------------------------------


def test_flipped_box_has_negative_volume(tmp_path):
    box = box_at([5.0, 2.0, 0.5])
    box.invert()
    box.export(tmp_path / "flipped.ply")
    issue = only(check(tmp_path, mesh_toml("flipped.ply")), "mesh.flipped")
    # A 1 m cube wound inside out: signed volume -1 m³ exactly (float32 corners at ±0.5 m).
    assert issue.object == "flipped" and "inward-facing normals (signed volume -1 m³ < 0)" in issue.message
    assert "invert" in issue.fix


def test_one_reversed_face_is_inconsistent_winding(tmp_path):
    box = box_at([5.0, 2.0, 0.5])
    faces = box.faces.copy()
    faces[0] = faces[0][::-1]
    trimesh.Trimesh(box.vertices, faces, process=False).export(tmp_path / "mixed.ply")
    issue = only(check(tmp_path, mesh_toml("mixed.ply")), "mesh.flipped")
    # Each of the reversed triangle's 3 edges now runs the same way as its neighbour's.
    assert "wound inconsistently: across 3 edge(s)" in issue.message


def test_fin_on_a_box_is_non_manifold(tmp_path):
    box = box_at([5.0, 2.0, 0.5])
    a, b = box.faces[0][:2]
    verts = np.vstack([box.vertices, box.vertices[[a, b]].mean(axis=0) + [0.0, 0.0, 2.0]])
    faces = np.vstack([box.faces, [[a, b, len(verts) - 1]]])
    trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "fin.ply")
    issue = only(check(tmp_path, mesh_toml("fin.ply")), "mesh.non_manifold")
    ends = sorted([box.vertices[a].tolist(), box.vertices[b].tolist()])
    assert "has 1 non-manifold edge(s), shared by three or more faces" in issue.message
    shown = [[float(x) for x in m.split(", ")] for m in re.findall(r"\[([-\d., ]+)\]", issue.message)[:2]]
    np.testing.assert_allclose(sorted(shown), ends, atol=0.005)  # printed to 1 cm


def test_zero_area_triangle_is_degenerate(tmp_path):
    box = box_at([5.0, 2.0, 0.5])
    line = np.array([[3.0, 3.0, 1.0], [3.5, 3.0, 1.0], [4.0, 3.0, 1.0]])  # three corners on one line
    verts = np.vstack([box.vertices, line])
    faces = np.vstack([box.faces, [[8, 9, 10]]])
    trimesh.Trimesh(verts, faces, process=False).export(tmp_path / "sliver.ply")
    issue = only(check(tmp_path, mesh_toml("sliver.ply")), "mesh.degenerate")
    assert "1 of the 13 faces of mesh 'sliver' are degenerate" in issue.message
    assert "face 12 with corners [3.00, 3.00, 1.00], [3.50, 3.00, 1.00], [4.00, 3.00, 1.00]" in issue.message


def test_mesh_in_millimetres_asks_for_scale_0_001(tmp_path):
    box_at([500.0, 1000.0, 250.0], extents=[1000.0, 2000.0, 500.0]).export(tmp_path / "rack_mm.stl")
    issue = only(check(tmp_path, mesh_toml("rack_mm.stl", translate="[4.0, 1.0, 0.0]")), "mesh.units")
    # 2000 mm read as metres: 2000 m across, 2000/12 = 167 hall lengths.
    assert issue.object == "rack_mm" and "is 2000 m across after scale 1, 167 times the hall" in issue.message
    assert "set scale = 0.001 in meshes[0]" in issue.fix and "2 m across" in issue.fix
    ok = check(tmp_path, mesh_toml("rack_mm.stl", translate="[4.0, 1.0, 0.0]", scale="0.001"))
    assert ok.issues == (), ok.format()


def test_y_up_mesh_lands_upright_only_when_rotated(tmp_path):
    # A 1 m × 2 m (tall, along the file's y) × 0.5 m rack exported y-up, standing on y = 0.
    box_at([0.0, 1.0, 0.0], extents=[1.0, 2.0, 0.5]).export(tmp_path / "rack_yup.obj")
    lying = only(check(tmp_path, mesh_toml("rack_yup.obj", translate="[5.0, 3.0, 0.0]")), "mesh.placement")
    assert "reaches 0.250 m below the floor" in lying.message and "rotate_deg = [90, 0, 0]" in lying.fix
    text = make_toml(mesh_toml("rack_yup.obj", translate="[5.0, 3.0, 0.0]", rotate_deg="[90, 0, 0]"))
    assert check_scene(loads_spec(text, base_dir=tmp_path)).issues == ()
    # Rx(90°): (x, y, z) -> (x, -z, y): 2 m tall, 0.5 m deep, centred on the translate.
    geo = load_geometry(build_scene(loads_spec(text, base_dir=tmp_path), tmp_path / "out").xml_path)
    np.testing.assert_allclose(geo.meshes["rack_yup"].bounds, [[4.5, 2.75, 0.0], [5.5, 3.25, 2.0]], atol=1e-5)


def test_mesh_outside_the_footprint(tmp_path):
    box_at([0.0, 0.0, 0.5]).export(tmp_path / "crate.stl")
    issue = only(check(tmp_path, mesh_toml("crate.stl", translate="[11.8, 4.0, 0.0]")), "mesh.placement")
    # The 1 m crate centred 0.2 m from wall_1 (x = 12) pokes 0.3 m through it.
    assert "leaves the footprint" in issue.message and "is 0.300 m outside" in issue.message


# --- the shell -----------------------------------------------------------------------------


def test_missing_wall_leaves_the_hall_open(tmp_path):
    folder = build_folder(tmp_path)
    drop_shape(folder, "wall_2")
    report = check_scene(folder)
    issue = only(report, "hall.open")
    assert issue.object == "wall_2" and not report.ok
    assert "footprint edge 2 from [12, 8] to [0, 8] m, 0 … 4 m high" in issue.message
    assert "scene.xml has no shape 'mesh-wall_2'" in issue.message
    assert re.search(r"\d+ of \d+ test rays from inside leave the scene through it", issue.message)
    assert "scene.stale" in report.rules  # the folder no longer matches its spec either


def test_half_height_wall_is_found_by_its_area(tmp_path):
    folder = build_folder(tmp_path)
    # wall_1 runs along x = 12 from y = 0 to 8: 8 m × 4 m = 32 m² to close; replace it by a 2 m high one.
    v, f = wall_mesh(np.array([12.0, 0.0]), np.array([12.0, 8.0]), 2.0, [])
    (folder / "meshes" / "wall_1.ply").write_bytes(ply_bytes(v, f))
    issue = only(check_scene(folder), "hall.open")
    assert issue.object == "wall_1" and "covers 16.000 m² of the 32.000 m² it must close" in issue.message
    assert "leave the scene through it" in issue.message


def test_removed_door_panel_opens_its_wall(tmp_path):
    folder = build_folder(tmp_path, make_toml('[[objects]]\nkind = "door"\nname = "gate"\nwall = 0\noffset = 4.0\n'
                                              "size = [1.0, 2.1]\n"))
    assert check_scene(folder).issues == ()
    drop_shape(folder, "gate")
    issue = only(check_scene(folder), "hall.open")
    # The hole is 1 m × 2.1 m in wall_0 (y = 0) around x = 4: the escaping rays leave there.
    assert issue.object == "wall_0"
    x, y, z = (float(v) for v in re.search(r"e\.g\. at \[([-\d.]+), ([-\d.]+), ([-\d.]+)\]", issue.message).groups())
    assert 3.5 <= x <= 4.5 and y == 0.0 and 0.0 <= z <= 2.1


# --- positions -----------------------------------------------------------------------------

L_HALL = "footprint = [[0, 0], [12, 0], [12, 4], [6, 4], [6, 8], [0, 8]]\nheight = 4.0"


@pytest.mark.parametrize(("kw", "key", "text"), [
    (dict(hall=L_HALL, ris='[[ris]]\nposition = [10.0, 2.0, 1.2]\nfacing = [2.0, 2.0, 1.2]\n',
          radar="[radar]\npositions = [[9.0, 6.0, 1.2]]\n"),  # in the notch of the L
     "radar.positions[0]", "the radar at [9, 6, 1.2] m is outside the hall footprint"),
    (dict(ris='[[ris]]\nposition = [10.0, 4.0, 4.5]\nfacing = [2.0, 4.0, 1.2]\n'),
     "ris[0].position", "the RIS's height z = 4.5 m is not between the floor (0) and the ceiling (4 m)"),
])
def test_radar_or_ris_outside_the_hall(tmp_path, kw, key, text):
    issue = only(check(tmp_path, **kw), "position.outside")
    assert issue.object == key and text in issue.message


def test_radar_inside_an_object(tmp_path):
    report = check(tmp_path, '[[objects]]\nkind = "box"\nname = "crate"\nmin = [1.0, 3.0, 0.0]\nmax = [3.0, 5.0, 2.0]\n'
                             'material = "metal"\n')
    issue = only(report, "position.inside")
    assert issue.object == "radar.positions[0]"
    assert "inside the closed object 'crate' (bounds [1.00, 3.00, 0.00] … [3.00, 5.00, 2.00] m)" in issue.message


def test_radar_touching_a_wall(tmp_path):
    issue = only(check(tmp_path, radar="[radar]\npositions = [[0.02, 4.0, 1.2]]\n"), "position.clearance")
    assert "is 0.020 m from 'wall_3', closer than 0.05 m" in issue.message and "at least 0.030 m further" in issue.fix


def test_ris_too_close_to_a_wall(tmp_path):
    report = check(tmp_path, ris='[[ris]]\nname = "ris0"\nposition = [11.92, 4.0, 1.2]\nfacing = [2.0, 4.0, 1.2]\n')
    issue = only(report, "ris.clearance")
    # 8 cm from wall_1; needed: 5 cm + half the diagonal of the 10 cm × 5 cm panel = 0.106 m.
    need = 0.05 + 0.5 * math.hypot(0.10, 0.05)
    assert issue.object == "ris0" and f"is 0.080 m from 'wall_1'; it needs {need:.3f} m" in issue.message
    assert "sionna-rt drops path segments shorter than 1 cm" in issue.message and "free-standing" in issue.message
    assert f"at least {need - 0.08:.3f} m further" in issue.fix


def test_ris_facing_a_wall(tmp_path):
    report = check(tmp_path, ris='[[ris]]\nname = "ris0"\nposition = [11.5, 4.0, 1.2]\nfacing = [20.0, 4.0, 1.2]\n')
    issue = only(report, "ris.facing_wall")
    assert "faces 'wall_1' 0.500 m in front of it" in issue.message and "at least 1 m is free" in issue.fix
    assert "ris.radar_behind" in report.rules  # and the radar is now behind it


def test_ris_boresight_leaving_an_open_hall(tmp_path):
    # Facing +x, 2 m before wall_1: fine while the wall is there; without it the boresight escapes.
    folder = build_folder(tmp_path, make_toml(ris='[[ris]]\nname = "ris0"\nposition = [10.0, 4.0, 1.2]\n'
                                                  "normal = [1, 0, 0]\n"))
    assert "ris.facing_wall" not in check_scene(folder).rules
    drop_shape(folder, "wall_1")
    issue = only(check_scene(folder), "ris.facing_wall")
    assert "leaves the scene without hitting a surface: it points out of the hall" in issue.message


def test_radar_behind_the_ris(tmp_path):
    report = check(tmp_path, ris='[[ris]]\nname = "ris0"\nposition = [10.0, 4.0, 1.2]\nnormal = [0, 1, 0]\n',
                   radar="[radar]\npositions = [[2.0, 2.0, 1.2]]\n")
    issue = only(report, "ris.radar_behind")
    angle = math.degrees(math.acos(-2.0 / math.hypot(8.0, 2.0)))  # 104°: the radar is 2 m behind the plane
    assert issue.level == "error" and f"radar.positions[0] ({angle:.0f}° off boresight) is behind" in issue.message


def test_loopback_beyond_the_unambiguous_range(tmp_path):
    report = check(tmp_path, hall="size = [40.0, 8.0]\nheight = 4.0",
                   ris='[[ris]]\nposition = [30.0, 4.0, 1.2]\nfacing = [8.0, 4.0, 1.2]\n',
                   radar="[radar]\npositions = [[8.0, 4.0, 1.2]]\n")
    issue = only(report, "ris.range")
    apparent = 22.0 + 1.78e-9 * SPEED_OF_LIGHT / 2  # distance + τ_RB·c/2
    assert f"radar.positions[0] (22.00 m, apparent {apparent:.2f} m)" in issue.message
    assert f"{RadarConfig().max_range:.2f} m unambiguous range" in issue.message


def test_radar_outside_the_sweep(tmp_path):
    pose = RisPose.facing(np.array([10.0, 4.0, 1.2]), np.array([2.0, 4.0, 1.2]))
    q = pose.point_at(np.deg2rad([60.0, 0.0]), 4.0)
    issue = only(check(tmp_path, radar=f"[radar]\npositions = [{q.tolist()}]\n"), "ris.sweep")
    assert issue.level == "warning"
    assert "radar.positions[0] (+60.0°) is seen outside the beam sweep (-45.0° … +45.0°)" in issue.message


def test_blocked_line_of_sight(tmp_path):
    report = check(tmp_path, '[[objects]]\nkind = "box"\nname = "blocker"\nmin = [5.0, 3.5, 0.0]\n'
                             'max = [6.0, 4.5, 2.0]\nmaterial = "metal"\n')
    issue = only(report, "ris.los")
    # The box's face at x = 5 m is 3 m from the radar at x = 2 m, on the line to the RIS.
    assert issue.level == "warning" and "radar.positions[0] (by 'blocker' 3.00 m from the radar)" in issue.message


def test_reflective_half_wavelength_ris_has_grating_lobes(tmp_path):
    pose = RisPose.facing(np.array([10.0, 4.0, 1.2]), np.array([2.0, 4.0, 1.2]))
    q = pose.point_at(np.deg2rad([21.0, 0.0]), 7.0)
    report = check(tmp_path, ris=RIS + 'mode = "reflective"\n', radar=f"[radar]\npositions = [{q.tolist()}]\n")
    issue = only(report, "ris.grating_lobe")
    # Doubled phase gradient: sin φ = sin θ - λ/(2d) = sin 21° - 1; lobes stay out of ±45° only
    # for |sin θ| < 1 - sin 45° (17.0°).
    lobe = math.degrees(math.asin(math.sin(math.radians(21.0)) - 1.0))
    safe = math.degrees(math.asin(1 - math.sin(math.radians(45.0))))
    assert f"radar.positions[0] (+21.0° also peaks at {lobe:+.1f}°)" in issue.message
    assert f"within ±{safe:.1f}° of broadside get none" in issue.message
    assert 'use mode = "relay"' in issue.fix


@pytest.mark.parametrize(("spacing", "warns"), [(2.95e-3, True), (2.90e-3, False), ("\"half-wavelength\"", False)])
def test_relay_grating_lobe_threshold(tmp_path, spacing, warns):
    # Relay: sin φ = sin θ - λ/d reaches the sweep edge sin 45° for a direction in the RIS plane
    # (sin θ → 1) once d > λ/(1 + sin 45°) = 2.928 mm at 60 GHz.
    threshold = WAVELENGTH / (1 + math.sin(math.radians(45.0)))
    assert 2.90e-3 < threshold < 2.95e-3
    report = check(tmp_path, ris=RIS + f"spacing = {spacing}\n")
    assert ("ris.grating_lobe" in report.rules) == warns, report.format()
    if warns:
        assert f"a spacing below {threshold * 1e3:.3g} mm" in report.by_rule("ris.grating_lobe")[0].fix


def test_wall_beyond_the_unambiguous_range(tmp_path):
    report = check(tmp_path, hall="size = [30.0, 8.0]\nheight = 4.0",
                   ris='[[ris]]\nposition = [19.38, 4.0, 1.2]\nfacing = [6.0, 4.0, 1.2]\n',
                   radar="[radar]\npositions = [[6.0, 4.0, 1.2]]\n")
    issue = only(report, "range.walls")
    assert issue.object == "wall_1" and report.ok
    assert f"apparent {24.0 - RadarConfig().max_range:.2f} m" in issue.message


def test_every_rule_has_a_test():
    text = Path(__file__).read_text()
    untested = [rule for rule in RULES if f'"{rule}"' not in text.split("def test_every_rule_has_a_test")[0]]
    assert untested == []


# --- report and command line ----------------------------------------------------------------


def run_cli(*argv: str) -> int:
    return risloc_main(list(argv))


def test_cli_check_exit_status(tmp_path, capsys):
    assert run_cli("scene", "check", str(REPO / "scenes" / "pillars_hall")) == 0
    assert "pillars_hall: ok: 0 error(s), 0 warning(s)" in capsys.readouterr().out
    assert run_cli("scene", "check", "paper_hall") == 0  # a name in scenes/; a warning only
    assert "warning [range.walls] wall_1" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text(make_toml(radar="[radar]\npositions = [[0.02, 4.0, 1.2]]\n"))
    assert run_cli("scene", "check", str(bad)) == 1
    out = capsys.readouterr().out
    assert "error [position.clearance] radar.positions[0]:" in out and "\n    fix: move it" in out
    assert out.rstrip().endswith("FAILED: 1 error(s), 0 warning(s)")
    assert run_cli("scene", "check", str(tmp_path / "nothing.toml")) == 2
    assert "risloc scene check: error:" in capsys.readouterr().err


def test_cli_build_writes_the_folder(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(make_toml())
    assert run_cli("scene", "build", str(spec), "-o", str(tmp_path / "out")) == 0
    assert (tmp_path / "out" / "scene.xml").is_file() and "sha256" in capsys.readouterr().out
    assert run_cli("scene", "build", str(spec)) == 0  # default: next to the spec
    assert (tmp_path / "scene.xml").is_file()
    shutil.rmtree(tmp_path / "meshes")
    spec.write_text(make_toml(hall="size = [12.0, -8.0]\nheight = 4.0"))
    assert run_cli("scene", "build", str(spec)) == 2
    assert "hall.size[1]: -8 must be > 0" in capsys.readouterr().err


def test_check_and_show_never_import_the_ray_tracer():
    code = ("import sys; from risloc_rt.authoring import check_scene, show_scene; import risloc_rt.cli.scene; "
            f"check_scene({str(REPO / 'scenes' / 'l_hall')!r}); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'sionna', 'mitsuba', 'drjit'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_with_two_rises_a_radar_needs_one_that_serves_it(tmp_path):
    """Issue 22: a radar behind one RIS or beyond its range is fine when the other RIS sees it; not when none does."""
    two = ('[[ris]]\nname = "ris0"\nposition = [30.0, 4.0, 1.2]\nfacing = [8.0, 4.0, 1.2]\n'
           '[[ris]]\nname = "ris1"\nposition = [2.0, 4.0, 1.2]\nfacing = [20.0, 4.0, 1.2]\n')
    hall = "size = [40.0, 8.0]\nheight = 4.0"
    # 22 m from ris0 (beyond its range), 6 m in front of ris1: served
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    radar = "[radar]\npositions = [[{}, 4.0, 1.2]]\nfacing = [20.0, 4.0, 1.2]\n"
    served = check(tmp_path / "a", hall=hall, ris=two, radar=radar.format(8.0))
    assert not {"ris.range", "ris.radar_behind"} & set(served.rules), served.format()
    # behind ris1 (x < 2) and 29 m from ris0 (beyond its range): no RIS serves it, both are reported
    lost = check(tmp_path / "b", hall=hall, ris=two, radar=radar.format(1.0))
    assert {"ris.range", "ris.radar_behind"} <= set(lost.rules), lost.format()
