"""The radar's CLI client against the pseudo-terminal emulator, and both against the SDK's protocol written out here.

The protocol (mmWave SDK user's guide, "CLI"; TI's ``utils/cli/src/cli.c``): the demo echoes the line
it read, writes ``Done`` for an accepted command or ``Error <code>`` for a refused one (``'<cmd>' is
not recognized as a CLI command`` for an unknown one), each line ended by ``\\r\\n`` (the UART's text
mode), then its prompt ``mmwDemo:/>``. The test-side decoder (:func:`decode_device_bytes`) and fake
device (:class:`WireDevice`) below import nothing from ``risloc_rt``: they check the emulator's bytes
and the client's bytes against that text, so the two halves are not each other's only judge.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty

import pytest

from risloc_rt.measured.emulate.radar_cli_server import EmulatedRadarCli
from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.live.radar_cli import RadarCli, RadarCliError

PROMPT = b"mmwDemo:/>"          # mmWave SDK demo prompt
CFG = """% IWR6843 3Tx x 4Rx TDM, 256 samples (tests/measured/conftest.py, started at 60 GHz)
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 7 0
adcCfg 2 1

adcbufCfg -1 0 1 1 1
lowPower 0 0
profileCfg 0 60 7 6 60 0 0 64.985 1 256 5000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
   % an indented comment
chirpCfg 2 2 0 0 0 0 0 2
frameCfg 0 2 64 8 40 1 0
lvdsStreamCfg -1 0 1 0
sensorStart
"""
SENT = [ln.strip() for ln in CFG.splitlines() if ln.strip() and not ln.strip().startswith("%")]
PROFILE_LINE = 10                # profileCfg's line number in CFG


def decode_device_bytes(data: bytes) -> list[tuple[str, list[str]]]:
    """The device's bytes as (echoed line, reply lines), one per prompt; the boot prompt first is skipped."""
    assert data.startswith(PROMPT), data[:40]
    out = []
    for segment in data[len(PROMPT):].split(PROMPT):
        if not segment:
            continue
        assert segment.endswith(b"\r\n"), segment              # every line ended by \r\n before the prompt
        lines = segment[:-2].split(b"\r\n")
        out.append((lines[0].decode(), [ln.decode() for ln in lines[1:]]))
    return out


