"""Flags a capture carries from its import reach the localization (issue 20 items 5 and 8)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.io.report import capture_flags, process_capture
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate


@pytest.fixture(scope="module")
def capture():
    scenario = analytic_scenario(distance=9.3, aod=np.deg2rad([17.2, 0.0]),
                                 radar=RadarConfig(num_samples=128, num_chirps=16),
                                 processing=ProcessingConfig(n_dft=255, k_dft=64))
    return simulate(scenario, rng=np.random.default_rng(5))


def test_import_flags_and_damaged_beams_become_flags(capture):
    loc, _ = process_capture(capture)
    best = loc.beam_index
    prov = {**capture.provenance, "reader": {"damaged_beams": [3, best]},
            "import_flags": [{"code": "schedule-mismatch", "message": "the data supports first_frame = 15, not 18"},
                             {"code": "not-a-code", "message": "ignored"}, "not a dict"]}
    loc2, _ = process_capture(replace(capture, provenance=prov))
    flags = {f.code: f.message for f in loc2.flags}
    assert flags["schedule-mismatch"] == "the data supports first_frame = 15, not 18"
    assert "2 of 61 beams (3, " in flags["damaged-beams"] and f"the best beam {best} among them" in flags["damaged-beams"]
    assert "not-a-code" not in flags
    assert loc2.position.tolist() == loc.position.tolist()            # flags only: the estimate is the same


def test_no_import_flags_on_a_clean_capture(capture):
    loc, _ = process_capture(capture)
    assert capture_flags(capture, loc) == ()
    assert not {"damaged-beams", "schedule-mismatch", "uncalibrated"} & set(loc.flag_codes)


def test_alternatives_reach_result_json(tmp_path):
    """Issue 20 item 7: a reflective RIS's grating twin beyond the sweep is listed in result.json, not chosen."""
    import json

    from risloc_rt.cli import main

    cap = tmp_path / "twin.npz"
    assert main(["simulate", "--distance", "13.38", "--aod", "15.2,0", "--mode", "reflective", "--tx-power-dbm", "10",
                 "--seed", "3", "-o", str(cap)]) == 0
    assert main(["locate", str(cap), "--out", str(tmp_path / "out")]) == 0
    est = json.loads((tmp_path / "out" / "result.json").read_text())["cases"][0]["estimate"]
    assert abs(np.rad2deg(est["aod"][0]) - 15.2) < 1.0                      # the in-sweep candidate
    twins = [a for a in est["alternatives"] if a["kind"] == "grating-twin"]
    assert twins and abs(twins[0]["aod_deg"][0] - (-47.5)) < 1.5
