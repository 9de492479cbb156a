"""Issue 19 (item 4): the append-only run log never loses rows.

Only a torn tail (the last line without its newline) is cut off; a bad line anywhere else is a
one-line error naming the file and line, and the log stays byte-identical. ``--force`` keeps a
previous study's log under a name that is never overwritten, and says where.
"""

from __future__ import annotations

import json

import pytest

from risloc_rt.cli import main
from risloc_rt.studies.store import LOG, RunLog, RunLogError, keep_log, open_study_folder

from .conftest import small_cli_args


def _row(point: int, run: int) -> bytes:
    return json.dumps({"point": point, "run": run, "detected": True}, sort_keys=True).encode() + b"\n"


def _log(tmp_path, middle: bytes = b"", tail: bytes = b"") -> tuple:
    path = tmp_path / LOG
    blob = _row(0, 0) + _row(0, 1) + middle + _row(1, 0) + _row(1, 1) + tail
    path.write_bytes(blob)
    return path, blob


@pytest.mark.parametrize("bad", [b"{not json\n", b"\n", b'{"point": 0}\n', b"[1, 2]\n", b'{"point": "x", "run": 0}\n'])
def test_a_bad_line_in_the_middle_is_an_error_naming_file_and_line_and_nothing_is_cut(tmp_path, bad):
    path, blob = _log(tmp_path, middle=bad)
    with pytest.raises(RunLogError) as err:
        RunLog(path).open()
    message = str(err.value)
    assert "\n" not in message and f"{str(path)!r} line 3 " in message
    assert path.read_bytes() == blob  # the two valid rows after the bad line are still there


def test_only_a_torn_tail_is_cut_off_and_every_row_before_it_is_kept(tmp_path):
    path, blob = _log(tmp_path, tail=b'{"point": 2, "ru')
    log = RunLog(path).open()
    log.close()
    assert log.done() == {(0, 0), (0, 1), (1, 0), (1, 1)}
    assert path.read_bytes() == blob[: -len(b'{"point": 2, "ru')]


def test_a_complete_row_without_its_newline_is_a_torn_tail_too(tmp_path):
    path, blob = _log(tmp_path, tail=_row(2, 0)[:-1])
    log = RunLog(path).open()
    log.close()
    assert (2, 0) not in log.done() and path.read_bytes().endswith(_row(1, 1))


def test_a_bad_last_line_with_its_newline_is_not_a_torn_tail(tmp_path):
    path, blob = _log(tmp_path, tail=b"garbage\n")
    with pytest.raises(RunLogError, match="line 5 "):
        RunLog(path).open()
    assert path.read_bytes() == blob


def test_the_cli_reports_a_bad_line_as_one_error_line_and_keeps_the_log(tmp_path, capsys):
    out = tmp_path / "s"
    args = ["study", "sweep", "--out", str(out), "--runs", "2", "--workers", "1", "--quiet",
            "--vary", "tx_power_dbm=25,35", *small_cli_args()]
    assert main(args) == 0
    log = out / LOG
    lines = log.read_bytes().splitlines(keepends=True)
    assert len(lines) == 4
    broken = b"".join(lines[:1] + [b"{oops\n"] + lines[1:])
    log.write_bytes(broken)
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("risloc study sweep: error: ") and "line 2 " in err[0], err
    assert log.read_bytes() == broken


def test_force_never_overwrites_a_kept_log(small_spec, tmp_path):
    out = tmp_path / "s"
    first, second = small_spec(seed=1), small_spec(seed=2)
    notes: list[str] = []
    log = open_study_folder(out, first, notice=notes.append)
    log.append([{"point": 0, "run": 0, "who": "first"}])
    log.close()
    first_bytes = (out / LOG).read_bytes()
    log = open_study_folder(out, second, force=True, notice=notes.append)
    log.append([{"point": 0, "run": 0, "who": "second"}])
    log.close()
    second_bytes = (out / LOG).read_bytes()
    log = open_study_folder(out, first, force=True, notice=notes.append)  # back to the first study
    log.close()
    open_study_folder(out, second, force=True, notice=notes.append).close()  # and again: both kept logs survive
    kept_first = out / f"runs-{first.key}.jsonl"
    kept_second = out / f"runs-{second.key}.jsonl"
    assert kept_first.read_bytes() == first_bytes
    assert kept_second.read_bytes() == second_bytes
    # the first study's second (empty) log was kept beside its first, not over it
    assert (out / f"runs-{second.key}-2.jsonl").exists() is False
    assert (out / f"runs-{first.key}-2.jsonl").read_bytes() == b""
    assert len(notes) == 3 and all(str(out) in n and "kept as" in n for n in notes)
    assert str(kept_first) in notes[0] and str(out / f"runs-{first.key}-2.jsonl") in notes[2]


def test_keep_log_takes_the_next_free_name(tmp_path):
    for n in range(3):
        (tmp_path / LOG).write_bytes(b"%d\n" % n)
        kept = keep_log(tmp_path / LOG, "k")
        assert kept.name == ("runs-k.jsonl" if n == 0 else f"runs-k-{n + 1}.jsonl")
    assert [(tmp_path / name).read_bytes() for name in ("runs-k.jsonl", "runs-k-2.jsonl", "runs-k-3.jsonl")] == \
        [b"0\n", b"1\n", b"2\n"]
    assert not (tmp_path / LOG).exists()
