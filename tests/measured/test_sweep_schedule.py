"""Sweep schedule files (risloc_rt.measured.sweep.schedule): parse, format, errors."""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.measured import (MeasuredFormatError, SweepSchedule, format_sweep_schedule, parse_sweep_schedule,
                                read_sweep_schedule)
from risloc_rt.measured.compare.calibration_file import read_calibration

GOOD = """\
frames_per_beam = 3
first_frame = 7
channel = 2

[sweep]
start_deg = -45
stop_deg = 45.0
step_deg = 1.5
elevation_deg = 2.0

[ris]
position = [0.0, 13.38, 1.2]
facing = [0, 0, 1.2]
loopback_delay_ns = 1.78
mode = "reflective"
rows = 16
columns = 4

[truth]
ue_position = [1.0, 2.0, 1.2]
"""


def _with(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new)


def test_parse_grid_and_round_trip():
    s = parse_sweep_schedule(GOOD)
    assert s.num_beams == 61 and s.angles_deg[0] == (-45.0, 2.0) and s.angles_deg[-1] == (45.0, 2.0)
    assert s.frames_per_beam == 3 and s.first_frame == 7 and s.channel == 2
    assert s.ris_position == (0.0, 13.38, 1.2) and s.ris_mode == "reflective" and s.loopback_delay_ns == 1.78
    assert s.truth_ue_position == (1.0, 2.0, 1.2)
    np.testing.assert_array_equal(s.frame_indices()[:3], [7, 10, 13])
    assert s.frames_needed == 7 + 60 * 3 + 1
    assert parse_sweep_schedule(format_sweep_schedule(s)) == s


def test_explicit_angles_defaults_and_file(tmp_path):
    text = ("frames_per_beam = 1\nfirst_frame = 0\n[sweep]\nangles_deg = [[-10, 0], [0, 5], [10.5, 0]]\n"
            "[ris]\nposition = [0, 5, 0]\nfacing = [0, 0, 0]\nloopback_delay_ns = 0\n")
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    s = read_sweep_schedule(path)
    assert s.angles_deg == ((-10.0, 0.0), (0.0, 5.0), (10.5, 0.0)) and s.grid is None
    assert (s.channel, s.ris_mode, s.ris_rows, s.ris_columns, s.truth_ue_position) == (0, "relay", 16, 4, None)
    assert parse_sweep_schedule(format_sweep_schedule(s)) == s
    built = SweepSchedule.azimuth(-45, 45, 1.5, frames_per_beam=1, first_frame=0, ris_position=(0, 1, 0),
                                  ris_facing=(0, 0, 0), loopback_delay_ns=1.0)
    assert built.num_beams == 61 and parse_sweep_schedule(format_sweep_schedule(built)) == built


def test_auto_first_frame_is_found_on_import_not_listed_without_the_recording():
    s = parse_sweep_schedule(_with(GOOD, "first_frame = 7", 'first_frame = "auto"'))
    assert s.first_frame is None
    with pytest.raises(MeasuredFormatError, match="found from the recording on import"):
        s.frame_indices()


def test_sync_table_and_clock_drift_round_trip_and_bad_values():
    text = _with(GOOD, "first_frame = 7", 'first_frame = "auto"\nmax_clock_drift = 0.05')
    text += "\n[sync]\non_frames = 5\noff_frames = 4\ncycles = 3\ngap_frames = 2\n"
    s = parse_sweep_schedule(text)
    assert (s.sync_on_frames, s.sync_off_frames, s.sync_cycles, s.sync_gap_frames) == (5, 4, 3, 2)
    assert s.max_clock_drift == 0.05 and s.program().sync_length == 3 * 9 + 2
    assert parse_sweep_schedule(format_sweep_schedule(s)) == s
    with pytest.raises(MeasuredFormatError, match=r"sync.cycles = 3 needs sync.on_frames >= 1"):
        parse_sweep_schedule(text.replace("on_frames = 5", "on_frames = 0"))
    with pytest.raises(MeasuredFormatError, match=r"sync.gap_frames = -1 must be an integer >= 0"):
        parse_sweep_schedule(text.replace("gap_frames = 2", "gap_frames = -1"))
    with pytest.raises(MeasuredFormatError, match=r"unknown key sync.'cycle'; did you mean sync.'cycles'"):
        parse_sweep_schedule(text.replace("cycles = 3", "cycle = 3"))
    with pytest.raises(MeasuredFormatError, match=r"max_clock_drift = 0.7 must be below 0.5"):
        parse_sweep_schedule(text.replace("max_clock_drift = 0.05", "max_clock_drift = 0.7"))


