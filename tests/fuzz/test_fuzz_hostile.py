"""Hypothesis fuzzing of hostile paths and corrupted run logs (issue 19).

(a) Paths taken from inputs (a ``build-manifest.json`` entry, a ``filename`` in ``scene.xml``, a
spec's ``[[meshes]].file``) made of ``..``, absolute paths, symbolic links out of (and inside) the
folder, odd unicode and very long names: the build and the scene readers end in a clean one-line
error or a correct result, and a sentinel file outside the folder, and its folder's listing, are
never touched.

(b) A study's ``runs.jsonl`` (made once per module by a tiny study) with random corruptions: a cut
at any byte (a torn tail) is repaired by dropping only the partial last row; any damage to a whole
line (a blank or garbage line, flipped, inserted or deleted bytes, two lines joined, odd values of
``point``/``run``) is either still a run row or a one-line error naming the file and the line, the
file left byte-identical.

Derandomized like ``test_fuzz_inputs.py``; about a minute in all.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest
import trimesh
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from risloc_rt.authoring import SpecError, load_spec
from risloc_rt.authoring.build import MANIFEST_NAME, build_scene, stale_files
from risloc_rt.authoring.scene_folder import (
    SceneError,
    scene_content_hash,
    scene_references,
)
from risloc_rt.studies.store import LOG, RunLog, RunLogError

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
LOG_SETTINGS = settings(SETTINGS, max_examples=150)

#: A clean error: a one-line message of one of these types.
CLEAN = (SpecError, SceneError, ValueError, OSError)

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
file = {mesh}
name = "{name}"
translate = [3.0, 3.0, 0.0]
material = "metal"
"""
SENTINEL = b"the user's thesis\n"

# --- (a) hostile paths ---------------------------------------------------------------------------

#: Path components; ABS (first) becomes the absolute path of the outside folder, the LINK_* are
#: symbolic links made in the scene folder: to the outside folder, to the sentinel, to meshes/.
_PARTS = st.one_of(
    st.sampled_from(["..", "..", ".", "", "meshes", "parts", "rack.stl", "rack.ply", "LINK_DIR_OUT", "LINK_FILE_OUT",
                     "LINK_DIR_IN", "outside", "important.txt", "spec.toml", "scene.xml", "é", "\u202eply.lts",
                     "\U0001F600", "a" * 255, "b" * 300, "~", "$HOME", " ", "\\..\\", "..."]),
    st.text(st.characters(blacklist_characters="/\x00", blacklist_categories=("Cs",)), min_size=1, max_size=12),
)
HOSTILE_PATHS = st.tuples(st.booleans(), st.lists(_PARTS, min_size=1, max_size=6))


def _tree(folder: Path) -> dict[str, object]:
    """Every entry under ``folder``, links not followed: bytes, None (a folder) or ("link", target)."""
    out: dict[str, object] = {}
    for top, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(top) / name
            rel = p.relative_to(folder).as_posix()
            out[rel] = ("link", os.readlink(p)) if p.is_symlink() else None if p.is_dir() else p.read_bytes()
    return out


def _stamp(outside: Path) -> tuple:
    """The outside folder as a user sees it: its listing, its bytes, its and the sentinel's stat."""
    st_dir, st_file = outside.stat(), (outside / "important.txt").stat()
    return (_tree(outside), st_dir.st_mtime_ns, st_dir.st_nlink, st_file.st_mtime_ns, st_file.st_ino, st_file.st_size)


@pytest.fixture(scope="module")
def halls(tmp_path_factory):
    """A built hall (spec A: object 'rack') and the same folder rebuilt from spec B (object 'shelf')."""
    base = tmp_path_factory.mktemp("halls")
    built = base / "a"
    (built / "parts").mkdir(parents=True)
    (built / "parts/rack.stl").write_bytes(trimesh.creation.box([1.0, 1.0, 2.0]).export(file_type="stl"))
    (built / "spec.toml").write_text(SPEC.format(mesh='"parts/rack.stl"', name="rack"))
    build_scene(built / "spec.toml", built)
    rebuilt = base / "b"
    shutil.copytree(built, rebuilt)
    (rebuilt / "spec.toml").write_text(SPEC.format(mesh='"parts/rack.stl"', name="shelf"))
    build_scene(rebuilt / "spec.toml", rebuilt)
    return built, rebuilt


