"""``risloc track``: every bad input is one line on stderr, exit status 2, before anything is traced or written."""

from __future__ import annotations

import pytest

from risloc_rt.cli import main

GOOD = "t,x,y,z\n0,14,6,1.2\n9,5,6,1.2\n"

#: (what, CSV text, schedule TOML or None, extra flags, words the one line must hold)
CASES = [
    ("outside the hall", "t,x,y,z\n0,14,6,1.2\n5,30,6,1.2\n", None, [], ["line 3", "outside the hall"]),
    ("in the corner's wall slab", "t,x,y,z\n0,14,6,1.2\n5,14.05,13,1.2\n", None, [], ["line 3"]),
    ("through a wall", "t,x,y,z\n0,20,6,1.2\n10,10,20,1.2\n", None, [],
     ["line 2", "line 3", "passes through 'wall_", "add a waypoint"]),
    ("time goes back", "t,x,y,z\n0,14,6,1.2\n5,10,6,1.2\n3,8,6,1.2\n", None, [], ["line 4", "goes back", "increase"]),
    ("time repeats", "t,x,y,z\n0,14,6,1.2\n5,10,6,1.2\n5,8,6,1.2\n", None, [], ["line 4", "repeats"]),
    ("malformed line", "t,x,y,z\n0,14,6,1.2\n# a comment\n5,ten,6,1.2\n", None, [], ["line 4", "not four numbers"]),
    ("three values", "t,x,y,z\n0,14,6,1.2\n5,10,6\n", None, [], ["line 3", "3 value(s)"]),
    ("no header", "0,14,6,1.2\n5,10,6,1.2\n", None, [], ["line 1", "header", "t,x,y,z"]),
    ("one waypoint", "t,x,y,z\n0,14,6,1.2\n", None, [], ["1 waypoint", "at least two"]),
    ("shorter than a sweep", "t,x,y,z\n0,14,6,1.2\n0.1,13.9,6,1.2\n", None, [], ["less than one sweep"]),
    ("overlapping slots", GOOD, '[schedule]\norder = ["ris0", "ris1"]\nstart_ms = [0.0, 100.0]\n', [],
     ["[schedule]", "overlap", "ris0", "ris1"]),
    ("unknown RIS", GOOD, '[schedule]\norder = ["ris0", "ris7"]\n', [], ["ris7", "does not have", "ris0, ris1"]),
    ("unknown key", GOOD, '[schedule]\norder = ["ris0"]\ngap = 1\n', [], ["unknown key 'gap'", "gap_ms"]),
    ("no schedule table", GOOD, 'order = ["ris0"]\n', [], ["no [schedule] table"]),
    ("not TOML", GOOD, "[schedule\n", [], ["not a TOML file"]),
    ("bad height", GOOD, None, ["--ue-height", "high"], ["--ue-height", "'path'"]),
    ("bad q", GOOD, None, ["--accel-density", "0"], ["--accel-density", "> 0"]),
    ("bad max sweeps", GOOD, None, ["--max-sweeps", "0"], ["--max-sweeps", ">= 1"]),
    # 1e9 s at 1 m/s back and forth is 2.56e9 sweeps: refused by the memory limit before a slot is planned (it
    # built a list of every slot before, for minutes, into an out-of-memory kill)
    ("a walk too long for memory", "t,x,y,z\n0,14,6,1.2\n1e9,13,6,1.2\n", None, [],
     ["1e+09 s", "2561475409 sweeps", "memory", "--max-sweeps"]),
]


@pytest.mark.parametrize("what, csv_text, schedule, extra, words", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_written(tmp_path, capsys, what, csv_text, schedule, extra, words):
    path = tmp_path / "walk.csv"
    path.write_text(csv_text)
    args = ["track", "l_hall_2ris", "--trajectory", str(path), "--out", str(tmp_path / "out"), "--no-cache"]
    if schedule is not None:
        (tmp_path / "schedule.toml").write_text(schedule)
        args += ["--schedule", str(tmp_path / "schedule.toml")]
    assert main(args + extra) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("risloc track: error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_missing_trajectory_file_is_one_line(tmp_path, capsys):
    assert main(["track", "l_hall_2ris", "--trajectory", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.csv" in err[0]


def test_a_scene_without_the_schedules_ris(tmp_path, capsys):
    """A schedule naming ris1 on a one-RIS scene (l_hall has only ris0)."""
    (tmp_path / "walk.csv").write_text(GOOD)
    (tmp_path / "s.toml").write_text('[schedule]\norder = ["ris0", "ris1"]\n')
    assert main(["track", "l_hall", "--trajectory", str(tmp_path / "walk.csv"), "--out", str(tmp_path / "o"),
                 "--schedule", str(tmp_path / "s.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'ris1'" in err[0] and "it has ris0" in err[0], err


@pytest.mark.slow
def test_a_short_walk_writes_every_output_and_reports_progress(tmp_path, capsys):
    """Two sweeps (ris0 then ris1) of 0.39 s along the long arm, cheap trace: exit 0, the five files
    in --out (and the ledger), one progress line per sweep on stderr, the summary line on stdout."""
    import json

    import pyarrow.parquet as pq

    (tmp_path / "walk.csv").write_text("t,x,y,z\n0,14,6,1.2\n0.8,13.2,6,1.2\n")
    out = tmp_path / "out"
    assert main(["track", "l_hall_2ris", "--trajectory", str(tmp_path / "walk.csv"), "--out", str(out),
                 "--depth", "1", "--samples", "10000", "--no-cache", "--progress-every", "1", "--seed", "5"]) == 0
    captured = capsys.readouterr()
    assert "2 sweeps: fixes on 2/2 in view (100.0 %)" in captured.out and f"wrote {out}" in captured.out
    assert [line.split(" (")[0] for line in captured.err.splitlines() if line.startswith("sweep ")] == \
        ["sweep 1/2", "sweep 2/2"]
    for name in ("walk.parquet", "summary.json", "plan.png", "error.png", "consistency.png"):
        assert (out / name).stat().st_size > 200, name
    table = pq.read_table(out / "walk.parquet")
    assert table.column("ris").to_pylist() == ["ris0", "ris1"]
    assert table.column("update").to_pylist() == ["start", "used"]
    doc = json.loads((out / "summary.json").read_text())
    assert doc["seed"] == 5 and doc["sweeps"] == 2 and doc["schedule"]["order"] == ["ris0", "ris1"]
    assert (out / ".risloc-outputs.json").is_file()  # the ledger: a rerun may replace them, a user's file not


def test_ctrl_c_during_the_walk_is_exit_130_and_leaves_no_output(tmp_path, capsys, monkeypatch):
    """Ctrl-C while sweeps are being simulated (here: at the walk's start): one line, exit 130, and --out
    is not created (the outputs are staged and moved in whole, risloc_rt._outputs)."""
    import risloc_rt.studies.walk as walk

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(walk, "run_walk", interrupted)
    (tmp_path / "walk.csv").write_text(GOOD)
    out = tmp_path / "out"
    assert main(["track", "l_hall_2ris", "--trajectory", str(tmp_path / "walk.csv"), "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("risloc track: interrupted") and "Traceback" not in "\n".join(err)
    assert not out.exists()
