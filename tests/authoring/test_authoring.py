"""Hall specs, the scene builder and the geometry checks (risloc_rt.authoring).

Tolerances: mesh coordinates are stored as float32, whose spacing is 1.9e-6 m at 20 m, so
positions read back from a PLY are compared within 1e-5 m and areas of halls up to 30 m within
1e-3 m² (relative 2·6e-8 of ~10² m² per coordinate, summed over a few triangles).
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from dsp import SPEED_OF_LIGHT
from risloc_rt.authoring import SpecError, load_spec, loads_spec
from risloc_rt.authoring.build import build_scene, content_hash
from risloc_rt.authoring.geometry import load_geometry
from risloc_rt.authoring.materials import ITU_MATERIALS, itu_properties, itu_valid
from risloc_rt.authoring.polygon import boundary_distance, contains

REPO = Path(__file__).resolve().parents[2]
PAPER_DIR = REPO / "scenes" / "paper_hall"
#: float32 position tolerance [m] (see the module docstring).
POS_TOL = 1e-5
#: Area tolerance for float32 meshes up to 30 m [m²].
AREA_TOL = 1e-3

SHELL = 'walls = "concrete"\nfloor = "concrete"\nceiling = "concrete"'


def make_toml(*, scene: str = 'name = "t"', hall: str = "size = [10.0, 6.0]\nheight = 3.0",
              materials: str = SHELL, extra: str = "") -> str:
    """A small valid spec (10 m × 6 m × 3 m concrete box) with the given sections replaced."""
    return f"[scene]\n{scene}\n\n[hall]\n{hall}\n\n[hall.materials]\n{materials}\n\n{extra}\n"


def make_spec(base_dir: Path | str = ".", **kw: str):
    return loads_spec(make_toml(**kw), base_dir=base_dir)


L_HALL = "footprint = [[0, 0], [0, 10], [6, 10], [6, 4], [20, 4], [20, 0]]\nheight = 5.0"  # clockwise L
L_POLY = np.array([[0, 0], [20, 0], [20, 4], [6, 4], [6, 10], [0, 10]], dtype=float)  # the same, CCW from (0,0)


def mm_part(tmp_path: Path) -> Path:
    """A 1000 × 2000 × 500 mm block with a corner at the origin, as STL (millimetres)."""
    m = trimesh.creation.box(extents=[1000.0, 2000.0, 500.0])
    m.apply_translation([500.0, 1000.0, 250.0])
    path = tmp_path / "part_mm.stl"
    m.export(path)
    return path


def rich_toml() -> str:
    """An L-shaped hall with every object kind, a custom and a frozen material, a mesh and a RIS."""
    return make_toml(hall=L_HALL, materials=(
        'walls = "concrete"\nfloor = {itu = "floorboard", thickness = 0.03}\n'
        'ceiling = {permittivity = 2.0, conductivity = 0.1, thickness = 0.05, name = "tiles"}'), extra="""
