"""Issue 20 items 4 and 8: a RIS on its own clock (25 ms per beam against 20 ms frames, an on/off chip code
repeated after the sweep, drift), and a given first_frame checked against the recording.

The expected RIS states and chirps are worked out by hand from the timing written in each test (chirp k
of frame f starts at radar time f + k·T_c/T_f frames); nothing expected is computed with
``chirp_states`` or ``select_chirps``.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.io.report import process_capture
from risloc_rt.measured import MeasuredFormatError, dca1000_radar, import_capture, parse_sweep_schedule
from risloc_rt.measured.emulate.recording import RecordingPlan, emulate_recording
from risloc_rt.measured.sweep.alignment import select_chirps
from risloc_rt.measured.sweep.ris_timing import OFF, SYNC, RisProgram, chirp_states
from risloc_rt.measured.sweep.schedule import format_sweep_schedule
from risloc_rt.model.builder import analytic_scenario

DISTANCE, AOD_DEG = 9.3, 12.0
CODE = "1111100110101"
K, T_C, T_F = 64, 140e-6, 20e-3          # chirps per frame, chirp period, frame period: chirps fill 44.8 % of a frame
C = T_C / T_F                            # one chirp [frames]


def test_program_states_tabulated_by_hand():
    # 3 beams of 25 ms on 20 ms frames (1.25 frames), code 1101 of 20 ms chips, 10 ms gap, repeated after.
    prog = RisProgram.from_ris_clock(3, beam_dwell=25e-3, frame_interval=20e-3, sync_pattern="1101", chip=20e-3,
                                     sync_gap=10e-3, repeat_after=True)
    assert prog.frames_per_beam == pytest.approx(1.25) and prog.chip_length == pytest.approx(1.0)
    assert prog.sync_length == pytest.approx(4.5) and prog.after_length == pytest.approx(4.5)
    # start 6: code 1.5-5.5 (1 1 0 1), gap 5.5-6, beams 6-7.25-8.5-9.75, gap 9.75-10.25, code 10.25-14.25
    table = {1.4: OFF, 1.5: SYNC, 3.4: SYNC, 3.6: OFF, 5.0: SYNC, 5.6: OFF, 6.0: 0, 7.2: 0, 7.3: 1, 8.49: 1, 8.5: 2,
             9.7: 2, 9.8: OFF, 10.3: SYNC, 12.3: OFF, 14.0: SYNC, 14.3: OFF}
    times = np.array(list(table))
    np.testing.assert_array_equal(chirp_states(prog, times, start=6.0, dwell=1.25), list(table.values()))
    # RIS clock 4 % slow: dwell 1.3 frames, beam 1 at 7.3, the code 4.5 x 1.04 = 4.68 frames before the sweep
    slow = {1.33: SYNC, 1.31: OFF, 7.29: 0, 7.31: 1, 9.89: 2, 9.91: OFF}
    np.testing.assert_array_equal(chirp_states(prog, np.array(list(slow)), start=6.0, dwell=1.3), list(slow.values()))
    # Four chirps per frame filling 3/4 of it (at f, f+3/16, f+6/16, f+9/16): frame 7 sees beam 0 then beam 1.
    frame7 = 7 + np.arange(4) * 3 / 16
    np.testing.assert_array_equal(chirp_states(prog, frame7, start=6.0, dwell=1.25), [0, 0, 1, 1])


def test_on_off_form_is_a_chip_code():
    old = RisProgram(num_beams=2, frames_per_beam=2, sync_on=2, sync_off=1, sync_cycles=2, sync_gap=1)
    assert old.chips == "110110" and old.sync_length == 7 and old.after_length == 0
    # start 8: chips at frames 1..6 = 1 1 0 1 1 0, gap 7, beams 8-10-12, nothing after
    t = np.arange(0.5, 14, 1.0)
    expect = [OFF, SYNC, SYNC, OFF, SYNC, SYNC, OFF, OFF, 0, 0, 1, 1, OFF, OFF]
    np.testing.assert_array_equal(chirp_states(old, t, start=8.0, dwell=2.0), expect)


@pytest.mark.parametrize("kw, match", [
    (dict(frames_per_beam=0), r"frames_per_beam=0 must be a finite number > 0"),
    (dict(sync_pattern="10x1"), r"must be up to 4096 characters '1' \(on\) and '0'"),
    (dict(sync_pattern="000"), r"has no '1' chip"),
    (dict(sync_pattern="101", sync_on=1, sync_cycles=1), r"not both"),
    (dict(chip_frames=-1.0), r"chip_frames=-1.0 must be a finite number > 0"),
])
def test_bad_programs_are_one_line_errors(kw, match):
    with pytest.raises(MeasuredFormatError, match=match) as info:
        RisProgram(num_beams=3, **{"frames_per_beam": 1.0, **kw})
    assert "\n" not in str(info.value)


def test_beam_chirps_spread_over_two_frames_by_hand():
    # Frames of 4 chirps filling 3/4 of the frame interval: chirp k of frame f at f + 3k/16, 3/16 long.
    # Beams of 1.25 frames from 6.3: [6.3, 7.55), [7.55, 8.8), [8.8, 10.05).
    prog = RisProgram(num_beams=3, frames_per_beam=1.25)
    # Beam 0: no frame fits (frame 6 starts before 6.3, frame 7's chirps end at 7.75). Inside: 6.375 (g 26),
    # 6.5625 (27), 7.0 (28), 7.1875 (29, ends 7.375); 7.375 ends at 7.5625 > 7.55. Four consecutive: 26..29.
    # Beam 1: frame 8 [8, 8.75) inside (margins 0.45, 0.05): chirps 32..35. Beam 2: frame 9 [9, 9.75): 36..39.
    start, mixed = select_chirps(prog, 6.3, 1.25, num_chirps=4, frame_width=0.75, assemble="span")
    np.testing.assert_array_equal(start, [26, 32, 36])
    np.testing.assert_array_equal(mixed, [False, False, False])
    # "frame": beam 0 takes the frame with most of its chirp time: frame 6 has 6.3-6.75 (0.45), frame 7 has
    # 7.0-7.55 (0.55): frame 7, mixed.
    start, mixed = select_chirps(prog, 6.3, 1.25, num_chirps=4, frame_width=0.75, assemble="frame")
    np.testing.assert_array_equal(start, [28, 32, 36])
    np.testing.assert_array_equal(mixed, [True, False, False])
    # A beam shorter than K chirps (one frame per beam, RIS clock 0.32 % fast): [14.38, 15.3768), K = 64 chirps of
    # 0.007 frames. Chirps k.. of frame 14 and ..k-1 of frame 15 hold (14.448 - max(14.38, 14 + 0.007 k))
    # + min(0.007 k, 0.3768) of it: k = 53: 0.4390, k = 54: 0.4448 (99.3 % of 0.448), k = 55: 0.4398.
    start, mixed = select_chirps(RisProgram(num_beams=1, frames_per_beam=1.0), 14.38, 0.9968, num_chirps=64,
                                 frame_width=0.448, assemble="span")
    assert (start[0], mixed[0]) == (14 * 64 + 54, False)


# ------------------------------------------------------------------------------------------- schedules

BASE = """\
first_frame = "auto"
channel = 0

