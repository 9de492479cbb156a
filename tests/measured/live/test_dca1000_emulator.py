"""The emulated DCA1000's data stream on loopback, read by a test-side receiver.

The receiver here decodes the datagrams itself, from the documented layout (DCA1000EVM user's
guide section 5 "data format"; TI's CLI ``defines.h`` ``RECORD_DATA_BUF_INDEX 10``): a little-endian
u32 sequence number (1 for the first packet), a 48-bit byte count of the data sent before the
packet, then up to 1456 data bytes. It places each payload at its byte count, so the stream it
rebuilds must equal the source except at the packets the emulator lists as lost (zeros there).
Commands are sent as raw vendor bytes (``5A A5 | code | 00 00 | AA EE``), not through our link.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from dataclasses import dataclass

import numpy as np
import pytest

from risloc_rt.measured.emulate.dca1000_server import EmulatedDca1000, StreamFaults
from risloc_rt.measured.errors import MeasuredFormatError

RECORD_START = bytes.fromhex("5AA5 0500 0000 AAEE")
RECORD_STOP = bytes.fromhex("5AA5 0600 0000 AAEE")
SYSTEM_CONNECT = bytes.fromhex("5AA5 0900 0000 AAEE")
PAYLOAD = 1456


@dataclass
class Datagram:
    seq: int
    byte_count: int
    payload: bytes
    t: float


def source_bytes(n: int, seed: int = 0) -> bytes:
    return np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()


def rebuild(datagrams: list[Datagram], length: int) -> bytes:
    out = bytearray(length)
    for d in datagrams:
        out[d.byte_count:d.byte_count + len(d.payload)] = d.payload
    return bytes(out)


def with_zeros(source: bytes, lost) -> bytes:
    out = bytearray(source)
    for s in lost:
        start = (s - 1) * PAYLOAD
        out[start:start + PAYLOAD] = bytes(len(out[start:start + PAYLOAD]))
    return bytes(out)


def record(ends, emu: EmulatedDca1000, *, stop_after: float | None = None, limit: float = 10.0) -> list[Datagram]:
    """Bind the host's ports, send RECORD_START, receive until the stream ends and the link is quiet."""
    host_ip, fpga_ip, config_port, data_port = ends
    got: list[Datagram] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as data, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as control:
        data.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        data.bind((host_ip, data_port))
        data.settimeout(0.05)
        control.bind((host_ip, config_port))
        control.settimeout(2.0)
        control.sendto(RECORD_START, (fpga_ip, config_port))
        assert control.recvfrom(64)[0] == bytes.fromhex("5AA5 0500 0000 AAEE")
        start = time.monotonic()
        quiet_since = None
        while time.monotonic() - start < limit:
            if stop_after is not None and time.monotonic() - start > stop_after:
                control.sendto(RECORD_STOP, (fpga_ip, config_port))
                stop_after = None
            try:
                raw, sender = data.recvfrom(2048)
            except socket.timeout:
                if emu.wait_finished(0):
                    quiet_since = quiet_since or time.monotonic()
                    if time.monotonic() - quiet_since > 0.2:
                        break
                continue
            assert sender == (fpga_ip, data_port)
            seq, lo, hi = struct.unpack_from("<IIH", raw, 0)
            got.append(Datagram(seq, lo | hi << 32, raw[10:], time.monotonic() - start))
    return got


def frame_period_of(starts) -> float:
    """Theil-Sen slope of the frames' first-packet arrival times [s/frame]: the median of all pairwise
    slopes, so one late wake-up of this receiver on a loaded machine does not bias it."""
    t = np.asarray(starts)
    i, j = np.triu_indices(len(t), 1)
    return float(np.median((t[j] - t[i]) / (j - i)))


def make(ends, source, **kw) -> EmulatedDca1000:
    host_ip, fpga_ip, config_port, data_port = ends
    kw.setdefault("frame_bytes", 20 * PAYLOAD)
    kw.setdefault("frame_period", 0.01)
    return EmulatedDca1000(source, host_ip=host_ip, fpga_ip=fpga_ip, config_port=config_port, data_port=data_port,
                           **kw)


