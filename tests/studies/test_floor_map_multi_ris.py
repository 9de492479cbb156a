"""``risloc study map`` with several RISs (issue 22, item 4): the multi-RIS PEB, the fused fix at a known
height, the serving RIS and the coverage; a one-RIS map as before; the bad-input lines."""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest

from dsp import RisPose

from .test_floor_map import tiny_hall  # noqa: F401 - the module-scoped fixture

#: The tiny box of tests/conftest.py with ris0 moved to x = 5 (cells at x > 5 are behind it) and a
#: second RIS in the south-east corner facing the diagonal (it sees the whole quadrant).
RIS1 = """[[ris]]
name = "ris1"
position = [7.5, 0.5, 1.2]
facing = [3.5, 4.5, 1.2]
rows = 16
columns = 4
spacing = "half-wavelength"
amplification_db = 45.532
loopback_delay = 1.78e-9
mode = "relay"
panel = { width = 0.10, height = 0.05, material = "metal" }
[radar]"""


@pytest.fixture(scope="module")
def tiny_hall_2ris(tmp_path_factory, tiny_hall_spec):
    from risloc_rt.cli import main

    spec = (tiny_hall_spec.replace('name = "tiny_box"', 'name = "tiny_box_2ris"')
            .replace("position = [7.0, 3.0, 1.2]", "position = [5.0, 3.0, 1.2]").replace("[radar]", RIS1))
    root = tmp_path_factory.mktemp("tiny2")
    (root / "spec.toml").write_text(spec)
    assert main(["scene", "build", str(root / "spec.toml"), "-o", str(root / "built")]) == 0
    return root / "built"


# --- the bound and the fusion, against geometry ---------------------------------------------------


def test_the_peb_of_one_ris_is_its_range_and_cross_range_bound():
    from risloc_rt.studies.floor_map import multi_ris_peb

    pose = RisPose.facing([0.0, 0.0, 1.2], [10.0, 0.0, 1.2])
    x = np.array([7.0, 2.0, 1.2])  # 7.28 m away at 15.9° azimuth
    d = float(np.linalg.norm(x - pose.position))
    crb = {"distance": 2e-3, "angle": 1e-3}
    # range along the line of sight, d·σ_az across it: sqrt(σ_d² + d² σ_az²)
    assert multi_ris_peb([(pose, crb)], x) == pytest.approx(math.hypot(2e-3, d * 1e-3), rel=1e-6)


def test_two_perpendicular_riss_sum_their_information():
    from risloc_rt.studies.floor_map import multi_ris_peb

    x = np.array([6.0, 5.0, 1.2])
    a = RisPose.facing([0.0, 5.0, 1.2], x)  # looks along +x: range along x, cross range along y
    b = RisPose.facing([6.0, 0.0, 1.2], x)  # looks along +y: range along y, cross range along x
    ca, cb = {"distance": 1e-3, "angle": 2e-3}, {"distance": 4e-3, "angle": 0.5e-3}
    info_x = 1 / 1e-3**2 + 1 / (5.0 * 0.5e-3) ** 2  # a's range, b's cross range (5 m lever)
    info_y = 1 / (6.0 * 2e-3) ** 2 + 1 / 4e-3**2  # a's cross range (6 m lever), b's range
    both = multi_ris_peb([(a, ca), (b, cb)], x)
    assert both == pytest.approx(math.sqrt(1 / info_x + 1 / info_y), rel=1e-6)
    assert both < min(multi_ris_peb([(a, ca)], x), multi_ris_peb([(b, cb)], x))


def _fix(name, pose, x, sd=1e-3, sa=1e-3, bias=0.0):
    from dsp import RisFix

    return RisFix(name=name, pose=pose, distance=float(np.linalg.norm(x - pose.position)) + bias, std_distance=sd,
                  aod=pose.angles_to(x), std_aod=[sa, np.nan])