[sweep]
start_deg = -45.0
stop_deg = 45.0
step_deg = 1.5
elevation_deg = 0.0

[ris]
position = [0.0, 13.38, 0.0]
facing = [0.0, 0.0, 0.0]
loopback_delay_ns = 1.78
mode = "relay"
rows = 16
columns = 4
"""
CLOCK = "beam_dwell_ms = 25.0\n" + BASE + f'\n[sync]\npattern = "{CODE}"\nchip_ms = 20.0\ngap_ms = 5.0\nrepeat_after = true\n'
OLD = "frames_per_beam = 2\n" + BASE + "\n[sync]\non_frames = 3\noff_frames = 3\ncycles = 3\ngap_frames = 2\n"


def test_ris_clock_schedule_parses_converts_and_round_trips():
    s = parse_sweep_schedule(CLOCK)
    assert s.frames_per_beam is None and s.beam_dwell_ms == 25.0
    assert (s.sync_pattern, s.sync_chip_ms, s.sync_gap_ms, s.sync_repeat_after) == (CODE, 20.0, 5.0, True)
    text = format_sweep_schedule(s, comment="c")
    assert text == "# c\n" + CLOCK                                        # written back key for key
    assert parse_sweep_schedule(text) == s
    prog = s.program(20e-3)                                               # the radar's frame period, from the .cfg
    assert prog.frames_per_beam == pytest.approx(1.25) and prog.chip_length == pytest.approx(1.0)
    assert prog.sync_gap == pytest.approx(0.25) and prog.sync_length == pytest.approx(13.25)
    assert s.program(25e-3).frames_per_beam == pytest.approx(1.0)
    with pytest.raises(MeasuredFormatError, match="frame period"):
        s.program()
    with pytest.raises(MeasuredFormatError, match="import_capture lists them"):
        parse_sweep_schedule(CLOCK.replace('"auto"', "15")).frame_indices()


def test_old_schedule_files_parse_and_write_as_before():
    s = parse_sweep_schedule(OLD)
    assert (s.frames_per_beam, s.beam_dwell_ms, s.sync_pattern) == (2, None, "")
    assert (s.sync_on_frames, s.sync_off_frames, s.sync_cycles, s.sync_gap_frames) == (3, 3, 3, 2)
    assert format_sweep_schedule(s, comment="c") == "# c\n" + OLD
    prog = s.program()
    assert prog.chips == "111000" * 3 and prog.sync_length == 20 and prog.frames_per_beam == 2
    np.testing.assert_array_equal(parse_sweep_schedule(OLD.replace('"auto"', "7")).frame_indices()[:3], [7, 9, 11])


@pytest.mark.parametrize("text, match", [
    (CLOCK.replace("beam_dwell_ms = 25.0\n", "beam_dwell_ms = 25.0\nframes_per_beam = 1\n"),
     r"frames_per_beam and beam_dwell_ms both give the RIS's time per beam"),
    (CLOCK.replace("beam_dwell_ms = 25.0\n", ""), r"frames_per_beam is missing; .* or beam_dwell_ms = 25.0"),
    (CLOCK.replace("beam_dwell_ms = 25.0", "beam_dwell_ms = 0"), r"beam_dwell_ms = 0 must be a finite number > 0"),
    (CLOCK.replace("beam_dwell_ms = 25.0", 'beam_dwell_ms = "25"'), r"beam_dwell_ms = '25' must be a finite number"),
    (CLOCK.replace("beam_dwell_ms", "beam_dwel_ms"), r"unknown key 'beam_dwel_ms'; did you mean 'beam_dwell_ms'"),
    (CLOCK.replace(CODE, "11120"), r"sync.pattern = '11120' must be a non-empty string of '1' and '0'"),
    (CLOCK.replace(CODE, "0000"), r"sync.pattern = '0000' has no 1 chip"),
    (CLOCK.replace("chip_ms = 20.0\n", ""), r"sync.pattern needs sync.chip_ms"),
    (CLOCK.replace("chip_ms = 20.0", "chip_ms = -20.0"), r"sync.chip_ms = -20.0 must be a finite number > 0"),
    (CLOCK.replace("chip_ms", "chipms"), r"unknown key sync.'chipms'; did you mean sync.'chip_ms'"),
    (CLOCK.replace("gap_ms = 5.0", "gap_ms = 5.0\ngap_frames = 1"), r"sync.gap_frames and sync.gap_ms both"),
    (CLOCK.replace("repeat_after = true", 'repeat_after = "yes"'), r"sync.repeat_after = 'yes' must be true or false"),
    (CLOCK.replace("chip_ms = 20.0", "chip_ms = 20.0\non_frames = 2"), r"sync.pattern and sync.on_frames both"),
    (CLOCK.replace(f'pattern = "{CODE}"\n', ""), r"sync.chip_ms needs sync.pattern"),
    (CLOCK.replace(CODE, "1" * 5000), r"sync.pattern has 5,000 chips, more than 4096"),
], ids=["both", "neither", "zero-dwell", "text-dwell", "misspelt", "bad-chip", "no-on-chip", "no-chip-ms",
        "negative-chip", "misspelt-chip", "two-gaps", "repeat-text", "two-forms", "chip-alone", "long-code"])
def test_bad_schedule_values_are_one_line_errors(text, match):
    with pytest.raises(MeasuredFormatError, match=match) as info:
        parse_sweep_schedule(text, source="s.toml")
    assert "\n" not in str(info.value) and str(info.value).startswith("s.toml: ")


# ------------------------------------------------------------------------------------ emulated recordings

def _scenario():
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=K, chirp_period=T_C, frame_period=T_F))
    return analytic_scenario(distance=DISTANCE, aod=np.deg2rad((AOD_DEG, 0.0)), radar=radar,
                             processing=ProcessingConfig(n_dft=255, k_dft=256))


def _record(tmp_path_factory, name, seed, **plan):
    return emulate_recording(_scenario(), tmp_path_factory.mktemp(name) / "rec", plan=RecordingPlan(**plan),
                             rng=np.random.default_rng(seed))


@pytest.fixture(scope="module")
def dwell25(tmp_path_factory):
    """25 ms per beam on 20 ms frames, the code (20 ms chips) from radar frame 2.3 and repeated after: the sweep
    starts at 2.3 + 13 = 15.3 frames; beam m lasts [15.3 + 1.25 m, 16.55 + 1.25 m)."""
    return _record(tmp_path_factory, "dwell25", 21, lead_frames=2.3, beam_dwell_ms=25.0, sync_pattern=CODE,
                   chip_ms=20.0, repeat_after=True, tail_frames=3)


@pytest.fixture(scope="module")
def coded(tmp_path_factory):
    """One 20 ms frame per beam, the code from frame 2.0 and repeated after; the schedule says first_frame = 15."""
    return _record(tmp_path_factory, "coded", 22, lead_frames=2.0, beam_dwell_ms=20.0, sync_pattern=CODE,
                   chip_ms=20.0, repeat_after=True, tail_frames=3, schedule_first_frame="true")


def _chirps_inside_true_beams(align, start, dwell):
    """Worst margin [frames] of each beam's K chirps inside its true dwell (negative: a chirp outside)."""
    worst = np.inf
    for m, segments in enumerate(align["beam_chirps"]):
        t = np.concatenate([f + (k0 + np.arange(n)) * C for f, k0, n in segments])
        assert t.size == K and np.all(np.diff(t) > 0)
        lo, hi = start + m * dwell, start + (m + 1) * dwell
        worst = min(worst, t[0] - lo, hi - (t[-1] + C))
    return worst


