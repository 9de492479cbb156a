"""Sweep alignment (first_frame = "auto"): emulated recordings with a known start, dwell and RIS clock drift.

The emulator (risloc_rt.measured.emulate.recording) switches the RIS chirp by chirp on its own
clock; the truth is the program's start and dwell in radar frames. A beam's selected chirps (one
frame, or K consecutive chirps across two) are right when they lie inside the beam's *true* dwell
(within 2·MIX_TOLERANCE frames).
"""

from __future__ import annotations

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.io.report import process_capture
from risloc_rt.measured import dca1000_radar, import_capture
from risloc_rt.measured.sweep.alignment import MIX_TOLERANCE
from risloc_rt.measured.emulate.recording import RecordingPlan, emulate_recording
from risloc_rt.measured.sweep.ris_timing import OFF, SYNC, RisProgram, chirp_states
from risloc_rt.model.builder import analytic_scenario

DISTANCE, AOD_DEG = 9.3, 17.2


def _scenario(**kw):
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))
    return analytic_scenario(distance=DISTANCE, aod=np.deg2rad((AOD_DEG, 0.0)), radar=radar,
                             processing=ProcessingConfig(n_dft=255, k_dft=64), **kw)


def _worst_margin(beam_chirps, start, dwell, num_chirps=16, frame_width=1.0):
    """Worst margin of a beam's chirps inside its true dwell [frames] (negative: some chirps in another state).

    ``beam_chirps``: the provenance's ``[[frame, first chirp, count], ...]`` per beam; chirp k of frame f spans
    ``[f + k·w/K, f + (k+1)·w/K)``.
    """
    c = frame_width / num_chirps
    worst = np.inf
    for m, segments in enumerate(beam_chirps):
        t = np.concatenate([f + (k0 + np.arange(n)) * c for f, k0, n in segments])
        worst = min(worst, t[0] - (start + m * dwell), start + (m + 1) * dwell - (t[-1] + c))
    return float(worst)


def test_chirp_states_follow_the_program():
    prog = RisProgram(num_beams=3, frames_per_beam=2, sync_on=1, sync_off=2, sync_cycles=2, sync_gap=1)
    assert prog.sync_length == 7
    t = np.arange(0, 16, 0.5)
    st = chirp_states(prog, t, start=8.0, dwell=2.0)        # the sync starts at frame 1
    expect = {0.0: OFF, 1.0: SYNC, 1.5: SYNC, 2.0: OFF, 4.0: SYNC, 5.0: OFF, 7.5: OFF, 8.0: 0, 9.5: 0, 10.0: 1,
              13.5: 2, 14.0: OFF}
    for time, state in expect.items():
        assert st[int(time * 2)] == state, time
    stretched = chirp_states(prog, np.array([8.0 + 2.1 * 1.5]), start=8.0, dwell=2.1)   # dwell 2.1: beam 1 at 10.1
    assert stretched[0] == 1 and chirp_states(prog, np.array([10.05]), start=8.0, dwell=2.1)[0] == 0


@pytest.fixture(scope="module")
def drifting(tmp_path_factory):
    """Lead 7.4 frames, 3 sync cycles (3 on, 3 off), gap 2, 2 frames per beam, RIS clock +1.3 %, leakage."""
    plan = RecordingPlan(lead_frames=7.4, frames_per_beam=2, sync_on=3, sync_off=3, sync_cycles=3, sync_gap=2,
                         clock_drift=0.013, tail_frames=3, leakage_dbm=-30.0, leakage_jitter=0.05)
    return emulate_recording(_scenario(), tmp_path_factory.mktemp("drift") / "rec", plan=plan,
                             rng=np.random.default_rng(2))


