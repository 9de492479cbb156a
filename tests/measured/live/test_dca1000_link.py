"""The DCA1000 configuration link on loopback: against the emulator and against a test-side fake FPGA.

The fake FPGA below answers with bytes written out from the DCA1000EVM user's guide section 5
(``5A A5 | code | status | AA EE``) and records the bytes the link sends, so the link is checked
against the vendor format and not only against our emulator (which shares ``dca1000.control``).
Everything binds and sends on 127.0.0.0/8.
"""

from __future__ import annotations

import socket
import threading
import time

import pytest

from risloc_rt.measured.dca1000.control import AsyncStatus, Command, FpgaConfig, FpgaVersion, PacketConfig
from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000
from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.live.addresses import Endpoints
from risloc_rt.measured.live.dca1000_link import Dca1000Error, Dca1000Link, send_record_stop


def emulator(loopback_endpoints, **kw) -> EmulatedDca1000:
    host_ip, fpga_ip, config_port, data_port = loopback_endpoints
    return EmulatedDca1000(bytes(8192), frame_bytes=4096, frame_period=0.05, host_ip=host_ip, fpga_ip=fpga_ip,
                           config_port=config_port, data_port=data_port, **kw)


class FakeFpga:
    """A test-side FPGA: answers each command with scripted bytes, records what it received."""

    def __init__(self, endpoints: Endpoints, answers):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((endpoints.fpga_ip, endpoints.config_port))
        self.sock.settimeout(0.05)
        self.answers, self.received = answers, []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)

    def run(self):
        while not self.stop.is_set():
            try:
                data, sender = self.sock.recvfrom(2048)
            except socket.timeout:
                continue
            self.received.append(data)
            for reply in self.answers(data):
                self.sock.sendto(reply, sender)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(timeout=2)
        self.sock.close()


def echo_ok(data: bytes) -> list[bytes]:
    """Status 0 for the command's code (user's guide section 5 response layout)."""
    return [b"\x5a\xa5" + data[2:4] + b"\x00\x00\xaa\xee"]


