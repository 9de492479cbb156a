"""``risloc locate --live`` end to end on loopback: the DCA1000 emulator and the radar CLI emulator (a pty).

The emulated DCA1000 streams a two-sweep recording (two emulated sweeps of 31 beams one after
another, one frame per beam, ``first_frame = 0``: the sweep period is 31 frames); ``risloc locate
--live`` records it and prints one line per sweep. The reference is the recorded folder read from
files afterwards: ``risloc capture import --first-frame 31·s`` + ``risloc locate --out``. The
printed position (4 decimals) must be the reference's, and the JSON lines file's full-precision
position, σ and flags equal to it (1e-12 m).
"""

from __future__ import annotations

import json
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000
from risloc_rt.measured.emulate.experiment import dca1000_radar, emulate_capture
from risloc_rt.measured.emulate.radar_cli_server import EmulatedRadarCli
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

BEAMS = 31
LINE = re.compile(r"^\d\d:\d\d:\d\d\.\d{3}  sweep (\d+)  (\S+)  x (\S+) y (\S+) z (\S+) ± (\S+) m  flags (\S+)  "
                  r"latency (\d+) ms$")


@pytest.fixture(scope="module")
def two_sweeps(tmp_path_factory):
    """A DCA1000 folder of two sweeps back to back (62 frames of 8192 bytes), its .cfg asking for 62 frames; chirps
    inside the IWR6843's 60-64 GHz band (the recorder checks the device family)."""
    root = tmp_path_factory.mktemp("src")
    radar = dca1000_radar(RadarConfig(num_samples=128, num_chirps=16, carrier_frequency=61.5e9, bandwidth=1e9))
    angles = np.deg2rad(np.stack([np.linspace(-45, 45, BEAMS), np.zeros(BEAMS)], axis=1))
    sc = analytic_scenario(ue_position=(0.0, 0.0, 0.0), ris_position=(2.0, 9.0, 0.0), ris_facing=(-1.0, 0.0, 0.0),
                           radar=radar, processing=ProcessingConfig(n_dft=255, k_dft=64), sweep=BeamSweep(angles))
    parts = [emulate_capture(simulate(sc, rng=np.random.default_rng(30 + k)), root / f"part{k}").folder
             for k in range(2)]
    folder = root / "rec"
    folder.mkdir()
    (folder / "adc_data_Raw_0.bin").write_bytes(b"".join((p / "adc_data_Raw_0.bin").read_bytes() for p in parts))
    cfg = (parts[0] / "adc_data.cfg").read_text()
    (folder / "adc_data.cfg").write_text(re.sub(r"^(frameCfg \S+ \S+ \S+ )(\d+)", rf"\g<1>{2 * BEAMS}", cfg,
                                                flags=re.M))
    shutil.copy(parts[0] / "sweep.toml", folder / "sweep.toml")
    return folder


def _reference(folder: Path, out: Path, first_frame: int) -> dict:
    assert main(["capture", "import", str(folder / "adc_data_Raw_0.bin"), "--config", str(folder / "adc_data.cfg"),
                 "--sweep", str(folder / "sweep.toml"), "--first-frame", str(first_frame), "-o",
                 str(out / "c.npz")]) == 0
    assert main(["locate", str(out / "c.npz"), "--out", str(out / "result")]) == 0
    return json.loads((out / "result" / "result.json").read_text())["cases"][0]


def test_locate_live_prints_one_line_per_sweep_equal_to_the_file_import(two_sweeps, loopback_endpoints, tmp_path,
                                                                          capsys):
    host, fpga, config_port, data_port = loopback_endpoints
    out = tmp_path / "live"
    with EmulatedRadarCli() as cli, EmulatedDca1000(two_sweeps / "adc_data_Raw_0.bin",
                                                    config=two_sweeps / "adc_data.cfg", host_ip=host, fpga_ip=fpga,
                                                    config_port=config_port, data_port=data_port, speed=4.0):
        rc = main(["locate", "--live", "--config", str(two_sweeps / "adc_data.cfg"), "--serial", cli.port,
                   "--out", str(out), "--sweep", str(two_sweeps / "sweep.toml"), "--host-ip", host,
                   "--fpga-ip", fpga, "--config-port", str(config_port), "--data-port", str(data_port)])
    captured = capsys.readouterr()
    printed = captured.out
    assert rc == 0, captured.err
    lines = [m for m in map(LINE.match, printed.splitlines()) if m]
    assert [(int(m[1]), m[2]) for m in lines] == [(0, "ris"), (1, "ris")], printed
    rows = [json.loads(r) for r in (out / "live_fixes.jsonl").read_text().splitlines()]
    assert [(r["kind"], r["sweep"], r["frames"]) for r in rows] == [("fix", 0, [0, 30]), ("fix", 1, [31, 61])]
    assert (out / "adc_data_Raw_0.bin").stat().st_size == 2 * BEAMS * 8192
    capsys.readouterr()
    for m, row in zip(lines, rows):
        s = int(m[1])
        ref = _reference(out, tmp_path / f"ref{s}", BEAMS * s)
        est = ref["estimate"]
        assert [m[3], m[4], m[5]] == [f"{x:+.4f}" for x in est["position"]]
        assert np.max(np.abs(np.subtract(row["position"], est["position"]))) <= 1e-12
        assert np.max(np.abs(np.subtract(row["std"], est["std"]["position"]))) <= 1e-12
        assert row["flags"] == ref["flags"]
        assert m[7] == ",".join(f["code"] for f in ref["flags"])
        assert 0 <= row["latency"] <= row["latency_printed"] < 10.0