[[objects]]
kind = "box"
name = "crate"
center = [10, 2, 0.5]
size = [1, 1, 1]
yaw_deg = 30
material = "metal"
[[objects]]
kind = "pillar"
center = [3, 3]
radius = 0.3
material = "concrete"
[[objects]]
kind = "pillar"
center = [15, 2]
size = [0.4, 0.4]
material = "concrete"
[[objects]]
kind = "shelf"
center = [2, 8]
size = [2, 0.6, 2]
material = "wood"
[[objects]]
kind = "door"
wall = 0
offset = 3
size = [1.0, 2.1]
[[objects]]
kind = "window"
position = [20, 2, 2.0]
size = [2.0, 1.0]
[[meshes]]
file = "part_mm.stl"
scale = 0.001
rotate_deg = [0, 0, 90]
translate = [12, 1, 0]
material = "metal"
[[ris]]
position = [18, 2, 1.2]
facing = [2, 2, 1.2]
[radar]
grid = {spacing = 2.0, height = 1.2}
""")


def tree_bytes(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# --- the paper hall ---------------------------------------------------------------------------


def test_paper_hall_spec_is_the_papers_geometry():
    spec = load_spec(PAPER_DIR / "spec.toml")
    assert spec.footprint == ((0.0, 0.0), (30.0, 0.0), (30.0, 18.0), (0.0, 18.0)) and spec.height == 7.0
    assert {m.itu for m in (spec.materials.walls, spec.materials.floor, spec.materials.ceiling)} == {"concrete"}
    assert spec.materials.walls.thickness == 0.2
    radar = spec.radar_positions()
    assert radar.shape == (2, 3)
    (ris,) = spec.ris_configs()
    # Both 13.38 m away at equal height; exact up to float64 rounding of the decimal inputs (1e-12 m).
    np.testing.assert_allclose(np.linalg.norm(ris.pose.position - radar, axis=1), 13.38, atol=1e-12)
    assert np.all(radar[:, 2] == ris.pose.position[2])
    # The RIS faces the first radar (broadside); the second is seen at azimuth +21°, on the sweep grid.
    np.testing.assert_allclose(ris.pose.angles_to(radar[0]), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(ris.pose.angles_to(radar[1]), [np.deg2rad(21.0), 0.0], atol=1e-12)
    # No fixed relay Rx direction in the spec: the simulator points it at the radar in use.
    assert spec.ris[0].relay_rx_toward is None
    assert (ris.num_rows, ris.num_columns, ris.mode) == (16, 4, "relay")
    assert ris.element_spacing == pytest.approx(SPEED_OF_LIGHT / 60e9 / 2, rel=1e-15)
    assert (ris.amplification_db, ris.loopback_delay) == (45.532, 1.78e-9)
    (plate,) = spec.ris_panels()
    assert (plate.width, plate.height, plate.reflection) == (0.10, 0.05, -1)
    np.testing.assert_allclose(spec.radar_boresights()[0], [1.0, 0.0, 0.0], atol=1e-15)


def test_paper_hall_committed_scene_is_up_to_date(tmp_path):
    built = build_scene(PAPER_DIR / "spec.toml", tmp_path)
    committed = tree_bytes(PAPER_DIR)
    assert tree_bytes(tmp_path) == committed, "scenes/paper_hall is stale: rerun risloc_rt.authoring.build"
    assert content_hash(PAPER_DIR / "scene.xml") == built.content_hash
    assert sorted(committed) == ["build-manifest.json", "meshes/ceiling.ply", "meshes/floor.ply", "meshes/wall_0.ply", "meshes/wall_1.ply",
                                 "meshes/wall_2.ply", "meshes/wall_3.ply", "scene.xml", "spec.toml"]


def test_paper_hall_positions_pass_the_checks_and_nothing_stands_behind_the_ris():
    geo = load_geometry(PAPER_DIR / "scene.xml")
    spec = load_spec(PAPER_DIR / "spec.toml")
    geo.check_points(spec.radar_positions(), what="radar")
    ris = spec.ris[0]
    geo.check_point(ris.position, what=ris.name)
    # Behind the RIS (along -normal) the first surface is wall_1 at x = 30: 30 - 19.38 = 10.62 m.
    name, dist = geo.first_hit(ris.position, -np.array(ris.normal))
    assert name == "wall_1" and dist == pytest.approx(10.62, abs=POS_TOL) and dist > 10.0


# --- determinism and the content hash ---------------------------------------------------------


def test_building_twice_gives_identical_bytes_and_hash(tmp_path):
    mm_part(tmp_path)
    (tmp_path / "rich.toml").write_text(rich_toml())
    a = build_scene(tmp_path / "rich.toml", tmp_path / "a")
    b = build_scene(tmp_path / "rich.toml", tmp_path / "b")
    files_a, files_b = tree_bytes(tmp_path / "a"), tree_bytes(tmp_path / "b")
    assert files_a == files_b
    # scene.xml, spec.toml, build-manifest.json, one PLY per object, and the copied source part_mm.stl
    # (so the spec copy builds from the output folder too)
    assert len(files_a) == 4 + len(a.spec.object_names)
    assert files_a["part_mm.stl"] == (tmp_path / "part_mm.stl").read_bytes()
    assert files_a["spec.toml"] == (tmp_path / "rich.toml").read_bytes()
    assert a.content_hash == b.content_hash == content_hash(tmp_path / "b" / "scene.xml")
    again = build_scene(tmp_path / "rich.toml", tmp_path / "a")  # rebuilding in place changes nothing
    assert again.content_hash == a.content_hash and tree_bytes(tmp_path / "a") == files_a


def test_changed_geometry_or_material_changes_the_hash_but_the_ris_does_not(tmp_path):
    base = build_scene(make_spec(), tmp_path / "base").content_hash
    taller = build_scene(make_spec(hall="size = [10.0, 6.0]\nheight = 3.01"), tmp_path / "taller").content_hash
    thicker = build_scene(make_spec(materials=SHELL.replace('walls = "concrete"',
                                                            'walls = {itu = "concrete", thickness = 0.25}')),
                          tmp_path / "thicker").content_hash
    with_ris = build_scene(make_spec(extra="[[ris]]\nposition = [5, 3, 1]\nfacing = [1, 3, 1]"),
                           tmp_path / "ris").content_hash
    assert len({base, taller, thicker}) == 3
    assert with_ris == base  # the RIS is modelled analytically, not part of the traced scene


def test_stale_meshes_are_removed(tmp_path):
    spec_box = make_spec(extra='[[objects]]\nkind = "box"\nname = "crate"\nmin = [1, 1, 0]\nmax = [2, 2, 1]\n'
                               'material = "metal"')
    build_scene(spec_box, tmp_path)
    assert (tmp_path / "meshes" / "crate.ply").is_file()
    built = build_scene(make_spec(), tmp_path)
    assert not (tmp_path / "meshes" / "crate.ply").exists()
    assert sorted(p.stem for p in (tmp_path / "meshes").glob("*.ply")) == sorted(built.object_names)


# --- sionna-rt loads what we write --------------------------------------------------------------


def test_sionna_loads_built_scenes_with_the_expected_objects_and_materials(tmp_path):
    rt = pytest.importorskip("sionna.rt")
    mm_part(tmp_path)
    built = build_scene(loads_spec(rich_toml(), base_dir=tmp_path), tmp_path / "rich")
    scene = rt.load_scene(str(built.xml_path), merge_shapes=False)
    scene.frequency = 60e9  # raises if a material is undefined at 60 GHz
    assert sorted(scene.objects) == sorted(built.object_names)
    assert len(built.object_names) == 2 + 6 + 6 + 1  # floor, ceiling, 6 walls, 6 objects, 1 mesh
    mats = scene.radio_materials
    # ITU-R P.2040 concrete at 60 GHz: ε_r = 5.24, σ = 0.0462 · 60^0.7822 S/m (float32 in sionna-rt).
    concrete = scene.objects["wall_0"].radio_material
    assert float(concrete.relative_permittivity[0]) == pytest.approx(5.24, rel=1e-6)
    assert float(concrete.conductivity[0]) == pytest.approx(0.0462 * 60**0.7822, rel=1e-6)
    assert float(concrete.thickness[0]) == pytest.approx(0.2, rel=1e-6)
    # floorboard, undefined at the 3.5 GHz load frequency, is written frozen at 60 GHz.
    floor = mats["floorboard-30mm"]
    assert float(floor.relative_permittivity[0]) == pytest.approx(3.66, rel=1e-6)
    assert float(floor.conductivity[0]) == pytest.approx(0.0044 * 60**1.3515, rel=1e-6)
    assert float(mats["tiles"].relative_permittivity[0]) == pytest.approx(2.0, rel=1e-6)
    assert scene.objects["door_4"].radio_material.itu_type == "metal"
    assert scene.objects["window_5"].radio_material.itu_type == "glass"

    paper = rt.load_scene(str(PAPER_DIR / "scene.xml"), merge_shapes=False)
    paper.frequency = 60e9
    assert sorted(paper.objects) == ["ceiling", "floor", "wall_0", "wall_1", "wall_2", "wall_3"]


def test_itu_table_and_float32_validity_match_sionna():
    pytest.importorskip("sionna.rt")
    import mitsuba as mi
    from sionna.rt.radio_materials.itu import ITU_MATERIALS_PROPERTIES, itu_material

    theirs = {name: tuple((*rng, *coef) for rng, coef in table.items())
              for name, table in ITU_MATERIALS_PROPERTIES.items()}
    assert theirs == ITU_MATERIALS
    for name in ("marble", "floorboard", "brick", "concrete", "glass"):
        for f in (3.5e9, 40e9, 59.99e9, 60e9, 60.01e9, 100e9):
            try:
                itu_material(name, mi.Float(f))
                valid = True
            except ValueError:
                valid = False
            assert itu_valid(name, f) == valid, (name, f)
    assert not itu_valid("marble", 60e9) and itu_valid("marble", 59.99e9)  # FINDINGS §6
    assert itu_properties("concrete", 60e9) == pytest.approx((5.24, 0.0462 * 60**0.7822), rel=1e-12)


# --- mesh geometry ----------------------------------------------------------------------------


def _normals(mesh: trimesh.Trimesh) -> np.ndarray:
    return np.asarray(mesh.face_normals)


def test_rectangle_hall_meshes_have_the_right_area_bounds_and_normals(tmp_path):
    built = build_scene(make_spec(), tmp_path)
    geo = load_geometry(built.xml_path)
    m = geo.meshes
    assert m["floor"].area == pytest.approx(60.0, abs=AREA_TOL) and m["ceiling"].area == pytest.approx(60.0, abs=AREA_TOL)
    np.testing.assert_allclose(m["floor"].bounds, [[0, 0, 0], [10, 6, 0]], atol=POS_TOL)
    np.testing.assert_allclose(m["ceiling"].bounds, [[0, 0, 3], [10, 6, 3]], atol=POS_TOL)
    expected = {"wall_0": ([[0, 0, 0], [10, 0, 3]], [0, 1, 0]), "wall_1": ([[10, 0, 0], [10, 6, 3]], [-1, 0, 0]),
                "wall_2": ([[0, 6, 0], [10, 6, 3]], [0, -1, 0]), "wall_3": ([[0, 0, 0], [0, 6, 3]], [1, 0, 0])}
    for name, (bounds, inward) in expected.items():
        np.testing.assert_allclose(m[name].bounds, bounds, atol=POS_TOL, err_msg=name)
        length = np.ptp(np.asarray(bounds)[:, :2], axis=0).max()
        assert m[name].area == pytest.approx(length * 3.0, abs=AREA_TOL), name
        np.testing.assert_allclose(_normals(m[name]), np.tile(inward, (len(m[name].faces), 1)), atol=1e-6)
    # Shell normals point into the hall: floor up, ceiling down.
    np.testing.assert_allclose(_normals(m["floor"])[:, 2], 1.0, atol=1e-6)
    np.testing.assert_allclose(_normals(m["ceiling"])[:, 2], -1.0, atol=1e-6)


def test_l_shaped_footprint_gives_one_wall_per_edge(tmp_path):
    spec = make_spec(hall=L_HALL)
    np.testing.assert_array_equal(spec.footprint_array, L_POLY)  # clockwise input reversed, vertex 0 kept
    geo = load_geometry(build_scene(spec, tmp_path).xml_path)
    walls = [n for n in geo.names if n.startswith("wall_")]
    assert walls == [f"wall_{i}" for i in range(6)]
    for i, name in enumerate(walls):
        p0, p1 = L_POLY[i], L_POLY[(i + 1) % 6]
        v = np.asarray(geo.meshes[name].vertices)
        e = (p1 - p0) / np.linalg.norm(p1 - p0)
        rel = v[:, :2] - p0
        assert np.max(np.abs(rel[:, 0] * e[1] - rel[:, 1] * e[0])) < POS_TOL, f"{name} leaves its edge"
        along = rel @ e
        assert along.min() == pytest.approx(0, abs=POS_TOL)
        assert along.max() == pytest.approx(np.linalg.norm(p1 - p0), abs=POS_TOL)
        assert geo.meshes[name].area == pytest.approx(np.linalg.norm(p1 - p0) * 5.0, abs=AREA_TOL)
        # The wall's normal points into the hall: a point just in front of it lies inside the L.
        c = geo.meshes[name].triangles_center[0] + 0.1 * geo.meshes[name].face_normals[0]
        assert contains(L_POLY, c[None, :2])[0], name
    shoelace = 20 * 4 + 6 * 6
    assert geo.meshes["floor"].area == pytest.approx(shoelace, abs=AREA_TOL)
    assert geo.meshes["ceiling"].area == pytest.approx(shoelace, abs=AREA_TOL)


@pytest.mark.parametrize(("rotate_deg", "expected"), [
    # Rz(90): (x, y, z) -> (-y, x, z); the 1 × 2 × 0.5 m block moves to x -2…0, y 0…1, + translate.
    ([0, 0, 90], [[10.0, 1.0, 0.0], [12.0, 2.0, 0.5]]),
    # Extrinsic x then z: Rx(90) (x, y, z) -> (x, -z, y), then Rz(90): x 0…0.5, y 0…1, z 0…2.
    # (The other order, Rx after Rz, would give x -2…0, y -0.5…0, z 0…1.)
    ([90, 0, 90], [[12.0, 1.0, 0.0], [12.5, 2.0, 2.0]]),
])
def test_imported_mesh_in_millimetres_lands_where_the_spec_says(tmp_path, rotate_deg, expected):
    mm_part(tmp_path)
    spec = make_spec(tmp_path, hall="size = [20.0, 10.0]\nheight = 5.0", extra=f"""
