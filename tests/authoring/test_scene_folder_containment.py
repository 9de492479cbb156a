"""Issue 19 regressions: a scene folder never touches anything outside itself, and a stopped
``risloc scene build`` leaves the previous build intact (or one the next build takes over)."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

from risloc_rt.authoring import SpecError, load_spec
from risloc_rt.authoring import build as build_mod
from risloc_rt.authoring.build import MANIFEST_NAME, build_scene, read_manifest, stale_files
from risloc_rt.authoring.scene_folder import SceneError, scene_content_hash, scene_references

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
name = "{name}"
translate = [3.0, 3.0, 0.0]
material = "metal"
"""


def _tree(folder: Path) -> dict[str, bytes | None]:
    """Every entry below ``folder`` (hidden ones too): file bytes, or None for a folder."""
    return {p.relative_to(folder).as_posix(): (None if p.is_dir() else p.read_bytes())
            for p in sorted(folder.rglob("*"))}


def _hall(tmp_path: Path, name: str = "rack") -> Path:
    folder = tmp_path / "hall"
    (folder / "parts").mkdir(parents=True)
    (folder / "parts/rack.stl").write_bytes(trimesh.creation.box([1.0, 1.0, 2.0]).export(file_type="stl"))
    (folder / "spec.toml").write_text(SPEC.format(mesh="parts/rack.stl", name=name))
    return folder


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "victim" / "important.txt"
    victim.parent.mkdir()
    victim.write_bytes(b"the user's thesis\n")
    return victim


def _add_to_manifest(folder: Path, rel: str, digest: str) -> None:
    path = folder / MANIFEST_NAME
    doc = json.loads(path.read_text())
    doc["files"][rel] = digest
    path.write_text(json.dumps(doc))


# --- manifest entries ---------------------------------------------------------------------------

@pytest.mark.parametrize("entry", ["../victim/important.txt", "meshes/../../victim/important.txt", "ABSOLUTE"])
def test_issue_19_hostile_manifest_entry_is_refused_and_the_victim_survives(tmp_path, entry):
    victim = _victim(tmp_path)
    folder = _hall(tmp_path)
    build_scene(folder / "spec.toml", folder)
    entry = str(victim) if entry == "ABSOLUTE" else entry
    _add_to_manifest(folder, entry, hashlib.sha256(victim.read_bytes()).hexdigest())
    (folder / "spec.toml").write_text(SPEC.format(mesh="parts/rack.stl", name="shelf"))  # a rebuild that deletes
    before = _tree(folder)
    with pytest.raises(SpecError) as info:
        build_scene(folder / "spec.toml", folder)
    message = str(info.value)
    assert entry in message and str(folder) in message and "\n" not in message
    assert victim.read_bytes() == b"the user's thesis\n"
    assert _tree(folder) == before  # refused before anything was written


def test_issue_19_manifest_entry_that_is_a_symlink_out_is_refused(tmp_path):
    victim = _victim(tmp_path)
    folder = _hall(tmp_path)
    build_scene(folder / "spec.toml", folder)
    (folder / "meshes/old.ply").symlink_to(victim)
    _add_to_manifest(folder, "meshes/old.ply", hashlib.sha256(victim.read_bytes()).hexdigest())
    with pytest.raises(SpecError, match=r"meshes/old\.ply.*symbolic link"):
        build_scene(folder / "spec.toml", folder)
    assert victim.read_bytes() == b"the user's thesis\n"
    assert (folder / "meshes/old.ply").is_symlink()


