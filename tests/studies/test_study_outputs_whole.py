"""Issue 19 item 2 for studies: a study's derived files (``runs.parquet``, ``summary.json``,
``study.png``) are moved in together, so a failure while writing them leaves the previous set."""

from __future__ import annotations

import pytest

import risloc_rt.studies.sweep as sweep_module
from risloc_rt.studies.sweep import run_study


def _files(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


def test_an_interrupt_while_writing_the_figure_leaves_the_previous_summary(small_spec, tmp_path, monkeypatch):
    out = tmp_path / "study"
    spec = small_spec(runs=2)
    run_study(spec, out, workers=1, quiet=True)
    before = _files(out)
    assert {"summary.json", "runs.parquet", "study.png"} <= set(before)

    def interrupted(summary, path, **kwargs):
        path.write_bytes(b"half a figure")      # the new summary and table are already written (staged)
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_module, "plot_summary", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_study(small_spec(runs=3), out, workers=1, quiet=True)   # one more run per point, then Ctrl-C
    after = _files(out)
    for name in ("summary.json", "runs.parquet", "study.png"):
        assert after[name] == before[name], name                   # the old set, whole
    assert not [p for p in out.iterdir() if p.name.startswith(".risloc-stage-")]
