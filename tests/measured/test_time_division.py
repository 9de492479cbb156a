"""Several RISs in one DCA1000 recording (time division): the sweep schedule's [[ris]] form, the emulator, the import.

Two RISs in free space (the analytic model: each RIS's loop-back and its panel's echo), a static
radar, a small radar (N = 128, K = 16) so it is fast. Each RIS sweeps in its own slot of one recording;
each RIS's import is checked against the physics: its slot's frames are the simulated cube in ADC
counts, it localizes to the truth within the one-RIS round trip's tolerances
(tests/measured/test_import_roundtrip.py: two range-grid steps, one sweep step), and the two fixes
fused agree with the truth within their stated covariance (the χ² level of the fusion's own test).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from dsp import ProcessingConfig, RadarConfig
from dsp.fusion import RisFix, fuse_fixes
from risloc_rt.io.report import process_capture
from risloc_rt.measured import (MeasuredFormatError, dca1000_radar, emulate_time_division, format_sweep_schedule,
                                format_sweep_schedules,
                                import_capture, import_captures, parse_sweep_schedule, parse_sweep_schedules)
from risloc_rt.measured.emulate.experiment import full_scale
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

UE = np.array([0.0, 0.0, 0.0])
RIS = {"north": ((2.0, 9.0, 0.0), (-1.0, 0.0, 0.0)), "east": ((8.0, 3.0, 0.0), (0.0, 1.5, 0.0))}
"""Two RISs at the radar's height, 9.2 m and 8.5 m away, the radar off their broadside (about 18 deg and 20 deg)."""
FIRST = (2, 2 + 61 + 3)
"""Each slot's first frame: 2 lead frames, then the first sweep, 3 idle frames, the second sweep."""


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))
    processing = ProcessingConfig(n_dft=255, k_dft=64)
    scenarios = [analytic_scenario(ue_position=UE, ris_position=p, ris_facing=f, radar=radar, processing=processing)
                 for p, f in RIS.values()]
    captures = [simulate(s, rng=np.random.default_rng(k)) for k, s in enumerate(scenarios)]
    idle = np.zeros(captures[0].cube.shape[1:], complex)              # free space: nothing between the sweeps
    folder = tmp_path_factory.mktemp("td") / "dca"
    rec = emulate_time_division(list(RIS), [s.ris for s in scenarios], captures, folder, idle=idle,
                                rng=np.random.default_rng(9), first_frames=FIRST, tail_frames=2,
                                division={"order": list(RIS), "idle": "off"})
    return captures, rec


def test_each_ris_imports_its_slot_and_localizes_like_one_ris(recording):
    captures, rec = recording
    M, K, N = captures[0].cube.shape
    assert rec.num_frames == FIRST[1] + M + 2
    imported = import_captures(rec.raw_path, rec.config_path, rec.schedule_path, leakage="none")  # the cube as recorded
    assert list(imported) == list(RIS)
    counts = 2.0 ** 15 / full_scale(captures[0].radar)
    fixes = []
    for (name, cap), sim, first, (position, _) in zip(imported.items(), captures, FIRST, RIS.values()):
        np.testing.assert_array_equal(cap.frame_index, first + np.arange(M))
        assert np.std(cap.cube - sim.cube * counts) < 0.5       # its own sweep's frames, quantization below the noise
        np.testing.assert_allclose(cap.ris.pose.position, position, atol=1e-12)
        slot = cap.provenance["ris_slot"]
        assert slot["name"] == name and slot["first_frames"] == list(FIRST) and cap.provenance["import_flags"] == []
        distance = float(np.linalg.norm(UE - np.asarray(position)))
        assert cap.truth.distance == pytest.approx(distance, abs=1e-9)
        loc, _ = process_capture(cap)
        grid_step = cap.radar.range_resolution * N / cap.processing.n_dft
        rel = UE - np.asarray(position)
        normal = cap.ris.pose.normal[:2]
        az = np.rad2deg(np.arctan2(normal[0] * rel[1] - normal[1] * rel[0], normal @ rel[:2]))   # off broadside
        assert loc.detected
        assert abs(loc.distance - distance) <= 2 * grid_step
        assert abs(abs(np.rad2deg(loc.aod[0])) - abs(az)) <= 1.5       # the sweep step; |az|: the frame's sign
        fixes.append(RisFix.from_localization(name, cap.ris.pose, loc))
    fused = fuse_fixes(fixes)
    assert fused.used == tuple(RIS) and not fused.excluded
    # Both RISs at the radar's height with azimuth sweeps: the height is unobservable, the plan position is not.
    err = (fused.position - UE)[:2]
    cov = fused.covariance[:2, :2]
    d2 = float(err @ np.linalg.solve(cov, err))
    print(f"fused: error {err * 1e3} mm, 1σ {np.sqrt(np.diag(cov)) * 1e3} mm, d² {d2:.2f}")
    assert d2 <= scipy.stats.chi2.isf(1e-3, 2)


