"""The output policy (``risloc_rt._outputs``, issue 19 item 2), as a library: the ledger, refusals,
``force``, all-or-nothing staging and names taken from inputs."""

from __future__ import annotations

import hashlib
import json
import os
import signal

import pytest

from risloc_rt._outputs import (LEDGER, OutputError, check_output_file, output_file, output_folder, record_outputs,
                                safe_name, written_by_risloc)


def _tree(root):
    """Every path under ``root`` with its bytes (folders as None): a folder's whole state."""
    found = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            found[os.path.relpath(os.path.join(dirpath, d), root)] = None
        for f in filenames:
            with open(os.path.join(dirpath, f), "rb") as fh:
                found[os.path.relpath(os.path.join(dirpath, f), root)] = fh.read()
    return found


def test_ledger_names_what_risloc_wrote_with_its_sha256(tmp_path):
    out = tmp_path / "a.bin"
    with output_file(out, force=False, flag="-o") as target:
        target.write_bytes(b"risloc bytes")
    doc = json.loads((tmp_path / LEDGER).read_text())
    assert doc["files"] == {"a.bin": hashlib.sha256(b"risloc bytes").hexdigest()}
    assert written_by_risloc(out)
    with output_file(out, force=False, flag="-o") as target:       # its own, unchanged: replaced
        target.write_bytes(b"new bytes")
    assert written_by_risloc(out) and out.read_bytes() == b"new bytes"


def test_foreign_or_edited_file_is_refused_unless_force(tmp_path):
    mine = tmp_path / "mine.npz"
    mine.write_bytes(b"the user's")
    with pytest.raises(OutputError, match=r"^-o .*mine.npz exists and risloc-rt did not write it .*--force"):
        check_output_file(mine, force=False, flag="-o")
    assert mine.read_bytes() == b"the user's"
    theirs = tmp_path / "theirs.npz"
    with output_file(theirs, force=False, flag="-o") as target:
        target.write_bytes(b"risloc")
    theirs.write_bytes(b"risloc, edited")                          # a risloc file edited by hand is the user's
    with pytest.raises(OutputError, match="did not write it"):
        check_output_file(theirs, force=False, flag="-o")
    with output_file(theirs, force=True, flag="-o") as target:
        target.write_bytes(b"forced")
    assert written_by_risloc(theirs)


def test_a_folder_is_never_replaced_and_a_link_is_foreign(tmp_path):
    (tmp_path / "dir").mkdir()
    with pytest.raises(OutputError, match="is a folder"):
        check_output_file(tmp_path / "dir", force=True, flag="-o")
    target = tmp_path / "elsewhere.txt"
    target.write_text("keep")
    (tmp_path / "link.npz").symlink_to(target)
    with pytest.raises(OutputError, match="did not write"):
        check_output_file(tmp_path / "link.npz", force=False, flag="-o")
    assert not written_by_risloc(tmp_path / "link.npz")


def test_unreadable_ledger_makes_every_file_foreign(tmp_path):
    f = tmp_path / "x.json"
    with output_file(f, force=False, flag="-o") as target:
        target.write_text("{}")
    (tmp_path / LEDGER).write_text("not json")
    assert not written_by_risloc(f)
    record_outputs(tmp_path, ["x.json"])                              # rewritten whole
    assert written_by_risloc(f)


def test_staged_folder_moves_in_whole_and_records_every_subfolder(tmp_path):
    out = tmp_path / "res"
    with output_folder(out, force=False, flag="--out", expect=("result.json",)) as stage:
        assert stage.parent == out and stage.name.startswith(".")
        (stage / "result.json").write_text("{}")
        (stage / "case").mkdir()
        (stage / "case" / "plot.png").write_bytes(b"png")
    assert sorted(_tree(out)) == sorted([LEDGER, "result.json", "case", os.path.join("case", LEDGER),
                                         os.path.join("case", "plot.png")])
    assert written_by_risloc(out / "result.json") and written_by_risloc(out / "case" / "plot.png")


@pytest.mark.parametrize("failure", [RuntimeError("a failed run"), KeyboardInterrupt()])
def test_a_failed_or_interrupted_folder_output_leaves_the_previous_state(tmp_path, failure):
    out = tmp_path / "res"
    with output_folder(out, force=False, flag="--out") as stage:
        (stage / "result.json").write_text("old")
        (stage / "case").mkdir()
        (stage / "case" / "plot.png").write_bytes(b"old png")
    before = _tree(out)
    with pytest.raises(type(failure)):
        with output_folder(out, force=False, flag="--out") as stage:
            (stage / "result.json").write_text("new")   # the first file is written, then the run fails
            raise failure
    assert _tree(out) == before
    fresh = tmp_path / "fresh"
    with pytest.raises(type(failure)):
        with output_folder(fresh, force=False, flag="--out") as stage:
            (stage / "result.json").write_text("new")
            raise failure
    assert not fresh.exists()                           # a folder it created is removed again


