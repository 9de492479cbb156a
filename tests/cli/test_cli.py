"""The ``risloc`` command line as a user runs it: exit codes, printed figures, files written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from risloc_rt.io.capture_file import load_capture
from risloc_rt.cli import main


def _result(folder):
    doc = json.loads((folder / "result.json").read_text())
    assert doc["format"] == "risloc-result" and doc["version"] == 1
    return doc


@pytest.mark.slow
def test_demo_on_the_default_hall(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--samples", "20000"]) == 0
    text = capsys.readouterr().out
    assert "paper_hall" in text and "RIS loop-back" in text and "time:" in text
    doc = _result(tmp_path)
    assert [c["name"] for c in doc["cases"]] == ["paper_hall-0", "paper_hall-1"]
    for case in doc["cases"]:
        # The refined estimator (default) is off the sweep grid: the AoD error stays within 4σ of
        # its own stated uncertainty, the position within the 2 cm bound of docs/ray-tracing.md.
        assert case["detection"]["detected"] is True and case["estimate"]["estimator"] == "refined"
        assert case["error"]["angle"] <= 4 * case["estimate"]["std"]["aod"][0]
        assert case["error"]["position"] < 0.02
        assert "elevation-assumed" in [f["code"] for f in case["flags"]]
        assert set(case["plots"]) == {"delay_doppler", "sweep", "range_profile", "traced_profile"}
        for rel in case["plots"].values():
            assert (tmp_path / rel).stat().st_size > 10_000
        assert {"synthesis", "dsp", "paths"} <= set(case["timing"])


def test_demo_analytic_writes_both_paper_cases(tmp_path, capsys):
    assert main(["demo", "--analytic", "--out", str(tmp_path), "--seed", "3"]) == 0
    doc = _result(tmp_path)
    assert [c["name"] for c in doc["cases"]] == ["paper-broadside", "paper-off-broadside"]
    np.testing.assert_allclose([c["truth"]["aod"][0] for c in doc["cases"]], np.deg2rad([0.0, 21.0]), atol=1e-12)
    # Half a delay-grid step (0.91 cm) of quantisation: the noiseless bound holds at this SNR too.
    assert all(abs(c["error"]["distance"]) < 0.0091 for c in doc["cases"])
    assert "paper-off-broadside" in capsys.readouterr().out


def test_simulate_a_traced_hall_then_locate_it(tmp_path, capsys):
    capture_file = tmp_path / "hall.npz"
    assert main(["simulate", "--scene", "paper_hall", "--radar-index", "1", "--samples", "20000", "--seed", "5",
                 "--complex64", "-o", str(capture_file)]) == 0
    capture = load_capture(capture_file)
    assert capture.cube.dtype == np.complex64 and capture.provenance["scene_hash"]
    np.testing.assert_allclose(capture.truth.aod, [np.deg2rad(21.0), 0.0], atol=1e-9)
    # the paper's method: the UE is on the sweep grid, so the AoD is exact
    assert main(["locate", str(capture_file), "--estimator", "paper", "--out", str(tmp_path / "paper")]) == 0
    case = _result(tmp_path / "paper")["cases"][0]
    assert case["estimate"]["estimator"] == "paper"
    assert case["error"]["angle"] < 1e-9 and case["error"]["position"] < 0.02
    # the refined default, with the radar's height known: within 4σ, and no elevation assumed
    assert main(["locate", str(capture_file), "--ue-height", "1.2", "--out", str(tmp_path / "out")]) == 0
    case = _result(tmp_path / "out")["cases"][0]
    assert case["error"]["angle"] <= 4 * np.hypot(*case["estimate"]["std"]["aod"]) and case["error"]["position"] < 0.02
    assert "elevation-assumed" not in [f["code"] for f in case["flags"]]


def test_nothing_detected_means_no_position_and_exit_status_3(tmp_path, capsys):
    capture_file = tmp_path / "silent.npz"
    assert main(["simulate", "--tx-power-dbm", "-140", "--seed", "2", "-o", str(capture_file)]) == 0
    assert main(["locate", str(capture_file), "--out", str(tmp_path / "out")]) == 3
    assert "NOTHING DETECTED: no position" in capsys.readouterr().out
    case = _result(tmp_path / "out")["cases"][0]
    assert case["detection"]["detected"] is False
    assert case["estimate"]["position"] == [None, None, None] and case["estimate"]["distance"] is None
    assert case["flags"][0]["code"] == "no-detection"
    text = (tmp_path / "out" / "result.json").read_text()
    assert "NaN" not in text


def test_locate_reports_missing_files_and_bad_captures(tmp_path, capsys):
    assert main(["locate", str(tmp_path / "nope.npz")]) == 2
    assert "does not exist" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    np.savez(bad, cube=np.zeros((1, 2, 3)))
    assert main(["locate", str(bad)]) == 2
    assert "missing array" in capsys.readouterr().err


def test_demo_with_an_unknown_scene_is_a_clear_error(tmp_path, capsys):
    assert main(["demo", "--scene", "atlantis", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "atlantis" in err and "available" in err
