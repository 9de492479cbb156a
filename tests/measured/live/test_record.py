"""The whole recording session on loopback: the radar CLI emulator (a pty) and the DCA1000 emulator (UDP).

The oracle is the source stream itself and the sequence numbers the emulator left out: the
recording must equal the source bytes except at the lost packets, which are zero at their offset
(packet j of the stream carries bytes ``[(j-1)·1456, j·1456)``, TI DCA1000EVM user's guide, data
packet format) and listed in ``lost_packets.csv`` (read here with the standard library). Command
codes are the user's guide's (section 5): RECORD_START 0x05, RECORD_STOP 0x06; the CONFIG_FPGA_GEN
payload of a raw-mode, 2-lane, Ethernet, 16-bit capture is ``01 02 01 02 03 1E`` (rf_api.h
``strFpgaConfigMode``: log mode 1 raw, LVDS mode 2 = two lanes, transfer 1 capture, capture 2
Ethernet, format 3 = 16 bit, timer 30).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.measured import dca1000_radar, emulate_capture
from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000, StreamFaults
from risloc_rt.measured.emulate.radar_cli_server import EmulatedRadarCli
from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.live.addresses import Endpoints
from risloc_rt.measured.live.record import RecordingError, RecordPlan, record, recording_summary
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

P = 1456
RECORD_START, RECORD_STOP, CONFIG_FPGA_GEN = 0x05, 0x06, 0x03
FAST = {"link_timeout": 0.3, "silence_timeout": 0.5, "start_timeout": 3.0, "serial_timeout": 1.0}


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    """An emulated one-sweep DCA1000 folder: 61 frames of 8192 bytes, raw form, adc_data.cfg, sweep.toml."""
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16, carrier_frequency=61.5e9, bandwidth=1e9))
    scenario = analytic_scenario(distance=9.3, aod=np.deg2rad((17.2, 0.0)), radar=radar,
                                 processing=ProcessingConfig(n_dft=255, k_dft=64))
    return emulate_capture(simulate(scenario, rng=np.random.default_rng(5)), tmp_path_factory.mktemp("src") / "dca")


@pytest.fixture
def endpoints(loopback_endpoints):
    return Endpoints(*loopback_endpoints)


def dca1000(exp, ep: Endpoints, **kw) -> EmulatedDca1000:
    return EmulatedDca1000(exp.raw_path, config=exp.config_path, host_ip=ep.host_ip, fpga_ip=ep.fpga_ip,
                           config_port=ep.config_port, data_port=ep.data_port, **kw)


def plan(exp, port: str, out: Path, ep: Endpoints, **kw) -> RecordPlan:
    return RecordPlan(config=exp.config_path, serial_port=port, out=out, sweep=exp.schedule_path, endpoints=ep, **kw)


def recorded(folder: Path) -> bytes:
    files = {int(m[1]): q for q in folder.iterdir() if (m := re.fullmatch(r"adc_data_Raw_(\d+)\.bin", q.name))}
    return b"".join(files[i].read_bytes() for i in sorted(files))


def with_zeros(source: bytes, lost_sequences) -> bytes:
    out = bytearray(source)
    for s in lost_sequences:
        out[(s - 1) * P:s * P] = bytes(len(out[(s - 1) * P:s * P]))
    return bytes(out)


def lost_csv(folder: Path) -> list[tuple[int, ...]]:
    rows = (folder / "lost_packets.csv").read_text().splitlines()
    return [tuple(int(x) for x in r.split(",")) for r in rows[1:]]


def runs_of(sequences) -> list[tuple[int, int]]:
    runs: list[list[int]] = []
    for s in sorted(sequences):
        if runs and s == runs[-1][0] + runs[-1][1]:
            runs[-1][1] += 1
        else:
            runs.append([s, 1])
    return [tuple(r) for r in runs]


def saw(dca: EmulatedDca1000, code: int) -> bool:
    return any(int(c.command) == code for c in dca.commands)


def test_the_recording_is_the_source_except_lost_packets(experiment, endpoints, tmp_path):
    faults = StreamFaults(lost=frozenset({3, 40, 41, 300}), duplicates=frozenset({10}), reorder_probability=0.05)
    source = experiment.raw_path.read_bytes()
    seen = []
    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, speed=2.0, faults=faults,
                                            rng=np.random.default_rng(11)) as dca:
        summary = record(plan(experiment, cli.port, tmp_path / "rec", endpoints), on_progress=seen.append, **FAST)
        lines, commands = cli.lines, list(dca.commands)
    out = tmp_path / "rec"
    lost = dca.lost_sequences
    assert lost == (3, 40, 41, 300) and len(source) == 61 * 8192
    assert recorded(out) == with_zeros(source, lost)
    assert lost_csv(out) == [(s, n, (s - 1) * P, n * P) for s, n in runs_of(lost)]
    assert [(d.first_sequence, d.count) for d in summary.lost] == runs_of(lost)
    assert summary.frames == 61 and summary.partial_frame_bytes == 0 and summary.stopped == "frames"
    assert summary.duplicates == 1 and summary.lost_packets == 4
    assert "sensorStop" in lines[lines.index("sensorStart"):] and lines[-1] == "sensorStop"
    codes = [int(c.command) for c in commands]
    assert codes.index(RECORD_START) < codes.index(RECORD_STOP)
    assert next(c.payload for c in commands if int(c.command) == CONFIG_FPGA_GEN) == bytes.fromhex("0102010203 1E")
    assert (out / "adc_data.cfg").read_bytes() == experiment.config_path.read_bytes()
    assert (out / "sweep.toml").read_bytes() == experiment.schedule_path.read_bytes()
    assert seen and seen[-1].final_bytes <= summary.bytes
    assert seen[0].socket_buffer == summary.socket_buffer and summary.socket_buffer.granted > 0
    assert all(b.final_bytes >= a.final_bytes for a, b in zip(seen, seen[1:]))


def test_capture_import_reads_the_recording_as_it_reads_the_source(experiment, endpoints, tmp_path, capsys):
    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, speed=4.0) as dca:
        record(plan(experiment, cli.port, tmp_path / "rec", endpoints), **FAST)
        assert dca.lost_sequences == ()
    out = tmp_path / "rec"
    for name, folder in (("rec", out), ("src", experiment.folder)):
        assert main(["capture", "import", str(folder / "adc_data_Raw_0.bin"), "--config", str(folder / "adc_data.cfg"),
                     "--sweep", str(folder / "sweep.toml"), "-o", str(tmp_path / f"{name}.npz")]) == 0
    assert "61 beams" in capsys.readouterr().out
    a, b = load_capture(tmp_path / "rec.npz"), load_capture(tmp_path / "src.npz")
    np.testing.assert_array_equal(a.cube, b.cube)


def test_a_refused_cfg_line_stops_both_and_leaves_a_readable_folder(experiment, endpoints, tmp_path):
    refusal = "Error: Invalid usage of the CLI command"
    with EmulatedRadarCli(refuse={"profileCfg": refusal}) as cli, dca1000(experiment, endpoints) as dca:
        with pytest.raises(MeasuredFormatError) as err:
            record(plan(experiment, cli.port, tmp_path / "rec", endpoints), **FAST)
        lines = cli.lines
    assert refusal in str(err.value) and "profileCfg" in str(err.value) and "\n" not in str(err.value)
    assert "sensorStop" in lines[lines.index(next(ln for ln in lines if ln.startswith("profileCfg"))):]
    assert saw(dca, RECORD_STOP)
    summary = recording_summary(err.value)
    assert summary is not None and summary.stopped == "error" and "profileCfg" in summary.message
    data = recorded(tmp_path / "rec")        # the emulator streams from RECORD_START on, radar or not
    assert len(data) == summary.bytes and data == experiment.raw_path.read_bytes()[:len(data)]
    assert "Number of received packets" in (tmp_path / "rec" / "adc_data_Raw_LogFile.csv").read_text()


def test_a_dead_dca1000_stops_the_radar(experiment, endpoints, tmp_path):
    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, dead=True) as dca:
        with pytest.raises(MeasuredFormatError) as err:
            record(plan(experiment, cli.port, tmp_path / "rec", endpoints), **FAST)
        lines = cli.lines
    assert "no answer from the DCA1000" in str(err.value)
    assert "sensorStart" not in lines and lines[-1] == "sensorStop"
    assert saw(dca, RECORD_STOP)                       # sent without waiting: the board never answers
    assert recording_summary(err.value).stopped == "error"
    assert not (tmp_path / "rec").exists()               # nothing arrived: the folder this run made is removed


def test_a_start_that_fails_can_be_run_again(experiment, endpoints, tmp_path):
    """Regression: a wrong serial port failed after the folder got its adc_data.cfg copy, and the next try was
    refused ("already holds a recording"). Nothing arrived, so the run removes what it wrote; a folder the
    user made stays, with the user's own files."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("bench log")
    for _ in range(2):                                 # the same error twice, not "already holds a recording"
        with pytest.raises(MeasuredFormatError, match="does not exist"):
            record(plan(experiment, str(tmp_path / "no-such-port"), out, endpoints), **FAST)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_link_that_dies_mid_stream(experiment, endpoints, tmp_path):
    source = experiment.raw_path.read_bytes()
    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, faults=StreamFaults(die_after=150)) as dca:
        with pytest.raises(RecordingError) as err:
            record(plan(experiment, cli.port, tmp_path / "rec", endpoints), **FAST)
        lines = cli.lines
    assert "link was lost" in str(err.value)
    summary = recording_summary(err.value)
    assert summary.stopped == "link-lost" and summary.bytes == 150 * P and summary.frames == 150 * P // 8192
    assert summary.partial_frame_bytes == 150 * P % 8192
    assert recorded(tmp_path / "rec") == source[:150 * P]
    assert lines[-1] == "sensorStop" and saw(dca, RECORD_STOP)


