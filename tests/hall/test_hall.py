"""Ray-traced halls end to end: traced legs -> RIS loop-back and panel paths -> beat cube -> DSP.

These tests run sionna-rt on the CPU (LLVM backend); each trace of these small scenes takes
well under a second once the kernels are compiled.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from dsp import scan_beams, localize
from risloc_rt.hall.antenna import RadarAntenna
from risloc_rt.cli import main
from risloc_rt.hall.scenario import HallScenario, hall_paths, hall_scenario
from risloc_rt.model.link_budget import one_way_free_space_gain
from risloc_rt.hall.path_table import load_path_set
from risloc_rt.hall.raytrace.cache import TraceCache
from risloc_rt.hall.raytrace.tracer import TraceSettings
from risloc_rt.model.scenario import Scenario, paper_scenario
from risloc_rt.model.simulate import simulate

DISTANCE = 13.38
HEIGHT = 1.0


def _write_scene(folder: Path, walls: list[str], write_wall) -> Path:
    """A scene with only the given walls of a 30 x 18 x 7 m box (none: free space), written by ``write_wall``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "meshes").mkdir(exist_ok=True)
    shapes = []
    for name in walls:
        write_wall(folder / "meshes" / f"{name}.ply", name, size=(30.0, 18.0, 7.0))
        shapes.append(f'  <shape type="ply" id="mesh-{name}"><string name="filename" value="meshes/{name}.ply"/>'
                      f'<boolean name="face_normals" value="true"/><ref id="mat-concrete" name="bsdf"/></shape>')
    material = ('  <bsdf type="itu-radio-material" id="mat-concrete"><string name="type" value="concrete"/>'
                '<float name="thickness" value="0.2"/></bsdf>')
    xml = folder / "scene.xml"
    xml.write_text('<scene version="2.1.0">\n' + (material + "\n" if walls else "") + "\n".join(shapes) + "\n</scene>\n")
    return xml


def _scenario_in(xml: Path, *, mode: str = "relay") -> HallScenario:
    """The paper's geometry (UE and RIS 13.38 m apart along +x at 1 m height) inside ``xml``."""
    ue = np.array([6.0, 9.0, HEIGHT])
    base = paper_scenario("broadside", mode=mode)
    ris_pos = ue + np.array([DISTANCE, 0.0, 0.0])
    from dsp import RisPose
    from dataclasses import replace

    ris = replace(base.ris, pose=RisPose.facing(ris_pos, ue)).with_rx_toward(ue)
    scen = Scenario(radar=base.radar, ris=ris, sweep=base.sweep, processing=base.processing, ue_position=ue,
                    name="test")
    return HallScenario(base=scen, scene_xml=xml, antenna=RadarAntenna.isotropic())


@pytest.fixture(scope="module")
def free_space(tmp_path_factory, box_hall) -> HallScenario:
    return _scenario_in(_write_scene(tmp_path_factory.mktemp("free"), [], box_hall.write_wall))


@pytest.mark.parametrize("mode", ["relay", "reflective"])
def test_traced_free_space_loopback_is_the_paper_formula(tmp_path, mode, box_hall):
    hs = _scenario_in(_write_scene(tmp_path, [], box_hall.write_wall), mode=mode)
    result = hall_paths(hs)
    assert result.counts == {"hall": 0, "ris_loopback": 1, "ris_structure": 1}
    loop = result.candidates.via_ris
    radar, ris = hs.base.radar, hs.base.ris
    paper = radar.tx_power * radar.antenna_gain * one_way_free_space_gain(DISTANCE, radar.wavelength) ** 2 * ris.amplification
    # The bound: the traced direct leg pair reproduces |γ0|² to 0.01 dB.
    assert abs(10 * np.log10(result.candidates.power[loop][0] / paper)) < 0.01
    # Delay 2d/c + τ_RB to 1 mm of path (float32 delays from the tracer).
    assert abs(result.candidates.delay[loop][0] - (2 * DISTANCE / C + ris.loopback_delay)) * C < 1e-3


def test_a_wall_adds_leg_pairs_at_the_image_source_delays(tmp_path, box_hall):
    hs = _scenario_in(_write_scene(tmp_path, ["floor"], box_hall.write_wall))
    result = hall_paths(hs)
    ue, ris = hs.base.ue_position, hs.base.ris.pose.position
    image = ue * np.array([1, 1, -1])  # the radar mirrored in the floor z = 0
    d_los, d_floor = np.linalg.norm(ris - ue), np.linalg.norm(ris - image)
    expected = np.sort([2 * d_los, d_los + d_floor, d_los + d_floor, 2 * d_floor])
    loop = result.candidates.via_ris
    got = np.sort(result.candidates.delay[loop] - hs.base.ris.loopback_delay) * C
    np.testing.assert_allclose(got, expected, atol=1e-3)  # 1 mm of path length
    # The monostatic floor echo straight below the radar: 2·height.
    hall = np.array([lab.startswith("hall") for lab in result.candidates.labels])
    np.testing.assert_allclose(result.candidates.delay[hall] * C, [2 * HEIGHT], atol=1e-3)


