"""Issue 19 item 3: a size a measured input declares is checked before anything of that size exists.

Each hostile file ends in one line (``BudgetError`` or ``MeasuredFormatError``) naming the file and
the field; none of these tests allocates more than a few MiB. The last test runs the worst cases
in a child process under ``RISLOC_MEMORY_LIMIT=1G`` and holds its peak RSS to the limit + 200 MiB.

Inputs are written here by hand (SDK ``.cfg`` text, Studio JSON, DCA1000 packet headers as
``<u4`` sequence + 48-bit byte count) so that the reader is not checked against its own writer.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dsp.budget import BudgetError
from risloc_rt.cli import main
from risloc_rt.measured import (MeasuredFormatError, RawLayout, import_capture, inspect_capture, parse_sweep_schedule,
                                read_raw, read_studio_json)

LIMIT = "1G"


@pytest.fixture(autouse=True)
def _limit(monkeypatch):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", LIMIT)


# ---------------------------------------------------------------------------------------------- test-side writers

def studio_doc(*, chirp_end: int = 2, frame_end: int = 2, loops: int = 64) -> dict:
    """An mmWave Studio export (3 Tx x 4 Rx, 256 samples); one rlChirps entry covers 0…chirp_end."""
    chirp = {"chirpStartIdx": 0, "chirpEndIdx": chirp_end, "profileId": 0, "startFreqVar_MHz": 0.0,
             "freqSlopeVar_KHz_usec": 0.0, "idleTimeVar_usec": 0.0, "adcStartTimeVar_usec": 0.0, "txEnable": "0x1"}
    profile = {"profileId": 0, "startFreqConst_GHz": 60.25, "idleTimeConst_usec": 7.0, "adcStartTimeConst_usec": 6.0,
               "rampEndTime_usec": 60.0, "freqSlopeConst_MHz_usec": 64.985, "txStartTime_usec": 1.0,
               "numAdcSamples": 256, "digOutSampleRate": 5000.0, "rxGain_dB": 30}
    rf = {"rlChanCfg_t": {"rxChannelEn": "0xF", "txChannelEn": "0x7"},
          "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": 2, "b2AdcOutFmt": 1}},
          "rlProfiles": [{"rlProfileCfg_t": profile}], "rlChirps": [{"rlChirpCfg_t": chirp}],
          "rlFrameCfg_t": {"chirpStartIdx": 0, "chirpEndIdx": frame_end, "numLoops": loops, "numFrames": 8,
                           "framePeriodicity_msec": 40.0}}
    return {"mmWaveDevices": [{"rfConfig": rf}]}


def sdk_cfg(num_samples: int, *, num_loops: int = 16, num_frames: int = 0) -> str:
    """1 Rx, 1 Tx, complex1x: a frame is 4·N·num_loops bytes."""
    return (f"channelCfg 1 1 0\nadcCfg 2 1\nadcbufCfg -1 0 0 1 1\n"
            f"profileCfg 0 60 30.2 6 19.8 0 0 68.69 0 {num_samples} 10000 0 0 30\n"
            f"chirpCfg 0 0 0 0 0 0 0 1\nframeCfg 0 0 {num_loops} {num_frames} 0.8 1 0\n")


def zeros_file(path: Path, size: int) -> Path:
    """A sparse file of ``size`` zero bytes (no disk, no memory)."""
    with open(path, "wb") as fh:
        fh.truncate(size)
    return path


def header(sequence: int, byte_count: int) -> bytes:
    """DCA1000 packet header: sequence number <u4, then the byte count as 6 little-endian bytes."""
    return sequence.to_bytes(4, "little") + byte_count.to_bytes(6, "little")


def schedule_text(*, step: str = "1.5", rows: int = 16, columns: int = 4) -> str:
    return (f"frames_per_beam = 1\nfirst_frame = 0\n[sweep]\nstart_deg = -45.0\nstop_deg = 45.0\nstep_deg = {step}\n"
            f"[ris]\nposition = [0.0, 13.38, 0.0]\nfacing = [0.0, 12.38, 0.0]\nloopback_delay_ns = 1.78\n"
            f"rows = {rows}\ncolumns = {columns}\n")


P = 20                                                       # payload bytes of the hand-built packet files
LAYOUT = RawLayout(num_samples=4, num_rx=1, chirps_per_loop=1, num_loops=2)     # 32 bytes per frame
STREAM = np.arange(48, dtype="<i2").tobytes()                                   # 3 frames, 5 payloads


def packet_file(path: Path, headers: dict[int, tuple[int, int]]) -> Path:
    """The 3-frame stream as packets k = 0…4 with header (k + 1, k·P), except those ``headers`` replaces."""
    payloads = [STREAM[i:i + P] for i in range(0, len(STREAM), P)]
    path.write_bytes(b"".join(header(*headers.get(k, (k + 1, k * P))) + p for k, p in enumerate(payloads)))
    return path


# ---------------------------------------------------------------------------------------------- mmWave Studio JSON

@pytest.mark.parametrize(("where", "doc"), [
    (r"rlChirps\[0\]\.rlChirpCfg_t\.chirpEndIdx=10000000000 is outside 0…511", studio_doc(chirp_end=10**10)),
    (r"rlFrameCfg_t\.chirpEndIdx=10000000000 is outside 0…511", studio_doc(chirp_end=511, frame_end=10**10)),
    (r"rlFrameCfg_t\.numLoops=1000000000000 must be 1…255", studio_doc(loops=10**12)),
])
def test_studio_json_chirp_ranges_and_loops_are_bounded(tmp_path, where, doc):
    path = tmp_path / "capture.mmwave.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(MeasuredFormatError, match=rf"^{path}: mmWaveDevices\[0\]\.rfConfig\.{where}"):
        read_studio_json(path)          # before: chirpEndIdx 1e10 expanded index by index, 5.4 GB then MemoryError


def test_studio_json_full_chirp_range_still_reads(tmp_path):
    path = tmp_path / "capture.mmwave.json"
    path.write_text(json.dumps(studio_doc(chirp_end=511, frame_end=511)))      # every chirp configuration used
    cfg = read_studio_json(path).config
    assert cfg.chirps_per_loop == 512 and cfg.num_loops == 64 and cfg.num_rx == 4


# ---------------------------------------------------------------------------------------------- DCA1000 raw files

def test_packet_header_declaring_terabytes_is_refused(tmp_path):
    s = 2**32 - 1                                            # last packet: sequence 2^32-1, consistent byte count
    path = packet_file(tmp_path / "adc_data_Raw_0.bin", {4: (s, (s - 1) * P)})
    declared = (s - 1) * P + 16
    with pytest.raises(MeasuredFormatError, match=rf"declares a stream of {declared:,} bytes but the files hold "
                                                  r"96 bytes of payload: 100\.0% would be lost packets"):
        read_raw(path, LAYOUT)
    with pytest.raises(MeasuredFormatError, match="lost packets"):
        inspect_capture(path, LAYOUT)


def test_mid_stream_sequence_jump_marks_only_the_frames_read(tmp_path):
    s = 2**32 - 1                                            # packet 3 jumps; packets 4, 5 then come "late"
    path = packet_file(tmp_path / "adc_data_Raw_0.bin", {2: (s, (s - 1) * P)})
    cap = read_raw(path, LAYOUT)
    assert cap.info.num_frames == 3 and cap.damaged_frames == (1, 2)
    assert cap.dropped[0].stream_offset == 2 * P and cap.dropped[0].num_bytes == (s - 1) * P - 2 * P
    words = np.frombuffer(STREAM, "<i2")
    i, q = cap.cube.real.ravel(), -cap.cube.imag.ravel()     # 2 lanes: I0 I1 Q0 Q1 per sample pair
    np.testing.assert_array_equal(i[:8], words[:16].reshape(4, 2, 2)[:, 0].ravel())   # frame 0 as written
    np.testing.assert_array_equal(q[:8], words[:16].reshape(4, 2, 2)[:, 1].ravel())
    assert not cap.cube[2].any()                             # the gap's zeros, cut at the last frame


def test_whole_read_and_inspection_blocks_are_checked(tmp_path):
    cfg = tmp_path / "c.cfg"
    cfg.write_text(sdk_cfg(2**20))                           # 64 MiB frames (numFrames 0: the file decides)
    raw = zeros_file(tmp_path / "big.bin", 2**26)
    with pytest.raises(BudgetError, match=r"big\.bin: inspecting 1 frame\(s\) of 16 loops x 1 channels x 1048576 "
                                          r"samples .* needs about 1\.25 GiB of memory, more than the limit 1 GiB"):
        inspect_capture(raw, cfg, form="raw")
    raw = zeros_file(tmp_path / "huge.bin", 2**31)           # 32 frames: 4 GiB as complex64
    with pytest.raises(BudgetError, match=r"huge\.bin: 32 frames of 2,147,483,648 bytes of raw stream read whole"):
        read_raw(raw, RawLayout(num_samples=2**20, num_rx=1, chirps_per_loop=1, num_loops=16), form="raw")


# ---------------------------------------------------------------------------------------------- sweep import

@pytest.mark.parametrize(("text", "what"), [
    (schedule_text(step="1e-9"), r"sweep\.step_deg = 1e-09 from -45 to 45 deg declares 90,000,000,001 beams"),
    (schedule_text(rows=1500, columns=1500),
     r"ris\.rows = 1500 x ris\.columns = 1500 \(2,250,000 elements\) with 61 beams .* needs about 4\.09 GiB"),
    (schedule_text(rows=6000, columns=6000), r"ris\.rows = 6000 x ris\.columns = 6000"),
])
def test_schedule_sizes_are_checked_at_parse(text, what):
    with pytest.raises(BudgetError, match=rf"^sweep\.toml: {what}.*more than the limit 1 GiB"):
        parse_sweep_schedule(text, source="sweep.toml")


def test_real_panels_parse():
    s = parse_sweep_schedule(schedule_text(rows=64, columns=64), source="sweep.toml")    # 8 MiB of beam weights
    assert (s.ris_rows, s.ris_columns, s.num_beams) == (64, 64, 61)


def test_import_checks_the_beams_frames(tmp_path):
    cfg = tmp_path / "c.cfg"
    cfg.write_text(sdk_cfg(2**16, num_frames=61))            # 61 frames of 4 MiB; beams x K x N x 3 x 16 B = 2.86 GiB
    raw = zeros_file(tmp_path / "adc_data_Raw_0.bin", 61 * 2**22)
    sched = tmp_path / "sweep.toml"
    sched.write_text(schedule_text())
    with pytest.raises(BudgetError, match=r"adc_data_Raw_0\.bin: 61 beams \(sweep schedule\) x 16 loops x 1 channel\(s\)"
                                          r" x 65536 samples .* needs about 2\.86 GiB"):
        import_capture(raw, cfg, sched)


def test_cli_gives_one_line(tmp_path, capsys):
    path = tmp_path / "capture.mmwave.json"
    path.write_text(json.dumps(studio_doc(chirp_end=10**10)))
    raw = zeros_file(tmp_path / "adc_data_Raw_0.bin", 1 << 16)
    assert main(["capture", "inspect", str(raw), "--config", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "chirpEndIdx=10000000000" in err
    cfg = tmp_path / "c.cfg"
    cfg.write_text(sdk_cfg(128, num_frames=0))
    sched = tmp_path / "sweep.toml"
    sched.write_text(schedule_text(rows=6000, columns=6000))
    assert main(["capture", "import", str(raw), "--config", str(cfg), "--sweep", str(sched),
                 "-o", str(tmp_path / "c.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "ris.rows = 6000" in err and "limit 1 GiB" in err


# ---------------------------------------------------------------------------------------------- peak memory

CHILD = r"""
import json, resource, sys
limit = 6 << 30                    # an unchecked case fails fast (MemoryError) instead of swapping the machine
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
import numpy as np
from risloc_rt.measured import RawLayout, import_capture, inspect_capture, read_raw, read_studio_json
from risloc_rt.model.ris import ris_response
cases = json.loads(sys.argv[1])
lay = RawLayout(num_samples=4, num_rx=1, chirps_per_loop=1, num_loops=2)
def run(name, a):
    if name == "json":
        return read_studio_json(a["json"])
    if name in ("jump_end", "jump_mid"):
        return read_raw(a[name], lay).cube.shape, inspect_capture(a[name], lay).frames
    if name == "inspect":
        return inspect_capture(a["big"], a["cfg"], form="raw")
    if name == "ris":              # what simulate/compare/calibrate do with an imported capture's RIS
        cap = import_capture(a["raw"], a["cfg61"], a["ris"])
        aod = np.array([[0.3, 0.0]])
        return ris_response(cap.ris, cap.sweep, aod, aod, wavelength=cap.radar.wavelength).shape