class Sandbox:
    """``root/outside/important.txt`` (the sentinel) and ``root/hall`` (a copy of a built hall with links)."""

    def __init__(self, root: Path, hall: Path) -> None:
        shutil.rmtree(root, ignore_errors=True)
        self.outside = root / "outside"
        self.outside.mkdir(parents=True)
        (self.outside / "important.txt").write_bytes(SENTINEL)
        self.folder = root / "hall"
        shutil.copytree(hall, self.folder, symlinks=True)
        (self.folder / "LINK_DIR_OUT").symlink_to(self.outside, target_is_directory=True)
        (self.folder / "LINK_FILE_OUT").symlink_to(self.outside / "important.txt")
        (self.folder / "LINK_DIR_IN").symlink_to(self.folder / "meshes", target_is_directory=True)
        self.stamp = _stamp(self.outside)

    def path(self, hostile: tuple[bool, list[str]]) -> str:
        absolute, parts = hostile
        rel = "/".join(parts)
        return f"{self.outside}/{rel}" if absolute else rel

    def untouched(self) -> None:
        assert _stamp(self.outside) == self.stamp, "a file outside the scene folder was touched"


def _clean_error(exc: BaseException) -> None:
    event(f"clean error: {type(exc).__name__}")
    assert isinstance(exc, CLEAN), f"{type(exc).__name__}: {exc}"
    assert str(exc) and "\n" not in str(exc).strip(), repr(str(exc))


def _inside(folder: Path, path: str | Path) -> bool:
    return Path(os.path.realpath(path)).is_relative_to(os.path.realpath(folder))


@SETTINGS
@given(hostile=HOSTILE_PATHS)
def test_a_hostile_manifest_entry_never_touches_a_file_outside(halls, tmp_path, hostile):
    built, rebuilt = halls
    box = Sandbox(tmp_path / "box", built)
    entry = box.path(hostile)
    manifest = box.folder / MANIFEST_NAME
    doc = json.loads(manifest.read_text())
    doc["files"][entry] = hashlib.sha256(SENTINEL).hexdigest()  # "unchanged since the build wrote it": deletable
    manifest.write_text(json.dumps(doc))
    (box.folder / "spec.toml").write_text(SPEC.format(mesh='"parts/rack.stl"', name="shelf"))  # deletes the stale mesh
    try:
        build_scene(box.folder / "spec.toml", box.folder)
    except Exception as exc:  # noqa: BLE001 - the oracle
        _clean_error(exc)
    else:  # a correct build: spec B's files, nothing stale
        event("built")
        new = json.loads(manifest.read_text())
        assert set(new["files"]) == set(json.loads((rebuilt / MANIFEST_NAME).read_text())["files"])
        for rel in new["files"]:
            assert (box.folder / rel).read_bytes() == (rebuilt / rel).read_bytes(), rel
        assert stale_files(box.folder) == []
    box.untouched()


@SETTINGS
@given(hostile=HOSTILE_PATHS)
def test_a_hostile_scene_xml_filename_is_refused_or_stays_inside(halls, tmp_path, hostile):
    built, _ = halls
    box = Sandbox(tmp_path / "box", built)
    value = box.path(hostile)
    xml = box.folder / "scene.xml"
    text = xml.read_text()
    assert 'value="meshes/rack.ply"' in text
    from xml.sax.saxutils import quoteattr

    xml.write_text(text.replace('value="meshes/rack.ply"', f"value={quoteattr(value)}"))
    for call in (scene_references, scene_content_hash):
        try:
            got = call(xml)
        except Exception as exc:  # noqa: BLE001 - the oracle
            _clean_error(exc)
        else:
            event(f"{call.__name__}: read")
            if call is scene_references:
                assert all(_inside(box.folder, p) and Path(p).is_file() for _, p in got), got
            else:
                assert len(got) == 64
    box.untouched()