@pytest.fixture(scope="module")
def paper_hall_runs():
    runs = {}
    for index in (0, 1):
        hs = hall_scenario("paper_hall", radar_index=index)
        traced = hall_paths(hs)
        capture = simulate(hs.base, rng=np.random.default_rng(100 + index), paths=traced.paths)
        scan = scan_beams(capture.cube, capture.sweep, capture.radar, capture.processing)
        loc = localize(scan, radar=capture.radar, pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay)
        runs[index] = (hs, traced, capture, loc)
    return runs


@pytest.mark.parametrize("index", [0, 1])
def test_default_hall_localizes_within_the_stated_bound(paper_hall_runs, index):
    hs, traced, capture, loc = paper_hall_runs[index]
    truth = hs.base.truth
    # The sweep peaks at the true AoD (both radar positions are on the 1.5° grid).
    np.testing.assert_allclose(loc.aod, truth.aod, atol=1e-9)
    # Bound: half a delay-grid step (0.91 cm) of quantisation plus at most one more grid step of
    # pull from noise and multipath (the nearest traced loop-back pair, out LOS / back via the
    # floor, is 11 cm away, three range resolutions): 2 cm.
    step = capture.radar.max_range / capture.processing.n_dft
    assert abs(loc.distance - truth.distance) < step / 2 + step
    assert np.linalg.norm(loc.position - truth.ue_position) < 0.02


def test_noiseless_sweep_over_the_hall_peaks_at_the_true_aod(paper_hall_runs):
    hs, traced, _, _ = paper_hall_runs[1]
    capture = simulate(hs.base, rng=np.random.default_rng(0), paths=traced.paths, noise=False)
    scan = scan_beams(capture.cube, capture.sweep, capture.radar, capture.processing)
    true_beam = hs.base.sweep.index_of(hs.base.truth.aod, atol=1e-9)
    assert true_beam is not None and scan.best_beam == true_beam


def test_the_panel_does_not_hide_the_wall_behind_the_ris(paper_hall_runs):
    hs, traced, _, _ = paper_hall_runs[0]
    mono = traced.trace.monostatic
    labels = [mono.describe(i) for i in range(len(mono))]
    # wall_1 (x = 30 m) stands 10.6 m behind the RIS on the radar's line of sight: its echo at
    # 2·24 m must be traced (a mirror panel would have shadowed it).
    behind = [i for i, lab in enumerate(labels) if lab == "specular:wall_1"]
    assert len(behind) == 1
    assert mono.delay[behind[0]] * C == pytest.approx(2 * (30.0 - hs.base.ue_position[0]), abs=1e-3)


def test_hall_paths_reuse_the_trace_cache(tmp_path):
    cache = TraceCache(tmp_path / "cache")
    hs = hall_scenario("paper_hall", trace=TraceSettings(max_depth=1, samples_per_src=10_000))
    first = hall_paths(hs, cache=cache)
    second = hall_paths(hs, cache=cache)
    assert not first.trace.cache_hit and second.trace.cache_hit
    np.testing.assert_array_equal(first.paths.gain, second.paths.gain)
    moved = hall_scenario("paper_hall", trace=hs.trace, ue_position=hs.base.ue_position + [0.5, 0.0, 0.0])
    assert not hall_paths(moved, cache=cache).trace.cache_hit


@pytest.mark.parametrize("position, message", [
    ([-2.0, 9.0, 1.2], "outside"),
    ([0.01, 9.0, 1.2], "wall"),
    ([6.0, 9.0, 9.0], "outside"),
])
def test_radar_outside_the_hall_or_in_a_wall_is_refused(position, message):
    with pytest.raises(ValueError, match=message):
        hall_scenario("paper_hall", ue_position=position)


def test_unknown_scene_names_the_available_ones():
    with pytest.raises(FileNotFoundError, match="paper_hall"):
        hall_scenario("no_such_hall")


def test_cli_trace_prints_saves_and_plots(tmp_path, capsys):
    out = tmp_path / "paths.npz"
    png = tmp_path / "profile.png"
    assert main(["trace", "paper_hall", "--ue", "6,9,1.2", "--depth", "2", "--samples", "20000",
                 "-o", str(out), "--plot", str(png), "--no-cache"]) == 0
    text = capsys.readouterr().out
    assert "ris_loopback: out LOS | back LOS" in text and "kept" in text
    paths, kept, meta = load_path_set(out)
    assert kept.sum() >= 3 and len(paths) == len(kept)
    assert meta["scene_hash"] and png.stat().st_size > 10_000


def test_cli_trace_bad_position_is_a_clear_error(capsys):
    assert main(["trace", "paper_hall", "--ue", "6,9"]) == 2
    assert "three" in capsys.readouterr().err