def _localize(cap):
    loc, _ = process_capture(cap)
    err_d, err_az = loc.distance - DISTANCE, np.rad2deg(loc.aod[0]) - AOD_DEG
    sd, saz = loc.std.distance, np.rad2deg(loc.std.aod[0])
    print(f"distance {err_d * 1e3:+.2f} mm (1 sigma {sd * 1e3:.2f} mm), AoD {err_az:+.4f} deg (1 sigma {saz:.4f} deg)")
    return err_d, err_az, sd, saz


def test_25ms_beams_on_20ms_frames_align_and_localize(dwell25):
    rec, exp = dwell25, dwell25.experiment
    assert exp.schedule.beam_dwell_ms == 25.0 and exp.schedule.frames_per_beam is None
    assert rec.start == pytest.approx(15.3) and rec.dwell == pytest.approx(1.25)
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    a = cap.provenance["alignment"]
    print(f"25 ms: start {a['start']:.3f} (15.300), dwell {a['dwell']:.4f} (1.2500), confidence {a['confidence']:.2f}")
    assert a["method"] == "auto" and a["confidence"] >= 0.5
    assert abs(a["start"] - 15.3) <= 0.1 and abs(a["dwell"] - 1.25) <= 0.005         # frames
    # RIS states under the fitted timing at a few chirps, by hand: the code occupies [2.3 + i, 3.3 + i) for
    # chip i, beam m [15.3 + 1.25 m, 16.55 + 1.25 m), beam 60 ends at 91.55, then the code again.
    t = np.array([2.0, 3.0, 7.0, 8.0, 15.0, 15 + 63 * C, 16.0, 17.0, 18.0, 91.0, 92.0, 96.0, 97.0])
    hand = [OFF, SYNC, SYNC, OFF, SYNC, 0, 0, 1, 2, 60, SYNC, SYNC, OFF]
    prog = exp.schedule.program(T_F)
    np.testing.assert_array_equal(chirp_states(prog, t, start=a["start"], dwell=a["dwell"]), hand)
    # Every beam's 64 chirps lie inside its true dwell; beam 3 [19.05, 20.3) holds no whole frame: its chirps
    # run from frame 19 chirp k0 to frame 20 chirp k0 - 1, k0 = 25 at the true timing (margins 0.125 both sides).
    assert _chirps_inside_true_beams(a, rec.start, rec.dwell) >= -1e-9
    (f1, k0, n1), (f2, zero, n2) = a["beam_chirps"][3]
    assert (f1, f2, zero, n1 + n2) == (19, 20, 0, K) and 22 <= k0 <= 28
    assert len(a["mixed_beams"]) == 0 and sum(len(b) == 2 for b in a["beam_chirps"]) >= 10
    err_d, err_az, sd, saz = _localize(cap)
    assert abs(err_az) <= max(4 * saz, 0.02) and abs(err_d) <= max(4 * sd, 2e-3)


