"""Ctrl-C at random moments of the long commands (issue 19): exit 130, one line, outputs intact,
and a rerun equal to an uninterrupted run.

The commands, the checks and the moments are those of ``benchmarks/interrupts.py`` (50 moments per
command, five commands); here three moments (seed fixed) of the three commands that take seconds:
``simulate``, ``scene build`` (a folder with a previous build: it must stay that build or become
the new one, byte for byte) and ``study sweep`` (every other moment starts from a stopped study:
its log keeps its rows and gains only whole reference rows). ``demo --analytic`` and ``study map``
take 15-25 s a run and are left to the benchmark.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("risloc_interrupts",
                                               Path(__file__).parents[2] / "benchmarks" / "interrupts.py")
interrupts = importlib.util.module_from_spec(_spec)
sys.modules["risloc_interrupts"] = interrupts  # dataclasses look their module up by name
_spec.loader.exec_module(interrupts)

MOMENTS = 3
SEED = 19


@pytest.mark.slow
@pytest.mark.parametrize("name", ["simulate", "scene build", "study sweep"])
def test_ctrl_c_at_random_moments(tmp_path, name):
    cmd = interrupts.commands()[name]
    env = interrupts.environment(None, tmp_path / "cache")
    row = interrupts.run_command(cmd, MOMENTS, SEED, tmp_path, env, twice=False)
    failures = interrupts.failure_lines(row, SEED)
    assert not failures, "\n".join(failures)
    assert row["moments"] == MOMENTS and row["intact"] == MOMENTS and row["resume_equal"] == MOMENTS
    assert row["exit_130"] == row["one_line"] == row["signalled"]
    assert row["signalled"] + row["startup"] + row["finished"] == MOMENTS


def test_the_checks_catch_a_broken_output():
    """The oracles of the benchmark reject what they must (a check that never fails checks nothing)."""
    row = b'{"point": 0, "run": %d, "seconds": %d}\n'
    ref = {"runs.jsonl": row % (0, 1) + row % (1, 1) + row % (2, 1), "summary.json": b'{"a": 1, "wall_seconds": 3}',
           "study.json": b"{}"}
    before = {"study.json": b"{}", "runs.jsonl": row % (0, 9)}
    ok = {"study.json": b"{}", "runs.jsonl": row % (0, 9) + row % (1, 5), "summary.json": b'{"a": 1, "wall_seconds": 7}'}
    assert interrupts.check_files(before, ok, ref) == ""  # time fields differ only
    assert "torn" in interrupts.check_files(before, {**ok, "runs.jsonl": ok["runs.jsonl"] + b'{"poi'}, ref)
    assert "previous bytes" in interrupts.check_files(before, {**ok, "runs.jsonl": row % (1, 5)}, ref)
    assert "not the reference" in interrupts.check_files(before, {**ok, "runs.jsonl": row % (0, 9) + row % (7, 1)}, ref)
    assert "twice" in interrupts.check_files(before, {**ok, "runs.jsonl": row % (0, 9) + row % (0, 1)}, ref)
    assert "left behind" in interrupts.check_files(before, {**ok, ".summary.json.tmp": b"{"}, ref)
    assert "deleted" in interrupts.check_files(before, {"runs.jsonl": before["runs.jsonl"]}, ref)
    assert "neither" in interrupts.check_files(before, {**ok, "summary.json": b'{"a": 2}'}, ref)
    assert interrupts.check_resume({**ref, "summary.json": b'{"a": 1, "wall_seconds": 9}'}, ref) == ""
    assert interrupts.check_resume({**ref, "runs.jsonl": row % (0, 1) + row % (1, 1)}, ref)
    old, new = {"a": b"1", "m.ply": b"x"}, {"a": b"2", "n.ply": b"y"}
    assert interrupts.check_scene(old, dict(old), new) == "" and interrupts.check_scene(old, dict(new), new) == ""
    assert interrupts.check_scene(old, {"a": b"2", "m.ply": b"x"}, new)
    assert interrupts.check_scene(old, {**old, ".a.x.risloc-build.tmp": b"2"}, new)
