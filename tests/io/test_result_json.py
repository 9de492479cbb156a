"""result.json is strict JSON: non-finite values become null and are listed; writes are atomic."""

from __future__ import annotations

import json
import math

import numpy as np

import dsp
from risloc_rt.io.report import json_safe, write_result


def test_json_safe_turns_nonfinite_into_null_and_reports_where():
    found: list[str] = []
    doc = json_safe({"a": np.float64("nan"), "b": [1.0, np.inf, np.int64(3)], "c": {"d": -np.inf, "e": np.bool_(True)},
                     "f": np.array([0.5, np.nan])}, nonfinite=found)
    assert doc == {"a": None, "b": [1.0, None, 3], "c": {"d": None, "e": True}, "f": [0.5, None]}
    assert found == ["$.a", "$.b[1]", "$.c.d", "$.f[1]"]
    json.dumps(doc, allow_nan=False)  # raises on any NaN left


def test_write_result_never_writes_nan(tmp_path, monkeypatch):
    import risloc_rt.io.report as report

    monkeypatch.setattr(report, "case_dict", lambda case: {"name": case, "estimate": {"distance": math.nan}})
    path = write_result(tmp_path, ["no-detection-case"])
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    assert doc["cases"][0]["estimate"]["distance"] is None
    assert doc["nonfinite"] == ["$.cases[0].estimate.distance"]
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]  # no temporary file left behind


def test_a_localization_without_its_per_beam_scan_is_reported_with_a_null_sweep(paper_run):
    """Regression: ``case_dict`` and ``format_case`` read ``localization.scan``, which ``self_localize(scan=False)``
    (a study's runs) leaves None; they raised AttributeError on such a case."""
    from dataclasses import replace

    from risloc_rt.io.report import CaseResult, case_dict, format_case

    scenario, capture = paper_run("broadside", "relay")
    loc = dsp.self_localize(capture.cube, sweep=capture.sweep, radar=capture.radar, processing=capture.processing,
                            pose=scenario.ris.pose, loopback_delay=scenario.ris.loopback_delay, scan=False)
    assert loc.scan is None and loc.detected
    case = CaseResult(name="no-scan", capture=capture, localization=loc)
    doc = case_dict(case)
    assert doc["sweep"] is None
    assert abs(doc["estimate"]["distance"] - capture.truth.distance) < 0.01  # [m]: the estimate is still there
    head = format_case(case).splitlines()[0]
    assert f"best beam {loc.beam_index} of {capture.sweep.num_beams}" in head
    with_scan = replace(case, localization=replace(loc, scan=dsp.scan_beams(capture.cube, capture.sweep, capture.radar,
                                                                              capture.processing)))
    assert len(case_dict(with_scan)["sweep"]["angles"]) == capture.sweep.num_beams