def test_connect_configure_record_against_the_emulator(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    fpga, packets = FpgaConfig(lanes=2, data_bits=16), PacketConfig(delay=20e-6)
    with emulator(loopback_endpoints) as emu, Dca1000Link(endpoints, timeout=1.0) as link:
        assert link.connect() == FpgaVersion(2, 9, False)
        link.configure(fpga, packets)
        link.start_record()
        link.stop_record()
        link.reset_radar()
        link.reset_fpga()
    assert [c.command for c in emu.commands] == [
        Command.SYSTEM_CONNECT, Command.READ_FPGA_VERSION, Command.CONFIG_FPGA_GEN, Command.CONFIG_PACKET_DATA,
        Command.RECORD_START, Command.RECORD_STOP, Command.RESET_AR_DEVICE, Command.RESET_FPGA]
    assert emu.fpga_config == fpga
    assert emu.packet_config.delay_cycles == 2500                      # 20 µs / 8 ns
    assert emu.streams_started == 1


def test_the_link_sends_vendor_bytes(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)

    def answers(data):
        if data[2] == 0x0E:                                            # READ_FPGA_VERSION: 2.9 record = 0x0482
            return [b"\x5a\xa5\x0e\x00\x82\x04\xaa\xee"]
        return echo_ok(data)

    with FakeFpga(endpoints, answers) as fake, Dca1000Link(endpoints, timeout=1.0) as link:
        version = link.connect()
        link.configure(FpgaConfig(lanes=4, data_bits=12), PacketConfig(delay=25e-6))
        link.start_record()
        link.stop_record()
    assert (version.major, version.minor, version.playback) == (2, 9, False)
    assert fake.received == [bytes.fromhex(h) for h in (
        "5AA5 0900 0000 AAEE", "5AA5 0E00 0000 AAEE",
        "5AA5 0300 0600 01 01 01 02 01 1E AAEE",                       # raw, FOUR_LANE=1, capture, Ethernet, BIT12=1
        "5AA5 0B00 0600 BE05 350C 0000 AAEE",                          # 1470 bytes, 3125 cycles, 0
        "5AA5 0500 0000 AAEE", "5AA5 0600 0000 AAEE")]


def test_answers_to_other_commands_and_async_packets_are_set_aside(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)

    def answers(data):
        stale = b"\x5a\xa5\x06\x00\x00\x00\xaa\xee"                     # a late RECORD_STOP answer
        record_completed = b"\x5a\xa5\x0a\x00\x00\x01\xaa\xee"           # SYSTEM_ERROR, bit 8
        garbage = b"\x00\x01\x02"
        return [stale, garbage, record_completed, *echo_ok(data)]

    with FakeFpga(endpoints, answers), Dca1000Link(endpoints, timeout=1.0, retries=0) as link:
        response = link.command(Command.SYSTEM_CONNECT)
    assert (response.command, response.status) == (Command.SYSTEM_CONNECT, 0)
    assert [e.status for e in link.async_events] == [0x0100]
    assert link.async_events[0].describe() == "record completed"


def test_an_async_status_from_the_emulator_is_kept(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    with emulator(loopback_endpoints) as emu, Dca1000Link(endpoints) as link:
        emu.send_async_status(AsyncStatus.NO_LVDS_DATA, AsyncStatus.DDR_FULL)
        link.connect()
    assert [e.describe() for e in link.async_events] == ["no LVDS data from the radar, FPGA DDR buffer full"]


def test_a_refused_command_is_one_line_and_not_retried(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    with emulator(loopback_endpoints, refuse={Command.CONFIG_FPGA_GEN: 5}) as emu, \
            Dca1000Link(endpoints, timeout=1.0, retries=2) as link:
        link.connect()
        with pytest.raises(Dca1000Error) as exc:
            link.configure(FpgaConfig())
    message = str(exc.value)
    assert "\n" not in message
    for needle in ("CONFIG_FPGA_GEN", f"{endpoints.fpga_ip}:{endpoints.config_port}", "status 5", "lane count"):
        assert needle in message
    assert [c.command for c in emu.commands].count(Command.CONFIG_FPGA_GEN) == 1


def test_a_dead_board_times_out_within_its_timeout(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    timeout, retries = 0.3, 1
    with emulator(loopback_endpoints, dead=True) as emu, Dca1000Link(endpoints, timeout, retries) as link:
        start = time.monotonic()
        with pytest.raises(Dca1000Error) as exc:
            link.connect()
        elapsed = time.monotonic() - start
    assert (retries + 1) * timeout - 0.02 <= elapsed <= (retries + 1) * timeout + 0.5
    message = str(exc.value)
    assert "\n" not in message
    for needle in ("no answer from the DCA1000", f"{endpoints.fpga_ip}:{endpoints.config_port}", "SYSTEM_CONNECT",
                   "within 0.3 s", "Ethernet cable", endpoints.host_ip, "SW2.5", "SW config"):
        assert needle in message
    assert [c.command for c in emu.commands] == [Command.SYSTEM_CONNECT] * (retries + 1)


def test_a_lost_answer_is_retried(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    seen = []

    def answers(data):                                                  # the first try's answer is "lost"
        seen.append(data)
        return [] if len(seen) == 1 else echo_ok(data)

    with FakeFpga(endpoints, answers), Dca1000Link(endpoints, timeout=0.2, retries=1) as link:
        link.start_record()
    assert len(seen) == 2


def test_a_playback_bitfile_is_refused(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    with emulator(loopback_endpoints, version=FpgaVersion(2, 9, True)), Dca1000Link(endpoints) as link:
        with pytest.raises(Dca1000Error, match="playback FPGA bitfile"):
            link.connect()


def test_binding_an_address_this_computer_lacks(loopback_endpoints):
    _, fpga_ip, config_port, data_port = loopback_endpoints
    endpoints = Endpoints("192.0.2.1", fpga_ip, config_port, data_port)   # TEST-NET-1: bound never, sent to never
    with pytest.raises(Dca1000Error) as exc:
        Dca1000Link(endpoints).open()
    assert "this computer has no address 192.0.2.1" in str(exc.value)
    assert "--host-ip" in str(exc.value) and "\n" not in str(exc.value)


def test_binding_a_port_in_use(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
        squatter.bind((endpoints.host_ip, endpoints.config_port))
        with pytest.raises(Dca1000Error) as exc:
            with Dca1000Link(endpoints):
                pass
    assert f"UDP port {endpoints.config_port} on {endpoints.host_ip}" in str(exc.value)
    assert "in use" in str(exc.value) and "\n" not in str(exc.value)


def test_a_closed_link_refuses_commands(loopback_endpoints):
    link = Dca1000Link(Endpoints(*loopback_endpoints))
    with pytest.raises(MeasuredFormatError, match="not open"):
        link.command(Command.SYSTEM_CONNECT)
    with pytest.raises(MeasuredFormatError, match="timeout"):
        Dca1000Link(Endpoints(*loopback_endpoints), timeout=0)


def test_record_stop_for_cleanup_never_raises(loopback_endpoints):
    endpoints = Endpoints(*loopback_endpoints)
    with emulator(loopback_endpoints) as emu:
        with Dca1000Link(endpoints) as link:                            # holds the configuration port
            link.start_record()
            assert send_record_stop(endpoints) is True                  # from an ephemeral port
            assert link.stop_record_quietly() is True
        assert emu.wait_finished(2.0)
        deadline = time.monotonic() + 2.0
        while [c.command for c in emu.commands].count(Command.RECORD_STOP) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert [c.command for c in emu.commands].count(Command.RECORD_STOP) == 2
    # no DCA1000 there, an address this computer lacks: still no exception
    _, fpga_ip, config_port, data_port = loopback_endpoints
    assert send_record_stop(Endpoints("192.0.2.1", fpga_ip, config_port, data_port)) in (True, False)
    assert Dca1000Link(endpoints).stop_record_quietly() in (True, False)
