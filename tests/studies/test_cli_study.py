"""``risloc study sweep``: one-line errors (exit 2), foreign folders, a full disk."""

from __future__ import annotations

import errno
import json

import pytest

from risloc_rt.cli import main

from .conftest import small_cli_args


def _run(capsys, *args):
    status = main(["study", "sweep", *args])
    err = capsys.readouterr().err
    return status, err


@pytest.mark.parametrize("args, match", [
    (["--vary", "foo=1,2", "--runs", "2"], "unknown parameter 'foo'"),
    (["--vary", "tx_power_dbm=", "--runs", "2"], "has no values"),
    (["--runs", "2"], "nothing to vary"),
    (["--vary", "tx_power_dbm=1", "--runs", "0"], "must be >= 1"),
    (["--vary", "tx_power_dbm=1", "--workers", "0"], "must be >= 1"),
    (["--vary", "tx_power_dbm=1", "--dask", "tcp://127.0.0.1:9", "--dask-timeout", "0.5"],
     "cannot reach the Dask scheduler"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, args, match):
    status, err = _run(capsys, *args, "--out", str(tmp_path / "o"), "--quiet")
    assert status == 2
    assert match in err and err.count("\n") == 1 and err.startswith("risloc study sweep: error:")


def test_a_folder_of_another_study_is_refused_unless_forced(capsys, tmp_path):
    out = tmp_path / "o"
    base = [*small_cli_args(), "--runs", "1", "--out", str(out), "--quiet", "--workers", "1"]
    assert _run(capsys, "--vary", "tx_power_dbm=30", *base)[0] == 0
    status, err = _run(capsys, "--vary", "tx_power_dbm=31", *base)
    assert status == 2 and "holds another study" in err
    old_key = json.loads((out / "study.json").read_text())["key"]
    assert _run(capsys, "--vary", "tx_power_dbm=31", *base, "--force")[0] == 0
    assert (out / f"runs-{old_key}.jsonl").exists()  # the old log is kept, not deleted
    other = tmp_path / "user"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    status, err = _run(capsys, "--vary", "tx_power_dbm=30", *small_cli_args(), "--runs", "1", "--out", str(other))
    assert status == 2 and "holds no study" in err and (other / "notes.txt").read_text() == "mine"


def test_a_full_disk_is_one_line_exit_2(capsys, tmp_path, monkeypatch):
    from risloc_rt.studies.store import RunLog

    def full(self, rows):
        raise OSError(errno.ENOSPC, "No space left on device", str(self.path))

    monkeypatch.setattr(RunLog, "append", full)
    status, err = _run(capsys, "--vary", "tx_power_dbm=30", *small_cli_args(), "--runs", "1", "--workers", "1",
                       "--out", str(tmp_path / "o"), "--quiet")
    assert status == 2 and "disk is full" in err and "rerun the same command" in err and err.count("\n") == 1


def test_a_study_file_runs_and_prints_its_table(capsys, tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "t"\nruns = 2\nseed = 1\n[fixed]\n' +
                 "".join(f"{a.split('=')[0]} = {a.split('=')[1]}\n" for a in small_cli_args()[1::2]) +
                 "[vary]\nestimator = [\"paper\", \"refined\"]\n")
    status = main(["study", "sweep", "--study", str(f), "--out", str(tmp_path / "o"), "--workers", "1"])
    out = capsys.readouterr().out
    assert status == 0 and "refined" in out and "MAE pos" in out
    assert (tmp_path / "o" / "study.png").exists()


@pytest.mark.parametrize("args, match", [
    (["no_such_hall"], "no_such_hall"),
    (["--spacing", "0"], "--spacing=0.0 must be a finite number > 0 [m]"),
    (["--margin", "-1"], "--margin=-1.0 must be a finite number >= 0 [m]"),
    (["--runs", "0"], "must be >= 1"),
])
def test_map_bad_input_is_one_line_exit_2(capsys, tmp_path, args, match):
    status = main(["study", "map", *args, "--out", str(tmp_path / "m"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and match in err and err.count("\n") == 1, err


def test_map_with_an_unreachable_scheduler_is_one_line_exit_2(capsys, tmp_path):
    status = main(["study", "map", "paper_hall", "--runs", "1", "--out", str(tmp_path / "m"), "--quiet",
                   "--dask", "tcp://127.0.0.1:9", "--dask-timeout", "0.5"])
    err = capsys.readouterr().err
    assert status == 2
    assert "cannot reach the Dask scheduler" in err and err.count("\n") == 1 and err.startswith("risloc study map: error:")
    assert not (tmp_path / "m").exists()  # nothing written before the cluster answered