def test_the_fused_fix_lies_at_the_known_height_and_leaves_out_a_wrong_ris():
    from risloc_rt.studies.floor_map import fuse_at_height

    x = np.array([6.0, 5.0, 1.0])  # 0.2 m below the RISs: the fixes alone barely see the height
    poses = [RisPose.facing(p, x) for p in ([0.0, 5.0, 1.2], [6.0, 0.0, 1.2], [12.0, 9.0, 1.2])]
    pos, fused = fuse_at_height([_fix(f"r{i}", p, x) for i, p in enumerate(poses)], 1.0)
    assert np.linalg.norm(pos - x) < 1e-6 and pos[2] == 1.0 and not fused.excluded
    # r2's distance 0.3 m off (300 σ): the χ² test leaves it out and the others still meet at x
    fixes = [_fix("r0", poses[0], x), _fix("r1", poses[1], x), _fix("r2", poses[2], x, bias=0.3)]
    pos, fused = fuse_at_height(fixes, 1.0)
    assert [n for n, _ in fused.excluded] == ["r2"] and np.linalg.norm(pos - x) < 1e-6


def test_a_run_with_one_detection_is_that_riss_own_fix_and_none_without():
    from risloc_rt.studies.floor_map import cell_run_position

    x = np.array([6.0, 5.0, 1.2])
    a, b = RisPose.facing([0.0, 5.0, 1.2], x), RisPose.facing([6.0, 0.0, 1.2], x)
    miss = {"detected": False}
    hit = {"detected": True, "distance": 6.001, "aod_az": 0.0, "std_distance": 1e-3, "std_aod_az": 1e-3,
           "x": 6.001, "y": 5.0, "z": 1.2, "position_error": 1e-3, "flags": "elevation-assumed"}
    assert cell_run_position([("a", a, miss), ("b", b, miss)], x, 1.2) is None
    assert cell_run_position([("a", a, hit), ("b", b, miss)], x, 1.2) == (1e-3, ("a",), (), ())


# --- a one-RIS map as before ----------------------------------------------------------------------


def test_a_one_ris_map_keeps_its_key_and_its_cells(tiny_hall):  # noqa: F811
    """Point p is cell p in a one-RIS map (the same noise: test_floor_map compares the run log's indices)."""
    from risloc_rt.studies.floor_map import MapSettings, floor_grid, grid_cells

    s = MapSettings(scene=str(tiny_hall), spacing=1.0, runs=3)
    before = {"scene": s.scene, "spacing": 1.0, "height": 1.2, "seed": 0, "estimator": "refined", "depth": 3,
              "samples": 100_000, "tx_power_dbm": None, "margin": 0.5}  # the key's settings before issue 22
    assert s.key == hashlib.sha256(json.dumps(before, sort_keys=True).encode()).hexdigest()[:16]
    assert MapSettings(scene=str(tiny_hall), spacing=1.0, peb_bound=0.2).key == s.key  # read after the runs
    assert MapSettings(scene=str(tiny_hall), spacing=1.0, ris=("ris0",)).key != s.key
    _, cells, keep = grid_cells(s)
    g = floor_grid(s)
    assert g.names == ("ris0",) and np.array_equal(keep, g.floor & g.sees[:, 0])
    # as before: in front of the RIS within ±45°, at least 1 m from it (it faces -x from [7, 3])
    az = np.degrees(np.arctan2(np.abs(cells[:, 1] - 3.0), 7.0 - cells[:, 0]))
    assert np.all(cells[:, 0] < 7.0) and np.all(az <= 45.0 + 1e-9)
    assert np.all(np.hypot(cells[:, 0] - 7.0, cells[:, 1] - 3.0) >= 1.0)


# --- a two-RIS map ----------------------------------------------------------------------------------


