"""Live sweeps (measured.live.live_sweeps): a growing recording localized sweep by sweep equals the file import.

The honesty test of issue 24: live localization of an emulated sweep gives the same answer as
importing the same recording from files. A finished emulated recording is revealed into a "live"
folder a few frames at a time, cut at arbitrary byte offsets (and into split files), as the
recorder writes it (``[0, final_bytes)`` on disk and final); the watcher is fed ``final_bytes``.
The reference is the command line on the finished folder: ``risloc capture import`` (with
``--first-frame`` of the sweep when the recording holds several) and ``risloc locate --out``'s
``result.json``. Position, σ and flags must be equal (to 1e-12 m; they are in fact bit for bit).

Recordings (a small radar, N = 128 samples, K = 16 chirps, 31 beams, so each sweep imports in a
fraction of a second): two sweeps one after another with a fixed first frame; lead frames, a sync
code and a drifting RIS clock (``first_frame = "auto"``); two RISs in time division; the two-sweep
recording with lost packets zero-filled at their place on the DCA1000's 1456-byte packet grid
(DCA1000EVM user's guide, raw-mode packet format; the payload size is written out here, not taken
from the package), one of them in the second sweep, whose first frame is not on the grid.
"""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.measured.emulate.experiment import dca1000_radar, emulate_capture
from risloc_rt.measured.emulate.recording import RecordingPlan, emulate_recording
from risloc_rt.measured.emulate.time_division import emulate_time_division
from risloc_rt.measured.live import live_sweeps
from risloc_rt.measured.live.live_sweeps import FusedLiveFix, LiveFix, SweepWatcher
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

#: The DCA1000's data payload per UDP packet [bytes] (DCA1000EVM user's guide, section 5 data format).
PAYLOAD = 1456
BEAMS = 31
UE = (0.0, 0.0, 0.0)
RIS = {"north": ((2.0, 9.0, 0.0), (-1.0, 0.0, 0.0)), "east": ((8.0, 3.0, 0.0), (0.0, 1.5, 0.0))}
TOL = 1e-12
"""Live against file [m]."""


def _radar():
    return dca1000_radar(RadarConfig(num_samples=128, num_chirps=16))


def _scenario(ris="north", radar=None):
    position, facing = RIS[ris]
    angles = np.deg2rad(np.stack([np.linspace(-45, 45, BEAMS), np.zeros(BEAMS)], axis=1))
    return analytic_scenario(ue_position=UE, ris_position=position, ris_facing=facing, radar=radar or _radar(),
                             processing=ProcessingConfig(n_dft=255, k_dft=64), sweep=BeamSweep(angles))


