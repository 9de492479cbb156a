"""Issue 19 item 3, studies: run plans are lazy, a study checks its memory and time before it starts,
workers are capped by the cores and the memory limit, a floor map's grid is counted before it is made."""

from __future__ import annotations

import itertools
import json
import time
import tracemalloc

import pytest

from dsp.budget import BudgetError
from risloc_rt.cli import main
from risloc_rt.studies import StudyError, engine
from risloc_rt.studies.floor_map import MapSettings, grid_budget, grid_cells
from risloc_rt.studies.kernel import prepare_point
from risloc_rt.studies.store import open_study_folder

from .conftest import small_cli_args


def _reference_batches(runs, n_points, done, size):
    """The batches as the eager planner made them: every missing run listed, cut at gaps and at ``size``."""
    out = []
    for p in range(n_points):
        missing = [r for r in range(runs) if (p, r) not in done]
        i = 0
        while i < len(missing):
            j = i
            while j + 1 < len(missing) and j + 1 - i < size and missing[j + 1] == missing[j] + 1:
                j += 1
            out.append((p, missing[i], missing[j] + 1))
            i = j + 1
    return out


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_the_lazy_plan_cuts_the_same_batches_as_listing_every_run(small_spec, workers):
    spec = small_spec(runs=60)
    done = {(0, 0), (0, 3), (0, 4), (0, 30), (0, 59), (1, 10), (1, 11), (1, 12), (7, 2), (0, 75)}
    size = max(1, min(25, -(-60 // (2 * workers))))
    got = [(b.point, b.start, b.stop) for b in engine.plan_batches(spec, done, workers=workers)]
    assert got == _reference_batches(60, 2, done, size)
    assert engine.count_missing(spec, done) == (120 - 8, 2)


def test_a_billion_runs_per_point_plans_its_first_batches_in_bounded_memory_and_time(small_spec):
    """The eager planner listed every missing run first (8 GB in 34 s for --runs 1e9)."""
    spec = small_spec(runs=10**9)
    done = {(0, r) for r in range(100)}
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        first = list(itertools.islice(engine.plan_batches(spec, done, workers=2), 5))
        missing = engine.count_missing(spec, done)
        seconds = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert [(b.point, b.start, b.stop) for b in first] == [(0, 100 + 25 * i, 125 + 25 * i) for i in range(5)]
    assert missing == (2 * 10**9 - 100, 2)
    assert peak < 2 << 20 and seconds < 1.0


def test_a_study_whose_rows_exceed_the_memory_limit_is_refused_before_any_run(small_spec, tmp_path, monkeypatch):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    spec = small_spec(runs=10**9)
    log = open_study_folder(tmp_path / "s", spec)
    t0 = time.perf_counter()
    try:
        with pytest.raises(BudgetError, match=r"2 point\(s\) x --runs 1000000000 = 2,000,000,000 runs.*TiB.*"
                                              r"more than the limit 1 GiB"):
            engine.execute(spec, log, prepare=prepare_point, workers=1, quiet=True)
    finally:
        log.close()
    assert time.perf_counter() - t0 < 5.0
    assert (tmp_path / "s" / "runs.jsonl").read_bytes() == b""


def test_a_long_study_is_refused_with_its_estimate_unless_forced(small_spec, tmp_path, monkeypatch):
    spec = small_spec(runs=60)
    monkeypatch.setattr(engine, "LONG_SECONDS", 1e-3)
    log = open_study_folder(tmp_path / "s", spec)
    try:
        with pytest.raises(StudyError, match=r"120 runs, 120 to do on 1 worker\(s\): expected about .* s .*"
                                             r"calibration: .* s per run.*--force-long"):
            engine.execute(spec, log, prepare=prepare_point, workers=1, quiet=True)
        assert (tmp_path / "s" / "runs.jsonl").read_bytes() == b""
        said = []
        out = engine.check_budget(spec, log.done(), prepare=prepare_point, workers=2, long_ok=True, say=said.append)
    finally:
        log.close()
    assert out["missing"] == 120 and out["points"] == 2 and out["expected_seconds"] > 0
    assert len(said) == 1 and "expected about" in said[0] and "on 2 worker(s)" in said[0]


def test_cli_a_billion_runs_is_one_line_exit_2_and_a_long_study_names_its_expected_time(capsys, tmp_path,
                                                                                        monkeypatch):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    status = main(["study", "sweep", "--vary", "tx_power_dbm=0,20", "--runs", "1000000000", "--out",
                   str(tmp_path / "a"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "2,000,000,000 runs" in err and "needs about" in err
    assert not (tmp_path / "a").exists()  # refused before the study's folder is made (it was left with a log)
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "100G")  # the rows fit; ~20 ms per run x 1e7 runs is days
    status = main(["study", "sweep", *small_cli_args(), "--vary", "tx_power_dbm=30", "--runs", "10000000",
                   "--workers", "1", "--out", str(tmp_path / "b"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert "10,000,000 runs" in err and "expected about" in err and "--force-long" in err
    assert (tmp_path / "b" / "runs.jsonl").read_bytes() == b""


def test_workers_beyond_the_cores_or_the_memory_limit_are_lowered_with_a_note(monkeypatch):
    monkeypatch.setattr(engine, "default_workers", lambda: 2)
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "100G")
    notes = []
    assert engine.choose_workers(1000, notice=notes.append) == 2
    assert len(notes) == 1 and "--workers 1000 lowered to 2: 2 core(s)" in notes[0] and "--force-workers" in notes[0]
    assert engine.choose_workers(2, notice=notes.append) == 2 and len(notes) == 1  # no note when it fits
    assert engine.choose_workers(None) == 2
    assert engine.choose_workers(5, insist=True) == 5  # the user insists: above the cores
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1.3G")  # room for 2 workers of 0.6 GiB
    monkeypatch.setattr(engine, "default_workers", lambda: 16)
    assert engine.choose_workers(8, notice=notes.append) == 2 and "holds 2 workers" in notes[-1]
    assert engine.choose_workers(None) == 2
    with pytest.raises(BudgetError, match=r"--workers 1000 .* needs about 600 GiB.*more than the limit"):
        engine.choose_workers(1000, insist=True)
    with pytest.raises(ValueError, match="must be >= 1"):
        engine.choose_workers(0)


def test_cli_workers_1000_on_a_small_machine_runs_on_the_cores(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(engine, "default_workers", lambda: 1)
    status = main(["study", "sweep", *small_cli_args(), "--vary", "tx_power_dbm=30", "--runs", "2",
                   "--workers", "1000", "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 0 and "note: --workers 1000 lowered to 1: 1 core(s)" in err
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["workers"] == 1


def test_grid_budget_counts_the_grid_grid_cells_makes():
    s = MapSettings(spacing=1.0, margin=0.0)
    points, estimate = grid_budget(s)
    _, _, keep = grid_cells(s)
    assert points == keep.size and estimate > 0


@pytest.mark.parametrize("limit, match", [("1G", "needs about .* more than the limit 1 GiB"),
                                          ("1T", "more than the 100,000 a map may have without --force-long")])
def test_cli_a_4_mm_floor_grid_is_refused_with_its_cell_count_and_memory(capsys, tmp_path, monkeypatch, limit, match):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", limit)
    t0 = time.perf_counter()
    status = main(["study", "map", "paper_hall", "--spacing", "0.004", "--out", str(tmp_path / "m"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert "a floor grid of" in err and "points" in err and "GiB" in err
    import re

    assert re.search(match, err), err
    n = int(re.search(r"grid of ([0-9,]+) points", err).group(1).replace(",", ""))
    assert n > 10**7  # paper_hall's footprint at 4 mm (the issue measured 2.9e7 positions)
    assert time.perf_counter() - t0 < 10.0 and not (tmp_path / "m").exists()


def test_cli_a_map_with_a_billion_runs_is_refused_before_its_folder_is_made(capsys, tmp_path, monkeypatch):
    """The rows' memory is checked before map-study.json and runs.jsonl are written (they were left behind, and
    the folder then held "another floor map" for the next command)."""
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    status = main(["study", "map", "paper_hall", "--spacing", "4", "--runs", "1000000000", "--out", str(tmp_path / "m"),
                   "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert "--runs 1000000000" in err and "needs about" in err and "more than the limit 1 GiB" in err
    assert not (tmp_path / "m").exists()