[[meshes]]
file = "part_mm.stl"
scale = 0.001
rotate_deg = {rotate_deg}
translate = [12.0, 1.0, 0.0]
material = "metal"
""")
    geo = load_geometry(build_scene(spec, tmp_path / "out").xml_path)
    part = geo.meshes["part_mm"]
    np.testing.assert_allclose(part.bounds, expected, atol=POS_TOL)
    assert part.volume == pytest.approx(1.0 * 2.0 * 0.5, rel=1e-5)  # a rotation keeps the volume
    assert "part_mm" in geo.closed


def test_door_and_window_cut_holes_closed_by_panels(tmp_path):
    spec = make_spec(extra="""
[[objects]]
kind = "door"
name = "gate"
wall = 0
offset = 2.0
size = [1.0, 2.1]
[[objects]]
kind = "window"
position = [10.0, 3.0, 1.5]
size = [2.0, 1.0]
material = {itu = "glass", thickness = 0.008}
""")
    gate, win = spec.objects
    assert (win.wall, win.offset, win.sill) == (1, pytest.approx(3.0), pytest.approx(1.0))
    geo = load_geometry(build_scene(spec, tmp_path).xml_path)
    m = geo.meshes
    assert m["wall_0"].area == pytest.approx(10 * 3 - 1.0 * 2.1, abs=AREA_TOL)
    assert m["wall_1"].area == pytest.approx(6 * 3 - 2.0 * 1.0, abs=AREA_TOL)
    assert m["gate"].area == pytest.approx(2.1, abs=AREA_TOL)
    np.testing.assert_allclose(m["gate"].bounds, [[1.5, 0.01, 0.0], [2.5, 0.01, 2.1]], atol=POS_TOL)
    np.testing.assert_allclose(m["window_1"].bounds, [[9.99, 2.0, 1.0], [9.99, 4.0, 2.0]], atol=POS_TOL)
    assert geo.materials["gate"] == "metal-40mm" and geo.materials["window_1"] == "glass-8mm"
    # From inside, toward the door: the panel 1 cm in front of the wall plane is hit first ...
    assert geo.first_hit([2.0, 1.0, 1.0], [0, -1, 0]) == ("gate", pytest.approx(0.99, abs=POS_TOL))
    # ... and there is no wall behind it (the hole): from outside the ray passes the plane y = 0.
    assert geo.first_hit([2.0, -1.0, 1.0], [0, 1, 0]) == ("gate", pytest.approx(1.01, abs=POS_TOL))
    assert geo.first_hit([4.0, -1.0, 1.0], [0, 1, 0]) == ("wall_0", pytest.approx(1.0, abs=POS_TOL))


# --- specs ------------------------------------------------------------------------------------


def test_ris_normal_with_yaw_and_radar_grid():
    spec = make_spec(hall=L_HALL, extra="""