@pytest.fixture(scope="module")
def dwell25_whole(tmp_path_factory):
    """25 ms per beam, the code from frame 2.0: the sweep starts at frame 15.0; the schedule says first_frame = 15."""
    return _record(tmp_path_factory, "dwell25w", 23, lead_frames=2.0, beam_dwell_ms=25.0, sync_pattern=CODE,
                   chip_ms=20.0, repeat_after=True, tail_frames=3, schedule_first_frame="true")


@pytest.mark.slow
def test_25ms_beams_by_hand(dwell25_whole):
    """The issue: such a RIS could not be imported at all, not even by hand. first_frame = 15 given: no warning."""
    exp = dwell25_whole.experiment
    assert exp.schedule.first_frame == 15 and exp.schedule.beam_dwell_ms == 25.0
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    a = cap.provenance["alignment"]
    assert a["method"] == "manual" and a["check"]["mismatch"] is False and cap.provenance["import_flags"] == []
    # By hand: beam m = [15 + 1.25 m, 16.25 + 1.25 m); a frame's chirps span [f, f + 0.448). Beam 0: frame 15
    # (margin 0); beam 1 [16.25, 17.5): frame 17; beam 2 [17.5, 18.75): 18; beam 3 [18.75, 20): 19; beam 4: 20.
    assert [seg for seg in a["beam_chirps"][:5]] == [[[f, 0, K]] for f in (15, 17, 18, 19, 20)]
    assert _chirps_inside_true_beams(a, 15.0, 1.25) >= -1e-9
    err_d, err_az, sd, saz = _localize(cap)
    assert abs(err_az) <= max(4 * saz, 0.02) and abs(err_d) <= max(4 * sd, 2e-3)