def test_ctrl_c_from_on_progress(experiment, endpoints, tmp_path):
    source = experiment.raw_path.read_bytes()

    def interrupt(progress):
        if progress.frames >= 5:
            raise KeyboardInterrupt

    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, speed=0.03) as dca:   # 61 frames in 1.6 s
        with pytest.raises(KeyboardInterrupt) as err:
            record(plan(experiment, cli.port, tmp_path / "rec", endpoints), on_progress=interrupt, **FAST)
        lines = cli.lines
    summary = recording_summary(err.value)
    assert summary.stopped == "interrupted" and 5 <= summary.frames < 61
    data = recorded(tmp_path / "rec")
    assert len(data) == summary.bytes and data == source[:len(data)]
    assert lines[-1] == "sensorStop" and saw(dca, RECORD_STOP)


def test_a_duration_stops_the_recording(experiment, endpoints, tmp_path):
    with EmulatedRadarCli() as cli, dca1000(experiment, endpoints, speed=0.01) as dca:   # 61 frames in 4.9 s
        t0 = time.monotonic()
        summary = record(plan(experiment, cli.port, tmp_path / "rec", endpoints, duration=0.6), **FAST)
        took = time.monotonic() - t0
        lines = cli.lines
    assert summary.stopped == "duration" and 0.6 <= summary.elapsed < 2.0 and took < 4.0
    assert 0 < summary.frames < 61
    data = recorded(tmp_path / "rec")
    assert len(data) == summary.bytes and data == experiment.raw_path.read_bytes()[:len(data)]
    assert lines[-1] == "sensorStop" and saw(dca, RECORD_STOP)


