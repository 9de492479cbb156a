"""``risloc locate a.npz b.npz``: the captures of several RISs, each localized and their fixes fused (issue 22).

Two analytic captures of one radar position from two relay RISs at different heights (2.6 m and
0.6 m): 1-D sweeps cannot see elevation, but the two distances and azimuths fix the height. The
fused error is checked against the stated covariance (a χ² bound on the Mahalanobis distance), the
truth against the scenario's geometry.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.stats

from dsp import RisPose
from risloc_rt.cli import main
from risloc_rt.io import save_capture
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

UE = np.array([0.0, 0.0, 1.2])
RISES = {"ris0": ([1.0, 11.0, 2.6], [0.0, 0.0, 1.6]), "ris1": ([-8.0, 7.0, 0.6], [0.0, 0.0, 1.0])}


def _capture(name: str, seed: int):
    position, facing = RISES[name]
    pose = RisPose.facing(np.array(position), np.array(facing))
    scenario = analytic_scenario(ue_position=UE, ris_pose=pose, name=name)
    return simulate(scenario, rng=np.random.default_rng(seed))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("several")
    paths = {}
    for seed, name in enumerate(RISES):
        paths[name] = folder / f"{name}.npz"
        save_capture(_capture(name, seed), paths[name])
    return paths


def test_two_rises_fuse_to_the_truth_within_the_stated_covariance(files, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["locate", str(files["ris0"]), str(files["ris1"]), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "== ris0" in text and "== ris1" in text and "== fused (2 RIS: " in text
    doc = json.loads((out / "result.json").read_text())
    fused = doc["fused"]
    assert fused["detected"] and sorted(fused["used"]) == ["ris0", "ris1"] and not fused["excluded"]
    np.testing.assert_allclose(fused["truth"], UE)
    cov = np.array(fused["covariance"])
    assert np.all(np.isfinite(cov)), "RISs at 2.6 m and 0.6 m see the height"
    err = np.array(fused["position"]) - UE
    assert err @ np.linalg.solve(cov, err) <= scipy.stats.chi2.isf(1e-4, 3)
    assert fused["error"] == pytest.approx(float(np.linalg.norm(err)))
    assert fused["peb"] == pytest.approx(float(np.sqrt(np.trace(cov))))
    assert [c["name"] for c in doc["cases"]] == ["ris0", "ris1"]
    assert (out / "ris0").is_dir() and (out / "ris1").is_dir()


def test_a_known_height_joins_the_fusion(files, tmp_path, capsys):
    """``--ue-height`` with several captures: the fused fix takes the height as one more measurement
    (``dsp.fusion.KNOWN_HEIGHT_STD``), so its z is the given height and its z 1σ that σ (it was left to
    the fixes' elevations, and the fused z was whatever they gave)."""
    from dsp.fusion import KNOWN_HEIGHT_STD

    out = tmp_path / "height"
    assert main(["locate", str(files["ris0"]), str(files["ris1"]), "--out", str(out), "--ue-height", "1.2"]) == 0
    fused = json.loads((out / "result.json").read_text())["fused"]
    assert fused["position"][2] == pytest.approx(1.2, abs=3 * KNOWN_HEIGHT_STD)
    assert np.sqrt(np.array(fused["covariance"])[2, 2]) <= KNOWN_HEIGHT_STD * 1.01
    err = np.array(fused["position"]) - UE
    assert err @ np.linalg.solve(np.array(fused["covariance"]), err) <= scipy.stats.chi2.isf(1e-4, 3)


def test_one_capture_is_located_as_before(files, tmp_path, capsys):
    out = tmp_path / "one"
    assert main(["locate", str(files["ris0"]), "--out", str(out)]) == 0
    assert "fused" not in json.loads((out / "result.json").read_text())
    assert "== fused" not in capsys.readouterr().out


def test_two_captures_of_one_ris_are_refused(files, tmp_path, capsys):
    copy = tmp_path / "again.npz"
    copy.write_bytes(files["ris0"].read_bytes())
    assert main(["locate", str(files["ris0"]), str(copy)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "are of the same RIS" in err and "one sweep per RIS" in err


def test_two_files_of_one_name_are_refused(files, tmp_path, capsys):
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "ris0.npz").write_bytes(files["ris1"].read_bytes())
    assert main(["locate", str(files["ris0"]), str(other / "ris0.npz")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "two capture files are named 'ris0'" in err