def test_auto_alignment_finds_start_and_drift_and_localizes(drifting, tmp_path, capsys):
    rec, exp = drifting, drifting.experiment
    assert exp.schedule.first_frame is None and exp.schedule.sync_cycles == 3
    out = tmp_path / "auto.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "alignment auto:" in text and "confidence" in text
    cap = load_capture(out)
    a = cap.provenance["alignment"]
    print(f"auto alignment: start {a['start']:.3f} (true {rec.start:.3f}) frames, dwell {a['dwell']:.5f} (true "
          f"{rec.dwell:.5f}), drift {a['drift']:+.5f} (true +0.01300), confidence {a['confidence']:.3f}, worst chirp margin "
          f"{_worst_margin(a['beam_chirps'], rec.start, rec.dwell):+.3f} frames")
    assert a["method"] == "auto" and 0.5 <= a["confidence"] <= 1.0
    assert abs(a["start"] - rec.start) <= 0.15                      # frames
    assert abs(a["drift"] - 0.013) <= 0.002
    assert _worst_margin(a["beam_chirps"], rec.start, rec.dwell) >= -2 * MIX_TOLERANCE   # frames: 1.6 chirps
    assert a["feature"]["range"] == pytest.approx(DISTANCE, abs=0.5)
    loc, _ = process_capture(cap)
    assert abs(loc.distance - DISTANCE) < 0.02 and abs(np.rad2deg(loc.aod[0]) - AOD_DEG) < 1.5
    # The manual override stays: the first frame given on the command line, beam m at first + m*frames_per_beam.
    manual = tmp_path / "manual.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(manual), "--first-frame", "28"]) == 0
    m = load_capture(manual)
    assert m.provenance["alignment"]["method"] == "manual" and m.provenance["alignment"]["confidence"] is None
    np.testing.assert_array_equal(m.frame_index, 28 + 2 * np.arange(61))


def test_no_sync_three_frames_per_beam_slow_clock(tmp_path):
    """No sync pattern: the beam-dependent power alone (edges and main-lobe boundaries) places the sweep."""
    plan = RecordingPlan(lead_frames=12.3, frames_per_beam=3, clock_drift=-0.008, tail_frames=6)
    rec = emulate_recording(_scenario(tx_power_dbm=30.0), tmp_path / "rec", plan=plan, rng=np.random.default_rng(4))
    exp = rec.experiment
    cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    a = cap.provenance["alignment"]
    print(f"no sync: start {a['start']:.3f} (true {rec.start:.3f}), drift {a['drift']:+.5f} (true -0.00800), "
          f"confidence {a['confidence']:.3f}")
    assert abs(a["start"] - rec.start) <= 0.25 and abs(a["drift"] + 0.008) <= 0.002
    assert _worst_margin(a["beam_chirps"], rec.start, rec.dwell) >= -2 * MIX_TOLERANCE


def test_a_recording_without_the_ris_is_refused_in_one_line(tmp_path, capsys):
    scenario = _scenario()
    from dataclasses import replace
    dead = replace(scenario, ris=replace(scenario.ris, amplification_db=-60.0))     # the RIS never shows
    rec = emulate_recording(dead, tmp_path / "rec", plan=RecordingPlan(lead_frames=5, frames_per_beam=2, tail_frames=5),
                            rng=np.random.default_rng(6))
    exp = rec.experiment
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(tmp_path / "c.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "could not be found reliably" in err and "--first-frame" in err
    assert not (tmp_path / "c.npz").exists()


@pytest.mark.parametrize("flag, value, message", [
    ("--first-frame", "soon", "--first-frame 'soon' must be 'auto' or a frame index"),
    ("--channels", "0,x", "--channels '0,x' must be comma-separated"),
    ("--channels", "3", "channel = 3 but the configuration has 1 virtual channel"),
    ("--gate-range", "-1", "gate range -1.0 must be a positive number of metres"),
])
def test_bad_import_options_are_one_line_errors(drifting, tmp_path, capsys, flag, value, message):
    exp = drifting.experiment
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(tmp_path / "c.npz"), flag, value]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err, err
