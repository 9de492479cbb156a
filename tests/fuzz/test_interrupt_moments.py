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