@pytest.mark.slow
def test_a_25ms_sweep_given_late_is_flagged(dwell25, tmp_path, capsys):
    """first_frame = 16 is the first frame inside beam 0 (start 15.3), but beam m is then assumed at 16 + 1.25 m,
    0.7 frame late: beam 1 [16.55, 17.8) would take frame 18, which holds beam 2 [17.8, 19.05)."""
    exp = dwell25.experiment
    out = tmp_path / "late.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(out), "--first-frame", "16"]) == 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("warning: ")
    assert "supports first_frame = 16 but a sweep start at frame 15.3" in err, err
    cap = load_capture(out)
    check = cap.provenance["alignment"]["check"]
    assert check["mismatch"] and check["beams_differ"] >= 10
    assert [f["code"] for f in cap.provenance["import_flags"]] == ["schedule-mismatch"]
    assert cap.provenance["alignment"]["beam_chirps"][1] == [[18, 0, K]]
    _, err_az, _, saz = _localize(cap)
    assert abs(err_az) > max(5 * saz, 0.5)                                  # a confident wrong angle, now flagged


def test_chip_code_one_frame_per_beam_aligns_to_the_true_frame(coded):
    """The issue: first_frame = "auto" refused this recording (confidence 0.37, best guess 15 frames off)."""
    rec, exp = coded, coded.experiment
    assert rec.start == pytest.approx(15.0) and exp.schedule.first_frame == 15
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path, first_frame="auto")
    a = cap.provenance["alignment"]
    print(f"code: start {a['start']:.3f} (15.000), dwell {a['dwell']:.4f}, confidence {a['confidence']:.3f}")
    assert a["first_frame"] == 15 and a["confidence"] >= 0.9
    np.testing.assert_array_equal(cap.frame_index, 15 + np.arange(61))
    # Chips i = 0..12 are frames 2..14 (1 1 1 1 1 0 0 1 1 0 1 0 1), beams frames 15..75, the code again 76..88.
    t = np.array([1.0, 2.0, 6.0, 7.0, 8.0, 9.0, 11.0, 13.0, 14.0, 15.0, 15 + 63 * C, 45.0, 75.0, 76.0, 81.0, 88.0,
                  89.0])
    hand = [OFF, SYNC, SYNC, OFF, OFF, SYNC, OFF, OFF, SYNC, 0, 0, 30, 60, SYNC, OFF, SYNC, OFF]
    prog = exp.schedule.program(T_F)
    np.testing.assert_array_equal(chirp_states(prog, t, start=a["start"], dwell=a["dwell"]), hand)
    assert _chirps_inside_true_beams(a, rec.start, rec.dwell) >= -1e-9
    err_d, err_az, sd, saz = _localize(cap)
    assert abs(err_az) <= max(4 * saz, 0.02) and abs(err_d) <= max(4 * sd, 2e-3)


