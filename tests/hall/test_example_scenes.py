"""Every example scene in ``scenes/``: spec -> build -> load in sionna-rt -> trace -> localize.

For each radar position of each example, the ray-traced hall (depth 2, 20 000 rays per source:
enough for the specular paths of these halls up to depth 2; the default depth-3 trace gives the same
AoD and distance) feeds the beat model, and the DSP must find the true on-grid AoD and the position.

Position bound, 3 cm: the delay grid step is c/(2 S T_s)/N_DFT = 1.82 cm, so quantisation alone
errs by up to 0.91 cm; noise and the nearest multipath loop-back pairs (the floor bounce, ≥ 10 cm
longer, three range resolutions away) may pull the peak by about one more grid step: 2.7 cm.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from dsp import localize, scan_beams
from risloc_rt.authoring import load_spec
from risloc_rt.authoring.build import build_scene, content_hash
from risloc_rt.hall.scenario import hall_paths, hall_scenario
from risloc_rt.hall.pruning import AliasWarning
from risloc_rt.hall.raytrace.tracer import TraceSettings
from risloc_rt.model.simulate import simulate

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes"
EXAMPLES = sorted(d.name for d in SCENES.iterdir() if (d / "spec.toml").is_file())
TRACE = TraceSettings(max_depth=2, samples_per_src=20_000)
#: Position error bound [m] (module docstring).
POSITION_BOUND = 0.03

RUNS = [(name, i) for name in EXAMPLES for i in range(len(load_spec(SCENES / name / "spec.toml").radar_positions()))]


def tree_bytes(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_issue_examples_are_there():
    assert {"paper_hall", "pillars_hall", "l_hall"} <= set(EXAMPLES)
    spec = load_spec(SCENES / "pillars_hall" / "spec.toml")
    kinds = [o.kind for o in spec.objects]
    assert kinds.count("pillar") >= 2 and kinds.count("shelf") == 2
    assert {o.material.itu for o in spec.objects if o.kind == "shelf"} == {"metal"}
    # The L: six walls, one reflex (inner) corner.
    fp = load_spec(SCENES / "l_hall" / "spec.toml").footprint_array
    e0, e1 = np.roll(fp, -1, axis=0) - fp, np.roll(fp, -2, axis=0) - np.roll(fp, -1, axis=0)
    assert len(fp) == 6 and np.count_nonzero(e0[:, 0] * e1[:, 1] - e0[:, 1] * e1[:, 0] < 0) == 1


@pytest.mark.parametrize("name", EXAMPLES)
def test_committed_scene_is_what_its_spec_builds(tmp_path, name):
    built = build_scene(SCENES / name / "spec.toml", tmp_path)
    assert tree_bytes(tmp_path) == tree_bytes(SCENES / name), f"scenes/{name} is stale: run risloc scene build"
    assert content_hash(SCENES / name / "scene.xml") == built.content_hash
    again = build_scene(SCENES / name / "spec.toml", tmp_path / "again")
    assert again.content_hash == built.content_hash


def test_moving_a_pillar_changes_the_hash_and_moving_a_radar_does_not(tmp_path):
    text = (SCENES / "pillars_hall" / "spec.toml").read_text()
    base = build_scene(SCENES / "pillars_hall" / "spec.toml", tmp_path / "base").content_hash
    moved = tmp_path / "moved.toml"
    moved.write_text(text.replace("center = [14.0, 3.5]", "center = [14.01, 3.5]", 1))
    radar = tmp_path / "radar.toml"
    radar.write_text(text.replace("positions = [[7.62, 8.0, 1.2]", "positions = [[7.5, 8.0, 1.2]", 1))
    assert moved.read_text() != text and radar.read_text() != text
    assert build_scene(moved, tmp_path / "moved").content_hash != base
    assert build_scene(radar, tmp_path / "radar").content_hash == base  # radars are not in the traced scene


@pytest.mark.parametrize("name", EXAMPLES)
def test_sionna_loads_every_object_with_its_material(name):
    rt = pytest.importorskip("sionna.rt")
    spec = load_spec(SCENES / name / "spec.toml")
    scene = rt.load_scene(str(SCENES / name / "scene.xml"), merge_shapes=False)
    scene.frequency = spec.frequency  # raises if a material is undefined there
    assert sorted(scene.objects) == sorted(spec.object_names)
    for obj in spec.objects:
        assert scene.objects[obj.name].radio_material.name == obj.material.name


@pytest.fixture(scope="module")
def localizations():
    """(scenario, localization, capture) per (scene, radar index), traced once."""
    out = {}
    for k, (name, index) in enumerate(RUNS):
        hs = hall_scenario(name, radar_index=index, trace=TRACE)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AliasWarning)  # the far walls of the halls fold back, as intended
            traced = hall_paths(hs)
        capture = simulate(hs.base, rng=np.random.default_rng(1000 + k), paths=traced.paths)
        scan = scan_beams(capture.cube, capture.sweep, capture.radar, capture.processing)
        loc = localize(scan, radar=capture.radar, pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay)
        out[name, index] = (hs, traced, loc, capture)
    return out


@pytest.mark.parametrize(("name", "index"), RUNS, ids=[f"{n}-{i}" for n, i in RUNS])
def test_traced_example_localizes(localizations, name, index):
    hs, traced, loc, capture = localizations[name, index]
    truth = hs.base.truth
    # The RIS loop-back was traced: the direct leg (radar -> RIS line of sight) exists.
    assert "LOS" in [traced.trace.legs[0].describe(i) for i in range(len(traced.trace.legs[0]))]
    # Every example radar position lies on the 1.5° sweep grid, and the sweep peaks there.
    beam = hs.base.sweep.index_of(truth.aod, atol=1e-9)
    assert beam is not None, f"{name}[{index}] is off the sweep grid at {np.rad2deg(truth.aod)}°"
    assert loc.beam_index == beam
    np.testing.assert_allclose(loc.aod, truth.aod, atol=1e-9)
    step = capture.radar.max_range / capture.processing.n_dft
    assert abs(loc.distance - truth.distance) < 1.5 * step
    assert np.linalg.norm(loc.position - truth.ue_position) < POSITION_BOUND