@SETTINGS
@given(hostile=HOSTILE_PATHS)
def test_a_hostile_spec_mesh_file_is_refused_or_stays_inside(halls, tmp_path, hostile):
    built, _ = halls
    box = Sandbox(tmp_path / "box", built)
    value = box.path(hostile)
    spec = box.folder / "spec.toml"
    spec.write_text(SPEC.format(mesh=json.dumps(value, ensure_ascii=False), name="rack"))
    before = _tree(box.folder)
    try:
        loaded = load_spec(spec)
        assert all(_inside(box.folder, m.file) for m in loaded.meshes), [m.file for m in loaded.meshes]
        build_scene(spec, box.folder)
    except AssertionError:
        raise
    except Exception as exc:  # noqa: BLE001 - the oracle
        _clean_error(exc)
        assert _tree(box.folder) == before  # a refused or failed build leaves the folder as it was
    else:
        event("built")
        assert stale_files(box.folder) == []
    box.untouched()


@pytest.mark.parametrize("value", ["../outside/x.ply", "ABS", "LINK_FILE_OUT", "LINK_DIR_OUT/important.txt"])
def test_load_scene_refuses_hostile_filenames_and_touches_nothing(halls, tmp_path, value):
    """The ray tracer's loader (sionna) on a few hostile names: too slow for every generated one."""
    pytest.importorskip("sionna.rt")
    from risloc_rt.hall.raytrace import load_scene

    box = Sandbox(tmp_path / "box", halls[0])
    value = f"{box.outside}/important.txt" if value == "ABS" else value
    xml = box.folder / "scene.xml"
    xml.write_text(xml.read_text().replace('value="meshes/rack.ply"', f'value="{value}"'))
    with pytest.raises(SceneError, match="outside the scene folder"):
        load_scene(xml, frequency=60e9)
    box.untouched()


# --- (b) corrupted run logs ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def log_bytes(tmp_path_factory):
    """``runs.jsonl`` of a tiny study (2 points x 3 runs), made once."""
    from risloc_rt.cli import main

    out = tmp_path_factory.mktemp("study") / "s"
    small = {"num_chirps": 32, "num_samples": 64, "n_dft": 128, "k_dft": 128, "sweep_span_deg": 15.0, "aod_deg": 10.3}
    args = ["study", "sweep", "--out", str(out), "--runs", "3", "--workers", "1", "--quiet",
            "--vary", "tx_power_dbm=25,35"] + [a for k, v in small.items() for a in ("--set", f"{k}={v}")]
    assert main(args) == 0
    data = (out / LOG).read_bytes()
    assert data.endswith(b"\n") and data.count(b"\n") == 6
    return data


def _keys(lines: list[bytes]) -> set[tuple[int, int]]:
    return {(json.loads(line)["point"], json.loads(line)["run"]) for line in lines}


def _open(path: Path) -> RunLog:
    log = RunLog(path).open()
    log.close()
    return log


@LOG_SETTINGS
@given(data=st.data())
def test_a_torn_tail_is_cut_and_every_whole_row_kept(log_bytes, tmp_path, data):
    cut = data.draw(st.integers(0, len(log_bytes) - 1), label="cut")
    path = tmp_path / LOG
    path.write_bytes(log_bytes[:cut])
    log = _open(path)
    whole = log_bytes[: log_bytes.rfind(b"\n", 0, cut) + 1]  # every row whose newline survived
    assert path.read_bytes() == whole
    assert log.done() == _keys(whole.splitlines())


def _is_run_row(line: bytes) -> bool:
    """What docs/robustness.md calls a run row: a JSON object with whole numbers >= 0 as point and run."""
    try:
        row = json.loads(line)
    except ValueError:
        return False
    return isinstance(row, dict) and all(type(row.get(k)) is int and row[k] >= 0 for k in ("point", "run"))


