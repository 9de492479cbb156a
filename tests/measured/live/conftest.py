"""Fixtures of the live-recording tests: a loopback DCA1000 bench on free UDP ports.

Everything binds and sends on 127.0.0.0/8 only: the host side is 127.0.0.1, the emulated DCA1000
127.0.0.2. The real ports 4096 (configuration) and 4098 (data) are used when they are free on both
addresses and no other test process holds them (an advisory lock file, so that two engineers' test
runs never race for them); otherwise a pair of free ephemeral ports, free on both addresses.
"""

from __future__ import annotations

import fcntl
import socket
import tempfile
from pathlib import Path

import pytest

HOST_IP = "127.0.0.1"
FPGA_IP = "127.0.0.2"
REAL_PORTS = (4096, 4098)
_LOCK = Path(tempfile.gettempdir()) / "risloc-test-dca1000-real-ports.lock"


def _free_on_both(port: int) -> bool:
    """Whether UDP ``port`` can be bound on both loopback addresses right now (released at once)."""
    socks = []
    try:
        for ip in (HOST_IP, FPGA_IP):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(s)
            s.bind((ip, port))
        return True
    except OSError:
        return False
    finally:
        for s in socks:
            s.close()


def _ephemeral_pair() -> tuple[int, int]:
    """Two distinct ports the kernel hands out on 127.0.0.1 that are free on 127.0.0.2 too."""
    found: list[int] = []
    for _ in range(200):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((HOST_IP, 0))
            port = s.getsockname()[1]
        if port not in found and port not in REAL_PORTS and _free_on_both(port):
            found.append(port)
            if len(found) == 2:
                return found[0], found[1]
    raise RuntimeError("no two free UDP ports on 127.0.0.1 and 127.0.0.2")


@pytest.fixture
def loopback_endpoints():
    """``(host_ip, fpga_ip, config_port, data_port)`` of a loopback bench: the real ports when free.

    Yields
    ------
    tuple of (str, str, int, int)
        127.0.0.1, 127.0.0.2 and the configuration and data UDP ports; ``Endpoints(*value)`` builds
        :class:`risloc_rt.measured.live.addresses.Endpoints`.
    """
    with open(_LOCK, "a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            held = True
        except OSError:
            held = False
        try:
            if held and all(_free_on_both(p) for p in REAL_PORTS):
                yield (HOST_IP, FPGA_IP, *REAL_PORTS)
            else:
                yield (HOST_IP, FPGA_IP, *_ephemeral_pair())
        finally:
            if held:
                fcntl.flock(lock, fcntl.LOCK_UN)
