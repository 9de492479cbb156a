"""The study engine knows no particular study: a plan and a module-level point preparer."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from risloc_rt.studies import engine
from risloc_rt.studies.floor_map import prepare_cell
from risloc_rt.studies.kernel import prepare_point, run_once
from risloc_rt.studies.params import complete_point

from .conftest import SMALL

ENGINE = Path(engine.__file__)


def test_the_engine_imports_no_study():
    """Only the per-run kernel and the run log: not the sweep, the floor map or any other study."""
    imported = set()
    for node in ast.walk(ast.parse(ENGINE.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            imported.add(node.module)
    assert imported == {"kernel", "store"}
    assert "map_cell" not in ENGINE.read_text()


def test_module_level_preparers_are_accepted_by_their_qualified_name():
    assert engine.check_preparer(prepare_point) == "risloc_rt.studies.kernel.prepare_point"
    assert engine.check_preparer(prepare_cell) == "risloc_rt.studies.floor_map.prepare_cell"


def _nested():
    def prepare(params):
        return prepare_point(params)

    return prepare


class _Holder:
    def prepare(self, params):
        return prepare_point(params)


@pytest.mark.parametrize("bad", [lambda params: prepare_point(params), _nested(), _Holder().prepare, "prepare_point"],
                         ids=["lambda", "closure", "bound method", "a string"])
def test_a_preparer_workers_cannot_import_is_refused_before_any_run(bad, small_spec, tmp_path):
    from risloc_rt.studies.store import open_study_folder

    spec = small_spec(runs=1)
    log = open_study_folder(tmp_path / "s", spec)
    try:
        with pytest.raises(TypeError, match="must be a module-level function"):
            engine.execute(spec, log, prepare=bad, workers=1, quiet=True)
    finally:
        log.close()
    assert (tmp_path / "s" / "runs.jsonl").read_bytes() == b""  # nothing ran


def test_a_batch_is_the_preparers_point_run_by_run():
    """run_batch(prepare, ...) gives the rows of run_once on prepare(params), bit for bit, and the point's bound."""
    params = complete_point({**SMALL, "tx_power_dbm": 30.0})
    out = engine.run_batch(prepare_point, params, 2, 1, 3, 9)
    prep = prepare_point(params)
    direct = [run_once(prep, study_seed=9, point=2, run=r) for r in (1, 2)]
    strip = lambda row: {k: v for k, v in row.items() if k != "seconds"}  # noqa: E731
    assert [strip(r) for r in out["rows"]] == [strip(r) for r in direct]
    assert out["crb"] == prep.crb and out["warnings"] == []
