"""The sionna-rt layer (risloc_rt.hall.raytrace) against geometry and physics in a 12 m × 8 m × 4 m box hall.

Oracles: image sources (delays, directions), free-space loss times the ITU-R P.2040 slab
reflection coefficient computed here (gains), the path-length derivative (delay rates), and
bit-for-bit equality (determinism, cache). One trace of the hall is shared by most tests.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dsp import SPEED_OF_LIGHT as C
from risloc_rt.hall import raytrace as rr
from risloc_rt.hall.traced import TracedPaths

FREQUENCY = 60e9
WAVELENGTH = C / FREQUENCY
#: Radar inside the hall, at a different distance from each wall (3, 9, 2.5, 5.5, 1.2, 2.8 m).
RADAR = np.array([3.0, 2.5, 1.2])
#: Radar velocity with a component along every axis [m/s].
VELOCITY = np.array([0.6, -0.4, 0.3])
#: RIS points: 0.5 m in front of wall_yW and 1 m in front of wall_xL.
RIS = np.array([[6.0, 7.5, 1.5], [11.0, 4.0, 2.0]])
SETTINGS = rr.TraceSettings(max_depth=3, samples_per_src=100_000)

#: Path-length tolerance [m]. sionna-rt's tau is float32 (ulp ≈ 4 µm of length at 40 m), so
#: 1 mm leaves a wide margin while still catching any geometric error (a wrong bounce is metres off).
LENGTH_TOL = 1e-3
#: Direction tolerance [rad]: angles and vertices are float32 (~1e-7 relative), 1e-5 rad ≈ 0.1 mm at 10 m.
ANGLE_TOL = 1e-5

# ITU-R P.2040-3 Table 3, concrete: eps_r = a f^b, sigma = c f^d (f in GHz), valid 1-100 GHz.
CONCRETE = {"a": 5.24, "b": 0.0, "c": 0.0462, "d": 0.7822}
THICKNESS = 0.2
EPS0 = 8.8541878128e-12


def p2040_slab_normal(frequency: float, thickness: float) -> complex:
    """Reflection coefficient of a single-layer slab at normal incidence, ITU-R P.2040 §2.2.3.

    η = ε_r − jσ/(2πfε0); R' = (1 − √η)/(1 + √η); q = 2π d √η / λ;
    R = R' (1 − e^{−j2q}) / (1 − R'² e^{−j2q}).
    """
    f_ghz = frequency / 1e9
    eps_r = CONCRETE["a"] * f_ghz ** CONCRETE["b"]
    sigma = CONCRETE["c"] * f_ghz ** CONCRETE["d"]
    eta = eps_r - 1j * sigma / (2 * np.pi * frequency * EPS0)
    root = np.sqrt(eta)
    r_half = (1 - root) / (1 + root)
    q = 2 * np.pi * thickness * root / (C / frequency)
    e = np.exp(-2j * q)
    return complex(r_half * (1 - e) / (1 - r_half**2 * e))


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(np.sum(unit(u) * unit(v), axis=-1), -1.0, 1.0))


def walls_of(paths: TracedPaths, i: int) -> list[str]:
    return [paths.object_names[o] for o in paths.objects[i] if o >= 0]


def near_an_edge(paths: TracedPaths, i: int, planes, *, margin: float) -> bool:
    """True if a bounce point of path ``i`` lies within ``margin`` [m] of a wall of ``planes`` other than its own."""
    for k, o in enumerate(paths.objects[i]):
        if o < 0:
            continue
        own = paths.object_names[o]
        for wall, (axis, coordinate) in planes.items():
            if wall != own and abs(paths.vertices[i, k, axis] - coordinate) < margin:
                return True
    return False


def image_source(point: np.ndarray, walls: list[str], reflect) -> np.ndarray:
    """Image of ``point`` after reflecting in ``walls`` in propagation order (``reflect(point, wall)``)."""
    for wall in walls:
        point = reflect(point, wall)
    return point


def assert_identical(a: TracedPaths, b: TracedPaths) -> None:
    """Every array bit-identical (same dtype, same bytes, NaNs in the same places)."""
    arrays_a, arrays_b = a.to_arrays(), b.to_arrays()
    assert arrays_a.keys() == arrays_b.keys()
    for name in arrays_a:
        x, y = np.asarray(arrays_a[name]), np.asarray(arrays_b[name])
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name


@pytest.fixture(scope="module")
def hall(tmp_path_factory, box_hall) -> Path:
    return box_hall.make(tmp_path_factory.mktemp("hall"))


@pytest.fixture(scope="module")
def trace(hall):
    """The shared trace: depth 3, radar moving, two RIS points."""
    return rr.trace_scene(hall, radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY,
                          frequency=FREQUENCY, settings=SETTINGS)


# --- monostatic paths -------------------------------------------------------------------------

def test_single_bounce_delay_and_gain_match_image_source_and_p2040_slab(trace, box_hall):
    mono = trace.monostatic
    single = np.flatnonzero(mono.depth == 1)
    assert sorted(walls_of(mono, i)[0] for i in single) == sorted(box_hall.planes), "one echo per wall"
    gamma = p2040_slab_normal(FREQUENCY, THICKNESS)
    for i in single:
        wall = walls_of(mono, i)[0]
        axis, coordinate = box_hall.planes[wall]
        distance = abs(RADAR[axis] - coordinate)
        assert abs(mono.delay[i] * C - 2 * distance) <= LENGTH_TOL, wall
        expected = (WAVELENGTH / (4 * np.pi * 2 * distance)) ** 2 * abs(gamma) ** 2
        assert abs(10 * np.log10(abs(mono.amplitude[i]) ** 2 / expected)) <= 0.2, wall
        # normal incidence: out along the wall normal, back along the same line, bounce on the wall
        normal = np.zeros(3)
        normal[axis] = np.sign(coordinate - RADAR[axis])
        assert angle_between(mono.departure[i], normal) <= ANGLE_TOL, wall
        assert angle_between(mono.arrival[i], normal) <= ANGLE_TOL, wall
        assert abs(mono.vertices[i, 0, axis] - coordinate) <= LENGTH_TOL, wall
        assert np.all(np.isnan(mono.vertices[i, 1:])), "unused vertex slots must be NaN"


def test_multi_bounce_monostatic_delays_match_image_sources(trace, box_hall):
    mono = trace.monostatic
    multi = np.flatnonzero(mono.depth >= 2)
    assert multi.size > 0
    for i in multi:
        walls = walls_of(mono, i)
        length = np.linalg.norm(image_source(RADAR, walls, box_hall.reflect) - RADAR)
        assert abs(mono.delay[i] * C - length) <= LENGTH_TOL, mono.describe(i)
    # A monostatic double bounce returns to its start only between parallel walls: for two
    # perpendicular walls (floor → wall) the image line runs through the corner edge, a set of
    # measure zero. So the depth-2 echoes are exactly the 6 ordered parallel pairs.
    pairs = sorted(tuple(walls_of(mono, i)) for i in np.flatnonzero(mono.depth == 2))
    planes = box_hall.planes
    parallel = sorted((a, b) for a in planes for b in planes if a != b and planes[a][0] == planes[b][0])
    assert pairs == parallel


def test_bounce_points_lie_on_their_walls(trace, box_hall):
    for paths in (trace.monostatic, *trace.legs):
        for i in range(len(paths)):
            for k, o in enumerate(paths.objects[i]):
                if o >= 0:
                    axis, coordinate = box_hall.planes[paths.object_names[o]]
                    assert abs(paths.vertices[i, k, axis] - coordinate) <= LENGTH_TOL, paths.describe(i)


def test_paths_are_sorted_by_delay(trace):
    for paths in (trace.monostatic, *trace.legs):
        assert np.all(np.diff(paths.delay) >= 0)


# --- one-way legs radar -> RIS point ---------------------------------------------------------

@pytest.mark.parametrize("r", [0, 1])
def test_leg_line_of_sight_delay_direction_and_free_space_gain(trace, r):
    leg = trace.legs[r]
    los = np.flatnonzero(leg.depth == 0)
    assert los.size == 1
    i = los[0]
    distance = np.linalg.norm(RIS[r] - RADAR)
    assert abs(leg.delay[i] * C - distance) <= LENGTH_TOL
    assert angle_between(leg.arrival[i], RADAR - RIS[r]) <= ANGLE_TOL  # from the RIS toward the radar
    assert angle_between(leg.departure[i], RIS[r] - RADAR) <= ANGLE_TOL
    # isotropic unit-gain antennas: |a|² is the free-space loss (λ/4πd)²
    assert abs(10 * np.log10(abs(leg.amplitude[i]) ** 2 / (WAVELENGTH / (4 * np.pi * distance)) ** 2)) <= 0.01


@pytest.mark.parametrize("r", [0, 1])
def test_leg_wall_bounces_arrive_from_the_image_source(trace, r, box_hall):
    leg = trace.legs[r]
    bounced = np.flatnonzero(leg.depth >= 1)
    assert {walls_of(leg, i)[0] for i in bounced if leg.depth[i] == 1} == set(box_hall.planes)
    for i in bounced:
        image = image_source(RADAR, walls_of(leg, i), box_hall.reflect)
        assert abs(leg.delay[i] * C - np.linalg.norm(RIS[r] - image)) <= LENGTH_TOL, leg.describe(i)
        assert angle_between(leg.arrival[i], image - RIS[r]) <= ANGLE_TOL, leg.describe(i)


def test_leg_corner_path_floor_then_wall(trace, box_hall):
    # floor → wall_yW toward RIS 0 (0.5 m in front of wall_yW): image of the radar in both planes
    leg = trace.legs[0]
    found = [i for i in range(len(leg)) if walls_of(leg, i) == ["floor", "wall_yW"]]
    assert len(found) == 1
    image = box_hall.reflect(box_hall.reflect(RADAR, "floor"), "wall_yW")
    assert abs(leg.delay[found[0]] * C - np.linalg.norm(RIS[0] - image)) <= LENGTH_TOL


# --- delay rates ----------------------------------------------------------------------------

def test_single_bounce_delay_rate_is_minus_two_v_dot_k_over_c(trace, box_hall):
    mono = trace.monostatic
    for i in np.flatnonzero(mono.depth == 1):
        axis, coordinate = box_hall.planes[walls_of(mono, i)[0]]
        k = np.zeros(3)
        k[axis] = np.sign(coordinate - RADAR[axis])  # exact geometric direction to the wall
        expected = -2 * VELOCITY @ k / C
        # departure comes from float32 angles: relative error ~1e-7 of 2|v|/c; allow 1e-6
        assert abs(mono.delay_rate[i] - expected) <= 1e-6 * 2 * np.linalg.norm(VELOCITY) / C


def test_delay_rate_matches_sionna_doppler(hall):
    from risloc_rt.hall.raytrace.tracer import paths_to_traced, r_hat, solve_paths

    loaded = rr.load_scene(hall, frequency=FREQUENCY)
    paths = solve_paths(loaded, radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY,
                        settings=SETTINGS)
    traced = paths_to_traced(paths, loaded, radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY)
    doppler = paths.doppler.numpy()[:, 0, :]
    tau = paths.tau.numpy()[:, 0, :].astype(np.float64)
    dep = r_hat(paths.theta_t.numpy()[:, 0, :], paths.phi_t.numpy()[:, 0, :])
    scale = 2 * np.linalg.norm(VELOCITY) * FREQUENCY / C  # largest |Doppler| [Hz], ≈ 300 Hz
    for r, tp in enumerate(traced):
        lookup = {(tau[r, j], dep[r, j].tobytes()): doppler[r, j] for j in range(tau.shape[1])}
        assert len(tp) > 0
        for i in range(len(tp)):
            fd = lookup[(tp.delay[i], tp.departure[i].tobytes())]
            # sionna computes in float32 (~1e-7 relative); 1e-5 of the largest shift is 3 mHz
            assert abs(-tp.delay_rate[i] * FREQUENCY - fd) <= 1e-5 * scale, tp.describe(i)


def test_delay_rate_is_the_derivative_of_delay(hall, trace, box_hall):
    # Central difference of delays traced at radar ± v·dt, for every path (multi-bounce included;
    # e.g. floor → ceiling → back is 2H long whatever the radar's height, so its rate is 0).
    dt = 0.05  # [s]: 4 cm of motion; the O(dt²) term is < 1e-15 s/s at ≥ 1 m from any wall
    traces = [rr.trace_scene(hall, radar_position=RADAR + s * VELOCITY * dt, ris_positions=RIS,
                             radar_velocity=VELOCITY, frequency=FREQUENCY, settings=SETTINGS)
              for s in (-1, 1)]
    for which in range(1 + len(RIS)):
        now, before, after = [(t.monostatic, *t.legs)[which] for t in (trace, *traces)]
        delays = [{p.describe(i): p.delay[i] for i in range(len(p))} for p in (before, after)]
        common = delays[0].keys() & delays[1].keys()
        # A path may (dis)appear when a bounce point crosses a corner edge; every path that bounces
        # more than 0.1 m (≫ the 4 cm of motion) from the other walls must be found in all three.
        for i in range(len(now)):
            if now.describe(i) not in common:
                assert near_an_edge(now, i, box_hall.planes, margin=0.1), now.describe(i)
        assert len(common) >= 0.9 * len(now)
        for i in range(len(now)):
            name = now.describe(i)
            if name not in common:
                continue
            rate = (delays[1][name] - delays[0][name]) / (2 * dt)
            # float32 delays: ≤ ~3e-14 s rounding each over 2dt = 0.1 s -> 6e-13 s/s (0.1 mm/s radial)
            assert abs(rate - now.delay_rate[i]) <= 1e-12, name


# --- determinism and the cache --------------------------------------------------------------

def test_same_trace_twice_is_bit_identical(hall, trace):
    again = rr.trace_scene(hall, radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY,
                           frequency=FREQUENCY, settings=SETTINGS)
    for a, b in zip((trace.monostatic, *trace.legs), (again.monostatic, *again.legs), strict=True):
        assert_identical(a, b)


def test_trace_in_another_process_is_bit_identical(hall, trace, tmp_path):
    # sionna-rt's object ids differ between processes; names and the delay order must not.
    out = tmp_path / "other.npz"
    proc = _run_python(f"""
        import numpy as np
        import risloc_rt.hall.raytrace as rr
        from risloc_rt.hall.raytrace import TraceSettings
        r = rr.trace_scene({str(hall)!r}, radar_position={RADAR.tolist()}, ris_positions={RIS.tolist()},
                           radar_velocity={VELOCITY.tolist()}, frequency={FREQUENCY!r}, settings={SETTINGS!r})
        np.savez({str(out)!r}, **{{f"{{i}}/{{k}}": v for i, p in enumerate((r.monostatic, *r.legs))
                                  for k, v in p.to_arrays().items()}})
    """)
    assert proc.returncode == 0, proc.stderr[-2000:]
    with np.load(out) as data:
        for i, paths in enumerate((trace.monostatic, *trace.legs)):
            other = TracedPaths.from_arrays({k.split("/", 1)[1]: data[k] for k in data.files if k.startswith(f"{i}/")})
            assert_identical(paths, other)


def test_moving_the_radar_reuses_the_loaded_scene(hall, trace, monkeypatch, box_hall):
    import risloc_rt.hall.raytrace.tracer as tracer

    def no_reload(*args, **kwargs):
        raise AssertionError("the scene was loaded again")

    monkeypatch.setattr(tracer, "load_scene", no_reload)
    moved = rr.trace_scene(hall, radar_position=RADAR + [1.0, 1.0, 0.5], ris_positions=RIS[:1],
                           frequency=FREQUENCY, settings=SETTINGS)
    ceiling = [i for i in range(len(moved.monostatic)) if walls_of(moved.monostatic, i) == ["ceiling"]]
    assert abs(moved.monostatic.delay[ceiling[0]] * C - 2 * (box_hall.size[2] - 1.7)) <= LENGTH_TOL


def test_a_process_keeps_only_the_last_loaded_scene(hall):
    """Regression (2026-11-28): every loaded scene's radio materials stay in Dr.Jit's registry and each solve
    dispatches over all of them, so the four scenes the tracer and the Jacobian each kept made every solve up to
    4x slower (docs/benchmarks.md). Tracing another hall, then differentiating a third, must release the first."""
    import gc

    from risloc_rt.hall.raytrace.material_gradients import material_jacobian
    from risloc_rt.hall.raytrace.scene import LoadedScene

    def alive(xml: str) -> int:
        gc.collect()
        return sum(1 for o in gc.get_objects() if isinstance(o, LoadedScene) and o.path == os.path.abspath(xml))

    small = rr.TraceSettings(max_depth=1, samples_per_src=1000)
    rr.trace_scene(hall, radar_position=RADAR, frequency=FREQUENCY, settings=small)
    material_jacobian(hall, RADAR, [next(iter(rr.load_scene(hall, frequency=FREQUENCY).materials))], settings=small)
    assert alive(hall) == 2  # one in the tracer, one in the Jacobian (the fixture's trace holds none)
    other = str(Path(__file__).resolve().parents[2] / "scenes" / "paper_hall" / "scene.xml")  # whatever the cwd
    rr.trace_scene(other, radar_position=[6.0, 9.0, 1.2], frequency=FREQUENCY, settings=small)
    assert alive(hall) == 1
    material_jacobian(other, [6.0, 9.0, 1.2], ["concrete-200mm"], settings=small)
    assert alive(hall) == 0 and alive(other) == 2


def test_cache_hit_is_bit_identical(hall, trace, tmp_path):
    cache = rr.TraceCache(tmp_path / "cache")
    kwargs = dict(radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY, frequency=FREQUENCY,
                  settings=SETTINGS, cache=cache)
    first = rr.trace_scene(hall, **kwargs)
    second = rr.trace_scene(hall, **kwargs)
    assert not first.cache_hit and second.cache_hit
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 1
    for a, b, c in zip((trace.monostatic, *trace.legs), (first.monostatic, *first.legs),
                       (second.monostatic, *second.legs), strict=True):
        assert_identical(a, b)
        assert_identical(b, c)
    assert second.settings == SETTINGS and second.scene_hash == first.scene_hash
    assert second.radar_velocity.tobytes() == first.radar_velocity.tobytes()


def test_corrupt_cache_file_is_retraced_and_overwritten(hall, trace, tmp_path):
    cache = rr.TraceCache(tmp_path)
    kwargs = dict(radar_position=RADAR, ris_positions=RIS, radar_velocity=VELOCITY, frequency=FREQUENCY,
                  settings=SETTINGS, cache=cache)
    rr.trace_scene(hall, **kwargs)
    (entry,) = tmp_path.glob("*.npz")
    entry.write_bytes(entry.read_bytes()[:100])  # truncated, as after a crash or a full disk
    retraced = rr.trace_scene(hall, **kwargs)
    assert not retraced.cache_hit
    assert_identical(retraced.monostatic, trace.monostatic)
    assert rr.trace_scene(hall, **kwargs).cache_hit


def test_cache_key_changes_with_every_input(hall):
    base = dict(scene_hash=rr.scene_content_hash(hall), radar_position=RADAR, ris_positions=RIS,
                radar_velocity=VELOCITY, frequency=FREQUENCY, settings=SETTINGS)
    key = rr.trace_key(**base)
    assert rr.trace_key(**base) == key
    moved_ris = RIS.copy()
    moved_ris[1, 2] = np.nextafter(moved_ris[1, 2], np.inf)  # one ulp
    changes = {
        "radar_position": RADAR + [0.0, 0.0, 1e-9],
        "ris_positions": moved_ris,
        "radar_velocity": VELOCITY * 2,
        "frequency": 59.99e9,
        "settings": rr.TraceSettings(max_depth=3, samples_per_src=100_000, seed=43),
    }
    keys = {name: rr.trace_key(**{**base, name: value}) for name, value in changes.items()}
    keys["no RIS"] = rr.trace_key(**{**base, "ris_positions": np.zeros((0, 3))})
    assert key not in keys.values() and len(set(keys.values())) == len(keys)


def test_scene_hash_changes_with_any_xml_or_mesh_byte(tmp_path, box_hall):
    xml = box_hall.make(tmp_path / "a")
    digest = rr.scene_content_hash(xml)
    # Moving the folder does not change the content hash.
    copy = box_hall.make(tmp_path / "b")
    assert rr.scene_content_hash(copy) == digest
    ply = tmp_path / "a" / "meshes" / "floor.ply"
    data = bytearray(ply.read_bytes())
    data[-1] ^= 1
    ply.write_bytes(bytes(data))
    assert rr.scene_content_hash(xml) != digest
    xml2 = tmp_path / "b" / "hall.xml"
    xml2.write_text(xml2.read_text() + " ")
    assert rr.scene_content_hash(xml2) != digest


def test_edited_mesh_misses_the_cache_and_is_retraced(tmp_path, box_hall):
    cache = rr.TraceCache(tmp_path / "cache")
    xml = box_hall.make(tmp_path / "hall")
    kwargs = dict(radar_position=RADAR, frequency=FREQUENCY, settings=SETTINGS, cache=cache)
    before = rr.trace_scene(xml, **kwargs)
    # raise the ceiling from 4.0 m to 4.5 m: the ceiling echo must move by 2 × 0.5 m
    length, width, _ = box_hall.size
    box_hall.write_wall(tmp_path / "hall" / "meshes" / "ceiling.ply", "ceiling", (length, width, 4.5))
    after = rr.trace_scene(xml, **kwargs)
    assert not after.cache_hit and after.scene_hash != before.scene_hash
    ceiling = [i for i in range(len(after.monostatic)) if walls_of(after.monostatic, i) == ["ceiling"]]
    assert abs(after.monostatic.delay[ceiling[0]] * C - 2 * (4.5 - RADAR[2])) <= LENGTH_TOL


def test_cache_defaults_to_env_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp_path / "x"))
    assert rr.default_cache_dir() == tmp_path / "x"
    assert rr.TraceCache().directory == tmp_path / "x"
    monkeypatch.delenv("RISLOC_CACHE_DIR")
    assert rr.default_cache_dir() == Path.home() / ".cache" / "risloc-rt" / "traces"


# --- scenes that cannot be used --------------------------------------------------------------

def test_loaded_scene_reports_objects_and_p2040_concrete_at_60ghz(hall, box_hall):
    loaded = rr.load_scene(hall, frequency=FREQUENCY)
    assert loaded.object_names == tuple(sorted(box_hall.planes))
    kind, eps_r, sigma, thickness = loaded.materials["concrete"]
    f_ghz = FREQUENCY / 1e9
    assert kind == "concrete"
    # values are float32 in sionna-rt: relative 1e-6 (the frequency itself is 60.000002 GHz in float32)
    assert eps_r == pytest.approx(CONCRETE["a"] * f_ghz ** CONCRETE["b"], rel=1e-6)
    assert sigma == pytest.approx(CONCRETE["c"] * f_ghz ** CONCRETE["d"], rel=1e-6)
    assert thickness == pytest.approx(THICKNESS, rel=1e-6)


def test_missing_scene_file(tmp_path):
    with pytest.raises(rr.SceneError, match=r"nope\.xml does not exist"):
        rr.load_scene(tmp_path / "nope.xml", frequency=FREQUENCY)


def test_malformed_xml(tmp_path, box_hall):
    xml = box_hall.make(tmp_path)
    xml.write_text(xml.read_text().replace("</scene>", ""))
    with pytest.raises(rr.SceneError, match=r"hall\.xml is not well-formed XML"):
        rr.trace_scene(xml, radar_position=RADAR, frequency=FREQUENCY)


def test_missing_mesh(tmp_path, box_hall):
    xml = box_hall.make(tmp_path)
    (tmp_path / "meshes" / "floor.ply").unlink()
    with pytest.raises(rr.SceneError, match=r"hall\.xml references 'meshes/floor\.ply'.*does not exist"):
        rr.load_scene(xml, frequency=FREQUENCY)


def test_corrupt_mesh(tmp_path, box_hall):
    xml = box_hall.make(tmp_path)
    (tmp_path / "meshes" / "floor.ply").write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nend_header\n\0")
    with pytest.raises(rr.SceneError, match=r"hall\.xml: mesh 'floor\.ply' cannot be read"):
        rr.load_scene(xml, frequency=FREQUENCY)


def test_unknown_plugin(tmp_path, box_hall):
    xml = box_hall.make(tmp_path)
    xml.write_text(xml.read_text().replace('type="ply"', 'type="plyy"', 1))
    with pytest.raises(rr.SceneError, match=r"hall\.xml uses an unknown Mitsuba plugin type 'plyy'"):
        rr.load_scene(xml, frequency=FREQUENCY)


def test_material_undefined_at_60ghz_is_refused(tmp_path, box_hall):
    # brick: ITU-R P.2040 defines it for 1-40 GHz and 110-330 GHz only; sionna-rt would keep its
    # 3.5 GHz values and trace silently if the ValueError were ignored.
    xml = box_hall.make(tmp_path, material="brick")
    with pytest.raises(rr.SceneError, match=r"material 'brick' .*not defined at 60 GHz"):
        rr.trace_scene(xml, radar_position=RADAR, frequency=FREQUENCY)


def test_material_undefined_at_load_frequency(tmp_path, box_hall):
    xml = box_hall.make(tmp_path, material="floorboard")  # 50-100 GHz: fails at sionna's 3.5 GHz load
    with pytest.raises(rr.SceneError, match=r"'floorboard' is not defined at sionna-rt's default 3\.5 GHz"):
        rr.load_scene(xml, frequency=FREQUENCY)


# --- argument checks -------------------------------------------------------------------------

@pytest.mark.parametrize(("kwargs", "match"), [
    ({"radar_position": [1.0, np.nan, 1.0]}, "radar_position contains 1 NaN"),
    ({"radar_position": [1.0, 2.0]}, r"radar_position has shape \[2\], expected \[3\]"),
    ({"ris_positions": [1.0, 2.0, 3.0]}, r"ris_positions has shape \[3\], expected \[\*, 3\]"),
    ({"ris_positions": [RADAR + [0.0, 0.0, 0.001]]}, r"ris_positions\[0\].*must be >= 0.01 m away"),
    ({"radar_velocity": [0.0, 0.0, np.inf]}, "radar_velocity contains 1 NaN or infinite"),
    ({"frequency": -1.0}, r"frequency=-1.0 must be a finite number > 0"),
])
def test_trace_rejects_bad_arguments(hall, kwargs, match):
    args = {"radar_position": RADAR, "frequency": FREQUENCY, **kwargs}
    with pytest.raises(ValueError, match=match):
        rr.trace_scene(hall, **args)


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"max_depth": -1}, ValueError, "max_depth=-1 must be >= 0"),
    ({"samples_per_src": 0}, ValueError, "samples_per_src=0 must be >= 1"),
    ({"samples_per_src": 1e5}, TypeError, "samples_per_src=100000.0 must be an int"),
    ({"refraction": 1}, TypeError, "refraction=1 must be True or False"),
    ({"seed": -3}, ValueError, "seed=-3 must be >= 0"),
])
def test_settings_validation(kwargs, error, match):
    with pytest.raises(error, match=match):
        rr.TraceSettings(**kwargs)


def test_settings_round_trip():
    s = rr.TraceSettings(max_depth=2, diffraction=True, seed=7)
    assert rr.TraceSettings(**s.to_dict()) == s


# --- backend ---------------------------------------------------------------------------------

def _run_python(code: str, **env: str) -> subprocess.CompletedProcess:
    full_env = {k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    full_env.update(env)
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=full_env,
                          capture_output=True, text=True, timeout=120)


def test_importing_the_package_loads_no_heavy_dependency():
    proc = _run_python("""
        import sys
        import risloc_rt.hall.raytrace as rr
        names = rr.TraceSettings, rr.TraceCache, rr.SceneError, rr.BackendError, rr.trace_scene
        heavy = sorted({m.split(".")[0] for m in sys.modules} & {"sionna", "mitsuba", "drjit"})
        print("heavy:", heavy)
    """)
    assert proc.returncode == 0, proc.stderr
    assert "heavy: []" in proc.stdout


LLVM15 = Path("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1")


@pytest.mark.parametrize("library", [
    pytest.param(str(LLVM15), marks=pytest.mark.skipif(not LLVM15.exists(), reason="no libLLVM-15 here")),
    "/nonexistent/libLLVM.so.19.1",
    "symlink-to-15",
])
def test_bad_llvm_library_raises_backend_error_instead_of_aborting(library, tmp_path):
    if library == "symlink-to-15":
        if not LLVM15.exists():
            pytest.skip("no libLLVM-15 here")
        link = tmp_path / "libcustom.so"  # a name that does not say the version
        link.symlink_to(LLVM15)
        library = str(link)
    proc = _run_python("""
        from risloc_rt.hall.raytrace import ensure_backend
        ensure_backend()
    """, DRJIT_LIBLLVM_PATH=library)
    # An LLVM 15 that reached a solve would SIGABRT (returncode -6 / 134): we need a Python error.
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-2000:])
    assert "BackendError" in proc.stderr
    assert "libLLVM >= 17" in proc.stderr and "apt-get install libllvm19" in proc.stderr


def test_find_libllvm_picks_the_newest_usable(tmp_path):
    lib = tmp_path / "x86_64-linux-gnu"
    lib.mkdir()
    for name in ("libLLVM-14.so.1", "libLLVM-15.so.1", "libLLVM.so.19.1", "libLLVM.so.18.1", "libLLVMCore.a"):
        (lib / name).write_bytes(b"")
    (lib / "libLLVM-19.so").symlink_to("libLLVM.so.19.1")
    pattern = (str(lib / "libLLVM*.so*"),)
    assert rr.find_libllvm(patterns=pattern) == str(lib / "libLLVM.so.19.1")
    for name in ("libLLVM.so.19.1", "libLLVM-19.so", "libLLVM.so.18.1"):
        (lib / name).unlink()
    assert rr.find_libllvm(patterns=pattern) is None  # only 14 and 15: both unusable


def test_backend_in_this_process_is_usable(trace):
    info = rr.backend_info()
    assert info["variant"] in ("llvm_ad_mono_polarized", "cuda_ad_mono_polarized")
    assert rr.ensure_backend() == info["variant"]
    if info["variant"].startswith("llvm"):
        assert int(str(info["llvm_version"]).split(".")[0]) >= 17