def _stream(folder: Path) -> bytes:
    files = sorted(folder.glob("adc_data_Raw_*.bin"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    return b"".join(p.read_bytes() for p in files)


def _concatenate(parts: list[Path], folder: Path) -> Path:
    """One recording of the parts' sweeps one after another (their .cfg's numFrames summed; the first schedule)."""
    folder.mkdir(parents=True)
    stream = b"".join(_stream(p) for p in parts)
    (folder / "adc_data_Raw_0.bin").write_bytes(stream)
    cfg = (parts[0] / "adc_data.cfg").read_text()
    frames = sum(int(re.search(r"^frameCfg \S+ \S+ \S+ (\d+)", (p / "adc_data.cfg").read_text(), re.M)[1])
                 for p in parts)
    (folder / "adc_data.cfg").write_text(re.sub(r"^(frameCfg \S+ \S+ \S+ )(\d+)", rf"\g<1>{frames}", cfg, flags=re.M))
    shutil.copy(parts[0] / "sweep.toml", folder / "sweep.toml")
    return folder


class Growing:
    """A finished recording revealed into ``live`` in steps, as the recorder writes it (split files, in place)."""

    def __init__(self, source: Path, live: Path, *, split_size: int | None = None):
        self.stream = _stream(source)
        self.live = live
        self.split = split_size or len(self.stream) + 1
        live.mkdir(parents=True)
        for name in ("adc_data.cfg", "sweep.toml"):
            shutil.copy(source / name, live / name)
        self.written = 0

    def reveal(self, upto: int) -> int:
        upto = min(upto, len(self.stream))
        while self.written < upto:
            index, offset = divmod(self.written, self.split)
            n = min(upto - self.written, self.split - offset)
            with open(self.live / f"adc_data_Raw_{index}.bin", "ab") as fh:
                fh.write(self.stream[self.written:self.written + n])
            self.written += n
        return self.written


def run_live(source: Path, live: Path, *, step: int, split_size: int | None = None, **kw):
    """Reveal ``source`` ``step`` bytes at a time into ``live``, feeding a watcher; ``(events, log)`` where log holds
    ``(final_bytes, events)`` per update (the last is the finish)."""
    growing = Growing(source, live, split_size=split_size)
    growing.reveal(1)
    watcher = SweepWatcher(live, **kw)
    log = []
    while growing.written < len(growing.stream):
        final = growing.reveal(growing.written + step)
        now = time.monotonic()                      # the recorder's clock: when final_bytes grew
        log.append((final, watcher.update(final, now) if final < len(growing.stream) else watcher.finish(final, now)))
    events = [e for _, got in log for e in got]
    return events, log, watcher


def reference(folder: Path, out: Path, *, first_frame: int | None = None) -> dict:
    """``risloc capture import`` + ``risloc locate --out`` of the finished folder: ``{name: case}`` (+ "fused")."""
    args = ["capture", "import", str(folder / "adc_data_Raw_0.bin"), "--config", str(folder / "adc_data.cfg"),
            "--sweep", str(folder / "sweep.toml")]
    several = "[[ris]]" in (folder / "sweep.toml").read_text()
    target = out / ("captures" if several else "capture.npz")
    assert main(args + ["-o", str(target)] + ([] if first_frame is None else ["--first-frame", str(first_frame)])) == 0
    files = sorted(target.glob("*.npz")) if several else [target]
    found = {}
    for f in files:
        assert main(["locate", str(f), "--out", str(out / f"result_{f.stem}")]) in (0, 3)
        found[f.stem] = json.loads((out / f"result_{f.stem}" / "result.json").read_text())["cases"][0]
    if several:
        assert main(["locate", *map(str, files), "--out", str(out / "result_fused")]) in (0, 3)
        found["fused"] = json.loads((out / "result_fused" / "result.json").read_text())["fused"]
    return found


def assert_same(fix: LiveFix, case: dict):
    """Position, σ per axis and flags of a live fix equal to ``risloc locate``'s result.json case."""
    est = case["estimate"]
    assert fix.detected and case["detection"]["detected"]
    assert np.max(np.abs(np.subtract(fix.position, est["position"]))) <= TOL
    assert np.max(np.abs(np.subtract(fix.std, est["std"]["position"]))) <= TOL
    assert fix.peb == pytest.approx(est["std"]["peb"], abs=TOL)
    assert [{"code": c, "message": m} for c, m in fix.flags] == case["flags"]


def assert_complete_when_reported(log, watcher, events):
    """Every fix came at the first update whose final bytes hold its last beam's frame (not before, not later)."""
    fb = watcher.frame_bytes
    for i, (final, got) in enumerate(log):
        for fix in (e for e in got if isinstance(e, LiveFix)):
            end = (max(fix.frames) + 1) * fb
            assert end <= final, f"sweep {fix.sweep} reported before its last frame was final"
            if not watcher.auto:          # the margin of "auto" delays it on purpose (module docstring)
                ready = -(-end // PAYLOAD) * PAYLOAD
                assert i == 0 or log[i - 1][0] < min(ready, log[-1][0]), f"sweep {fix.sweep} reported late"
    keys = [(e.sweep, getattr(e, "ris", None), type(e).__name__) for e in events]
    assert len(keys) == len(set(keys)), "a sweep reported twice"


# ------------------------------------------------------------------------------------------ recordings


@pytest.fixture(scope="module")
def two_sweeps(tmp_path_factory):
    """Two sweeps back to back (frames 0-30, 31-61), first_frame = 0, one frame per beam: period 31 frames."""
    root = tmp_path_factory.mktemp("two")
    sc = _scenario()
    parts = []
    for k in range(2):
        emulate_capture(simulate(sc, rng=np.random.default_rng(10 + k)), root / f"part{k}")
        parts.append(root / f"part{k}")
    return _concatenate(parts, root / "rec")


def test_fixed_first_frame_two_sweeps_equal_the_file_import(two_sweeps, tmp_path):
    events, log, watcher = run_live(two_sweeps, tmp_path / "live", step=3 * 8192 + 1001)
    assert not watcher.auto and watcher.period == BEAMS and watcher.frame_bytes == 8192
    assert [(e.sweep, e.ris) for e in events] == [(0, ""), (1, "")]
    assert_complete_when_reported(log, watcher, events)
    for fix in events:
        assert fix.error is None and fix.lost_packets == 0
        assert fix.frames == tuple(range(BEAMS * fix.sweep, BEAMS * (fix.sweep + 1)))
        assert fix.window == (BEAMS * fix.sweep, BEAMS * (fix.sweep + 1))     # one sweep read, nothing more
        ref = reference(two_sweeps, tmp_path / f"ref{fix.sweep}", first_frame=BEAMS * fix.sweep)
        assert_same(fix, ref["capture"])
        assert 0 <= fix.latency < 10.0                     # one sweep imported and localized [s]


SYNC_PLAN = RecordingPlan(lead_frames=4.3, frames_per_beam=2, sync_on=3, sync_off=3, sync_cycles=3, sync_gap=2,
                          clock_drift=0.004, tail_frames=3)


@pytest.fixture(scope="module")
def synced(tmp_path_factory):
    """Lead frames, a sync code (3 x 3 frames on, 3 off), a gap, two frames per beam and a RIS clock 0.4 % slow;
    the schedule says first_frame = "auto"."""
    rec = emulate_recording(_scenario(), tmp_path_factory.mktemp("sync") / "rec", plan=SYNC_PLAN,
                            rng=np.random.default_rng(5))
    return rec


def test_lead_frames_and_sync_code_auto_equal_the_file_import(synced, tmp_path):
    folder = synced.experiment.folder
    assert 'first_frame = "auto"' in (folder / "sweep.toml").read_text()      # found from the sync code
    events, log, watcher = run_live(folder, tmp_path / "live", step=2 * 8192 + 77)
    assert watcher.auto
    fixes = [e for e in events if e.error is None]
    assert len(fixes) == 1 and fixes[0].sweep == 0
    fix = fixes[0]
    np.testing.assert_array_equal(fix.frames, synced.true_frame_index)
    assert_complete_when_reported(log, watcher, events)
    # the first fix needs the lead frames, the code, the gap, the sweep and the margin to be final
    reported = next(final for final, got in log if got)
    assert reported >= (synced.start + BEAMS * synced.dwell + watcher.margin_frames) * watcher.frame_bytes
    assert_same(fix, reference(folder, tmp_path / "ref")["capture"])


@pytest.fixture(scope="module")
def two_ris(tmp_path_factory):
    """Two RISs in time division: 2 lead frames, north's sweep, 3 idle frames, east's sweep, 2 tail frames."""
    radar = _radar()
    scenarios = [_scenario(name, radar) for name in RIS]
    captures = [simulate(s, rng=np.random.default_rng(20 + k)) for k, s in enumerate(scenarios)]
    idle = np.zeros(captures[0].cube.shape[1:], complex)
    rec = emulate_time_division(list(RIS), [s.ris for s in scenarios], captures,
                                tmp_path_factory.mktemp("td") / "rec", idle=idle, rng=np.random.default_rng(9),
                                first_frames=(2, 2 + BEAMS + 3), tail_frames=2,
                                division={"order": list(RIS), "idle": "off"})
    return rec


def test_two_ris_time_division_equal_the_file_import(two_ris, tmp_path):
    folder = two_ris.folder
    events, log, watcher = run_live(folder, tmp_path / "live", step=5 * 8192 + 333)
    assert [(type(e).__name__, e.sweep, getattr(e, "ris", None)) for e in events] == [
        ("LiveFix", 0, "north"), ("LiveFix", 0, "east"), ("FusedLiveFix", 0, None)]
    assert_complete_when_reported(log, watcher, events)
    ref = reference(folder, tmp_path / "ref")
    for fix in events[:2]:
        assert fix.frames[0] == two_ris.first_frames[list(RIS).index(fix.ris)]
        assert_same(fix, ref[fix.ris])
    fused = events[2]
    assert isinstance(fused, FusedLiveFix) and fused.detected
    assert list(fused.used) == ref["fused"]["used"]
    assert np.max(np.abs(np.subtract(fused.position, ref["fused"]["position"]))) <= TOL
    # result.json writes an unobservable axis's inf as null
    np.testing.assert_allclose(fused.std, [np.inf if s is None else s for s in ref["fused"]["std"]], rtol=0, atol=TOL)
    assert [{"code": c, "message": m} for c, m in fused.flags] == ref["fused"]["flags"]


@pytest.fixture(scope="module")
def lossy(two_sweeps, tmp_path_factory):
    """The two-sweep recording with lost packets zero-filled at their place on the packet grid: one in sweep 0
    (frame 3), one across the boundary of frames 35 and 36 (sweep 1's beams 4 and 5), one in frame 32."""
    folder = tmp_path_factory.mktemp("lossy") / "rec"
    shutil.copytree(two_sweeps, folder)
    stream = bytearray(_stream(two_sweeps))
    fb = 8192
    packets = {3 * fb // PAYLOAD + 1, 36 * fb // PAYLOAD, 32 * fb // PAYLOAD + 2}
    for j in packets:
        stream[j * PAYLOAD:(j + 1) * PAYLOAD] = bytes(PAYLOAD)
    (folder / "adc_data_Raw_0.bin").write_bytes(bytes(stream))
    assert (36 * fb) % PAYLOAD and (31 * fb) % PAYLOAD          # sweep 1 and the straddling packet: off the grid
    return folder, sorted(packets)


def test_lost_packets_are_flagged_and_equal_the_file_import(lossy, tmp_path):
    folder, packets = lossy
    events, log, watcher = run_live(folder, tmp_path / "live", step=4 * 8192 + 5, split_size=40 * PAYLOAD)
    assert len(sorted((tmp_path / "live").glob("adc_data_Raw_*.bin"))) > 5       # read across split files
    assert [e.sweep for e in events] == [0, 1]
    assert_complete_when_reported(log, watcher, events)
    assert events[0].lost_packets == 1 and events[1].lost_packets == 2
    for fix in events:
        ref = reference(folder, tmp_path / f"ref{fix.sweep}", first_frame=BEAMS * fix.sweep)
        assert "damaged-beams" in [c for c, _ in fix.flags]
        assert_same(fix, ref["capture"])
    # sweep 1 starts off the packet grid: its window starts earlier, on the grid, to find the same lost packets
    assert events[1].window[0] < BEAMS and (events[1].window[0] * 8192) % PAYLOAD == 0


def test_memory_one_sweep_at_a_time(two_sweeps, tmp_path, monkeypatch):
    """No read covers more than one sweep (+ the packet that ends it); the temporary windows are removed."""
    reads = []
    original = live_sweeps.read_stream

    def spy(files, start, stop):
        reads.append((start, stop))
        return original(files, start, stop)

    monkeypatch.setattr(live_sweeps, "read_stream", spy)
    work = tmp_path / "work"
    work.mkdir()
    events, _, _ = run_live(two_sweeps, tmp_path / "live", step=10 * 8192, workdir=work)
    assert len(events) == 2 and reads
    assert max(stop - start for start, stop in reads) <= BEAMS * 8192 + PAYLOAD
    assert list(work.iterdir()) == []


def test_auto_finds_each_later_sweep_around_its_predicted_start(synced, tmp_path):
    """Two recordings with lead frames, sync code and drifting clock back to back: the second sweep is found in a
    window around where the first one's start and dwell put it, and equals the import of its own recording."""
    second = emulate_recording(_scenario(), tmp_path / "second", plan=SYNC_PLAN, rng=np.random.default_rng(6))
    folder = _concatenate([synced.experiment.folder, second.experiment.folder], tmp_path / "rec")
    F = synced.num_frames
    events, log, watcher = run_live(folder, tmp_path / "live", step=3 * 8192 + 999,
                                    period_frames=F / (1 + SYNC_PLAN.clock_drift))
    assert [(e.sweep, e.error) for e in events] == [(0, None), (1, None)]
    assert_complete_when_reported(log, watcher, events)
    np.testing.assert_array_equal(events[0].frames, synced.true_frame_index)
    np.testing.assert_array_equal(events[1].frames, F + second.true_frame_index)
    assert F <= events[1].window[0] < F + second.start                 # the window: around sweep 1 only
    assert_same(events[1], reference(second.experiment.folder, tmp_path / "ref1")["capture"])


def test_bad_watcher_input_is_one_line(two_sweeps, two_ris, tmp_path):
    from risloc_rt.measured.errors import MeasuredFormatError

    with pytest.raises(MeasuredFormatError, match=r"^sweep period 20 frames is shorter than one sweep \(31 frames\)"):
        SweepWatcher(two_sweeps, period_frames=20)
    with pytest.raises(MeasuredFormatError, match=r"^--first-frame: .* describes 2 RISs in time division"):
        SweepWatcher(two_ris.folder, first_frame=3)
    with pytest.raises(MeasuredFormatError, match=r"radar configuration .*nothing.cfg does not exist"):
        SweepWatcher(two_sweeps, tmp_path / "nothing.cfg")
    watcher = SweepWatcher(two_sweeps)
    assert watcher.update(5 * 8192) == []
    with pytest.raises(MeasuredFormatError, match=r"^final_bytes went back from 40960 to 8192"):
        watcher.update(8192)
