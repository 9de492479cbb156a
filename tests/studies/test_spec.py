"""Study specs: the grid, the parameters' checks, study files, the key that guards a folder."""

from __future__ import annotations

import pytest

from risloc_rt.studies import StudySpec, load_study_file, spec_from_options
from risloc_rt.studies.params import complete_point, parse_values


def test_the_grid_is_the_cartesian_product_with_every_parameter_filled_in():
    spec = StudySpec(name="g", runs=2, fixed={"estimator": "refined"},
                     vary=(("tx_power_dbm", (0, 10)), ("ris_size", ("8x2", "16x4", "32x8"))))
    pts = spec.points()
    assert len(pts) == 6
    assert [(p["tx_power_dbm"], p["ris_size"]) for p in pts[:3]] == [(0.0, "8x2"), (0.0, "16x4"), (0.0, "32x8")]
    assert all(p["estimator"] == "refined" and p["distance"] == 13.38 for p in pts)  # fixed and default
    assert spec.x_name == "tx_power_dbm"


def test_ranges_and_types():
    assert parse_values("tx_power_dbm", "0:20:5") == [0.0, 5.0, 10.0, 15.0, 20.0]
    assert parse_values("estimator", "paper,refined") == ["paper", "refined"]
    assert complete_point({"structure": "false"})["structure"] is False


@pytest.mark.parametrize("kwargs, match", [
    ({"vary": ["foo=1,2"]}, "unknown parameter 'foo'"),
    ({"vary": ["tx_power_dbm="]}, "has no values"),
    ({"vary": []}, "nothing to vary"),
    ({"vary": ["tx_power_dbm=a"]}, "is not a float"),
    ({"vary": ["sweep_step_deg=0,1"]}, r"sweep_step_deg=0.0 must be a finite number > 0 \[deg\]"),
    ({"vary": ["estimator=best"]}, "estimator='best' must be one of paper, refined"),
    ({"vary": ["aod_deg=10,90"]}, r"aod_deg=90.0 must lie in \(-90, 90\) \[deg\]"),
    ({"vary": ["aod_spread_deg=0,90"]}, r"aod_spread_deg=90.0 must lie in \[0, 90\) \[deg\]"),
    ({"vary": ["pfa=0.5,1"]}, r"pfa=1.0 must lie in \(0, 1\)$"),
    ({"vary": ["num_chirps=0"]}, "num_chirps=0 must be an integer >= 1"),
    ({"vary": ["radar_index=-1"]}, "radar_index=-1 must be an integer >= 0"),
    ({"vary": ["ris_size=16by4"]}, "ROWSxCOLUMNS"),
    ({"vary": ["tx_power_dbm=1,1"]}, "lists a value twice"),
    ({"vary": ["tx_power_dbm=1", "tx_power_dbm=2"]}, "varied twice"),
    ({"vary": ["tx_power_dbm=1"], "fixed": ["tx_power_dbm=2"]}, "both fixed and varied"),
    ({"vary": ["tx_power_dbm=1"], "fixed": ["scene=paper_hall", "distance=5"]}, "cannot be set for a hall"),
    ({"vary": ["tx_power_dbm=0:1e6:0.01"]}, "more than 10000"),
    ({"vary": ["tx_power_dbm=1"], "runs": 0}, "runs=0 must be an integer >= 1"),
])
def test_bad_grids_are_refused_naming_the_problem(kwargs, match):
    args = {"fixed": None, "runs": 3, "seed": 0, **kwargs}
    with pytest.raises(ValueError, match=match):
        spec_from_options(**args)


def test_study_file_and_key(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "t"\nruns = 5\nseed = 3\n[fixed]\naod_deg = 10.3\n[vary]\ntx_power_dbm = [0, 10]\n')
    spec = load_study_file(f)
    assert (spec.name, spec.runs, spec.seed, spec.fixed) == ("t", 5, 3, {"aod_deg": 10.3})
    assert load_study_file(f, runs=50).key == spec.key  # more runs extend the same study
    assert load_study_file(f, seed=4).key != spec.key
    f.write_text('[study]\nname = "t"\n[vary]\ntx_power = [0]\n')
    with pytest.raises(ValueError, match="unknown parameter 'tx_power' in \\[vary\\]"):
        load_study_file(f)
    f.write_text('[study]\nname = "t"\n[vary]\ntx_power_dbm = []\n')
    with pytest.raises(ValueError, match="grid of tx_power_dbm is empty"):
        load_study_file(f)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_study_file(tmp_path / "none.toml")


def test_the_closed_ends_of_a_range_are_accepted_and_kinds_are_kept():
    """[0, 90) takes 0, radar_index >= 0 takes 0; an int parameter stays an int (it enters the study key)."""
    point = complete_point({"aod_spread_deg": "0", "radar_index": "0", "num_chirps": "16", "pfa": "0.5"})
    assert point["aod_spread_deg"] == 0.0 and point["radar_index"] == 0 and point["pfa"] == 0.5
    assert type(point["num_chirps"]) is int and point["num_chirps"] == 16