@pytest.mark.parametrize("old, new, match", [
    ("channel = 2", "chanel = 2", r"unknown key 'chanel'; did you mean 'channel'"),
    ("rows = 16", "row = 16", r"unknown key ris.'row'; did you mean ris.'rows'"),
    ("step_deg = 1.5", "stepdeg = 1.5", r"did you mean sweep.'step_deg'"),
    ("frames_per_beam = 3", "frames_per_beam = 0", r"frames_per_beam = 0 must be an integer >= 1"),
    ("frames_per_beam = 3", "frames_per_beam = 1.5", r"frames_per_beam = 1.5 must be an integer"),
    ("first_frame = 7", "first_frame = -1", r"first_frame = -1 must be an integer >= 0"),
    ("first_frame = 7", 'first_frame = "later"', r"first_frame = 'later' must be an integer"),
    ("step_deg = 1.5", "step_deg = 7", r"sweep.step_deg = 7 does not divide"),
    ("step_deg = 1.5", "step_deg = 0", r"sweep.step_deg = 0 must be a finite number > 0"),
    ('mode = "reflective"', 'mode = "mirror"', r"ris.mode = 'mirror' must be \"relay\" or \"reflective\""),
    ("position = [0.0, 13.38, 1.2]", "position = [0.0, 13.38]", r"ris.position = .* must be a list of 3"),
    ("loopback_delay_ns = 1.78", "loopback_delay_ns = -1", r"ris.loopback_delay_ns = -1 must be a finite number >= 0"),
    ("loopback_delay_ns = 1.78\n", "", r"ris.loopback_delay_ns is missing"),
    ("elevation_deg = 2.0", "angles_deg = [[0, 0]]", r"sweep.angles_deg and sweep.start_deg both give the beams"),
    ("[truth]\nue_position = [1.0, 2.0, 1.2]", "[truth]\nue = [1, 2, 3]", r"unknown key truth.'ue'"),
    ("frames_per_beam = 3", "frames_per_beam = [3", r"not valid TOML"),
])
def test_bad_values_are_one_line_errors(old, new, match):
    with pytest.raises(MeasuredFormatError, match=match) as info:
        parse_sweep_schedule(_with(GOOD, old, new), source="s.toml")
    assert "\n" not in str(info.value) and str(info.value).startswith("s.toml: ")


def test_missing_file_and_tables(tmp_path):
    with pytest.raises(MeasuredFormatError, match="does not exist"):
        read_sweep_schedule(tmp_path / "nope.toml")
    with pytest.raises(MeasuredFormatError, match=r"the \[ris\] table is missing"):
        parse_sweep_schedule(GOOD.split("[ris]")[0])


@pytest.mark.parametrize("reader, what", [(read_sweep_schedule, "sweep schedule"),
                                          (read_calibration, "calibration file")])
def test_unreadable_text_files_are_one_line_errors(tmp_path, reader, what):
    # regression: a binary calibration file raised UnicodeDecodeError (a traceback)
    binary = tmp_path / "bad.toml"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    for path, match in ((binary, "not a UTF-8 text file"), (tmp_path, "is a folder"),
                        (tmp_path / "nope.toml", "does not exist")):
        with pytest.raises(MeasuredFormatError, match=match) as info:
            reader(path)
        assert "\n" not in str(info.value)
        assert what in str(info.value) or str(path) in str(info.value)