def test_a_wrong_first_frame_is_a_warning_and_a_flag(coded, tmp_path, capsys):
    """The issue: first_frame = 18 for a true 15 gave AoD 7.57 deg for 12.00 deg, no flag."""
    exp = coded.experiment
    out = tmp_path / "c.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(out), "--first-frame", "18"]) == 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("warning: ") and "supports first_frame = 15, not the given 18" in err
    cap = load_capture(out)
    flags = cap.provenance["import_flags"]
    assert [f["code"] for f in flags] == ["schedule-mismatch"] and "first_frame = 15" in flags[0]["message"]
    check = cap.provenance["alignment"]["check"]
    assert check["mismatch"] and check["given"] == 18 and check["supported"] == 15 and check["delta_rss"] >= 25
    np.testing.assert_array_equal(cap.frame_index, 18 + np.arange(61))      # the given frames are kept
    loc, _ = process_capture(cap)
    print(f"first_frame 18: AoD {np.rad2deg(loc.aod[0]):.2f} deg (true {AOD_DEG})")
    assert abs(np.rad2deg(loc.aod[0]) - AOD_DEG) > 3.0                       # 3 beams x 1.5 deg shifted


def test_a_correct_first_frame_gives_no_warning(coded, tmp_path, capsys):
    exp = coded.experiment
    out = tmp_path / "c.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(out)]) == 0                  # the schedule's first_frame = 15
    assert "warning" not in capsys.readouterr().err
    cap = load_capture(out)
    assert cap.provenance["import_flags"] == [] and cap.provenance["import_warnings"] == []
    assert cap.provenance["alignment"]["check"]["supported"] == 15


@pytest.mark.slow
@pytest.mark.parametrize("plan, first", [
    (dict(lead_frames=4.0, frames_per_beam=2, tail_frames=3), 4),                                  # no sync
    (dict(lead_frames=6.0, frames_per_beam=1, tail_frames=3), 6),                                  # no sync, 1 frame
    (dict(lead_frames=1.0, frames_per_beam=1, sync_on=2, sync_off=2, sync_cycles=2, sync_gap=1), 10),  # on/off sync
], ids=["no-sync-2", "no-sync-1", "on-off"])
def test_correct_first_frames_without_a_code_give_no_warning(tmp_path_factory, plan, first):
    rec = _record(tmp_path_factory, "ok", 30 + first, schedule_first_frame="true", **plan)
    exp = rec.experiment
    assert exp.schedule.first_frame == first
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    check = cap.provenance["alignment"]["check"]
    print(f"first_frame {first}: fitted {check['start']:.2f}, confidence {check['confidence']:.2f}, "
          f"delta {check['delta_rss']:.1f}")
    assert check["mismatch"] is False and cap.provenance["import_flags"] == []