class WireDevice:
    """A test-side pseudo-terminal device: records the raw bytes it reads, answers each line ``Done`` + prompt."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.received = bytearray()
        self.arrivals: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> "WireDevice":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(5)
        os.close(self.master)
        os.close(self.slave)

    def _run(self) -> None:
        pending = b""
        while not self._stop.is_set():
            if not select.select([self.master], [], [], 0.02)[0]:
                continue
            data = os.read(self.master, 4096)
            self.received += data
            pending += data
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                self.arrivals.append(time.monotonic())
                time.sleep(0.02)        # the reply comes 20 ms later: the next line must wait for the prompt
                os.write(self.master, line + b"\r\nDone\r\n" + PROMPT)


@pytest.fixture
def cfg_file(tmp_path):
    path = tmp_path / "radar.cfg"
    path.write_text(CFG)
    return path


def test_whole_cfg_line_by_line_in_order(cfg_file):
    seen = []
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        exchanges = cli.send_config(cfg_file, progress=lambda done, total, line: seen.append((done, total, line)))
        assert list(radar.lines) == SENT
        assert radar.started and radar.starts == 1
        assert [ex.sent for ex in exchanges] == SENT and all(ex.accepted for ex in exchanges)
        assert exchanges[0].reply == "Ignored: Sensor is already stopped\nDone"      # sensorStop of a stopped radar
        assert all(ex.reply == "Done" for ex in exchanges[1:])
        assert seen == [(i + 1, len(SENT), line) for i, line in enumerate(SENT)]
        assert cli.transcript == exchanges
        log = cli.transcript_text()
        assert log.startswith("> sensorStop\n< Ignored: Sensor is already stopped\n< Done\n> flushCfg\n< Done\n")
        written = radar.written
    # the emulator's bytes, decoded by the SDK's format: echo, Done, prompt, for every line in order
    decoded = decode_device_bytes(written)
    assert [echo for echo, _ in decoded] == SENT
    assert all(reply[-1] == "Done" for _, reply in decoded)


def test_client_bytes_on_the_wire_and_waits_for_each_prompt():
    lines = ["sensorStop", "flushCfg", "channelCfg 15 7 0", "frameCfg 0 2 64 8 40 1 0"]
    with WireDevice() as device, RadarCli(device.port, timeout=2) as cli:
        replies = [cli.send(line) for line in lines]
    assert bytes(device.received) == b"".join(line.encode() + b"\n" for line in lines)
    assert replies == ["Done"] * len(lines)               # the echo stripped, the prompt removed
    gaps = [b - a for a, b in zip(device.arrivals, device.arrivals[1:])]
    assert min(gaps) >= 0.015                             # each line only after the 20 ms reply and its prompt


def test_a_stale_prompt_is_not_taken_for_the_answer():
    with WireDevice() as device, RadarCli(device.port, timeout=2) as cli:
        os.write(device.master, b"\r\n" + PROMPT)            # e.g. the boot prompt, after the port was opened
        time.sleep(0.05)
        assert cli.send("flushCfg") == "Done"
        assert cli.transcript[-1].reply == "Done"


def test_refused_line_gives_the_radars_text_and_stops(cfg_file):
    refusal = "Error: Invalid usage of the CLI command"
    with EmulatedRadarCli(refuse={"profileCfg": refusal}) as radar, RadarCli(radar.port, timeout=2) as cli:
        with pytest.raises(RadarCliError) as info:
            cli.send_config(cfg_file)
        msg = str(info.value)
        assert "\n" not in msg
        assert f"radar.cfg:{PROFILE_LINE}:" in msg and "'profileCfg 0 60 7 6 60 0 0 64.985 1 256 5000 0 0 30'" in msg
        assert f"{refusal} / Error -1" in msg
        assert isinstance(info.value, MeasuredFormatError)
        # nothing after the refused line but the best-effort sensorStop
        index = SENT.index("profileCfg 0 60 7 6 60 0 0 64.985 1 256 5000 0 0 30")
        assert list(radar.lines) == SENT[: index + 1] + ["sensorStop"]
        assert not radar.started


def test_unknown_command_is_the_radars_own_text():
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        with pytest.raises(RadarCliError, match=r"<config>:2: the radar refused 'foo 1 2': 'foo' is not recognized "
                                                r"as a CLI command;"):
            cli.send_config(["flushCfg", "foo 1 2", "channelCfg 15 7 0"])
        assert list(radar.lines) == ["flushCfg", "foo 1 2", "sensorStop"]


def test_sensor_start_before_the_configuration_is_refused_and_stopped():
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        cli.send("flushCfg")
        with pytest.raises(RadarCliError, match=r"refused 'sensorStart': .*Error -1"):
            cli.sensor_start()
        assert radar.lines[-1] == "sensorStop" and not radar.started


def test_start_false_leaves_the_start_to_the_caller(cfg_file):
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        cli.send_config(cfg_file, start=False)
        assert "sensorStart" not in radar.lines and not radar.started
        assert cli.sensor_start() == "Done" and radar.started
        assert cli.sensor_stop() == "Done" and not radar.started


def test_silent_device_times_out_with_what_to_check(cfg_file):
    timeout = 0.5
    with EmulatedRadarCli(silent=True) as radar, RadarCli(radar.port, timeout=timeout) as cli:
        t0 = time.monotonic()
        with pytest.raises(RadarCliError) as info:
            cli.send_config(cfg_file)
        elapsed = time.monotonic() - t0
        assert elapsed < timeout + 1.0
        msg = str(info.value)
        assert "\n" not in msg
        assert "radar.cfg:2: the radar on" in msg and "did not answer 'sensorStop'" in msg
        for what in ("CLI", "data port", "SOP", "demo flashed", "115200 baud"):
            assert what in msg
        assert radar.lines[0] == "sensorStop"          # it was sent; the device never answered


def test_reply_delay_inside_and_over_the_timeout():
    with EmulatedRadarCli(reply_delay=0.2) as radar, RadarCli(radar.port, timeout=1.0) as cli:
        assert cli.send("flushCfg") == "Done"
        assert cli.transcript[-1].seconds >= 0.2
    with EmulatedRadarCli(reply_delay=0.6) as radar, RadarCli(radar.port, timeout=0.2) as cli:
        with pytest.raises(RadarCliError, match=r"did not answer 'flushCfg'"):
            cli.send("flushCfg")


def test_leaving_the_context_on_an_exception_stops_the_sensor(cfg_file):
    with EmulatedRadarCli() as radar:
        with pytest.raises(KeyboardInterrupt):
            with RadarCli(radar.port, timeout=2) as cli:
                cli.send_config(cfg_file)
                assert radar.started
                raise KeyboardInterrupt
        assert radar.lines[-1] == "sensorStop" and not radar.started


def test_missing_port_is_one_line():
    with pytest.raises(RadarCliError) as info:
        with RadarCli("/dev/ttyRISLOC-no-such-port"):
            pass
    msg = str(info.value)
    assert "\n" not in msg and "/dev/ttyRISLOC-no-such-port does not exist" in msg and "ttyUSB" in msg


def test_busy_port_is_one_line():
    with EmulatedRadarCli() as radar, RadarCli(radar.port):
        with pytest.raises(RadarCliError, match=r"is busy; close the program holding it"):
            RadarCli(radar.port).open()


def test_permission_denied_names_the_dialout_group(monkeypatch):
    serial = pytest.importorskip("serial")

    def refuse(*args, **kwargs):       # pyserial 3.5's message for an EACCES open
        raise serial.SerialException(errno.EACCES, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied: "
                                                   "'/dev/ttyUSB0'")

    monkeypatch.setattr(serial, "Serial", refuse)
    with pytest.raises(RadarCliError, match=r"/dev/ttyUSB0: permission denied; add yourself to the dialout group"):
        RadarCli("/dev/ttyUSB0").open()


def _emulator_threads() -> int:
    return sum(t.name == "emulated-radar-cli" and t.is_alive() for t in threading.enumerate())


def test_emulator_closes_on_every_path():
    before = _emulator_threads()
    radar = EmulatedRadarCli()
    with pytest.raises(RuntimeError):
        with radar:
            assert _emulator_threads() == before + 1
            raise RuntimeError("boom")
    assert _emulator_threads() == before and radar.error is None
    radar.close()                                              # idempotent
    with EmulatedRadarCli(silent=True) as radar, RadarCli(radar.port, timeout=0.1) as cli:
        with pytest.raises(RadarCliError):
            cli.send("flushCfg")
    assert _emulator_threads() == before


def test_cfg_text_and_lines_are_sent_alike(cfg_file):
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        cli.send_config(CFG, start=False)
        cli.send_config(CFG.splitlines(), start=False)
        assert list(radar.lines) == [ln for ln in SENT if ln != "sensorStart"] * 2


def test_a_line_longer_than_the_cli_reads_is_refused_before_sending():
    long_line = "compRangeBiasAndRxChanPhase 0.0 " + " ".join(["1.000000000000 0.000000000000"] * 12)
    assert len(long_line) + 1 > 255                       # cli.c reads into a 256-byte buffer
    with EmulatedRadarCli() as radar, RadarCli(radar.port, timeout=2) as cli:
        with pytest.raises(RadarCliError, match=r"<config>:2: compRangeBiasAndRxChanPhase is 3\d\d characters long; "
                                                r"the radar's CLI reads at most 255"):
            cli.send_config(["flushCfg", long_line])
        time.sleep(0.05)
        assert radar.lines == ()