def test_an_existing_recording_is_refused_before_any_device(experiment, endpoints, tmp_path):
    out = tmp_path / "rec"
    out.mkdir()
    (out / "adc_data_Raw_0.bin").write_bytes(b"mine")
    with pytest.raises(MeasuredFormatError, match="already holds a recording"):
        record(plan(experiment, "/dev/null-not-a-port", out, endpoints), **FAST)
    assert (out / "adc_data_Raw_0.bin").read_bytes() == b"mine" and not (out / "adc_data.cfg").exists()


def test_frames_beyond_the_cfg_are_refused(experiment, endpoints, tmp_path):
    with pytest.raises(MeasuredFormatError, match="more than the 61 frames"):
        record(plan(experiment, "/dev/null-not-a-port", tmp_path / "rec", endpoints, frames=62), **FAST)


def test_the_cli_verb_end_to_end(experiment, endpoints, tmp_path, capsys):
    ep = endpoints
    with EmulatedRadarCli() as cli, dca1000(experiment, ep, speed=4.0, faults=StreamFaults(lost=frozenset({7}))):
        rc = main(["capture", "record", "--config", str(experiment.config_path), "--serial", cli.port,
                   "--out", str(tmp_path / "rec"), "--frames", "40", "--sweep", str(experiment.schedule_path),
                   "--host-ip", ep.host_ip, "--fpga-ip", ep.fpga_ip, "--config-port", str(ep.config_port),
                   "--data-port", str(ep.data_port)])
    out = capsys.readouterr().out
    assert rc == 0 and "40 frame(s) of 8192 B" in out and "lost packets 7..7: 1456 B zero-filled at byte 8736" in out
    assert recorded(tmp_path / "rec") == with_zeros(experiment.raw_path.read_bytes()[:40 * 8192], [7])


def test_the_cli_bad_input_is_one_line(experiment, tmp_path, capsys):
    rc = main(["capture", "record", "--config", str(experiment.config_path), "--serial", "/dev/x", "--out",
               str(tmp_path / "rec"), "--host-ip", "300.1.1.1"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and "--host-ip" in err


def test_ctrl_c_in_the_cli_exits_130_with_the_recording_complete(experiment, endpoints, tmp_path):
    ep = endpoints
    out = tmp_path / "rec"
    with EmulatedRadarCli() as cli, dca1000(experiment, ep, speed=0.02):   # 61 frames take 2.4 s
        proc = subprocess.Popen(
            [sys.executable, "-c", "import sys; from risloc_rt.cli import main; sys.exit(main())", "capture", "record",
             "--config", str(experiment.config_path), "--serial", cli.port, "--out", str(out),
             "--host-ip", ep.host_ip, "--fpga-ip", ep.fpga_ip, "--config-port", str(ep.config_port),
             "--data-port", str(ep.data_port)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[3])
        try:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and len(recorded(out) if out.is_dir() else b"") < 3 * 8192:
                time.sleep(0.05)
            proc.send_signal(signal.SIGINT)
            _, stderr = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
        lines = cli.lines
    assert proc.returncode == 130, stderr
    assert "stopped: interrupted" in stderr
    assert "the recording in --out holds what arrived" in stderr and "atomic writes" not in stderr
    data = recorded(out)
    assert 3 * 8192 <= len(data) < 61 * 8192 and data == experiment.raw_path.read_bytes()[:len(data)]
    assert lines[-1] == "sensorStop"
    assert "Number of received packets" in (out / "adc_data_Raw_LogFile.csv").read_text()
    assert os.path.getsize(out / "lost_packets.csv") > 0