[[ris]]
name = "east"
position = [18, 2, 1.2]
normal = [-1, 0, 0]
yaw_deg = 21
spacing = 0.003
[radar]
grid = {spacing = 1.0, height = 1.5, margin = 0.5}
facing = "east"
""")
    (ris,) = spec.ris_configs()
    # conventions.md: a panel turned by yaw ψ about up sees its former broadside target at azimuth -ψ.
    np.testing.assert_allclose(ris.pose.angles_to([8.0, 2.0, 1.2]), [math.radians(-21), 0.0], atol=1e-12)
    assert ris.element_spacing == 0.003
    pts = spec.radar_positions()
    assert np.all(contains(L_POLY, pts[:, :2])) and np.all(boundary_distance(L_POLY, pts[:, :2]) >= 0.5 - 1e-9)
    np.testing.assert_array_equal(pts[:, 2], 1.5)
    # Brute force: grid points 0.5 + k m inside the L (x 0.5…19.5, y 0.5…9.5) at least 0.5 m from its edges.
    xs, ys = np.meshgrid(np.arange(0.5, 20, 1.0), np.arange(0.5, 10, 1.0), indexing="ij")
    cand = np.column_stack([xs.ravel(), ys.ravel()])
    keep = contains(L_POLY, cand) & (boundary_distance(L_POLY, cand) >= 0.5 - 1e-9)
    np.testing.assert_allclose(pts[:, :2], cand[keep], atol=1e-12)
    np.testing.assert_allclose(spec.radar_facing_point(), [18, 2, 1.2])


BAD_SPECS = [
    (dict(scene='name = "t"\ndescripton = "x"'), r"scene\.descripton: unknown key.*did you mean 'description'"),
    (dict(extra='[[objects]]\nkind = "box"\nmin = [1, 1, 0]\nmax = [2, 2, 1]\nmaterial = "metal"\ncolour = "red"'),
     r"objects\[0\]\.colour: unknown key"),
    (dict(hall="size = [10.0, 6.0]"), r"hall\.height: required key is missing; add height = 7\.0"),
    (dict(hall='size = [10.0, 6.0]\nheight = "3"'), r"hall\.height: must be a number \[m\], got a string"),
    (dict(hall="footprint = [[0, 0], [5, 0], [10, 0]]\nheight = 3"), r"hall\.footprint: .*on the line through"),
    (dict(hall="footprint = [[0, 0], [4, 0], [4, 0], [0, 4]]\nheight = 3"), r"hall\.footprint: .*zero length"),
    (dict(hall="footprint = [[0, 0], [4, 4], [4, 0], [0, 4]]\nheight = 3"), r"hall\.footprint: .*cross or touch"),
    (dict(materials=SHELL.replace('"concrete"', '"unobtainium"', 1)),
     r"hall\.materials\.walls: unknown ITU material type 'unobtainium'"),
    (dict(materials=SHELL.replace('floor = "concrete"', 'floor = {itu = "brick"}')),
     r"hall\.materials\.floor\.itu: ITU material 'brick' is defined for 1–40 GHz, 110–330 GHz only"),
    (dict(materials=SHELL.replace('floor = "concrete"', 'floor = {itu = "marble"}')),
     r"hall\.materials\.floor\.itu: ITU material 'marble' .* float32: 60\.0000038"),
    (dict(materials=SHELL.replace('floor = "concrete"', 'floor = {itu = "metal", name = "concrete"}')),
     r"hall\.materials\.floor\.name: material name 'concrete' collides"),
    (dict(extra='[[objects]]\nkind = "box"\ncenter = [5, 3, 1]\nsize = [1, -1, 1]\nmaterial = "metal"'),
     r"objects\[0\]\.size\[1\]: -1 must be > 0"),
    (dict(extra='[[objects]]\nkind = "box"\ncenter = [9.8, 3, 1]\nsize = [1, 1, 1]\nmaterial = "metal"'),
     r"objects\[0\]: the box reaches outside the hall footprint"),
    (dict(extra='[[objects]]\nkind = "cone"\nmaterial = "metal"'), r"objects\[0\]\.kind: 'cone' is not one of"),
    (dict(extra='[[objects]]\nkind = "door"\nwall = 0\noffset = 9.8\nsize = [1, 2]'),
     r"objects\[0\]: the door spans 9\.300 … 10\.300 m along wall 0"),
    (dict(extra='[[objects]]\nkind = "box"\nname = "floor"\nmin = [1, 1, 0]\nmax = [2, 2, 1]\nmaterial = "metal"'),
     r"objects\[0\]\.name: 'floor' is reserved"),
    (dict(extra="[[ris]]\nposition = [5, 3, 1]\nfacing = [1, 3, 1]\nrows = 16.0"), r"ris\[0\]\.rows: must be an integer"),
    (dict(extra="[[ris]]\nposition = [5, 3, 1]\nfacing = [1, 3, 1]\npanel = {width = 0.01}"),
     r"ris\[0\]\.panel\.width: 0\.01 m is smaller than the element grid"),
    (dict(extra="[[ris]]\nposition = [5, 3, 1]\nfacing = [1, 3, 1]\n[radar]\npositions = [[1, 1, 1]]\nfacing = \"ris9\""),
     r"radar\.facing: 'ris9' is not a RIS of this spec"),
    (dict(extra="[radar]\npositions = [[11, 1, 1]]\nfacing = [1, 1, 1]"), r"radar\.positions\[0\]: the radar .* outside"),
    (dict(materials=SHELL.replace('walls = "concrete"', 'walls = {itu = "concrete", scattering_coefficient = 1.5}')),
     r"hall\.materials\.walls\.scattering_coefficient: is 1\.5: a scattering coefficient lies in \[0, 1\]"),
    (dict(materials=SHELL.replace('walls = "concrete"', 'walls = {itu = "concrete", scattering_coefficient = -0.1}')),
     r"hall\.materials\.walls\.scattering_coefficient: -0\.1 must be >= 0"),
    (dict(materials=SHELL.replace('walls = "concrete"', 'walls = {itu = "concrete", scattering_coefficient = "rough"}')),
     r"hall\.materials\.walls\.scattering_coefficient: must be a number"),
    (dict(extra='[[ris]]\nposition = [5, 3, 1]\nfacing = [1, 3, 1]\n'
                'panel = {material = {itu = "metal", scattering_coefficient = 0.2}}'),
     r"ris\[0\]\.panel\.material\.scattering_coefficient: is not used: the RIS panel is not ray traced"),
]


@pytest.mark.parametrize(("kw", "match"), BAD_SPECS, ids=[m.split(":")[0].replace("\\", "") for _, m in BAD_SPECS])
def test_bad_specs_name_the_key(kw, match):
    with pytest.raises(SpecError, match=match):
        make_spec(**kw)


def test_spec_errors_from_files_name_the_file_and_bad_toml(tmp_path):
    path = tmp_path / "hall.toml"
    path.write_text(make_toml(hall="size = [10.0, 6.0]"))
    with pytest.raises(SpecError, match=r"hall\.toml: hall\.height: required key is missing") as info:
        load_spec(path)
    assert info.value.key == "hall.height" and isinstance(info.value, ValueError)
    path.write_text("[scene\nname = 1")
    with pytest.raises(SpecError, match=r"not valid TOML.*line 1"):
        load_spec(path)


def test_marble_is_accepted_just_below_60ghz():
    spec = make_spec(scene='name = "t"\nfrequency = 59.99e9', materials=SHELL.replace('"concrete"', '"marble"', 1))
    assert spec.materials.walls.itu == "marble"


# --- geometry checks --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def crate_hall(tmp_path_factory):
    """10 m × 6 m × 3 m concrete hall with a 1 m metal crate at x 4…5, y 2…3, z 0…1."""
    spec = make_spec(extra='[[objects]]\nkind = "box"\nname = "crate"\nmin = [4, 2, 0]\nmax = [5, 3, 1]\n'
                           'material = "metal"')
    return load_geometry(build_scene(spec, tmp_path_factory.mktemp("crate")).xml_path)


@pytest.mark.parametrize(("point", "match"), [
    ([-1.0, 3.0, 1.0], r"radar: position \[-1\.000, 3\.000, 1\.000\] m is outside the hall"),
    ([5.0, 3.0, 3.5], r"is outside the hall: rays toward .*\[0, 0, 1\]"),
    ([-0.05, 3.0, 1.0], r"outside the hall.*'wall_3', is 0\.050 m away: the point is inside its 0\.2 m thick"),
    ([0.01, 3.0, 1.0], r"is 0\.010 m from 'wall_3' \(concrete-200mm\), closer than the clearance 0\.05 m.*"
                       r"at least 0\.040 m further"),
    ([4.5, 2.5, 0.5], r"inside the closed object 'crate'"),
    ([4.5, 2.5, 1.02], r"is 0\.020 m from 'crate'"),
])
def test_check_point_rejects_bad_positions(crate_hall, point, match):
    with pytest.raises(SpecError, match=match):
        crate_hall.check_point(point)


def test_check_point_accepts_free_positions(crate_hall):
    crate_hall.check_point([4.5, 2.5, 1.06])  # 6 cm above the crate
    crate_hall.check_point([0.06, 0.06, 0.06])  # in a corner, 6 cm from three surfaces
    crate_hall.check_point([0.01, 3.0, 1.0], clearance=0.005)
    assert crate_hall.nearest_surface([0.06, 3.0, 1.0]) == ("wall_3", pytest.approx(0.06, abs=POS_TOL))


# --- packaging --------------------------------------------------------------------------------


def test_authoring_never_imports_the_ray_tracer():
    code = ("import sys, risloc_rt.authoring, risloc_rt.authoring.build, risloc_rt.authoring.geometry; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'sionna', 'mitsuba', 'drjit'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_command_line_builds_and_reports_errors(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(make_toml())
    ok = subprocess.run([sys.executable, "-m", "risloc_rt.authoring.build", str(spec), "-o", str(tmp_path / "out")],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert ok.stderr == ""  # in particular no runpy RuntimeWarning
    assert content_hash(tmp_path / "out" / "scene.xml") in ok.stdout
    spec.write_text(make_toml(hall="size = [10.0, -6.0]\nheight = 3"))
    bad = subprocess.run([sys.executable, "-m", "risloc_rt.authoring.build", str(spec)], capture_output=True, text=True)
    assert bad.returncode == 2 and "hall.size[1]: -6 must be > 0" in bad.stderr


def test_a_scattering_coefficient_is_a_named_material_written_to_the_xml_only_when_non_zero(tmp_path):
    rough = make_spec(materials=SHELL.replace('walls = "concrete"', 'walls = {itu = "concrete", scattering_coefficient = 0.3}'))
    walls = rough.materials.walls
    assert walls.scattering_coefficient == 0.3 and walls.name == "concrete-200mm-S0p3" and "S=0.3" in walls.describe()
    assert rough.materials.floor.scattering_coefficient == 0.0 and rough.materials.floor.name == "concrete-200mm"
    build_scene(rough, tmp_path / "rough")
    xml = (tmp_path / "rough" / "scene.xml").read_text()
    assert xml.count('name="scattering_coefficient"') == 1 and '<float name="scattering_coefficient" value="0.3"/>' in xml
    # a smooth material (S = 0, the default, or given as 0) writes the same bytes as before the key existed
    smooth = make_spec(materials=SHELL.replace('walls = "concrete"', 'walls = {itu = "concrete", scattering_coefficient = 0}'))
    build_scene(smooth, tmp_path / "zero")
    build_scene(make_spec(), tmp_path / "plain")
    assert (tmp_path / "zero" / "scene.xml").read_bytes() == (tmp_path / "plain" / "scene.xml").read_bytes()
    assert "scattering_coefficient" not in (tmp_path / "plain" / "scene.xml").read_text()
    custom = make_spec(materials=SHELL.replace(
        'walls = "concrete"', 'walls = {permittivity = 6.1, conductivity = 0.6, scattering_coefficient = 0.45}'))
    assert custom.materials.walls.name == "eps6p1-sig0p6-200mm-S0p45"
