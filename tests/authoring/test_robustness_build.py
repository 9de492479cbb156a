"""Issue 11 regressions for 'risloc scene build' and hall specs: no user file lost, stable rebuilds,
scenes that load from anywhere, absurd specs refused."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import trimesh

from risloc_rt.authoring import SpecError, loads_spec
from risloc_rt.authoring.build import MANIFEST_NAME, build_scene, stale_files
from risloc_rt.authoring.scene_folder import scene_references

SPEC = """
[scene]
name = "t"
[hall]
size = [12.0, 8.0]
height = 4.0
[hall.materials]
walls = "concrete"
floor = "concrete"
ceiling = "concrete"
[[meshes]]
file = "{mesh}"
name = "rack"
translate = [3.0, 3.0, 0.0]
material = "metal"
"""


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _spec_folder(tmp_path: Path, mesh: str = "parts/rack.stl") -> Path:
    folder = tmp_path / "hall"
    (folder / mesh).parent.mkdir(parents=True)
    (folder / mesh).write_bytes(trimesh.creation.box([1.0, 1.0, 2.0]).export(file_type=Path(mesh).suffix[1:]))
    (folder / "spec.toml").write_text(SPEC.format(mesh=mesh))
    return folder


def test_issue_11_build_in_place_keeps_user_files_and_is_bit_identical(tmp_path):
    folder = _spec_folder(tmp_path)
    (folder / "meshes").mkdir()
    user_mesh = folder / "meshes" / "my_notes.ply"
    user_mesh.write_bytes(b"not generated")
    build_scene(folder / "spec.toml", folder)
    first = _tree(folder)
    build_scene(folder / "spec.toml", folder)
    assert _tree(folder) == first  # bit-identical, the manifest included
    assert user_mesh.read_bytes() == b"not generated"  # never deleted
    assert first["parts/rack.stl"] == (folder / "parts/rack.stl").read_bytes()  # the source is untouched
    assert MANIFEST_NAME in first


def test_issue_11_source_mesh_in_meshes_folder_is_never_overwritten(tmp_path):
    # Defect 1: the builder wrote the transformed mesh over its own source, and transformed it again
    # on every build (geometry drifting build after build).
    folder = _spec_folder(tmp_path, mesh="meshes/rack.ply")
    before = (folder / "meshes/rack.ply").read_bytes()
    with pytest.raises(SpecError, match="overwrite the source.*outside meshes/"):
        build_scene(folder / "spec.toml", folder)
    assert (folder / "meshes/rack.ply").read_bytes() == before


def test_issue_11_foreign_files_are_not_overwritten_without_force(tmp_path):
    folder = _spec_folder(tmp_path)
    other = tmp_path / "out"
    other.mkdir()
    (other / "scene.xml").write_text("<scene>my own</scene>")
    with pytest.raises(SpecError, match="scene.xml .was not written by 'risloc scene build'.*--force"):
        build_scene(folder / "spec.toml", other)
    assert (other / "scene.xml").read_text() == "<scene>my own</scene>"
    assert not (other / "meshes").exists() or not any((other / "meshes").iterdir())  # nothing written
    build_scene(folder / "spec.toml", other, force=True)
    # An edited generated file is refused too; a renamed object's old mesh is removed only if unchanged.
    (other / "meshes" / "floor.ply").write_bytes(b"edited")
    with pytest.raises(SpecError, match="edited after the last build"):
        build_scene(folder / "spec.toml", other)


def test_issue_11_scene_built_elsewhere_loads_from_there(tmp_path):
    # Defect 1: with -o OTHER the copied spec referred to meshes that do not resolve from OTHER.
    folder = _spec_folder(tmp_path)
    out = tmp_path / "elsewhere" / "scene"
    build_scene(folder / "spec.toml", out)
    shutil.rmtree(folder)  # the output must stand on its own
    assert all(Path(p).is_file() for _, p in scene_references(out / "scene.xml"))
    assert stale_files(out) == []  # its spec.toml builds again, from there, to the same bytes


def test_issue_11_edited_spec_is_detected_as_stale(tmp_path):
    # Defect 8: a spec edited after its build was traced from the old XML.
    from risloc_rt.hall.scenario import check_up_to_date

    folder = _spec_folder(tmp_path)
    build_scene(folder / "spec.toml", folder)
    check_up_to_date(folder)
    (folder / "spec.toml").write_text(SPEC.format(mesh="parts/rack.stl").replace("12.0, 8.0", "14.0, 8.0"))
    with pytest.raises(ValueError, match="out of date: .*run 'risloc scene build"):
        check_up_to_date(folder)


@pytest.mark.parametrize("edit,match", [
    (("12.0, 8.0", "12000.0, 8000.0"), "millimetres"),
    (("height = 4.0", "height = 0.004"), "kilometres"),
    (('name = "t"', 'name = "t"\nfrequency = 1e-300'), "outside .* Hz"),
    (('name = "t"', 'name = "t"\nfrequncy = 60e9'), "did you mean 'frequency'"),
    (("height = 4.0", "height = true"), "must be a number"),
])
def test_issue_11_absurd_specs_are_refused(tmp_path, edit, match):
    folder = _spec_folder(tmp_path)
    with pytest.raises(SpecError, match=match):
        loads_spec(SPEC.format(mesh="parts/rack.stl").replace(*edit), base_dir=folder)


def test_issue_11_mesh_outside_the_spec_folder_is_refused(tmp_path):
    folder = _spec_folder(tmp_path)
    (tmp_path / "outside.stl").write_bytes((folder / "parts/rack.stl").read_bytes())
    with pytest.raises(SpecError, match="outside the spec's folder"):
        loads_spec(SPEC.format(mesh="../outside.stl"), base_dir=folder)
