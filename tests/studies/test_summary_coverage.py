"""summary.json's ``coverage``: the share of detected runs within 1, 2, 3 stated σ, with Wilson intervals."""

from __future__ import annotations

import math

import numpy as np

import pytest

from risloc_rt.studies import StudySpec
from risloc_rt.studies.summary import GAUSSIAN_COVERAGE, coverage, summarize


def _wilson_by_hand(k: int, n: int) -> list[float]:
    """The Wilson score interval, written out: (p + z²/2n ± z sqrt(p(1-p)/n + z²/4n²)) / (1 + z²/n)."""
    z = 1.959964
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return [max(0.0, centre - half), min(1.0, centre + half)]


def test_coverage_counts_errors_within_each_multiple_of_sigma():
    # |e|/σ = 0.5, 1.0 (on the edge: counted), 1.5, 2.5, 3.5, 0.2; one NaN error, one inf σ, one σ = 0: left out
    errors = [0.5, -2.0, 3.0, -0.25, 7.0, 0.02, math.nan, 1.0, 1.0]
    sigmas = [1.0, 2.0, 2.0, 0.1, 2.0, 0.1, 1.0, math.inf, 0.0]
    c = coverage(errors, sigmas)
    assert c["n"] == 6
    assert c["levels"] == [1, 2, 3]
    assert c["share"] == [3 / 6, 4 / 6, 5 / 6]
    for got, k in zip(c["ci95"], (3, 4, 5)):
        assert got == pytest.approx(_wilson_by_hand(k, 6), abs=1e-12)
    # 3 of 6: Wilson [0.1876, 0.8124] (hand: centre 0.5, half 1.96·sqrt(0.25/6 + 3.8416/144)/1.6403)
    assert c["ci95"][0] == pytest.approx([0.18761, 0.81239], abs=1e-5)


def test_coverage_of_nothing_is_nan_with_the_whole_interval():
    c = coverage([math.nan], [1.0])
    assert c["n"] == 0 and all(math.isnan(s) for s in c["share"]) and c["ci95"] == [[0.0, 1.0]] * 3
    with pytest.raises(ValueError, match="one σ per error"):
        coverage([1.0, 2.0], [1.0])


def test_gaussian_reference_is_the_normal_distribution():
    assert GAUSSIAN_COVERAGE == pytest.approx([math.erf(k / math.sqrt(2)) for k in (1, 2, 3)], abs=1e-6)


def _row(point: int, run: int, *, detected: bool, d: float = math.nan, sd: float = math.nan, az: float = math.nan,
         saz: float = math.nan, pos: float = math.nan, peb: float = math.nan) -> dict:
    return {"point": point, "run": run, "detected": detected, "snr_db": 20.0, "flags": "", "seconds": 0.01,
            "distance_error": d, "std_distance": sd, "aod_az_error": az, "std_aod_az": saz, "angle_error": abs(az),
            "position_error": pos, "peb": peb}


def test_summary_point_carries_the_coverage_of_its_detected_runs():
    spec = StudySpec(name="c", runs=4, seed=1, vary=(("tx_power_dbm", (10.0,)),))
    rows = [
        _row(0, 0, detected=True, d=0.001, sd=0.002, az=-0.003, saz=0.001, pos=0.05, peb=0.02),  # 0.5, 3, 2.5
        _row(0, 1, detected=True, d=-0.005, sd=0.002, az=0.0005, saz=0.001, pos=0.01, peb=0.02),  # 2.5, 0.5, 0.5
        _row(0, 2, detected=True, d=0.0015, sd=0.001, az=0.0021, saz=0.001, pos=0.07, peb=0.02),  # 1.5, 2.1, 3.5
        _row(0, 3, detected=False),  # no detection: not counted
    ]
    info = {"crb": [{"distance": 0.001, "angle": 0.001, "position": 0.01}], "prepare_seconds": {0: 0.0}}
    point = summarize(spec, rows, info)["points"][0]
    cov = point["coverage"]
    assert set(cov) == {"distance", "angle", "position"}
    assert cov["distance"]["n"] == 3 and cov["distance"]["share"] == [1 / 3, 2 / 3, 1.0]
    assert cov["angle"]["share"] == [1 / 3, 1 / 3, 1.0]
    assert cov["position"]["share"] == [1 / 3, 1 / 3, 2 / 3]
    assert cov["position"]["ci95"][2] == pytest.approx(_wilson_by_hand(2, 3), abs=1e-12)


def test_doubted_runs_are_counted_and_left_out_of_mae_undoubted_only():
    # Five runs of one point: two detected runs carry a flag of a possible gross error (off-detection, grating-lobe:
    # dsp.fusion.DOUBT_CODES), two carry none or only elevation-assumed, one is not detected.
    spec = StudySpec(name="d", runs=5, seed=3, vary=(("tx_power_dbm", (0.0,)),))
    rows = [
        _row(0, 0, detected=True, d=4.2, az=0.5, pos=9.0),
        _row(0, 1, detected=True, d=0.003, az=0.001, pos=0.02),
        _row(0, 2, detected=True, d=-1.7, az=-0.9, pos=11.0),
        _row(0, 3, detected=True, d=-0.001, az=0.002, pos=0.01),
        _row(0, 4, detected=False),
    ]
    for r, flags in zip(rows, ("off-detection,grating-lobe,elevation-assumed", "elevation-assumed", "grating-lobe",
                               "", "no-detection")):
        r["flags"] = flags
    (point,) = summarize(spec, rows, {"crb": {0: {"distance": 0.0005}}, "prepare_seconds": {}})["points"]
    assert point["detected"] == 4 and point["doubted"] == 2
    # the MAE stays over every detected run; the undoubted one over runs 1 and 3 only
    assert point["mae"]["distance"] == pytest.approx((4.2 + 0.003 + 1.7 + 0.001) / 4, rel=1e-12)
    assert point["mae_undoubted"]["distance"] == pytest.approx((0.003 + 0.001) / 2, rel=1e-12)
    assert point["mae_undoubted"]["position"] == pytest.approx((0.02 + 0.01) / 2, rel=1e-12)
    lo, hi = point["mae_undoubted_ci95"]["distance"]
    assert 0.001 <= lo <= point["mae_undoubted"]["distance"] <= hi <= 0.003  # resamples of {0.003, 0.001}
    # and the RMSE and its ratio to the bound likewise: the RMSE over every detected run is the noise peaks'
    rms = np.sqrt((0.003**2 + 0.001**2) / 2)
    assert point["rmse_undoubted"]["distance"] == pytest.approx(rms, rel=1e-12)
    assert point["rmse"]["distance"] == pytest.approx(np.sqrt((4.2**2 + 0.003**2 + 1.7**2 + 0.001**2) / 4), rel=1e-12)
    assert point["rmse_undoubted_over_crb"]["distance"] == pytest.approx(rms / 0.0005, rel=1e-12)
    lo, hi = point["rmse_undoubted_ci95"]["position"]
    assert 0.01 <= lo <= point["rmse_undoubted"]["position"] <= hi <= 0.02
    assert point["flags"] == {"elevation-assumed": 2, "grating-lobe": 2, "no-detection": 1, "off-detection": 1}