def test_a_conflict_found_after_the_run_writes_nothing(tmp_path):
    out = tmp_path / "res"
    (out / "case").mkdir(parents=True)
    (out / "case" / "plot.png").write_bytes(b"the user's figure")
    before = _tree(out)
    with pytest.raises(OutputError, match=r"plot.png exists and risloc-rt did not write it; nothing was written"):
        with output_folder(out, force=False, flag="--out", expect=("result.json",)) as stage:
            (stage / "result.json").write_text("{}")
            (stage / "case").mkdir()
            (stage / "case" / "plot.png").write_bytes(b"new")
    assert _tree(out) == before
    (out / "result.json").write_text("the user's result")
    with pytest.raises(OutputError, match="result.json exists"):       # refused before the run
        with output_folder(out, force=False, flag="--out", expect=("result.json",)):
            pytest.fail("the block must not run")


def test_a_linked_subfolder_is_not_written_through(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    out = tmp_path / "res"
    out.mkdir()
    (out / "case").symlink_to(outside, target_is_directory=True)
    for force in (False, True):
        with pytest.raises(OutputError, match="symbolic link"):
            with output_folder(out, force=force, flag="--out") as stage:
                (stage / "case").mkdir()
                (stage / "case" / "plot.png").write_bytes(b"png")
    assert list(outside.iterdir()) == []


def test_signals_are_held_during_the_swap_and_delivered_after(tmp_path, monkeypatch):
    import risloc_rt._outputs as outputs

    seen = []
    real_replace = os.replace

    def replace_and_interrupt(src, dst):
        if not seen:
            os.kill(os.getpid(), signal.SIGINT)     # Ctrl-C between the first and the second rename
        seen.append(dst)
        real_replace(src, dst)

    monkeypatch.setattr(outputs.os, "replace", replace_and_interrupt)
    out = tmp_path / "res"
    with pytest.raises(KeyboardInterrupt):
        with output_folder(out, force=False, flag="--out") as stage:
            for name in ("a.txt", "b.txt", "c.txt"):
                (stage / name).write_text(name)
    assert len(seen) >= 3                                       # every rename ran before the interrupt
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["a.txt", "b.txt", "c.txt"]


@pytest.mark.parametrize(("text", "expected"), [("capture", "capture"), ("paper_hall-0", "paper_hall-0"),
                                                  ("..", "_.."), (".", "_."), ("", "case"), ("a/../b", "a_.._b"),
                                                  ("x\\y", "x_y"), ("tab\there", "tab_here"), (".hidden", "_.hidden")])
def test_safe_name_keeps_a_name_inside_its_folder(text, expected):
    assert safe_name(text) == expected
    assert len(safe_name("n" * 500)) == 120


def test_ctrl_c_as_a_file_is_moved_in_still_records_it(tmp_path, monkeypatch):
    # Regression (issue 19, found by benchmarks/interrupts.py): the file used to be moved in by the
    # writer and hashed into the ledger afterwards; Ctrl-C in between left a complete file the
    # ledger did not name, and the rerun the interrupt message advises was refused.
    import risloc_rt._outputs as outputs

    real_replace = os.replace
    calls = []

    def interrupt_then_replace(src, dst):
        if not calls:
            os.kill(os.getpid(), signal.SIGINT)     # Ctrl-C exactly as the output is moved in
        calls.append(dst)
        real_replace(src, dst)

    monkeypatch.setattr(outputs.os, "replace", interrupt_then_replace)
    out = tmp_path / "x.npz"
    with pytest.raises(KeyboardInterrupt):
        with output_file(out, force=False, flag="-o") as staged:
            assert staged.parent == tmp_path and staged.name.startswith(".x.npz.") and staged.suffix == ".npz"
            staged.write_bytes(b"the capture")
    assert out.read_bytes() == b"the capture" and written_by_risloc(out)    # the rerun may replace it
    assert sorted(p.name for p in tmp_path.iterdir()) == [LEDGER, "x.npz"]   # nothing staged left


def test_a_failed_single_file_output_leaves_the_previous_file(tmp_path):
    out = tmp_path / "sub" / "plot.png"
    with pytest.raises(RuntimeError):
        with output_file(out, force=False, flag="-o") as staged:
            staged.write_bytes(b"half")
            raise RuntimeError("the writer failed")
    assert not (tmp_path / "sub").exists()             # the folder made for it is gone again
    with output_file(out, force=False, flag="-o") as staged:
        staged.write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt):
        with output_file(out, force=False, flag="-o") as staged:
            staged.write_bytes(b"new")
            raise KeyboardInterrupt
    assert out.read_bytes() == b"old" and sorted(p.name for p in out.parent.iterdir()) == [LEDGER, "plot.png"]


@pytest.mark.parametrize(("name", "suffix"), [("plot.png", ".png"), ("cap.npz", ".npz"), ("plot", ""),
                                              (".hidden", ""), ("a.b.toml", ".toml")])
def test_the_staged_file_keeps_the_suffix_a_writer_reads(tmp_path, name, suffix):
    with output_file(tmp_path / name, force=False, flag="-o") as staged:
        assert staged.suffix == suffix and staged.name.startswith(".") and staged.parent == tmp_path
        staged.write_bytes(b"x")
    assert (tmp_path / name).read_bytes() == b"x"


def test_a_file_written_in_place_gets_an_ordinary_files_mode(tmp_path):
    out = tmp_path / "x.json"
    with output_file(out, force=False, flag="-o") as staged:
        with open(staged, "w") as fh:             # a writer that writes the given path itself
            fh.write("{}")
    mask = os.umask(0)
    os.umask(mask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~mask
