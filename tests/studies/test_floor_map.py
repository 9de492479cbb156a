"""``risloc study map`` on a tiny box hall (8 m × 6 m × 3 m, built from a spec): a few cells, one run each."""

from __future__ import annotations

import json

import numpy as np
import pytest



@pytest.fixture(scope="module")
def tiny_hall(tmp_path_factory, tiny_hall_spec):
    from risloc_rt.cli import main

    root = tmp_path_factory.mktemp("tiny")
    (root / "spec.toml").write_text(tiny_hall_spec)
    assert main(["scene", "build", str(root / "spec.toml"), "-o", str(root / "built")]) == 0
    return root / "built"


def test_cells_lie_inside_in_front_of_the_ris_and_within_its_sweep(tiny_hall):
    from risloc_rt.studies.floor_map import MapSettings, grid_cells

    _, cells, _ = grid_cells(MapSettings(scene=str(tiny_hall), spacing=1.0, margin=0.5))
    assert np.all((cells[:, 0] >= 0.5) & (cells[:, 0] <= 7.5) & (cells[:, 1] >= 0.5) & (cells[:, 1] <= 5.5))
    assert np.all(cells[:, 0] < 7.0)  # in front of the RIS (it faces -x)
    az = np.degrees(np.arctan2(np.abs(cells[:, 1] - 3.0), 7.0 - cells[:, 0]))
    assert np.all(az <= 45.0 + 1e-9) and np.all(cells[:, 2] == 1.2)
    with pytest.raises(ValueError, match="no grid cell"):
        grid_cells(MapSettings(scene=str(tiny_hall), spacing=1.0, margin=5.0))


@pytest.mark.slow
def test_a_tiny_map_detects_everywhere_and_meets_its_bound(tiny_hall, tmp_path):
    from risloc_rt.studies.floor_map import MapSettings, run_map

    res = run_map(MapSettings(scene=str(tiny_hall), spacing=3.0, runs=1, depth=1, samples=10_000), tmp_path / "m",
                  quiet=True)
    cells = json.loads((tmp_path / "m" / "map.json").read_text())["cells"]
    assert len(cells) == len(res.cells) >= 2
    for c in cells:
        # 50-70 dB post-integration SNR a few metres from the RIS: always detected
        assert c["detection_probability"] == 1.0 and c["peak_snr_db"] > 40
        if c["dominant_flag"] == "none":  # an unflagged estimate is within 6 PEB (a 2-D Gaussian: P < 1e-7)
            assert c["rmse_position"] < 6 * c["peb"], c
    assert (tmp_path / "m" / "map.png").stat().st_size > 10_000 and (tmp_path / "m" / "map.parquet").exists()
    again = run_map(MapSettings(scene=str(tiny_hall), spacing=3.0, runs=1, depth=1, samples=10_000), tmp_path / "m",
                    quiet=True)
    assert again.cells == res.cells  # resumed from the log: nothing recomputed differently
    # and it still names what ran the runs (regression: a rerun with nothing left to run named no device)
    assert len(res.devices) == 1 and again.devices == res.devices
    assert json.loads((tmp_path / "m" / "map.json").read_text())["devices"] == res.devices


@pytest.mark.slow
def test_a_map_on_two_worker_processes_equals_the_one_process_map(tiny_hall, tmp_path):
    from risloc_rt.studies.floor_map import MapSettings, run_map

    settings = MapSettings(scene=str(tiny_hall), spacing=3.0, runs=2, depth=1, samples=10_000, tx_power_dbm=-25.0)
    one = run_map(settings, tmp_path / "one", workers=1, quiet=True)
    two = run_map(settings, tmp_path / "two", workers=2, quiet=True)
    assert len(one.cells) >= 2
    assert two.cells == one.cells  # same noise streams (cell, run) whatever process ran them
    rows = [json.loads(line) for line in (tmp_path / "two" / "runs.jsonl").read_text().splitlines()]
    assert sorted((r["point"], r["run"]) for r in rows) == [(c, r) for c in range(len(one.cells)) for r in range(2)]
