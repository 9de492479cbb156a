"""Trace mechanisms beyond specular reflection: diffuse reflection (with a scattering coefficient),
diffraction and refraction, as TraceSettings, CLI flags and trace-cache keys.

Physics oracles: a diffuse path of a monostatic radar in a box is a single scatter point on a wall
(delay = 2·|radar − point|/c), the specular part loses exactly the factor √(1 − S²) in amplitude
(sionna-rt's energy split), and tracing the same scene again without the option gives the plain
specular trace bit for bit (the scene's materials are restored).
"""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from risloc_rt.cli import main
from risloc_rt.cli.common import trace_settings
from risloc_rt.hall import raytrace as rr
from risloc_rt.hall.raytrace.cache import trace_key
from risloc_rt.hall.raytrace.tracer import MAX_DIFFUSE_LEGS
from risloc_rt.hall.traced import TracedPaths

RADAR = np.array([3.0, 2.5, 1.2])
RIS = np.array([[6.0, 7.5, 1.5]])
SPECULAR = rr.TraceSettings(max_depth=1, samples_per_src=10_000)
DIFFUSE = rr.TraceSettings(max_depth=1, samples_per_src=10_000, diffuse_reflection=True, scattering_coefficient=0.5)


@pytest.fixture(scope="module")
def traces(tmp_path_factory, box_hall):
    hall = box_hall.make(tmp_path_factory.mktemp("hall"))
    run = lambda s: rr.trace_scene(hall, radar_position=RADAR, ris_positions=RIS, frequency=60e9, settings=s)  # noqa: E731
    return run(SPECULAR), run(DIFFUSE), run(SPECULAR)


def test_diffuse_paths_are_single_scatter_points_on_the_walls(traces):
    _, diffuse, _ = traces
    mono = diffuse.monostatic
    kinds = mono.interactions[:, 0]
    assert np.count_nonzero(kinds == 2) > 100  # many diffuse paths (code 2) besides the 6 specular ones
    scatter = mono.vertices[kinds == 2, 0]
    expected = 2 * np.linalg.norm(scatter - RADAR, axis=1) / C
    # float32 vertices and delays: 1 mm of path length.
    np.testing.assert_allclose(mono.delay[kinds == 2], expected, atol=1e-3 / C)


def test_specular_part_keeps_sqrt_one_minus_s_squared(traces):
    specular, diffuse, _ = traces
    s = DIFFUSE.scattering_coefficient
    a = specular.monostatic
    b = diffuse.monostatic
    for i in np.flatnonzero(a.interactions[:, 0] == 1):  # each single specular bounce, matched by delay
        j = np.flatnonzero((b.interactions[:, 0] == 1) & np.isclose(b.delay, a.delay[i], rtol=0, atol=1e-14))
        assert j.size == 1
        assert abs(b.amplitude[j[0]]) == pytest.approx(np.sqrt(1 - s**2) * abs(a.amplitude[i]), rel=1e-5)


def test_materials_are_restored_after_a_diffuse_trace(traces):
    before, _, after = traces
    for x, y in zip(before.monostatic.to_arrays().values(), after.monostatic.to_arrays().values()):
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes()


def test_diffuse_legs_are_capped_to_the_strongest(traces):
    _, diffuse, _ = traces
    leg = diffuse.legs[0]
    assert len(leg) == MAX_DIFFUSE_LEGS
    assert np.all(np.diff(leg.delay) >= 0)  # still in delay order
    assert np.any(np.all(leg.interactions == 0, axis=1))  # the line of sight, the strongest, is kept


def test_strongest_keeps_the_largest_amplitudes_in_order():
    n = 6
    amp = np.array([1e-3, 5e-2, 2e-3, 5e-2, 1e-1, 1e-4], complex)
    paths = TracedPaths(tx_position=np.zeros(3), rx_position=np.ones(3), frequency=60e9,
                        delay=np.arange(n) * 1e-8, amplitude=amp, departure=np.tile([1.0, 0, 0], (n, 1)),
                        arrival=np.tile([1.0, 0, 0], (n, 1)), delay_rate=np.zeros(n),
                        interactions=np.ones((n, 1), np.int64), objects=np.zeros((n, 1), np.int64),
                        vertices=np.zeros((n, 1, 3)), object_names=("wall",))
    top = paths.strongest(3)
    np.testing.assert_array_equal(top.amplitude, amp[[1, 3, 4]])  # the three largest, in delay order
    assert paths.strongest(6) is paths


