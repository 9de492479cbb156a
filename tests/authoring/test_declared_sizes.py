"""Issue 19 item 3: sizes a hall spec declares (a radar grid, a RIS's rows x columns, a pillar's segments, the
cells doors and windows cut a wall into) are checked against $RISLOC_MEMORY_LIMIT before anything of that size
is made; the geometry checks' ray tests work in blocks whatever the scene's size."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dsp.budget import BudgetError
from risloc_rt.authoring import geometry, load_spec, loads_spec
from risloc_rt.authoring.build import build_scene

ROOT = Path(__file__).resolve().parents[2]
PAPER_SPEC = (ROOT / "scenes" / "paper_hall" / "spec.toml").read_text()
PAPER_POSITIONS = "positions = [[6.0, 9.0, 1.2], [6.888693893467439, 4.205036835083882, 1.2]]"
PAPER_RIS = 'rows = 16\ncolumns = 4\nspacing = "half-wavelength"'
#: Peak RSS of a child refused by a size check may exceed the limit by no more than this [bytes].
RSS_MARGIN = 200 << 20


def grid_spec(spacing: float) -> str:
    return PAPER_SPEC.replace(PAPER_POSITIONS, f"grid = {{spacing = {spacing}, height = 1.2}}")


def ris_spec(rows: int, columns: int) -> str:
    return PAPER_SPEC.replace(PAPER_RIS, f"rows = {rows}\ncolumns = {columns}\nspacing = 1e-6")


def pillar_spec(segments: int) -> str:
    pillar = f'[[objects]]\nkind = "pillar"\ncenter = [15.0, 15.0]\nradius = 0.3\nsegments = {segments}\n' \
             'material = "concrete"\n\n'
    return PAPER_SPEC.replace("[[ris]]", pillar + "[[ris]]", 1)


def windows_spec(count: int) -> str:
    """``count`` small windows on wall_0 in a diagonal, each with its own offset and sill: (2n+1)² cells."""
    windows = "".join(f'[[objects]]\nkind = "window"\nwall = 0\nsize = [0.04, 0.01]\noffset = {0.5 + i * 0.08:.4f}\n'
                      f"sill = {0.3 + i * 0.015:.4f}\n\n" for i in range(count))
    return PAPER_SPEC.replace("[[ris]]", windows + "[[ris]]", 1)


@pytest.fixture
def limit_1g(monkeypatch):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")


def _write(tmp_path: Path, text: str) -> Path:
    folder = tmp_path / "hall"
    folder.mkdir(exist_ok=True)
    (folder / "spec.toml").write_text(text)
    return folder / "spec.toml"


def test_radar_grid_is_counted_before_it_is_made(tmp_path, limit_1g):
    # spacing 0.004 m over paper_hall made 3.1e7 positions: 7.2 GB of RSS and no end in sight.
    path = _write(tmp_path, grid_spec(0.004))
    with pytest.raises(BudgetError, match=r"spec\.toml: radar\.grid\.spacing = 0\.004 m over 29 m x 17 m makes "
                                          r"7,251 x 4,251 = 30,824,001 radar positions, which needs about 11\.9 GiB"
                                          r".*raise radar\.grid\.spacing \(1 m gives 540 positions here\)"):
        load_spec(path)
    # A spacing so small that the count overflows a float is a count, not an OverflowError.
    with pytest.raises(BudgetError, match=r"radar\.grid\.spacing = 1e-300 m"):
        loads_spec(grid_spec(1e-300))
    # A usable grid is unchanged: x-major points 1 m apart, 0.5 m from the walls.
    positions = loads_spec(grid_spec(1.0)).radar_positions()
    assert positions.shape == (540, 3)
    np.testing.assert_allclose(positions[:2], [[0.5, 0.5, 1.2], [0.5, 1.5, 1.2]])


def test_ris_elements_are_checked_at_parse_and_against_the_sweep(tmp_path, limit_1g):
    with pytest.raises(BudgetError, match=r"ris\[0\]\.rows = 6,000 x ris\[0\]\.columns = 6,000 \(36,000,000 elements\)"):
        load_spec(_write(tmp_path, ris_spec(6000, 6000)))
    # 1500 x 1500 fits one beam (the parse check) but not the 61 beams every simulation of the hall sweeps.
    from risloc_rt.hall.scenario import hall_scenario

    path = _write(tmp_path, ris_spec(1500, 1500))
    build_scene(load_spec(path), path.parent)
    with pytest.raises(BudgetError, match=r"spec\.toml: ris\[0\] \(rows, columns\): num_rows = 1,500 x num_columns = "
                                          r"1,500 \(2,250,000 elements\) x 61 beams needs about 4\.31 GiB"):
        hall_scenario(path.parent)


def test_pillar_segments_are_checked(limit_1g):
    # segments = 1e8 reached 22.9 GB of RSS in 'risloc scene check'.
    with pytest.raises(BudgetError, match=r"objects\[0\]\.segments = 100,000,000 \(a round pillar of 400,000,000 "
                                          r"triangles\) needs about 381 GiB"):
        loads_spec(pillar_spec(100_000_000))
    assert loads_spec(pillar_spec(128)).objects[0].segments == 128


def test_wall_cells_cut_by_doors_and_windows_are_checked(tmp_path, limit_1g):
    spec = loads_spec(windows_spec(340))  # 681 x 681 cells on wall_0
    with pytest.raises(BudgetError, match=r"wall_0: 340 doors/windows cut it into 681 x 681 = 463,761 cells"):
        build_scene(spec, tmp_path / "out")
    assert not (tmp_path / "out" / "scene.xml").exists()
    build_scene(loads_spec(windows_spec(3)), tmp_path / "few")  # a few windows build as before


def test_ray_hits_in_blocks_equal_one_block(monkeypatch):
    geo = geometry.load_geometry(ROOT / "scenes" / "pillars_hall" / "scene.xml")
    rng = np.random.default_rng(0)
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = geo.bounds.mean(axis=0)
    whole = geo.ray_hits(origin, d)
    monkeypatch.setattr(geometry, "RAY_BLOCK", 40 * 7)  # blocks of 7 triangles
    blocks = geo.ray_hits(origin, d)
    np.testing.assert_array_equal(blocks[0], whole[0])
    np.testing.assert_array_equal(blocks[1], whole[1])
    assert np.isfinite(whole[0]).all()  # inside a closed hall every ray hits


@pytest.mark.slow
def test_hostile_specs_stay_within_the_limit_in_a_child(tmp_path):
    """``risloc scene check`` on the worst specs, in a child under RISLOC_MEMORY_LIMIT=1G: exit 2, one line on
    stderr naming the key, and a peak RSS below the limit + 200 MB."""
    cases = {"radar.grid.spacing = 0.004": grid_spec(0.004), "objects[0].segments = 100,000,000": pillar_spec(10**8),
             "ris[0].rows = 6,000": ris_spec(6000, 6000)}
    limit = 1 << 30
    probe = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
             "print(r.returncode); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024); "
             "sys.stderr.write(r.stderr)")
    for i, (key, text) in enumerate(cases.items()):
        (tmp_path / str(i)).mkdir()
        path = _write(tmp_path / str(i), text)
        done = subprocess.run([sys.executable, "-c", probe, sys.executable, "-m", "risloc_rt", "scene", "check",
                               str(path)], capture_output=True, text=True, timeout=300,
                              env={**os.environ, "RISLOC_MEMORY_LIMIT": "1G"})
        status, peak = (int(v) for v in done.stdout.split())
        lines = done.stderr.strip().splitlines()
        assert status == 2, (key, done.stderr)
        assert len(lines) == 1 and key in lines[0] and "more than the limit 1 GiB" in lines[0], lines
        assert peak < limit + RSS_MARGIN, f"{key}: peak RSS {peak / 2**20:.0f} MiB"