def test_issue_19_cli_build_with_hostile_manifest_is_one_line_and_keeps_the_victim(tmp_path, capsys):
    victim = _victim(tmp_path)
    folder = _hall(tmp_path)
    assert build_mod.main([str(folder / "spec.toml")]) == 0
    _add_to_manifest(folder, "../victim/important.txt", hashlib.sha256(victim.read_bytes()).hexdigest())
    capsys.readouterr()
    assert build_mod.main([str(folder / "spec.toml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "../victim/important.txt" in err and "Traceback" not in err
    assert victim.exists()


def test_issue_19_build_never_writes_through_a_symlinked_folder(tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    folder = _hall(tmp_path)
    (folder / "meshes").symlink_to(outside, target_is_directory=True)
    with pytest.raises(SpecError, match=r"meshes/.*outside the scene folder"):
        build_scene(folder / "spec.toml", folder)
    assert list(outside.iterdir()) == []
    assert not (folder / "scene.xml").exists()


# --- scene.xml references -----------------------------------------------------------------------

def _scene_with_reference(tmp_path: Path, value_of) -> tuple[Path, str]:
    folder = _hall(tmp_path)
    build_scene(folder / "spec.toml", folder)
    outside = tmp_path / "outside.ply"
    outside.write_bytes((folder / "meshes/rack.ply").read_bytes())
    value = value_of(folder, outside)
    xml = folder / "scene.xml"
    xml.write_text(xml.read_text().replace('value="meshes/rack.ply"', f'value="{value}"'))
    assert value in xml.read_text()
    return xml, value


_REFERENCES = {
    "dotdot": lambda folder, outside: "../outside.ply",
    "absolute": lambda folder, outside: str(outside),
    "symlink": lambda folder, outside: (folder / "meshes/link.ply").symlink_to(outside) or "meshes/link.ply",
}


@pytest.mark.parametrize("kind", sorted(_REFERENCES))
def test_issue_19_scene_reference_outside_the_folder_is_refused(tmp_path, kind):
    xml, value = _scene_with_reference(tmp_path, _REFERENCES[kind])
    for call in (scene_references, scene_content_hash):
        with pytest.raises(SceneError) as info:
            call(xml)
        message = str(info.value)
        assert repr(value) in message and str(xml.parent) in message and "outside the scene folder" in message
        assert "\n" not in message


@pytest.mark.parametrize("kind", sorted(_REFERENCES))
def test_issue_19_load_scene_and_trace_refuse_a_reference_out(tmp_path, kind):
    pytest.importorskip("sionna.rt")
    from risloc_rt.hall.raytrace import load_scene
    from risloc_rt.hall.raytrace.tracer import trace_scene

    xml, value = _scene_with_reference(tmp_path, _REFERENCES[kind])
    with pytest.raises(SceneError, match="outside the scene folder"):
        load_scene(xml, frequency=60e9)
    with pytest.raises(SceneError, match="outside the scene folder"):
        trace_scene(xml, radar_position=[1.0, 1.0, 1.0], frequency=60e9)


def test_issue_19_references_inside_the_folder_still_load(tmp_path):
    folder = _hall(tmp_path)
    build_scene(folder / "spec.toml", folder)
    (folder / "meshes/alias.ply").symlink_to(folder / "meshes/rack.ply")  # a link that stays inside
    xml = folder / "scene.xml"
    xml.write_text(xml.read_text().replace('value="meshes/rack.ply"', 'value="meshes/../meshes/alias.ply"'))
    refs = scene_references(xml)
    assert "meshes/../meshes/alias.ply" in [v for v, _ in refs]
    assert len(scene_content_hash(xml)) == 64


# --- spec mesh imports --------------------------------------------------------------------------

def test_issue_19_spec_mesh_symlinked_out_of_the_spec_folder_is_refused(tmp_path):
    folder = _hall(tmp_path)
    outside = tmp_path / "outside.stl"
    outside.write_bytes((folder / "parts/rack.stl").read_bytes())
    (folder / "parts/link.stl").symlink_to(outside)
    (folder / "spec.toml").write_text(SPEC.format(mesh="parts/link.stl", name="rack"))
    with pytest.raises(SpecError, match="outside the spec's folder"):
        load_spec(folder / "spec.toml")
    (folder / "spec.toml").write_text(SPEC.format(mesh=str(outside), name="rack"))
    with pytest.raises(SpecError, match="outside the spec's folder"):
        load_spec(folder / "spec.toml")
    (folder / "spec.toml").write_text(SPEC.format(mesh="parts/rack.stl", name="rack"))
    assert load_spec(folder / "spec.toml").meshes[0].file == (folder / "parts/rack.stl").resolve()


# --- a stopped build ----------------------------------------------------------------------------

def _two_builds(tmp_path: Path) -> tuple[Path, str, str]:
    """A folder built from spec A (object 'rack'); spec B renames it (new mesh, old one stale)."""
    folder = _hall(tmp_path)
    spec_a = SPEC.format(mesh="parts/rack.stl", name="rack")
    spec_b = SPEC.format(mesh="parts/rack.stl", name="shelf").replace("[3.0, 3.0, 0.0]", "[5.0, 4.0, 0.0]")
    build_scene(folder / "spec.toml", folder)
    return folder, spec_a, spec_b


def test_issue_19_ctrl_c_while_staging_leaves_the_folder_byte_identical(tmp_path, monkeypatch):
    folder, spec_a, spec_b = _two_builds(tmp_path)
    (folder / "spec.toml").write_text(spec_b)
    before = _tree(folder)
    real_stage = build_mod._stage
    calls = []

    def stage_then_interrupt(target, data):
        calls.append(target)
        if len(calls) == 2:  # after the first mesh is staged
            raise KeyboardInterrupt
        return real_stage(target, data)

    monkeypatch.setattr(build_mod, "_stage", stage_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        build_scene(folder / "spec.toml", folder)
    assert calls[0].name.endswith(".ply")
    assert _tree(folder) == before  # no new mesh, no temporary file, manifest unchanged
    monkeypatch.setattr(build_mod, "_stage", real_stage)
    (folder / "spec.toml").write_text(spec_a)
    build_scene(folder / "spec.toml", folder)  # the previous spec builds again
    assert _tree(folder) == {**before, "spec.toml": spec_a.encode()}
    (folder / "spec.toml").write_text(spec_b)
    build_scene(folder / "spec.toml", folder)  # and so does the new one
    assert stale_files(folder) == []
    assert (folder / "meshes/shelf.ply").is_file() and not (folder / "meshes/rack.ply").exists()


@pytest.mark.parametrize("respec", ["a", "b"])
def test_issue_19_build_killed_during_the_swap_is_taken_over_by_the_next(tmp_path, monkeypatch, respec):
    folder, spec_a, spec_b = _two_builds(tmp_path)
    built_a = _tree(folder)
    (folder / "spec.toml").write_text(spec_b)
    moves = []

    def move_then_die(src, dst):
        if moves:
            raise KeyboardInterrupt  # as if killed after the first rename
        moves.append(dst)
        os.replace(src, dst)

    monkeypatch.setattr(build_mod, "_move", move_then_die)
    with pytest.raises(KeyboardInterrupt):
        build_scene(folder / "spec.toml", folder)
    assert len(moves) == 1 and _tree(folder) != built_a  # a mix of the old and the new build
    assert read_manifest(folder)["pending"]  # the half-swapped state is recorded
    monkeypatch.setattr(build_mod, "_move", os.replace)
    assert not list(folder.rglob(f"*{build_mod._STAGE_SUFFIX}"))  # the files not yet moved are removed
    if respec == "a":
        (folder / "spec.toml").write_text(spec_a)
        build_scene(folder / "spec.toml", folder)  # no conflict with the half-written new files
        assert _tree(folder) == built_a
    else:
        build_scene(folder / "spec.toml", folder)
        assert stale_files(folder) == []
        assert not (folder / "meshes/rack.ply").exists()
        assert read_manifest(folder)["pending"] == {}


def test_issue_19_completed_build_manifest_has_no_pending_and_is_unchanged(tmp_path):
    folder, spec_a, spec_b = _two_builds(tmp_path)
    doc = json.loads((folder / MANIFEST_NAME).read_text())
    assert set(doc) == {"format", "version", "spec_sha256", "files"}
    assert not list(folder.rglob(f"*{build_mod._STAGE_SUFFIX}"))
    assert np.all([(folder / rel).is_file() for rel in doc["files"]])


def test_issue_19_a_spec_symlinked_into_the_folder_still_builds_in_place(tmp_path):
    folder = _hall(tmp_path)
    kept = tmp_path / "specs" / "hall.toml"
    kept.parent.mkdir()
    text = SPEC.split("[[meshes]]")[0]  # meshes resolve from the spec's real folder: none here
    kept.write_text(text)
    (folder / "spec.toml").unlink()
    (folder / "spec.toml").symlink_to(kept)  # the user keeps the spec elsewhere and links it in
    built = build_scene(folder / "spec.toml", folder)
    assert built.xml_path.is_file() and (folder / "spec.toml").is_symlink()
    assert kept.read_text() == text
    build_scene(folder / "spec.toml", folder)  # and rebuilds