@pytest.mark.parametrize("argv, says", [
    (["locate"], "give the capture file(s) to localize"),
    (["locate", "--live", "--config", "x.cfg"], "--live needs --serial, --out, --sweep"),
    (["locate", "c.npz", "--serial", "/dev/ttyUSB0"], "--serial /dev/ttyUSB0 is for --live"),
    (["locate", "c.npz", "--live", "--config", "x.cfg", "--serial", "p", "--out", "o", "--sweep", "s.toml"],
     "leave out the capture files"),
])
def test_bad_live_input_is_one_line(argv, says, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and says in err and err.startswith("risloc locate: error: ")


def test_a_dead_dca1000_leaves_nothing_and_an_earlier_run_is_not_appended_to(two_sweeps, loopback_endpoints, tmp_path,
                                                                             capsys):
    """A start that fails leaves no folder behind; and (regression) live_fixes.jsonl was opened for appending,
    so a run into a folder holding an earlier run's file appended to it: it is now made at the first fix,
    exclusively, and a folder holding one is refused before anything starts, the file untouched."""
    host, fpga, config_port, data_port = loopback_endpoints
    out = tmp_path / "live"
    argv = ["locate", "--live", "--config", str(two_sweeps / "adc_data.cfg"), "--out", str(out), "--sweep",
            str(two_sweeps / "sweep.toml"), "--host-ip", host, "--fpga-ip", fpga, "--config-port", str(config_port),
            "--data-port", str(data_port)]
    with EmulatedRadarCli() as cli, EmulatedDca1000(two_sweeps / "adc_data_Raw_0.bin", config=two_sweeps / "adc_data.cfg",
                                                    host_ip=host, fpga_ip=fpga, config_port=config_port,
                                                    data_port=data_port, dead=True):
        assert main([*argv, "--serial", cli.port]) == 2
    assert "no answer from the DCA1000" in capsys.readouterr().err and not out.exists()
    out.mkdir()
    (out / "live_fixes.jsonl").write_text('{"kind": "fix", "sweep": 0}\n')
    assert main([*argv, "--serial", "/dev/null"]) == 2
    assert "already holds live_fixes.jsonl" in capsys.readouterr().err
    assert (out / "live_fixes.jsonl").read_text() == '{"kind": "fix", "sweep": 0}\n'


def test_ctrl_c_exits_130_and_leaves_complete_lines(two_sweeps, loopback_endpoints, tmp_path):
    """SIGINT once sweep 0's line is out, while recording slowly (1/100 of the real rate: 62 frames take 5 s): exit
    130, one line on stderr, the recording readable from its start, sweep 0's JSON line whole, no sweep 1."""
    host, fpga, config_port, data_port = loopback_endpoints
    out = tmp_path / "live"
    with EmulatedRadarCli() as cli, EmulatedDca1000(two_sweeps / "adc_data_Raw_0.bin",
                                                    config=two_sweeps / "adc_data.cfg", host_ip=host, fpga_ip=fpga,
                                                    config_port=config_port, data_port=data_port, speed=0.01):
        proc = subprocess.Popen(
            [sys.executable, "-c", "import sys; from risloc_rt.cli import main; sys.exit(main())", "locate", "--live",
             "--config", str(two_sweeps / "adc_data.cfg"), "--serial", cli.port, "--out", str(out),
             "--sweep", str(two_sweeps / "sweep.toml"), "--host-ip", host, "--fpga-ip", fpga,
             "--config-port", str(config_port), "--data-port", str(data_port)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[3])
        try:
            raw, fixes = out / "adc_data_Raw_0.bin", out / "live_fixes.jsonl"
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and (not fixes.is_file() or not fixes.read_text().endswith("\n")):
                time.sleep(0.05)
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted" in stderr
    data = raw.read_bytes()
    assert BEAMS * 8192 <= len(data) < 2 * BEAMS * 8192
    assert data == (two_sweeps / "adc_data_Raw_0.bin").read_bytes()[:len(data)]
    rows = [json.loads(r) for r in fixes.read_text().splitlines()]
    assert [(r["sweep"], r["frames"]) for r in rows] == [(0, [0, BEAMS - 1])]
    assert re.search(r"  sweep 0  ris  x ", stdout) and "sweep 1" not in stdout