_BYTE = st.integers(0, 255).filter(lambda b: b != 0x0A)
_ODD_VALUES = ["Infinity", "-Infinity", "NaN", "1e999", "-1", "1.5", "true", "null", '"1"', "[0]", "{}", "2e0",
               "99999999999999999999999"]


@st.composite
def _damage(draw, lines: list[bytes]) -> tuple[int, list[bytes]]:
    """(index of the damaged line, the new lines); every line keeps its newline."""
    i = draw(st.integers(0, len(lines) - 1), label="line")
    line = bytearray(lines[i])
    kind = draw(st.sampled_from(["blank", "garbage", "flip", "insert", "delete", "join", "value"]), label="kind")
    out = list(lines)
    if kind == "blank":
        out.insert(i, draw(st.sampled_from([b"", b" ", b"\r", b"\t "])))
    elif kind == "garbage":
        out.insert(i, bytes(draw(st.lists(_BYTE, min_size=1, max_size=40))))
    elif kind == "flip":
        pos = draw(st.integers(0, len(line) - 1))
        line[pos] = draw(_BYTE.filter(lambda b: b != line[pos]))
        out[i] = bytes(line)
    elif kind == "insert":
        pos = draw(st.integers(0, len(line)))
        line[pos:pos] = bytes(draw(st.lists(_BYTE, min_size=1, max_size=8)))
        out[i] = bytes(line)
    elif kind == "delete":
        pos = draw(st.integers(0, len(line) - 1))
        del line[pos: pos + draw(st.integers(1, 8))]
        out[i] = bytes(line)
    elif kind == "join":  # a newline lost in the middle: two rows on one line
        if i == len(lines) - 1:
            i -= 1
        out[i: i + 2] = [lines[i] + lines[i + 1]]
    else:  # an odd value of point or run
        key = draw(st.sampled_from([b'"point": ', b'"run": ']))
        start = line.index(key) + len(key)
        end = start
        while chr(line[end]).isdigit():
            end += 1
        line[start:end] = draw(st.sampled_from(_ODD_VALUES)).encode()
        out[i] = bytes(line)
    return i, out


@LOG_SETTINGS
@given(data=st.data())
def test_damage_to_a_whole_line_is_an_error_naming_it_and_the_log_stays_as_it_was(log_bytes, tmp_path, data):
    lines = log_bytes.splitlines()
    i, damaged = data.draw(_damage(lines), label="damage")
    blob = b"".join(line + b"\n" for line in damaged)
    path = tmp_path / LOG
    path.write_bytes(blob)
    bad = [n for n, line in enumerate(damaged, 1) if not _is_run_row(line)]
    event("a bad line" if bad else "still a run row")
    if bad:
        with pytest.raises(RunLogError) as err:
            RunLog(path).open()
        message = str(err.value)
        assert "\n" not in message and f"{str(path)!r} line {bad[0]} " in message, message
        assert bad[0] == i + 1  # the damaged line, or the line inserted before it
    else:  # the damage left a valid row (a changed digit): read as it is, nothing cut
        log = _open(path)
        assert log.done() == {(json.loads(line)["point"], json.loads(line)["run"]) for line in damaged}
    assert path.read_bytes() == blob


@pytest.mark.parametrize("value", ["Infinity", "1e999", "-Infinity", "1.7", '"1"', "true", "-1"])
def test_regression_odd_point_values_are_a_bad_line_not_a_traceback_or_another_run(tmp_path, value):
    """Issue 19 fuzzing: 'point': Infinity (or 1e999) raised OverflowError out of RunLog.open (the CLI
    said 'internal error', exit 1, without the line), and 1.7, "1" or true were read as run 1."""
    path = tmp_path / LOG
    blob = (b'{"point": 0, "run": 0}\n{"point": ' + value.encode() + b', "run": 1}\n{"point": 0, "run": 2}\n')
    path.write_bytes(blob)
    with pytest.raises(RunLogError, match=r"line 2 .*whole numbers"):
        RunLog(path).open()
    assert path.read_bytes() == blob