out = {}
for name in ("json", "jump_end", "jump_mid", "inspect", "ris"):
    try:
        run(name, cases)
        out[name] = "ok"
    except Exception as exc:
        out[name] = type(exc).__name__
# the peak RSS of this process image: VmHWM (ru_maxrss would include the pytest process's RSS,
# which a vfork'ed child carries over its exec)
out["peak"] = 1024 * int(next(l for l in open("/proc/self/status") if l.startswith("VmHWM:")).split()[1])
print(json.dumps(out))
"""


@pytest.mark.slow
def test_worst_cases_stay_within_the_limit(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps(studio_doc(chirp_end=10**10)))
    s = 2**32 - 1
    cfg = tmp_path / "c.cfg"
    cfg.write_text(sdk_cfg(2**20))
    cfg61 = tmp_path / "c61.cfg"
    cfg61.write_text(sdk_cfg(128, num_frames=61))
    (tmp_path / "end").mkdir()
    (tmp_path / "mid").mkdir()
    sched = tmp_path / "sweep.toml"
    sched.write_text(schedule_text(rows=1500, columns=1500))
    cases = {"json": str(path), "cfg": str(cfg), "cfg61": str(cfg61), "ris": str(sched),
             "jump_end": str(packet_file(tmp_path / "end" / "adc_data_Raw_0.bin", {4: (s, (s - 1) * P)})),
             "jump_mid": str(packet_file(tmp_path / "mid" / "adc_data_Raw_0.bin", {2: (s, (s - 1) * P)})),
             "big": str(zeros_file(tmp_path / "big.bin", 2**26)),
             "raw": str(zeros_file(tmp_path / "adc_data_Raw_0.bin", 61 * 4 * 128 * 16))}
    limit = 1 << 30
    with open(tmp_path / "out.txt", "w+") as out, open(tmp_path / "err.txt", "w+") as err:
        proc = subprocess.Popen([sys.executable, "-c", CHILD, json.dumps(cases)], stdout=out, stderr=err,
                                env=dict(os.environ, RISLOC_MEMORY_LIMIT=LIMIT))
        proc.wait()
    assert proc.returncode == 0, (tmp_path / "err.txt").read_text()[-2000:]
    result = json.loads((tmp_path / "out.txt").read_text())
    peak = result.pop("peak")                                    # the child's VmHWM [bytes]
    assert result == {
        "json": "MeasuredFormatError", "jump_end": "MeasuredFormatError", "jump_mid": "ok", "inspect": "BudgetError",
        "ris": "BudgetError"}
    assert peak < limit + (200 << 20), f"child peak RSS {peak / 2**20:.0f} MiB"
