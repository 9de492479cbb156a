"""The speed study of ``risloc speed`` (``risloc_rt.studies.speed``) on a tiny grid of the default hall.

Oracles that can fail: the model error of each setting equals the relative distance of its cube
from a reference cube traced and synthesised here, independently of the study's loop (−inf only
where the two traces give the same paths); diffraction in a closed box hall (no convex edge) adds
no path, so it changes neither the cube nor any estimate; the screened (zoom) search finds the
full 2-D DFT's grid maximum, so its position error equals the full search's bit for bit; the
refined estimate lies within a few of its own 1σ; the table's ratios and the verdicts follow from
the rows' numbers.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from risloc_rt.cli import main
from risloc_rt.studies.speed import (MOVE_FRACTION, format_table, mechanism_verdicts, model_error_db, run_speed_study)

D1 = {"max_depth": 1, "samples_per_src": 10_000}
GRID = (("d1 1e4", D1), ("+diffraction", {**D1, "diffraction": True}))
#: The model reference: depth 2 (second-order reflections: more paths than depth 1).
REFERENCE = {"max_depth": 2, "samples_per_src": 10_000}


@pytest.fixture(scope="module")
def summaries():
    return run_speed_study(["paper_hall"], realizations=1, full=1, seed=1, positions=1, grid=GRID,
                           reference=REFERENCE, log=lambda *_: None)


@pytest.fixture(scope="module")
def by(summaries):
    return {(s["setting"], s["estimator"]): s for s in summaries}


def _traced_cube(overrides):
    """(kept paths, noiseless cube [√W]) of paper_hall's first radar position, traced with ``overrides`` here."""
    from risloc_rt.hall import hall_paths, hall_scenario
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.model import beat_cube

    hs = hall_scenario("paper_hall", radar_index=0, trace=TraceSettings(**overrides))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traced = hall_paths(hs)
    sc = hs.base
    return len(traced.paths), beat_cube(traced.paths, radar=sc.radar, sweep=sc.sweep, ris=sc.ris)


def test_every_setting_and_estimator_is_measured_once_per_realization(by):
    assert set(by) == {(label, est) for label, _ in GRID for est in ("zoom", "refined")} | {("d1 1e4", "full")}
    assert all(s["n"] == 1 and s["scene"] == "paper_hall" for s in by.values())
    assert math.isnan(by["d1 1e4", "refined"]["max_shift_m"])  # the default setting is what shifts are against


def test_the_model_error_is_the_distance_from_an_independently_traced_reference_cube(by):
    paths, cube = _traced_cube(D1)
    ref_paths, ref = _traced_cube(REFERENCE)
    assert ref_paths > paths  # depth 2 adds second-order reflections
    expected = 20 * np.log10(np.sqrt(np.sum(np.abs(cube - ref) ** 2)) / np.sqrt(np.sum(np.abs(ref) ** 2)))
    assert np.isfinite(expected) and expected < 0
    for est in ("zoom", "refined"):
        assert by["d1 1e4", est]["paths"] == paths
        assert by["d1 1e4", est]["model_error_db"] == pytest.approx(expected, abs=1e-9)


def test_model_error_db_is_minus_infinity_only_for_equal_cubes():
    rng = np.random.default_rng(0)
    ref = rng.standard_normal((3, 4, 5)) + 1j * rng.standard_normal((3, 4, 5))
    assert model_error_db(ref.copy(), ref) == -np.inf
    assert model_error_db(ref * (1 + 1e-3), ref) == pytest.approx(-60.0, abs=1e-9)  # 20 log10(1e-3)
    assert model_error_db(ref * 1j, ref) == pytest.approx(20 * np.log10(np.sqrt(2)), abs=1e-12)  # |j - 1| = √2


def test_diffraction_in_a_closed_box_hall_adds_no_path_and_moves_nothing(by, summaries):
    # A closed box hall has no convex edge: diffraction adds no path, so the cube and every estimate are unchanged.
    for est in ("zoom", "refined"):
        assert by["+diffraction", est]["paths"] == by["d1 1e4", est]["paths"]
        assert by["+diffraction", est]["model_error_db"] == by["d1 1e4", est]["model_error_db"]
        assert by["+diffraction", est]["rmse_m"] == by["d1 1e4", est]["rmse_m"]
        assert by["+diffraction", est]["max_shift_m"] == 0.0
    verdict = mechanism_verdicts(summaries)
    assert len(verdict) == 1 and verdict[0].startswith("paper_hall: +diffraction only costs time (largest shift 0.00 mm")


