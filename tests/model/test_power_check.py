"""The link budget catches range aliasing: a UE beyond R_max folds back closer, and arrives far too weak."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from risloc_rt.io import process_capture
from risloc_rt.model import simulate
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.power_check import expected_loopback_snr_db, measured_loopback_snr_db, range_alias_flag


def _locate(scenario, seed=1):
    capture = simulate(scenario, rng=np.random.default_rng(seed))
    loc, _ = process_capture(capture)
    return capture, loc


@pytest.mark.parametrize("distance", [6.0, 13.38, 20.0])
def test_the_prediction_matches_the_measured_snr(distance):
    capture, loc = _locate(analytic_scenario(distance=distance, aod=np.deg2rad([10.3, 0.0])))
    predicted = expected_loopback_snr_db(capture, capture.truth.distance, capture.truth.aod)
    # the fitted amplitude is off-grid: only its noise (1σ of β̂²: 2/√ρΣA², < 0.1 dB at >= 20 dB)
    # and the structural reflection's leakage separate the two
    assert abs(measured_loopback_snr_db(loc, capture) - predicted) < 0.3
    # the detector's statistic integrates its window's beams on the half-bin grid: it reads lower
    assert -3.0 < loc.detection.snr_db - predicted < 0.5
    assert "aliased" not in loc.flag_codes


def test_a_ue_beyond_the_unambiguous_range_is_flagged_aliased():
    capture, loc = _locate(analytic_scenario(distance=25.4, aod=[0.0, 0.0]))
    assert capture.truth.distance > capture.radar.max_range
    assert loc.detected and loc.distance < 5.0          # folded back to 25.4 - 21.82 = 3.6 m
    flag = next(f for f in loc.flags if f.code == "aliased")
    assert f"d̂ + 1·R_max = {loc.distance + capture.radar.max_range:.3f} m" in flag.message


def test_measured_captures_without_calibration_are_not_judged_by_power():
    capture, loc = _locate(analytic_scenario(distance=25.4, aod=[0.0, 0.0]))
    measured = dataclasses.replace(capture, provenance={**capture.provenance, "source": "measurement"})
    assert range_alias_flag(loc, measured) is None
    calibrated = dataclasses.replace(measured, provenance={**measured.provenance, "calibrated": True})
    assert range_alias_flag(loc, calibrated) is not None