# ---------------------------------------------------------------------------------------------- the stream
def test_the_stream_rebuilds_the_source_byte_for_byte(loopback_endpoints):
    src = source_bytes(100 * PAYLOAD + 700)                             # a short last packet
    with make(loopback_endpoints, src, speed=4.0) as emu:
        got = record(loopback_endpoints, emu)
    assert rebuild(got, len(src)) == src
    assert [d.seq for d in got] == list(range(1, 102))
    assert all(d.byte_count == (d.seq - 1) * PAYLOAD for d in got)
    assert [len(d.payload) for d in got] == [PAYLOAD] * 100 + [700]
    assert emu.sent_sequences == tuple(range(1, 102))
    assert emu.lost_sequences == emu.duplicated == emu.reordered == ()


def test_lost_packets_are_zero_and_listed(loopback_endpoints):
    src = source_bytes(60 * PAYLOAD, seed=1)
    with make(loopback_endpoints, src, faults=StreamFaults(lost={2, 7, 8, 60}), speed=math.inf) as emu:
        got = record(loopback_endpoints, emu)
    assert emu.lost_sequences == (2, 7, 8, 60)
    assert sorted(set(range(1, 61)) - {d.seq for d in got}) == [2, 7, 8, 60]
    assert rebuild(got, len(src)) == with_zeros(src, emu.lost_sequences)
    assert rebuild(got, len(src)) != src


def test_random_loss_is_what_the_emulator_lists(loopback_endpoints):
    src = source_bytes(200 * PAYLOAD, seed=2)
    faults = StreamFaults(loss_probability=0.05)
    with make(loopback_endpoints, src, faults=faults, rng=np.random.default_rng(7), speed=math.inf) as emu:
        got = record(loopback_endpoints, emu)
    missing = sorted(set(range(1, 201)) - {d.seq for d in got})
    assert 2 <= len(missing) <= 30                                      # 10 expected at 5 %
    assert tuple(missing) == emu.lost_sequences
    assert rebuild(got, len(src)) == with_zeros(src, missing)


def test_the_rate_is_the_real_rate(loopback_endpoints):
    frame_bytes, period, frames = 20 * PAYLOAD, 0.05, 12
    src = source_bytes(frames * frame_bytes, seed=3)
    with make(loopback_endpoints, src, frame_bytes=frame_bytes, frame_period=period) as emu:
        got = record(loopback_endpoints, emu)
    starts = sorted(d.t for d in got if d.byte_count % frame_bytes == 0)
    assert len(starts) == frames
    slope = frame_period_of(starts)
    assert slope == pytest.approx(period, rel=0.10), starts            # frame period within 10 %
    assert frame_bytes / slope == pytest.approx(emu.rate, rel=0.10)    # bytes/s within 10 %
    assert starts[-1] - starts[0] > 0.5 * (frames - 1) * period        # not sent in one go
    assert rebuild(got, len(src)) == src


def test_speed_compresses_time(loopback_endpoints):
    frame_bytes, period, frames, speed = 10 * PAYLOAD, 0.1, 10, 5.0
    src = source_bytes(frames * frame_bytes, seed=4)
    with make(loopback_endpoints, src, frame_bytes=frame_bytes, frame_period=period, speed=speed) as emu:
        got = record(loopback_endpoints, emu)
    starts = sorted(d.t for d in got if d.byte_count % frame_bytes == 0)
    assert frame_period_of(starts) == pytest.approx(period / speed, rel=0.10), starts


CFG = """\
sensorStop
channelCfg 15 5 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
profileCfg 0 60.25 7 6 60 0 0 64.985 1 64 5000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
frameCfg 0 1 16 4 30 1 0
sensorStart
"""


