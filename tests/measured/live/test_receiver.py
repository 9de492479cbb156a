"""DatagramReceiver on loopback: every datagram queued in order, counters, socket fill, silence, clean stop."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from risloc_rt.measured.errors import MeasuredFormatError
from risloc_rt.measured.live.addresses import Endpoints
from risloc_rt.measured.live.receiver import DatagramReceiver, SocketBuffer


@pytest.fixture
def endpoints(loopback_endpoints):
    return Endpoints(*loopback_endpoints)


def sender(ip: str) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((ip, 0))
    return s


def take(rx: DatagramReceiver, n: int, timeout: float = 5.0) -> list[bytes]:
    got, end = [], time.monotonic() + timeout
    while len(got) < n and time.monotonic() < end:
        d = rx.get(timeout=0.1)
        if d is not None:
            got.append(d)
    return got


def test_every_datagram_is_queued_in_order_and_counted(endpoints):
    payloads = [k.to_bytes(4, "little") + bytes([k % 251]) * 1462 for k in range(2000)]
    with DatagramReceiver(endpoints) as rx, sender(endpoints.fpga_ip) as tx:
        for p in payloads:
            tx.sendto(p, (endpoints.host_ip, endpoints.data_port))
        got = take(rx, len(payloads))
        stats = rx.stats()
    assert got == payloads
    assert stats.datagrams == 2000 and stats.bytes == 2000 * 1466 and stats.foreign == 0
    assert stats.kernel_drops in (0, None)
    assert stats.first_time <= stats.last_time


def test_the_socket_high_water_mark_sees_a_backlog(endpoints):
    """2000 datagrams sent while nobody takes them: the kernel holds some before the thread drains them."""
    with DatagramReceiver(endpoints) as rx, sender(endpoints.fpga_ip) as tx:
        for k in range(2000):
            tx.sendto(bytes(1466), (endpoints.host_ip, endpoints.data_port))
        assert len(take(rx, 2000)) == 2000
        high = rx.stats().high_water
    assert high >= 1466                           # at least one datagram waited (kernel bytes, with overhead)
    assert high <= rx.buffer.granted


def test_datagrams_from_another_address_are_ignored(endpoints):
    with DatagramReceiver(endpoints) as rx, sender("127.0.0.3") as other, sender(endpoints.fpga_ip) as tx:
        other.sendto(b"x" * 20, (endpoints.host_ip, endpoints.data_port))
        tx.sendto(b"y" * 20, (endpoints.host_ip, endpoints.data_port))
        assert take(rx, 1) == [b"y" * 20]
        time.sleep(0.1)
        assert rx.foreign == 1 and rx.get(timeout=0.05) is None


def test_silence_after_data_is_reported(endpoints):
    with DatagramReceiver(endpoints, silence_timeout=0.2) as rx, sender(endpoints.fpga_ip) as tx:
        time.sleep(0.3)
        assert not rx.silent                      # no data yet: not a lost link
        tx.sendto(b"z" * 30, (endpoints.host_ip, endpoints.data_port))
        assert take(rx, 1)
        assert not rx.silent
        time.sleep(0.35)
        assert rx.silent


def test_stop_is_clean_and_idempotent(endpoints):
    rx = DatagramReceiver(endpoints, poll=0.02)
    rx.stop()
    rx.stop()
    assert not [t for t in threading.enumerate() if t.name == "dca1000-receiver"]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:     # the port is free again
        s.bind((endpoints.host_ip, endpoints.data_port))


def test_a_taken_port_is_one_line(endpoints):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((endpoints.host_ip, endpoints.data_port))
        with pytest.raises(MeasuredFormatError) as err:
            DatagramReceiver(endpoints)
    assert "in use" in str(err.value) and "\n" not in str(err.value)


def test_the_buffer_granted_and_the_rmem_max_hint():
    short = SocketBuffer(asked=64 << 20, granted=425984, rmem_max=212992)
    assert short.short and "net.core.rmem_max=67108864" in short.hint()
    assert SocketBuffer(asked=1 << 20, granted=2 << 20, rmem_max=None).hint() is None