def test_the_two_ris_grid_sees_behind_ris0_through_ris1(tiny_hall_2ris):
    from risloc_rt.studies.floor_map import MapSettings, floor_grid

    g = floor_grid(MapSettings(scene=str(tiny_hall_2ris), spacing=2.0))
    assert g.names == ("ris0", "ris1")
    cells = g.positions[g.floor]
    sees = g.sees[g.floor]
    behind = cells[:, 0] > 5.0
    assert behind.any() and not sees[behind, 0].any() and sees[behind, 1].all()
    assert all(np.linalg.norm(cells[:, :2] - p, axis=1).min() >= 1.0 for p in ([5.0, 3.0], [7.5, 0.5]))
    only0 = floor_grid(MapSettings(scene=str(tiny_hall_2ris), spacing=2.0, ris=("ris0",)))
    assert only0.names == ("ris0",) and np.array_equal(only0.floor, g.floor)


@pytest.mark.slow
def test_a_two_ris_map_fuses_serves_and_counts_its_coverage(tiny_hall_2ris, tmp_path):
    from risloc_rt.studies.floor_map import COVERED_PD, MapSettings, multi_ris_peb, run_map
    from risloc_rt.authoring.spec import load_spec

    settings = MapSettings(scene=str(tiny_hall_2ris), spacing=2.0, runs=1, depth=1, samples=10_000, peb_bound=1e-4)
    res = run_map(settings, tmp_path / "m", workers=1, quiet=True)
    saved = json.loads((tmp_path / "m" / "map.json").read_text())
    cells, cov = saved["cells"], saved["coverage"]
    assert saved["ris"] == ["ris0", "ris1"] and len(cells) >= 6
    poses = {r.name: c.pose for r, c in zip(load_spec(tiny_hall_2ris / "spec.toml").ris,
                                            load_spec(tiny_hall_2ris / "spec.toml").ris_configs())}
    both = [c for c in cells if set(c["ris"]) == {"ris0", "ris1"}]
    behind = [c for c in cells if c["x"] > 5.0]
    assert both and behind
    for c in behind:  # ris0 faces -x from x = 5: only ris1 can serve these
        assert set(c["ris"]) == {"ris1"} and c["served_by"] == "ris1" and c["detection_probability"] == 1.0
        assert c["peb"] == c["ris"]["ris1"]["peb"]
    for c in both:
        x = np.array([c["x"], c["y"], c["z"]])
        own = {n: v["peb"] for n, v in c["ris"].items()}
        assert c["peb"] < min(own.values())  # two RISs' information beats either
        # the single-term sum of the Fisher information is the RIS's own bound (same height: exact geometry)
        pts = json.loads((tmp_path / "m" / "points.json").read_text())["points"]
        for n in own:
            crb = next(p["crb"] for p in pts if p["ris"] == n and
                       np.allclose(res.cells[p["cell"]]["x"], c["x"]) and np.allclose(res.cells[p["cell"]]["y"], c["y"]))
            assert multi_ris_peb([(poses[n], crb)], x) == pytest.approx(own[n], rel=1e-4)
        assert c["served_by"] == min(own, key=own.get)  # both detected: the smaller own PEB serves
        assert c["detection_probability"] == 1.0 and c["rmse_position"] < 0.05  # 50-70 dB SNR, a few metres
    # the coverage is what map.json's cells recount
    assert cov["floor_cells"] == len(cells) + len(cov["unseen"])
    covered = sum(1 for c in cells if c["detection_probability"] >= COVERED_PD and c["peb"] < 1e-4)
    assert 0 < covered < len(cells)  # the 0.1 mm bound splits this hall
    assert cov["covered"] == covered and cov["share"] == pytest.approx(covered / cov["floor_cells"])
    accurate = sum(1 for c in cells if c["detection_probability"] >= COVERED_PD and c["peb"] < 1e-4
                   and c["rmse_position"] < 1e-4)
    assert cov["accurate"] == accurate and cov["share_accurate"] == pytest.approx(accurate / cov["floor_cells"])
    assert res.coverage == {k: v for k, v in cov.items() if k != "unseen"}
    assert f"coverage {100 * cov['share']:.1f} %" in res.describe()
    assert (tmp_path / "m" / "map.png").stat().st_size > 10_000
    # two workers: the same points, noise streams and fused cells (the rows depend on (point, run) only)
    two = run_map(settings, tmp_path / "two", workers=2, quiet=True)
    assert two.cells == res.cells and two.coverage == res.coverage