def test_the_screened_search_finds_the_full_grids_maximum(by):
    """zoom is exact on the grid: on the same capture its position error equals the full 2-D DFT's."""
    assert by["d1 1e4", "zoom"]["rmse_m"] == by["d1 1e4", "full"]["rmse_m"]


def test_the_refined_estimate_lies_within_a_few_of_its_own_sigma(by):
    """RMSE/CRB ~ |N(0, 1)| per axis for a near-efficient estimator: beyond 5 has probability < 1e-5."""
    s = by["d1 1e4", "refined"]
    assert 0 < s["peb_m"] < 0.05 and s["rmse_over_crb"] == s["rmse_m"] / s["peb_m"] < 5


def test_the_tables_ratios_follow_from_the_rows(summaries):
    lines = format_table(summaries).splitlines()
    assert len(lines) == 2 + len(summaries)
    full = next(s for s in summaries if s["estimator"] == "full")
    for s, line in zip(summaries, lines[2:]):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[:3] == [s["scene"], s["setting"], s["estimator"]]
        time_ratio = (s["synthesis_s"] + s["dsp_s"]) / (full["synthesis_s"] + full["dsp_s"])
        assert cells[9] == f"{time_ratio:.3f}" and cells[12] == f"{s['rmse_m'] / full['rmse_m']:.2f}"


def test_table_gives_ratios_against_the_full_grid():
    row = {"scene": "h", "setting": "s", "n": 1, "trace_s": 0.1, "paths": 5, "model_error_db": -30.0,
           "synthesis_s": 0.1, "peb_m": 1e-3, "rmse_over_crb": 1.0, "max_shift_m": float("nan")}
    table = format_table([dict(row, estimator="full", dsp_s=9.9, rmse_m=4e-3),
                          dict(row, estimator="zoom", dsp_s=0.1, rmse_m=4e-3),
                          dict(row, estimator="refined", dsp_s=0.3, rmse_m=2e-3),
                          dict(row, estimator="zoom", scene="other", dsp_s=0.3, rmse_m=2e-3,
                               model_error_db=float("-inf"))])
    lines = table.splitlines()
    assert "| 0.020 |" in lines[3] and "| 1.00 |" in lines[3]  # zoom: (0.1 + 0.1)/(0.1 + 9.9), same error
    assert "| 0.040 |" in lines[4] and "| 0.50 |" in lines[4]  # refined: 0.4/10, half the error
    assert "| reference |" in lines[5] and lines[5].count("| nan |") == 2  # another scene has no full row


def test_the_verdict_follows_from_the_shift_against_the_sigma():
    base = {"scene": "h", "estimator": "refined", "peb_m": 2e-3, "model_error_db": -40.0, "trace_s": 0.1}
    rows = [dict(base, setting="+a", max_shift_m=1.01 * MOVE_FRACTION * 2e-3),
            dict(base, setting="+b", max_shift_m=0.99 * MOVE_FRACTION * 2e-3),
            dict(base, setting="d1 1e4", max_shift_m=1.0),  # not a mechanism
            dict(base, setting="+c", estimator="zoom", max_shift_m=1.0)]  # the verdicts are the refined estimator's
    out = mechanism_verdicts(rows)
    assert len(out) == 2
    assert out[0].startswith("h: +a changes the localization") and out[1].startswith("h: +b only costs time")


def test_the_tradeoff_figure_is_a_png_drawn_without_pyplot(tmp_path):
    import json
    import subprocess
    import sys

    code = ("import sys, json; from risloc_rt.studies.speed import plot_tradeoff; "
            "rows = json.loads(sys.argv[1]); p = plot_tradeoff(rows, sys.argv[2]); "
            "print('matplotlib.pyplot' in sys.modules, open(p, 'rb').read(8) == b'\\x89PNG\\r\\n\\x1a\\n')")
    row = {"scene": "h", "setting": "d1 1e4", "trace_s": 0.1, "model_error_db": -20.0, "synthesis_s": 0.1,
           "dsp_s": 0.2, "rmse_m": 2e-3}
    rows = [dict(row, estimator=e) for e in ("full", "zoom", "refined")]
    rows.append(dict(row, estimator="zoom", setting="ref", model_error_db=float("-inf")))  # drawn at -200 dB
    out = subprocess.run([sys.executable, "-c", code, json.dumps(rows), str(tmp_path / "t.png")], capture_output=True,
                         text=True, check=True)
    assert out.stdout.split() == ["False", "True"]


def test_bad_counts_are_refused(capsys):
    assert main(["speed", "--realizations", "0"]) == 2
    assert "--realizations and --positions must be >= 1" in capsys.readouterr().err
