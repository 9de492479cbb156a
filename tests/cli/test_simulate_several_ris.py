"""risloc simulate on a hall with several RISs (--ris, --idle, --schedule, --format dca1000) and the import of a
time-division recording (risloc capture import --ris, or -o a folder with one capture per RIS).

The scene is scenes/paper_hall_2ris (ris0 at [19.38, 9, 1.2] facing -x, ris1 at [29.5, 0.5, 1.2] facing
[20.5, 9.5, 1.2]); the radar stands at [12, 6, 1.2], in front of both and within the unambiguous range of
each (7.97 m and 18.34 m). The expected distances are the geometry's, written out here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.io.report import process_capture
from risloc_rt.measured import read_sweep_schedules

SCENE = "paper_hall_2ris"
TRACE = ["--depth", "2", "--samples", "20000"]
UE = (12.0, 6.0, 1.2)
RIS = {"ris0": (19.38, 9.0, 1.2), "ris1": (29.5, 0.5, 1.2)}
FRAME_MS = 128 * 0.070                 # Table I's 128 chirps of 70 µs (the TI chirp, dca1000_radar): 8.96 ms


def _distance(name: str) -> float:
    return math.dist(UE, RIS[name])


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    return err


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    root = tmp_path_factory.mktemp("several")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RISLOC_CACHE_DIR", str(root / "cache"))
        schedule = root / "slots.toml"
        schedule.write_text(f'[schedule]\norder = ["ris1", "ris0"]\ngap_ms = {2 * FRAME_MS!r}\nidle = "off"\n')
        folder = root / "dca"
        code = main(["simulate", "--scene", SCENE, "--ue", ",".join(map(str, UE)), "--format", "dca1000",
                     "--schedule", str(schedule), "--seed", "3", "-o", str(folder), *TRACE])
        assert code == 0
    return root, folder


def test_time_division_recording_imports_one_capture_per_ris(recording, capsys):
    root, folder = recording
    schedules = read_sweep_schedules(folder / "sweep.toml")
    assert schedules.several and schedules.names == ("ris1", "ris0")
    assert schedules.first_frames() == (0, 61 + 2)                  # ris1's 61 beams, 2 frames of gap, then ris0
    assert schedules.division["idle"] == "off"
    for name, sched in zip(schedules.names, schedules.schedules):
        np.testing.assert_allclose(sched.ris_position, RIS[name])
    out = root / "captures"
    raw = folder / "adc_data_Raw_0.bin"
    argv = ["capture", "import", str(raw), "--config", str(folder / "adc_data.cfg"), "--sweep",
            str(folder / "sweep.toml")]
    assert main([*argv, "-o", str(out)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith(f"wrote {out / 'ris1.npz'}: RIS ris1, 61 beams (frames 0..60 of 124")
    assert "RIS ris0, 61 beams (frames 63..123 of 124" in lines[1]
    for name in RIS:
        cap = load_capture(out / f"{name}.npz")
        assert cap.truth.distance == pytest.approx(_distance(name), abs=1e-9)
        np.testing.assert_allclose(cap.ris.pose.position, RIS[name])
        loc, _ = process_capture(cap)
        N = cap.cube.shape[2]
        grid_step = cap.radar.range_resolution * N / cap.processing.n_dft
        print(f"{name}: distance error {(loc.distance - _distance(name)) * 1e3:+.1f} mm (grid step "
              f"{grid_step * 1e3:.1f} mm), AoD error {np.rad2deg(loc.aod[0] - cap.truth.aod[0]):+.3f} deg")
        assert loc.detected and abs(loc.distance - _distance(name)) <= 2 * grid_step
        assert abs(np.rad2deg(loc.aod[0] - cap.truth.aod[0])) <= 1.5
    # a RIS the recording does not have; a file name for several captures (one RIS by name: tests/measured)
    assert main([*argv, "--ris", "ris7", "-o", str(root / "x.npz")]) == 2
    assert "--ris ris7: " in (err := _one_line(capsys)) and "has no such RIS; it has ris1, ris0" in err
    assert main([*argv, "-o", str(root / "both.npz")]) == 2
    assert "-o is a folder that gets one capture per RIS (ris1.npz, ris0.npz)" in _one_line(capsys)
    assert not (root / "x.npz").exists() and not (root / "both.npz").exists()


def test_npz_of_one_ris_with_the_others_parked(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "ris1.npz"
    assert main(["simulate", "--scene", SCENE, "--ris", "ris1", "--idle", "parked", "--ue", ",".join(map(str, UE)),
                 "--no-noise", "-o", str(out), *TRACE]) == 0
    assert "(ris1 sweeping)" in capsys.readouterr().out
    cap = load_capture(out)
    np.testing.assert_allclose(cap.ris.pose.position, RIS["ris1"])
    assert cap.truth.distance == pytest.approx(_distance("ris1"), abs=1e-9)
    assert cap.provenance["ris_name"] == "ris1"
    assert cap.provenance["idle_ris"] == [{"name": "ris0", "parked_beam": [0.0, 0.0]}]


def test_a_slot_whose_ris_faces_away_holds_no_return(tmp_path, monkeypatch, capsys):
    """The radar at [24, 9, 1.2] stands behind ris0 (it faces -x from x = 19.38) and 10.1 m in front of ris1."""
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp_path / "cache"))
    folder = tmp_path / "dca"
    assert main(["simulate", "--scene", SCENE, "--ue", "24,9,1.2", "--format", "dca1000", "--idle", "parked",
                 "-o", str(folder), *TRACE]) == 0
    out = capsys.readouterr().out
    assert "note: the radar stands behind ris0's panel: its slot holds no return" in out
    assert "(ris1 sweeping)" in out and "(ris0 sweeping)" not in out
    schedules = read_sweep_schedules(folder / "sweep.toml")
    assert schedules.names == ("ris0", "ris1") and schedules.first_frames() == (0, 61)
    assert schedules.division["idle"] == "parked"
    np.testing.assert_allclose(schedules.schedule("ris0").ris_position, RIS["ris0"])
    assert (folder / "adc_data_Raw_0.bin").stat().st_size == 122 * 128 * 600 * 4      # frames x chirps x samples x I/Q


@pytest.mark.parametrize("argv, message", [
    (["--scene", SCENE, "--ris", "ris7"],
     "--ris='ris7': the scene 'paper_hall_2ris' has no such RIS; it has ris0, ris1"),
    (["--scene", SCENE, "--ris", "2"], "has no such RIS; it has ris0, ris1"),
    (["--ris", "ris1"], "--ris chooses among the RISs of a hall; give --scene NAME with it"),
    (["--idle", "parked"], "--idle chooses among the RISs of a hall"),
    (["--scene", SCENE, "--ris", "ris0", "--ue", "25,9,1.2"], "--ris ris0: the radar stands behind ris0's panel"),
    (["--scene", SCENE, "--schedule", "SCHEDULE"], "--schedule places the slots of several RISs"),
    (["--scene", SCENE, "--format", "dca1000", "--schedule", "OVERLAP"], "overlap"),
    (["--scene", SCENE, "--format", "dca1000", "--schedule", "UNKNOWN"], "order names RIS 'ris9'"),
    (["--scene", SCENE, "--format", "dca1000", "--schedule", "SCHEDULE", "--idle", "parked"],
     "--idle and --schedule both"),
    (["--scene", SCENE, "--format", "dca1000", "--schedule", "FRACTION"],
     "[schedule]: the slot of 'ris1' starts at 556.56 ms = 62.12 frames of 8.96 ms; a recording's slots start on whole"),
    (["--scene", SCENE, "--format", "dca1000", "--ue-velocity", "0.5,0,0"],
     "a moving radar in a time-division recording is not modelled"),
])
def test_bad_several_ris_input_is_one_line(tmp_path, capsys, argv, message):
    files = {"SCHEDULE": '[schedule]\norder = ["ris0", "ris1"]\n',
             "OVERLAP": '[schedule]\norder = ["ris0", "ris1"]\nstart_ms = [0.0, 100.0]\n',
             "UNKNOWN": '[schedule]\norder = ["ris0", "ris9"]\n',
             "FRACTION": '[schedule]\ngap_ms = 10.0\n'}
    for name, text in files.items():
        (tmp_path / f"{name}.toml").write_text(text)
    argv = [str(tmp_path / f"{a}.toml") if a in files else a for a in argv]
    out = tmp_path / ("dca" if "dca1000" in argv else "x.npz")
    assert main(["simulate", *argv, "-o", str(out), *TRACE]) == 2
    err = _one_line(capsys)
    assert err.startswith("risloc simulate: error: ") and message in err
    assert not out.exists()