def test_one_ris_by_name_and_unknown_ris(recording):
    captures, rec = recording
    cap = import_capture(rec.raw_path, rec.config_path, rec.schedule_path, ris="east", check_schedule=False)
    np.testing.assert_array_equal(cap.frame_index[[0, -1]], [FIRST[1], FIRST[1] + 60])
    with pytest.raises(MeasuredFormatError, match=r"ris7: .*sweep.toml has no such RIS; it has north, east "):
        import_capture(rec.raw_path, rec.config_path, rec.schedule_path, ris="ris7")
    with pytest.raises(MeasuredFormatError, match="describes 2 RISs .*choose one"):
        import_capture(rec.raw_path, rec.config_path, rec.schedule_path)
    with pytest.raises(MeasuredFormatError, match="look alike to the aligner"):
        import_capture(rec.raw_path, rec.config_path, rec.schedule_path, ris="east", first_frame="auto")
    with pytest.raises(MeasuredFormatError, match="use --leakage gate"):
        import_capture(rec.raw_path, rec.config_path, rec.schedule_path, ris="east", leakage="background")
    single = rec.folder / "one.toml"                            # the one-RIS form: its RIS has no name
    single.write_text(format_sweep_schedule(rec.schedules.schedule("east")))
    with pytest.raises(MeasuredFormatError, match=r"^--ris east: .*one.toml describes one RIS in a \[ris\] table"):
        import_capture(rec.raw_path, rec.config_path, single, ris="east")
    cap = import_capture(rec.raw_path, rec.config_path, single, check_schedule=False)
    np.testing.assert_array_equal(cap.frame_index[[0, -1]], [FIRST[1], FIRST[1] + 60])


# ---------------------------------------------------------------------------------------------- the file format

TWO = """\
frames_per_beam = 1
channel = 0
[sweep]
start_deg = -45.0
stop_deg = 45.0
step_deg = 1.5
[schedule]
order = ["ris0", "ris1"]
idle = "parked"
parked_deg = [10.0, 0.0]
[truth]
ue_position = [12.0, 6.0, 1.2]
[[ris]]
name = "ris0"
first_frame = 0
position = [19.38, 9.0, 1.2]
facing = [6.0, 9.0, 1.2]
loopback_delay_ns = 1.78
[[ris]]
name = "ris1"
first_frame = 61
position = [29.5, 0.5, 1.2]
facing = [20.5, 9.5, 1.2]
loopback_delay_ns = 1.78
mode = "reflective"
"""


def test_two_ris_schedule_round_trips_and_keeps_the_one_ris_form():
    s = parse_sweep_schedules(TWO, source="s.toml")
    assert s.several and s.names == ("ris0", "ris1") and s.first_frames() == (0, 61)
    assert parse_sweep_schedules(format_sweep_schedules(s)) == s
    one = s.schedule("ris1")
    assert one.first_frame == 61 and one.ris_position == (29.5, 0.5, 1.2) and one.ris_mode == "reflective"
    assert one.truth_ue_position == (12.0, 6.0, 1.2) and one.num_beams == 61
    td = s.time_division(0.02)                              # 20 ms frames: slots of 61 frames = 1.22 s
    assert td.order == ("ris0", "ris1") and td.idle == "parked"
    assert td.starts == pytest.approx((0.0, 1.22)) and np.rad2deg(td.parked_beam) == pytest.approx((10.0, 0.0))
    # a one-RIS file reads as before, and as the one-RIS form of SweepSchedules
    single = "first_frame = 4\n" + TWO.split("[schedule]")[0] + "[ris]\nposition = [0.0, 13.38, 0.0]\n" \
        "facing = [0.0, 0.0, 0.0]\nloopback_delay_ns = 1.78\n"
    old = parse_sweep_schedule(single)
    both = parse_sweep_schedules(single)
    assert not both.several and both.schedule() == old and old.first_frame == 4
    with pytest.raises(MeasuredFormatError, match="describes one RIS in a \\[ris\\] table"):
        both.schedule("ris0")
    with pytest.raises(MeasuredFormatError, match=r"^s.toml: describes 2 RIS\(s\) in \[\[ris\]\] tables"):
        parse_sweep_schedule(TWO, source="s.toml")


