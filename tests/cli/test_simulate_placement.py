"""risloc simulate --distance D --aod AZ,EL: the UE placed in the RIS frame from the command line."""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.cli import main
from risloc_rt.io import load_capture


def test_distance_and_aod_reach_the_capture_truth(tmp_path, capsys):
    out = tmp_path / "placed.npz"
    assert main(["simulate", "--distance", "10", "--aod", "7.3,-2", "--no-noise", "-o", str(out)]) == 0
    truth = load_capture(out).truth
    assert truth.distance == pytest.approx(10.0, abs=1e-9)
    np.testing.assert_allclose(np.rad2deg(truth.aod), [7.3, -2.0], atol=1e-9)
    assert "truth: distance 10.0000 m, AoD +7.30° az -2.00° el" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--distance", "10"], "--distance and --aod go together"),
    (["--aod", "3,0"], "--distance and --aod go together"),
    (["--distance", "10", "--aod", "3"], "--aod '3' must be two"),
    (["--distance", "10", "--aod", "3,nan"], "must be two finite"),
    (["--distance", "10", "--aod", "3,0", "--ue", "0,0,0"], "--ue and --distance/--aod both place the UE"),
    (["--distance", "-1", "--aod", "3,0"], "distance"),
    (["--distance", "10", "--aod", "3,0", "--scene", "paper_hall"], "with --scene use --ue"),
])
def test_bad_placements_are_one_line_errors(tmp_path, capsys, argv, message):
    assert main(["simulate", *argv, "-o", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("risloc simulate: error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "x.npz").exists()


def test_frozen_geometry_flag_reaches_the_simulator(tmp_path):
    """A UE walking tangentially at 1.5 m/s: the per-frame cube differs from the frozen one; at rest they agree."""
    cubes = {}
    for name, extra in (("moving", []), ("frozen", ["--frozen-geometry"])):
        out = tmp_path / f"{name}.npz"
        assert main(["simulate", "--distance", "10", "--aod", "5,0", "--ue-velocity", "1.5,0,0", "--no-noise",
                     "-o", str(out), *extra]) == 0
        capture = load_capture(out)
        assert capture.provenance["motion"] == ("frozen" if extra else "sweep")
        cubes[name] = capture.cube
    # 61 frames of 6.4 ms: the UE walks 0.59 m over the sweep, so the loop-back phase history differs
    assert np.max(np.abs(cubes["moving"] - cubes["frozen"])) > 0.1 * np.max(np.abs(cubes["frozen"]))
