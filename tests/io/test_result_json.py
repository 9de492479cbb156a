"""result.json is strict JSON: non-finite values become null and are listed; writes are atomic."""

from __future__ import annotations

import json
import math

import numpy as np

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