def test_slots_from_a_schedule_table_in_milliseconds():
    text = TWO.replace("first_frame = 0\n", "").replace("first_frame = 61\n", "").replace(
        "channel = 0", "channel = 0\nfirst_frame = 5").replace('idle = "parked"', 'idle = "parked"\ngap_ms = 40.0')
    s = parse_sweep_schedules(text, source="d.toml")
    assert s.first_frames(0.02) == (5, 5 + 61 + 2)             # 61 frames of 20 ms, then a 40 ms gap
    assert s.schedule("ris1", frame_interval=0.02).first_frame == 68
    with pytest.raises(MeasuredFormatError, match=r"^d.toml: \[schedule\] starts RIS 'ris1' at frame 67.6"):
        s.first_frames(0.025)                                  # 40 ms is 1.6 frames of 25 ms: 5 + 61 + 1.6
    with pytest.raises(MeasuredFormatError, match="frame period .* is needed"):
        s.first_frames()


def _error(text: str) -> str:
    with pytest.raises(MeasuredFormatError) as info:
        parse_sweep_schedules(text, source="s.toml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("s.toml")
    return message


@pytest.mark.parametrize("edit, expected", [
    (("first_frame = 61", "first_frame = 60"), "ris[1].first_frame = 60: the slot of 'ris1' overlaps that of 'ris0' "
                                               "(frames 0 to 60"),
    (('name = "ris1"', 'name = "ris0"'), "ris[1].name = 'ris0' is the name of ris[0] too"),
    (('order = ["ris0", "ris1"]', 'order = ["ris0", "ris2"]'), "[schedule]: order names RIS 'ris2', which has no "
                                                               "[[ris]] table"),
    (('order = ["ris0", "ris1"]', 'order = ["ris0"]'), "order leaves out RIS 'ris1'"),
    (('order = ["ris0", "ris1"]', 'order = ["ris1", "ris0"]'), "order = ['ris1', 'ris0'] but the first frames"),
    (("first_frame = 61\n", ""), "'ris1' does not; give every RIS its first_frame, or none"),
    (("first_frame = 61", 'first_frame = "auto"'), 'ris[1].first_frame = "auto": with several RISs'),
    (('idle = "parked"', 'idle = "parked"\nstart_ms = [0.0, 2000.0]'), "start_ms and each [[ris]] first_frame both"),
    (('idle = "parked"', 'idle = "sleeping"'), "idle = 'sleeping' must be"),
    (('idle = "parked"', 'idel = "parked"'), "unknown key 'idel'; did you mean 'idle'?"),
    (("channel = 0", "channel = 0\n[sync]\non_frames = 2"), "[sync] is for a one-RIS recording"),
    (("mode = \"reflective\"", "mode = \"reflective\"\nfirst = 3"), "unknown key ris[1].'first'"),
])
def test_bad_two_ris_schedules_get_one_line(edit, expected):
    old, new = edit
    assert old in TWO
    assert expected in _error(TWO.replace(old, new, 1) if old != "first_frame = 61\n" else TWO.replace(old, new))


def test_overlapping_slots_of_a_schedule_table():
    text = TWO.replace("first_frame = 0\n", "").replace("first_frame = 61\n", "").replace(
        "channel = 0", "channel = 0\nfirst_frame = 0").replace('idle = "parked"', 'idle = "parked"\n'
                                                               'start_ms = [0.0, 1000.0]')
    s = parse_sweep_schedules(text, source="s.toml")
    with pytest.raises(MeasuredFormatError, match=r"^s.toml: \[schedule\]: the slots of ris0 .* overlap"):
        s.first_frames(0.02)                                   # 61 frames of 20 ms last 1220 ms > 1000 ms
