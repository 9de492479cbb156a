"""The DCA1000 data port's receiver: a thread that only receives and hands every datagram on.

The DCA1000 streams up to ~1 Gbit/s of UDP datagrams to the host's data port (4098); the kernel
drops a datagram only when the socket's receive buffer is full. :class:`DatagramReceiver` keeps that
buffer drained: its thread does nothing but ``recv`` into an unbounded queue (it never drops a
datagram the kernel gave it), while the consumer (the recording writer) parses and writes
elsewhere. The receive buffer is asked as large as the system grants (``SO_RCVBUF``, then
``SO_RCVBUFFORCE`` where the process may); what was granted is reported, with the Linux hint
``sysctl -w net.core.rmem_max=...`` when it is smaller than asked.

Socket fill: on Linux ``SO_MEMINFO`` gives the bytes waiting in the socket (``rmem_alloc``, the
kernel's accounting including per-datagram overhead) and the datagrams the kernel dropped for a
full buffer (``drops``); the thread samples it after every received batch and keeps the high-water
mark. Where ``SO_MEMINFO`` is missing, ``FIONREAD`` (``SIOCINQ``, the size of the next datagram
only, for UDP) is the fallback and kernel drops are unknown.
"""

from __future__ import annotations

import errno
import fcntl
import queue
import socket
import struct
import termios
import threading
import time
from dataclasses import dataclass

from ..errors import MeasuredFormatError
from .addresses import Endpoints

__all__ = ["DEFAULT_RCVBUF", "DatagramReceiver", "ReceiverStats", "SocketBuffer", "open_data_socket"]

#: Receive buffer asked for by default [bytes] (about 0.5 s of the DCA1000's fastest stream).
DEFAULT_RCVBUF = 64 * 1024 * 1024
_SO_MEMINFO = getattr(socket, "SO_MEMINFO", 55)            # Linux >= 4.12
_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
_MEMINFO = struct.Struct("9I")                             # SK_MEMINFO_VARS: rmem_alloc, rcvbuf, ..., drops
_MAX_DATAGRAM = 2048


@dataclass(frozen=True)
class SocketBuffer:
    """The receive buffer a data socket got.

    Attributes
    ----------
    asked : int
        Bytes asked for [bytes].
    granted : int
        ``SO_RCVBUF`` as read back [bytes] (Linux doubles the value set, for its bookkeeping).
    rmem_max : int or None
        ``/proc/sys/net/core/rmem_max`` [bytes], None where it cannot be read.
    """

    asked: int
    granted: int
    rmem_max: int | None

    @property
    def short(self) -> bool:
        """Whether the system granted less than asked."""
        return self.granted < self.asked

    def hint(self) -> str | None:
        """One line for the user when the buffer is smaller than asked, else None.

        Returns
        -------
        str or None
        """
        if not self.short:
            return None
        return (f"the data socket's receive buffer is {self.granted} bytes, {self.asked} were asked "
                f"(net.core.rmem_max = {self.rmem_max}); raise it with "
                f"'sudo sysctl -w net.core.rmem_max={self.asked}' so that a busy disk cannot make the kernel drop "
                "datagrams")


@dataclass(frozen=True)
class ReceiverStats:
    """What the receiver saw.

    Attributes
    ----------
    datagrams : int
        Datagrams received and queued.
    bytes : int
        Their bytes, headers included [bytes].
    foreign : int
        Datagrams from another address than the DCA1000's, ignored.
    high_water : int
        Most bytes seen waiting in the socket [bytes] (kernel accounting, with overhead).
    kernel_drops : int or None
        Datagrams the kernel dropped for a full buffer since the socket opened (None: unknown).
    first_time, last_time : float or None
        ``time.monotonic()`` of the first and last datagram [s].
    """

    datagrams: int
    bytes: int
    foreign: int
    high_water: int
    kernel_drops: int | None
    first_time: float | None
    last_time: float | None