def test_frame_size_and_period_from_the_cfg(loopback_endpoints, tmp_path):
    cfg = tmp_path / "radar.cfg"
    cfg.write_text(CFG)
    # complex1x: I and Q int16 per sample: 2 words x 2 bytes x 64 samples x 4 rx x 2 chirps x 16 loops
    frame_bytes = 2 * 2 * 64 * 4 * 2 * 16
    src = source_bytes(8 * frame_bytes, seed=5)
    with make(loopback_endpoints, src, config=cfg, frame_bytes=None, frame_period=None) as emu:
        assert (emu.frame_bytes, emu.frame_period) == (frame_bytes, pytest.approx(0.030))
        got = record(loopback_endpoints, emu)
    starts = sorted(d.t for d in got if d.byte_count % frame_bytes < PAYLOAD)   # each frame's first packet
    assert len(starts) == 8
    assert frame_period_of(starts) == pytest.approx(0.030, rel=0.10), starts
    assert rebuild(got, len(src)) == src


def test_a_folder_of_split_files_is_one_stream(loopback_endpoints, tmp_path):
    parts = [source_bytes(30 * PAYLOAD + 2, seed=6), source_bytes(12345 + 1, seed=7)]
    for i, part in enumerate(parts):
        (tmp_path / f"adc_data_Raw_{i}.bin").write_bytes(part)
    with make(loopback_endpoints, tmp_path, speed=math.inf) as emu:
        assert emu.stream_bytes == sum(map(len, parts))
        got = record(loopback_endpoints, emu)
    assert rebuild(got, emu.stream_bytes) == b"".join(parts)


# ---------------------------------------------------------------------------------------------- faults
def test_duplicates_happen_as_asked(loopback_endpoints):
    src = source_bytes(40 * PAYLOAD, seed=8)
    with make(loopback_endpoints, src, faults=StreamFaults(duplicates={3, 10}), speed=math.inf) as emu:
        got = record(loopback_endpoints, emu)
    seqs = [d.seq for d in got]
    assert {s for s in seqs if seqs.count(s) > 1} == {3, 10}
    assert seqs.count(3) == seqs.count(10) == 2 and len(seqs) == 42
    assert emu.duplicated == (3, 10)
    assert rebuild(got, len(src)) == src


def test_random_duplicates_are_listed(loopback_endpoints):
    src = source_bytes(150 * PAYLOAD, seed=9)
    faults = StreamFaults(duplicate_probability=0.1)
    with make(loopback_endpoints, src, faults=faults, rng=np.random.default_rng(3), speed=math.inf) as emu:
        got = record(loopback_endpoints, emu)
    seqs = [d.seq for d in got]
    twice = sorted(s for s in set(seqs) if seqs.count(s) == 2)
    assert 3 <= len(twice) <= 35 and twice == sorted(emu.duplicated)


def test_reordering_happens_as_asked(loopback_endpoints):
    src = source_bytes(150 * PAYLOAD, seed=10)
    faults = StreamFaults(reorder_probability=0.1, reorder_window=3)
    with make(loopback_endpoints, src, faults=faults, rng=np.random.default_rng(11), speed=math.inf) as emu:
        got = record(loopback_endpoints, emu)
    seqs = [d.seq for d in got]
    late = {s for i, s in enumerate(seqs) if any(t > s for t in seqs[:i])}
    assert len(late) >= 3 and late == set(emu.reordered)
    positions = {s: i for i, s in enumerate(seqs)}
    assert all(positions[s] - (s - 1) <= 3 for s in late)               # at most reorder_window late
    assert sorted(seqs) == list(range(1, 151))
    assert rebuild(got, len(src)) == src                                # placed by byte count: nothing shifts


def test_the_same_seed_gives_the_same_faults(loopback_endpoints):
    src = source_bytes(80 * PAYLOAD, seed=12)
    faults = StreamFaults(loss_probability=0.05, duplicate_probability=0.05, reorder_probability=0.05)
    runs = []
    for _ in range(2):
        with make(loopback_endpoints, src, faults=faults, rng=np.random.default_rng(5), speed=math.inf) as emu:
            record(loopback_endpoints, emu)
        runs.append((emu.lost_sequences, emu.duplicated, emu.reordered, emu.sent_sequences))
    assert runs[0] == runs[1]
    assert any(runs[0][:3])


