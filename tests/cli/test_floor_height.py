"""``--floor-height`` on ``risloc locate`` (and ``demo``): a traced hall's capture reads the floor's ladder.

The case: the traced L-shaped hall, ris0 sweeping, the radar 20.8 m away at [5, 20, 1.2], no
noise: the RIS's return via the floor (one rung δ = 6.9 cm later) is stronger than the straight leg
(``tests/hall/test_walk_biases.py``). Oracle: the geometry (the true distance, δ from the mirror image).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import dsp
from risloc_rt.cli import main

UE = np.array([5.0, 20.0, 1.2])
RIS0 = np.array([17.0, 3.0, 1.2])


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    path = tmp_path_factory.mktemp("floor") / "far.npz"
    assert main(["simulate", "--scene", "l_hall_2ris", "--ris", "ris0", "--ue", "5,20,1.2", "--no-noise",
                 "-o", str(path)]) == 0
    return path


def _located(capture, tmp_path, *flags):
    out = tmp_path / "out"
    assert main(["locate", str(capture), "--out", str(out), "--ue-height", "1.2", *flags]) == 0
    (case,) = json.loads((out / "result.json").read_text())["cases"]
    return case


def test_auto_reads_the_hall_floor_and_takes_the_first_arrival(capture, tmp_path):
    truth = float(np.linalg.norm(UE - RIS0))
    case = _located(capture, tmp_path)
    assert "first-arrival" in [f["code"] for f in case["flags"]]
    assert abs(case["estimate"]["distance"] - truth) < 0.01
    delta = dsp.rung_spacing(RIS0, UE, 0.0)
    none = _located(capture, tmp_path / "none", "--floor-height", "none")
    assert none["estimate"]["distance"] - truth == pytest.approx(delta, abs=0.25 * delta)   # the floor leg, unflagged


def test_a_bad_floor_height_is_one_line(capture, tmp_path, capsys):
    assert main(["locate", str(capture), "--out", str(tmp_path / "o"), "--floor-height", "floor"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--floor-height 'floor'" in err[0] and "Traceback" not in err[0]