def _rmem_max() -> int | None:
    try:
        with open("/proc/sys/net/core/rmem_max", encoding="ascii") as fh:
            return int(fh.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def open_data_socket(endpoints: Endpoints, rcvbuf: int = DEFAULT_RCVBUF) -> tuple[socket.socket, SocketBuffer]:
    """A UDP socket bound to the host's data port with the largest receive buffer granted.

    Parameters
    ----------
    endpoints : Endpoints
        ``host_ip`` and ``data_port`` are bound.
    rcvbuf : int, default :data:`DEFAULT_RCVBUF`
        Receive buffer to ask for [bytes].

    Returns
    -------
    (socket.socket, SocketBuffer)
        The bound socket (the caller closes it) and the buffer it got.

    Raises
    ------
    MeasuredFormatError
        The address is not one of this computer's, or the port is taken (one line, with the fix).
    """
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        if sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF) < rcvbuf:
            try:                                               # beyond rmem_max: needs CAP_NET_ADMIN
                sock.setsockopt(socket.SOL_SOCKET, _SO_RCVBUFFORCE, rcvbuf)
            except OSError:
                pass
        granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        try:
            sock.bind((endpoints.host_ip, endpoints.data_port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                why = (f"UDP port {endpoints.data_port} on {endpoints.host_ip} is in use (another recording, "
                       "mmWave Studio or the DCA1000 CLI?): stop it, or check with 'ss -ulpn'")
            elif exc.errno == errno.EADDRNOTAVAIL:
                why = (f"{endpoints.host_ip} is not an address of this computer: give the Ethernet port wired to "
                       f"the DCA1000 that address (e.g. 'sudo ip addr add {endpoints.host_ip}/24 dev eth0') or pass "
                       "--host-ip")
            else:
                why = f"cannot bind {endpoints.host_ip}:{endpoints.data_port}: {exc.strerror}"
            raise MeasuredFormatError(f"data port: {why}") from None
    except BaseException:
        sock.close()
        raise
    return sock, SocketBuffer(asked=int(rcvbuf), granted=int(granted), rmem_max=_rmem_max())


def _socket_fill(sock: socket.socket) -> tuple[int, int | None]:
    """(bytes waiting [bytes], kernel drops or None) of ``sock``."""
    try:
        info = _MEMINFO.unpack(sock.getsockopt(socket.SOL_SOCKET, _SO_MEMINFO, _MEMINFO.size))
        return int(info[0]), int(info[8])
    except OSError:
        buf = bytearray(4)
        fcntl.ioctl(sock.fileno(), termios.FIONREAD, buf)
        return int.from_bytes(buf, "little"), None


class DatagramReceiver:
    """A thread that receives the DCA1000's data datagrams and queues every one.

    Parameters
    ----------
    endpoints : Endpoints
        Binds ``(host_ip, data_port)``; datagrams from another address than ``fpga_ip`` are
        counted as ``foreign`` and dropped.
    rcvbuf : int, default :data:`DEFAULT_RCVBUF`
        Receive buffer to ask for [bytes].
    silence_timeout : float, default 2.0
        After the first datagram, this long without one makes :attr:`silent` true [s].
    poll : float, default 0.05
        The thread's longest wait in ``recv`` before it checks for a stop [s].

    Attributes
    ----------
    buffer : SocketBuffer
        The receive buffer granted.

    Raises
    ------
    MeasuredFormatError
        The data port cannot be bound (one line).
    """

    def __init__(self, endpoints: Endpoints, *, rcvbuf: int = DEFAULT_RCVBUF, silence_timeout: float = 2.0,
                 poll: float = 0.05) -> None:
        self.endpoints = endpoints
        self.silence_timeout, self.poll = float(silence_timeout), float(poll)
        self._sock, self.buffer = open_data_socket(endpoints, rcvbuf)
        self._sock.settimeout(self.poll)
        self._queue: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self._stop = threading.Event()
        self.datagrams = self.bytes = self.foreign = self.high_water = 0
        self.kernel_drops: int | None = None
        self._drops0: int | None = _socket_fill(self._sock)[1]
        self.first_time = self.last_time = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="dca1000-receiver", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        sock, source, recv = self._sock, self.endpoints.fpga_ip, self._sock.recvfrom
        put, clock = self._queue.put, time.monotonic
        try:
            while not self._stop.is_set():
                try:
                    data, (ip, _) = recv(_MAX_DATAGRAM)
                except socket.timeout:
                    continue
                if ip != source:
                    self.foreign += 1
                    continue
                put(data)
                now = clock()
                if self.first_time is None:
                    self.first_time = now
                self.last_time = now
                self.datagrams += 1
                self.bytes += len(data)
                if self.datagrams % 64 == 1:
                    self._sample()
        except OSError as exc:                 # the socket closed under the thread, or a real error
            if not self._stop.is_set():
                self.error = exc

    def _sample(self) -> None:
        fill, drops = _socket_fill(self._sock)
        if fill > self.high_water:
            self.high_water = fill
        if drops is not None and self._drops0 is not None:
            self.kernel_drops = drops - self._drops0

    def get(self, timeout: float) -> bytes | None:
        """The next datagram, or None when none comes within ``timeout``.

        Parameters
        ----------
        timeout : float
            Longest wait [s].

        Returns
        -------
        bytes or None
        """
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def get_nowait(self) -> bytes | None:
        """The next datagram already queued, or None.

        Returns
        -------
        bytes or None
        """
        try:
            return self._queue.get_nowait()
        except queue.Empty:
            return None

    @property
    def queued(self) -> int:
        """Datagrams received and not yet taken."""
        return self._queue.qsize()

    @property
    def silent(self) -> bool:
        """Whether data started and then nothing came for ``silence_timeout`` seconds."""
        last = self.last_time
        return last is not None and time.monotonic() - last > self.silence_timeout

    def stats(self) -> ReceiverStats:
        """A snapshot of the counters (the socket fill sampled now).

        Returns
        -------
        ReceiverStats
        """
        if not self._stop.is_set():
            self._sample()
        return ReceiverStats(datagrams=self.datagrams, bytes=self.bytes, foreign=self.foreign,
                             high_water=self.high_water, kernel_drops=self.kernel_drops,
                             first_time=self.first_time, last_time=self.last_time)

    def stop(self, drain: float = 0.0) -> None:
        """Stop receiving and close the socket; idempotent.

        Parameters
        ----------
        drain : float, default 0
            First keep receiving until nothing came for this long [s] (the datagrams in flight
            after RECORD_STOP), at most ``10·drain``.
        """
        if drain > 0 and self._thread.is_alive():
            end = time.monotonic() + 10 * drain
            while time.monotonic() < end:
                last = self.last_time
                if last is None or time.monotonic() - last > drain:
                    break
                time.sleep(min(drain, 0.02))
        if not self._stop.is_set():
            self._sample()
        self._stop.set()
        self._thread.join(timeout=max(1.0, 4 * self.poll))
        self._sock.close()

    def __enter__(self) -> "DatagramReceiver":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