def test_cache_key_changes_with_the_mechanisms_and_default_keys_stay():
    assert "scattering_coefficient" not in rr.TraceSettings().to_dict()
    key = lambda s: trace_key(scene_hash="h", radar_position=RADAR, ris_positions=RIS,  # noqa: E731
                              radar_velocity=np.zeros(3), frequency=60e9, settings=s)
    keys = {key(rr.TraceSettings(**kw)) for kw in ({}, {"diffuse_reflection": True},
                                                   {"diffuse_reflection": True, "scattering_coefficient": 0.3},
                                                   {"diffuse_reflection": True, "scattering_coefficient": 0.4},
                                                   {"diffraction": True}, {"refraction": True})}
    assert len(keys) == 6


@pytest.mark.parametrize("value", [-0.1, 1.5, True, "0.3"])
def test_scattering_coefficient_outside_zero_one_is_refused(value):
    with pytest.raises(ValueError, match="scattering_coefficient=.* must be a number in \\[0, 1\\]"):
        rr.TraceSettings(scattering_coefficient=value)


def test_cli_flags_map_to_trace_settings():
    args = argparse.Namespace(depth=2, samples=5000, diffuse=0.3, diffraction=True, refraction=False)
    s = trace_settings(args)
    assert (s.max_depth, s.samples_per_src, s.diffuse_reflection, s.scattering_coefficient,
            s.diffraction, s.refraction) == (2, 5000, True, 0.3, True, False)


@pytest.mark.parametrize("verb", [["trace", "paper_hall", "--ue", "6,9,1.2"], ["simulate", "-o", "x.npz", "--scene",
                                                                             "paper_hall"], ["demo"]])
def test_cli_refuses_a_scattering_coefficient_above_one(verb, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(verb + ["--diffuse", "1.5"]) == 2
    assert "--diffuse 1.5 must be a scattering coefficient in [0, 1]" in capsys.readouterr().err


def test_a_spec_scattering_coefficient_turns_diffuse_reflection_on_for_that_material_only(tmp_path, traces):
    """A wall material with S = 0.5 in the spec: traced with diffuse paths without being asked, the specular echo of
    that wall alone loses √(1 − S²), the other walls' echoes are the smooth trace's bit for bit."""
    from risloc_rt.authoring import build_scene, loads_spec
    from risloc_rt.hall.raytrace.tracer import scene_scatters, settings_for_scene

    spec = ("[scene]\nname = \"rough\"\n[hall]\nsize = [12.0, 8.0]\nheight = 4.0\nwall_thickness = 0.2\n"
            "[hall.materials]\nwalls = \"concrete\"\nfloor = {itu = \"concrete\", scattering_coefficient = 0.5}\n"
            "ceiling = \"concrete\"\n")
    build_scene(loads_spec(spec), tmp_path / "rough")
    build_scene(loads_spec(spec.replace(", scattering_coefficient = 0.5", "")), tmp_path / "smooth")
    rough = rr.trace_scene(tmp_path / "rough" / "scene.xml", radar_position=RADAR, frequency=60e9, settings=SPECULAR)
    smooth = rr.trace_scene(tmp_path / "smooth" / "scene.xml", radar_position=RADAR, frequency=60e9, settings=SPECULAR)
    assert rough.settings.diffuse_reflection and not smooth.settings.diffuse_reflection
    assert SPECULAR.diffuse_reflection is False                                   # what was asked is unchanged
    a, b = smooth.monostatic, rough.monostatic
    assert a.interactions[:, 0].tolist() == [1] * len(a)                          # six single specular bounces
    floor_id = list(b.object_names).index("floor")
    diffuse = b.interactions[:, 0] == 2
    assert diffuse.sum() > 100 and np.all(b.objects[diffuse, 0] == floor_id)     # only the floor scatters
    for i in range(len(a)):
        j = np.flatnonzero((b.interactions[:, 0] == 1) & np.isclose(b.delay, a.delay[i], rtol=0, atol=1e-14))
        assert j.size == 1
        on_floor = a.object_names[a.objects[i, 0]] == "floor"
        expected = np.sqrt(1 - 0.5**2) * abs(a.amplitude[i]) if on_floor else abs(a.amplitude[i])
        assert abs(b.amplitude[j[0]]) == pytest.approx(expected, rel=1e-5 if on_floor else 0)
    # --diffuse S overrides every material and is not changed; a smooth scene is traced as asked
    from risloc_rt.hall.raytrace.scene import load_scene
    loaded = load_scene(tmp_path / "rough" / "scene.xml", frequency=60e9)
    assert scene_scatters(loaded) == ("concrete-200mm-S0p5",)
    assert settings_for_scene(DIFFUSE, loaded) is DIFFUSE
    assert settings_for_scene(SPECULAR, loaded).diffuse_reflection