# --- bad input: one line ----------------------------------------------------------------------------


@pytest.mark.parametrize("args, match", [
    (["--peb-bound", "0"], "--peb-bound=0.0 must be a finite number > 0 [m]"),
    (["--peb-bound", "nan"], "--peb-bound=nan must be a finite number > 0 [m]"),
    (["--ris", "ris7"], "--ris='ris7': the scene 'paper_hall' has no such RIS; it has ris0"),
    (["--ris", "ris0", "--ris", "ris0"], "--ris names a RIS twice"),
])
def test_map_bad_ris_or_bound_is_one_line_exit_2(capsys, tmp_path, args, match):
    from risloc_rt.cli import main

    status = main(["study", "map", "paper_hall", *args, "--runs", "1", "--out", str(tmp_path / "m"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and match in err and err.count("\n") == 1, err
    assert not (tmp_path / "m").exists()


def test_a_return_from_beyond_the_unambiguous_range_is_found_folded_by_its_power():
    """The loop-back falls as d⁻⁴: a radar 26 m from the RIS, seen at 26 - R_max, arrives far weaker than the
    link budget predicts at the folded distance (risloc locate's check, applied to the map's runs)."""
    from risloc_rt.hall import hall_scenario
    from risloc_rt.model.power_check import expected_loopback_snr_db
    from risloc_rt.studies.floor_map import folded_return

    base = hall_scenario("paper_hall", ue_position=[6.0, 9.0, 1.2]).base
    pose = base.ris.pose
    span = base.radar.max_range
    aod = np.array([0.2, 0.0])
    folded = 26.0 - span  # 4.2 m: where the DSP puts a radar 26 m away
    x = pose.point_at(aod, folded)
    row = {"detected": True, "distance": folded, "aod_az": aod[0], "x": x[0], "y": x[1], "z": x[2]}
    capture = type("C", (), {"radar": base.radar, "ris": base.ris, "sweep": base.sweep})
    energy = float(np.sum(base.ris.beam_pattern().for_wavelength(base.radar.wavelength)
                          .amplitude(aod, base.sweep.angles) ** 2))

    def peak(d):  # the post-integration peak SNR of a return from distance d [dB]
        return expected_loopback_snr_db(capture, d, aod) - 10 * np.log10(energy)

    assert peak(folded) - peak(26.0) > 20  # (26 / 4.2)⁴: 32 dB
    flag = folded_return(row, base, pose, peak(26.0))
    assert flag is not None and flag.code == "aliased" and "1·R_max" in flag.message
    assert folded_return(row, base, pose, peak(folded)) is None  # the power it should have there: a true fix


def test_a_fix_before_the_loop_back_delay_is_not_fused():
    """A return folded to just below zero distance (seen in paper_hall_2ris beyond ris1's range) cannot be a
    RisFix: the other RIS's fix is the position."""
    from risloc_rt.studies.floor_map import cell_run_position

    x = np.array([6.0, 5.0, 1.2])
    a, b = RisPose.facing([0.0, 5.0, 1.2], x), RisPose.facing([6.0, 0.0, 1.2], x)
    good = {"detected": True, "distance": 6.0, "aod_az": 0.0, "std_distance": 1e-3, "std_aod_az": 1e-3,
            "x": 6.0, "y": 5.0, "z": 1.2, "position_error": 2e-3, "flags": ""}
    before = {**good, "distance": -0.25, "x": 6.0, "y": -0.25, "position_error": 5.25}
    assert cell_run_position([("a", a, good), ("b", b, before)], x, 1.2) == (2e-3, ("a",), (), ())
    assert cell_run_position([("b", b, before)], x, 1.2) is None  # alone it is no position either
