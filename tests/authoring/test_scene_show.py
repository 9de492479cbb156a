"""``risloc scene show``: the plan/elevation PNG of a hall, optionally with traced paths.

Oracles: the PNG exists and is a real figure; the views cover the footprint and the height; what
was drawn (walls, objects, RIS, radars, path polylines) matches the spec and the trace item by item.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from risloc_rt.authoring import load_spec
from risloc_rt.cli import main as risloc_main
from risloc_rt.authoring.show import path_polylines, show_scene
from risloc_rt.hall.raytrace.result import TraceResult
from risloc_rt.hall.traced import TracedPaths

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(d.name for d in (REPO / "scenes").iterdir() if (d / "spec.toml").is_file())
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def traced(tx, rx, bounces: list[list[list[float]]]) -> TracedPaths:
    """Paths tx -> bounce points -> rx (depth 2, NaN-padded), with placeholder gains."""
    n = len(bounces)
    verts = np.full((n, 2, 3), np.nan)
    inter = np.zeros((n, 2), dtype=int)
    objs = np.full((n, 2), -1)
    for i, pts in enumerate(bounces):
        if pts:
            verts[i, :len(pts)] = pts
            inter[i, :len(pts)] = 1
            objs[i, :len(pts)] = 0
    return TracedPaths(tx_position=np.array(tx, float), rx_position=np.array(rx, float), frequency=60e9,
                       delay=np.arange(1, n + 1) * 1e-8, amplitude=np.ones(n, complex), departure=np.tile([1.0, 0, 0], (n, 1)),
                       arrival=np.tile([1.0, 0, 0], (n, 1)), delay_rate=np.zeros(n), interactions=inter, objects=objs,
                       vertices=verts, object_names=("floor",))


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_plan_covers_the_hall_and_shows_everything(tmp_path, name):
    spec = load_spec(REPO / "scenes" / name / "spec.toml")
    fig = show_scene(REPO / "scenes" / name, tmp_path / "plan.png")
    data = fig.path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 50_000  # a drawn hall, not an empty canvas (~10 kB)
    fp = spec.footprint_array
    (x0, x1), (y0, y1) = fig.plan_limits
    assert x0 < fp[:, 0].min() and x1 > fp[:, 0].max() and y0 < fp[:, 1].min() and y1 > fp[:, 1].max()
    (ex0, ex1), (z0, z1) = fig.elevation_limits
    assert (ex0, ex1) == (x0, x1) and z0 < 0.0 and z1 > spec.height
    assert fig.counts == {"walls": len(fp), "objects": len(spec.objects), "meshes": len(spec.meshes),
                          "ris": len(spec.ris), "radars": len(spec.radar_positions()), "monostatic_paths": 0,
                          "ris_legs": 0}
    assert fig.radar_index is None


def test_trace_result_paths_are_drawn_one_polyline_each(tmp_path):
    spec = load_spec(REPO / "scenes" / "paper_hall" / "spec.toml")
    radar, ris = spec.radar_positions()[1], np.array(spec.ris[0].position)
    mono = traced(radar, radar, [[[radar[0], radar[1], 0.0]], [[radar[0], 18.0, 1.2], [radar[0], 0.0, 1.2]]])
    leg = traced(radar, ris, [[], [[12.0, 6.0, 0.0]], [[12.0, 6.0, 7.0]]])
    result = TraceResult(monostatic=mono, legs=(leg,), scene_hash="x", cache_hit=False, timing={})
    fig = show_scene(REPO / "scenes" / "paper_hall", tmp_path / "paths.png", paths=result)
    assert (fig.counts["monostatic_paths"], fig.counts["ris_legs"]) == (2, 3)
    assert fig.radar_index == 1  # the spec position the trace starts from
    # A HallPaths (anything with .trace) works the same; radar_index overrides the highlight.
    fig2 = show_scene(REPO / "scenes" / "paper_hall", tmp_path / "p2.png", paths=SimpleNamespace(trace=result),
                      radar_index=0)
    assert fig2.radar_index == 0 and fig2.counts == fig.counts


def test_polylines_of_a_real_trace_are_as_long_as_the_paths():
    pytest.importorskip("sionna.rt")
    from dsp import SPEED_OF_LIGHT
    from risloc_rt.hall.scenario import hall_paths, hall_scenario
    from risloc_rt.hall.raytrace.tracer import TraceSettings

    hs = hall_scenario("pillars_hall", radar_index=1, trace=TraceSettings(max_depth=2, samples_per_src=20_000))
    trace = hall_paths(hs).trace
    for paths in (trace.monostatic, trace.legs[0]):
        lines = path_polylines(paths)
        assert len(lines) == len(paths) > 5
        np.testing.assert_allclose(lines[0][0], paths.tx_position)
        lengths = np.array([np.linalg.norm(np.diff(line, axis=0), axis=1).sum() for line in lines])
        # Drawn through the traced interaction points, each polyline is as long as its delay says:
        # c·τ (round trip for the monostatic paths), to 1 mm (float32 vertices and delays).
        np.testing.assert_allclose(lengths, paths.delay * SPEED_OF_LIGHT, atol=1e-3)
        ends = np.array([line[-1] for line in lines])
        np.testing.assert_allclose(ends, np.broadcast_to(paths.rx_position, ends.shape))


def test_imported_mesh_is_drawn(tmp_path):
    box = trimesh.creation.box(extents=[1000.0, 500.0, 2000.0])
    box.apply_translation([500.0, 250.0, 1000.0])
    box.export(tmp_path / "cabinet_mm.stl")
    (tmp_path / "spec.toml").write_text(
        '[scene]\nname = "m"\n[hall]\nsize = [10.0, 6.0]\nheight = 3.0\n[hall.materials]\nwalls = "concrete"\n'
        'floor = "concrete"\nceiling = "concrete"\n[[meshes]]\nfile = "cabinet_mm.stl"\nscale = 0.001\n'
        'translate = [2.0, 2.0, 0.0]\nmaterial = "wood"\n')
    fig = show_scene(tmp_path / "spec.toml", tmp_path / "m.png")
    assert fig.counts["meshes"] == 1 and fig.counts["ris"] == 0 and fig.counts["radars"] == 0
    assert fig.path.stat().st_size > 20_000


@pytest.mark.parametrize(("kw", "error", "match"), [
    (dict(radar_index=5), ValueError, r"radar_index=5 is out of range: the spec has 2 radar position\(s\)"),
    (dict(paths="not a trace"), TypeError, r"paths must be a HallPaths or a TraceResult, got str"),
])
def test_bad_arguments(tmp_path, kw, error, match):
    with pytest.raises(error, match=match):
        show_scene(REPO / "scenes" / "paper_hall", tmp_path / "x.png", **kw)


def test_missing_spec(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        show_scene(tmp_path / "none.toml", tmp_path / "x.png")


def test_cli_show_traces_one_radar_position(tmp_path, capsys):
    pytest.importorskip("sionna.rt")
    png = tmp_path / "pillars.png"
    assert risloc_main(["scene", "show", str(REPO / "scenes" / "pillars_hall" / "spec.toml"), "-o", str(png),
                        "--paths", "1", "--depth", "1", "--samples", "5000"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"wrote {png} with ") and "of radar position 1" in out
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert risloc_main(["scene", "show", "pillars_hall", "-o", str(png), "--paths", "7"]) == 2
    assert "radar_index=7 is out of range" in capsys.readouterr().err