def test_the_link_dies_after_n_packets(loopback_endpoints):
    host_ip, fpga_ip, config_port, _ = loopback_endpoints
    src = source_bytes(100 * PAYLOAD, seed=13)
    with make(loopback_endpoints, src, faults=StreamFaults(die_after=25), speed=2.0) as emu:
        got = record(loopback_endpoints, emu)
        assert emu.died
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as control:   # the config port is silent too
            control.bind((host_ip, config_port))
            control.settimeout(0.3)
            control.sendto(SYSTEM_CONNECT, (fpga_ip, config_port))
            with pytest.raises(socket.timeout):
                control.recvfrom(64)
    assert [d.seq for d in got] == list(range(1, 26))
    assert len(emu.sent_sequences) == 25


def test_record_stop_stops_the_stream(loopback_endpoints):
    frame_bytes, period = 10 * PAYLOAD, 0.05
    src = source_bytes(100 * frame_bytes, seed=14)                      # 5 s at the real rate
    with make(loopback_endpoints, src, frame_bytes=frame_bytes, frame_period=period) as emu:
        t0 = time.monotonic()
        got = record(loopback_endpoints, emu, stop_after=0.3)
        assert time.monotonic() - t0 < 2.0
    assert 4 * 10 <= len(got) <= 12 * 10                                # about 7 frames of 10 packets
    assert len(emu.sent_sequences) == len(got) < 1000
    n = len(got) * PAYLOAD
    assert rebuild(got, len(src))[:n] == src[:n]


def test_answers_go_only_to_the_host_address(loopback_endpoints):
    _, fpga_ip, config_port, _ = loopback_endpoints
    with make(loopback_endpoints, bytes(PAYLOAD)) as emu, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
        other.bind(("127.0.0.3", 0))                                    # loopback, but not the host's address
        other.settimeout(0.3)
        other.sendto(SYSTEM_CONNECT, (fpga_ip, config_port))
        with pytest.raises(socket.timeout):
            other.recvfrom(64)
    assert len(emu.commands) == 1 and emu.streams_started == 0


# ---------------------------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("kwargs,needle", [
    ({"host_ip": "192.168.33.30"}, "loopback only"),
    ({"fpga_ip": "192.168.33.180"}, "loopback only"),
    ({"faults": StreamFaults(loss_probability=0.1)}, "rng="),
    ({"frame_bytes": None, "frame_period": None}, "real rate"),
    ({"speed": 0}, "speed"),
])
def test_bad_emulator_settings_are_one_line(loopback_endpoints, kwargs, needle):
    host_ip, fpga_ip, config_port, data_port = loopback_endpoints
    args = {"host_ip": host_ip, "fpga_ip": fpga_ip, "config_port": config_port, "data_port": data_port,
            "frame_bytes": PAYLOAD, "frame_period": 0.01, **kwargs}
    with pytest.raises(MeasuredFormatError, match=needle) as exc:
        EmulatedDca1000(bytes(PAYLOAD), **args)
    assert "\n" not in str(exc.value)


def test_a_packet_recorded_source_is_refused(loopback_endpoints):
    packets = b"".join(struct.pack("<IIH", s, (s - 1) * PAYLOAD, 0) + bytes(PAYLOAD) for s in (1, 2, 3))
    with pytest.raises(MeasuredFormatError, match="packet-recorded"):
        make(loopback_endpoints, packets)


@pytest.mark.parametrize("kwargs", [{"loss_probability": 1.5}, {"reorder_window": 0}, {"die_after": -1}])
def test_bad_faults_are_refused(kwargs):
    with pytest.raises(MeasuredFormatError):
        StreamFaults(**kwargs)
