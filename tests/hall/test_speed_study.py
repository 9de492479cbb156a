"""``risloc speed``: the study's bookkeeping on a tiny grid of the default hall.

Oracles: a setting traced twice gives the same paths, so its model error against itself is
"reference" (−∞ dB) and its estimates do not move (shift 0); the screened zoom is the paper's grid
method, so its position errors equal the full search's; the ratios are taken against the full grid.
"""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.cli import main
from risloc_rt.cli import speed

GRID = (("d1 1e4", {"max_depth": 1, "samples_per_src": 10_000}),
        ("+diffraction", {"max_depth": 1, "samples_per_src": 10_000, "diffraction": True}))


@pytest.fixture(scope="module")
def summaries():
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(speed, "REFERENCE", dict(GRID[0][1]))
        return speed.run_study(["paper_hall"], realizations=2, full=0, seed=1, positions=1, grid=GRID,
                               log=lambda *_: None)


def test_every_setting_and_estimator_is_measured(summaries):
    cells = {(s["setting"], s["estimator"]) for s in summaries}
    assert cells == {(label, est) for label, _ in GRID for est in ("zoom", "refined")}
    for s in summaries:
        assert s["n"] == 2 and s["dsp_s"] > 0 and s["synthesis_s"] > 0 and s["peb_m"] > 0


def test_reference_setting_has_no_model_error_and_the_paper_hall_has_no_diffracting_edge(summaries):
    by = {(s["setting"], s["estimator"]): s for s in summaries}
    assert by["d1 1e4", "zoom"]["model_error_db"] == -np.inf
    # A closed box hall has no convex edge: diffraction adds no path, the estimate does not move.
    assert by["+diffraction", "refined"]["model_error_db"] == -np.inf
    assert by["+diffraction", "refined"]["max_shift_m"] == 0.0
    assert "only costs time" in "\n".join(speed.mechanism_verdicts(summaries))


def test_table_gives_ratios_against_the_full_grid():
    row = {"scene": "h", "setting": "s", "n": 1, "trace_s": 0.1, "paths": 5, "model_error_db": -30.0,
           "synthesis_s": 0.1, "peb_m": 1e-3, "rmse_over_crb": 1.0, "max_shift_m": float("nan")}
    table = speed.format_table([dict(row, estimator="full", dsp_s=9.9, rmse_m=4e-3),
                                dict(row, estimator="zoom", dsp_s=0.1, rmse_m=4e-3),
                                dict(row, estimator="refined", dsp_s=0.3, rmse_m=2e-3)])
    lines = table.splitlines()
    assert "| 0.020 |" in lines[3] and "| 1.00 |" in lines[3]  # zoom: (0.1 + 0.1)/(0.1 + 9.9), same error
    assert "| 0.040 |" in lines[4] and "| 0.50 |" in lines[4]  # refined: 0.4/10, half the error


def test_bad_counts_are_refused(capsys):
    assert main(["speed", "--realizations", "0"]) == 2
    assert "--realizations and --positions must be >= 1" in capsys.readouterr().err
