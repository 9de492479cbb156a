"""An emulated DCA1000EVM on loopback: the configuration protocol and the data stream, at the real rate, with faults.

:class:`EmulatedDca1000` is a context manager running two threads:

- the *configuration port* ``(fpga_ip, config_port)`` (default 127.0.0.2:4096) answers every
  command with its documented response (``A55A | code | status | EEAA``, status 0; READ_FPGA_VERSION
  answers its version word; :mod:`risloc_rt.measured.dca1000.control`); it can refuse chosen
  commands (a non-zero status) or be a dead board that never answers;
- on RECORD_START, the *data stream*: the source bytes cut into datagrams ``pack_header(seq,
  byte_count) + payload`` (≤ 1456 bytes, sequence from 1; :mod:`risloc_rt.measured.dca1000.packets`)
  sent from ``(fpga_ip, data_port)`` to ``(host_ip, data_port)`` until the source ends or
  RECORD_STOP comes.

Timing: frame ``k``'s packets are released from ``k · frame_period`` on, one every inter-packet
delay (the host's CONFIG_PACKET_DATA, 25 µs until it sends one), so the stream averages the real
rate ``frame_bytes / frame_period`` in bursts the way an LVDS frame arrives; ``speed`` divides every
time (tests), ``speed=inf`` sends as fast as the socket takes them.

Faults (:class:`StreamFaults`, drawn from an explicit ``numpy.random.Generator``): lost sequence
numbers or a loss probability, duplicates, reordering (a packet held back and sent up to
``reorder_window`` packets later), and ``die_after`` (the link goes silent after that many
datagrams: no more data, no more answers). The emulator records what it did: the sequences it sent
(in order, duplicates included), lost, duplicated and reordered, and the commands it received.

It binds and sends only on 127.0.0.0/8 (a non-loopback address is refused) and answers only the host
address it was given, so no test can spray a real network.
"""

from __future__ import annotations

import ipaddress
import math
import select
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

from ..dca1000.control import (AsyncStatus, Command, CommandPacket, FpgaConfig, FpgaVersion, PacketConfig,
                               async_status_word, decode_command, encode_response)
from ..dca1000.packets import MAX_PAYLOAD, detect_payload_size, pack_header
from ..dca1000.raw_layout import RawLayout
from ..dca1000.split_files import capture_files, iter_file_bytes
from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig
from ..ti.sdk_cfg import read_sdk_cfg

__all__ = ["DEFAULT_VERSION", "EmulatedDca1000", "StreamFaults"]

#: The FPGA version the emulator reports (a record bitfile).
DEFAULT_VERSION = FpgaVersion(2, 9, False)
_READ_BLOCK = 1 << 20


@dataclass(frozen=True)
class StreamFaults:
    """Faults of the emulated data link.

    Parameters
    ----------
    lost : frozenset of int
        Sequence numbers never sent.
    loss_probability : float, default 0
        Independent chance that any other packet is lost.
    duplicates : frozenset of int
        Sequence numbers sent twice (the copy right after the original).
    duplicate_probability : float, default 0
        Independent chance that a packet is sent twice.
    reorder_probability : float, default 0
        Chance that a packet is held back and sent 1 to ``reorder_window`` packets later.
    reorder_window : int, default 3
        Largest displacement of a held packet [packets].
    die_after : int or None
        Datagrams sent before the link goes silent (no more data and no more answers); None: never.
    """

    lost: frozenset[int] = frozenset()
    loss_probability: float = 0.0
    duplicates: frozenset[int] = frozenset()
    duplicate_probability: float = 0.0
    reorder_probability: float = 0.0
    reorder_window: int = 3
    die_after: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "lost", frozenset(int(s) for s in self.lost))
        object.__setattr__(self, "duplicates", frozenset(int(s) for s in self.duplicates))
        for name in ("loss_probability", "duplicate_probability", "reorder_probability"):
            p = getattr(self, name)
            if not 0.0 <= float(p) <= 1.0:
                raise MeasuredFormatError(f"StreamFaults {name}={p!r} must be a probability in [0, 1]")
        if isinstance(self.reorder_window, bool) or int(self.reorder_window) < 1:
            raise MeasuredFormatError(f"StreamFaults reorder_window={self.reorder_window!r} must be >= 1 packet")
        if self.die_after is not None and int(self.die_after) < 0:
            raise MeasuredFormatError(f"StreamFaults die_after={self.die_after!r} must be >= 0 datagrams or None")

    @property
    def random(self) -> bool:
        """Whether any fault is drawn at random (needs a generator)."""
        return bool(self.loss_probability or self.duplicate_probability or self.reorder_probability)


def _loopback(ip: str, what: str) -> str:
    try:
        addr = ipaddress.IPv4Address(ip)
    except ValueError:
        raise MeasuredFormatError(f"{what} {ip!r} is not an IPv4 address") from None
    if not addr.is_loopback:
        raise MeasuredFormatError(f"the emulated DCA1000 runs on loopback only; {what} {ip} is not in 127.0.0.0/8: "
                                  "use 127.0.0.1 (host) and 127.0.0.2 (DCA1000)")
    return str(addr)


def _bound_socket(ip: str, port: int, what: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((ip, port))
    except OSError as exc:
        sock.close()
        raise MeasuredFormatError(f"the emulated DCA1000 cannot bind its {what} port {ip}:{port}: "
                                  f"{exc.strerror or exc}; another emulator or program holds it: pick free ports"
                                  ) from None
    return sock


class _Source:
    """The byte stream to send: bytes in memory, or the raw files of a capture (read in blocks)."""

    def __init__(self, source) -> None:
        if isinstance(source, (bytes, bytearray, memoryview)):
            self.data, self.files = memoryview(bytes(source)), ()
            self.length = len(self.data)
            head = bytes(self.data[:3 * (MAX_PAYLOAD + 10)])
            where = "the source bytes"
        else:
            self.data, self.files = None, _capture_files(Path(source))
            self.length = sum(p.stat().st_size for p in self.files)
            with open(self.files[0], "rb") as fh:
                head = fh.read(3 * (MAX_PAYLOAD + 10))
            where = str(self.files[0])
        if self.length == 0:
            raise MeasuredFormatError(f"{where} is empty: the emulated DCA1000 needs bytes to stream")
        if detect_payload_size(head) is not None:
            raise MeasuredFormatError(f"{where} is packet-recorded (10-byte headers before each payload): stream the "
                                      "sample bytes (the raw form), not a recording's packets")

    def blocks(self) -> Iterator[memoryview]:
        if self.data is not None:
            yield self.data
        else:
            yield from iter_file_bytes(self.files, _READ_BLOCK)

    def packets(self, payload_size: int) -> Iterator[tuple[int, int, bytes]]:
        """(sequence, byte count before it, payload) from sequence 1."""
        seq, sent, carry = 1, 0, b""
        for block in self.blocks():
            data = carry + bytes(block)
            full = len(data) // payload_size * payload_size
            for at in range(0, full, payload_size):
                yield seq, sent, data[at:at + payload_size]
                seq, sent = seq + 1, sent + payload_size
            carry = data[full:]
        if carry:
            yield seq, sent, carry


def _capture_files(path: Path) -> tuple[Path, ...]:
    if path.is_dir():
        firsts = sorted(path.glob("*_Raw_0.bin"))
        if len(firsts) != 1:
            raise MeasuredFormatError(f"{path} holds {len(firsts)} '*_Raw_0.bin' files; the emulated DCA1000 streams "
                                      "one capture: give its first file")
        return capture_files(firsts[0])
    return capture_files(path)


def _frame_timing(config, frame_bytes, frame_period, lanes) -> tuple[int, float]:
    if config is not None:
        cfg = config if isinstance(config, TiChirpConfig) else read_sdk_cfg(config).config
        frame_bytes = RawLayout.from_config(cfg, lanes=lanes).frame_bytes if frame_bytes is None else frame_bytes
        frame_period = cfg.frame_periodicity if frame_period is None else frame_period
    if frame_bytes is None or frame_period is None:
        raise MeasuredFormatError("the emulated DCA1000 streams at the real rate: give config= (a .cfg or "
                                  "TiChirpConfig) or both frame_bytes= and frame_period=")
    if isinstance(frame_bytes, bool) or int(frame_bytes) < 1:
        raise MeasuredFormatError(f"frame_bytes={frame_bytes!r} must be >= 1 byte")
    if not float(frame_period) > 0:
        raise MeasuredFormatError(f"frame_period={frame_period!r} s must be > 0 (frameCfg framePeriodicity)")
    return int(frame_bytes), float(frame_period)


class EmulatedDca1000:
    """An emulated DCA1000EVM on loopback (a context manager running its threads).

    Parameters
    ----------
    source : bytes or path
        The sample stream: bytes, a raw capture file (``adc_data_Raw_0.bin``; its split siblings
        follow) or a folder holding one capture.
    config : TiChirpConfig or path, optional
        The radar configuration (a ``.cfg``): frame size and frame period [s].
    frame_bytes : int, optional
        Bytes per frame (overrides ``config``'s) [bytes].
    frame_period : float, optional
        Frame period (overrides ``config``'s) [s].
    lanes : {2, 4}, default 2
        LVDS lanes, for the frame size from ``config``.
    host_ip, fpga_ip : str, default "127.0.0.1", "127.0.0.2"
        The host's and the emulated FPGA's addresses (both on 127.0.0.0/8).
    config_port, data_port : int, default 4096, 4098
        UDP ports.
    speed : float, default 1
        Time compression: every delay is divided by it (``inf``: no pacing).
    faults : StreamFaults, default none
        Link faults.
    rng : numpy.random.Generator, optional
        Draws the random faults (required when ``faults.random``).
    refuse : mapping of Command to int, optional
        Commands answered with that non-zero status.
    dead : bool, default False
        Never answer (a dead board or a wrong address).
    version : FpgaVersion, default :data:`DEFAULT_VERSION`
        What READ_FPGA_VERSION answers.
    payload_size : int, default 1456
        Data bytes per datagram [bytes].

    Attributes
    ----------
    commands : list of CommandPacket
        Every well-formed command received, in order.
    malformed : list of str
        The one-line errors of malformed command packets (they get no answer).
    fpga_config : FpgaConfig or None
        The last CONFIG_FPGA_GEN.
    packet_config : PacketConfig
        The last CONFIG_PACKET_DATA (default until one comes).
    """

    def __init__(self, source, *, config: TiChirpConfig | str | Path | None = None, frame_bytes: int | None = None,
                 frame_period: float | None = None, lanes: int = 2, host_ip: str = "127.0.0.1",
                 fpga_ip: str = "127.0.0.2", config_port: int = 4096, data_port: int = 4098, speed: float = 1.0,
                 faults: StreamFaults = StreamFaults(), rng: np.random.Generator | None = None,
                 refuse: Mapping[Command, int] | None = None, dead: bool = False,
                 version: FpgaVersion = DEFAULT_VERSION, payload_size: int = MAX_PAYLOAD) -> None:
        self.host_ip, self.fpga_ip = _loopback(host_ip, "host_ip"), _loopback(fpga_ip, "fpga_ip")
        self.config_port, self.data_port = int(config_port), int(data_port)
        self.frame_bytes, self.frame_period = _frame_timing(config, frame_bytes, frame_period, lanes)
        if not float(speed) > 0:
            raise MeasuredFormatError(f"speed={speed!r} must be > 0 (inf: no pacing)")
        if payload_size % 2 or not 2 <= payload_size <= MAX_PAYLOAD:
            raise MeasuredFormatError(f"payload_size={payload_size} must be even and in [2, {MAX_PAYLOAD}] bytes")
        if faults.random and rng is None:
            raise MeasuredFormatError("random StreamFaults need rng=numpy.random.default_rng(seed)")
        self.source, self.speed, self.faults, self.rng = _Source(source), float(speed), faults, rng
        self.refuse = {Command(c): int(s) for c, s in (refuse or {}).items()}
        if any(not 1 <= s <= 0xFFFF for s in self.refuse.values()):
            raise MeasuredFormatError("refuse= statuses must be 1-65535 (0 is success)")
        self.dead, self.version, self.payload_size = bool(dead), version, int(payload_size)
        self.commands: list[CommandPacket] = []
        self.malformed: list[str] = []
        self.fpga_config: FpgaConfig | None = None
        self.packet_config = PacketConfig()
        self._sent: list[int] = []
        self._lost: list[int] = []
        self._duplicated: list[int] = []
        self._reordered: list[int] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._stream_stop = threading.Event()
        self._finished = threading.Event()
        self._stream: threading.Thread | None = None
        self._server: threading.Thread | None = None
        self._config_sock: socket.socket | None = None
        self._data_sock: socket.socket | None = None
        self.died = False
        self.streams_started = 0

    # ------------------------------------------------------------------ records
    @property
    def sent_sequences(self) -> tuple[int, ...]:
        """Sequence numbers of the datagrams sent, in sending order (duplicates twice)."""
        with self._lock:
            return tuple(self._sent)

    @property
    def lost_sequences(self) -> tuple[int, ...]:
        """Sequence numbers never sent (lost, or held back when the link died), ascending."""
        with self._lock:
            return tuple(sorted(self._lost))

    @property
    def duplicated(self) -> tuple[int, ...]:
        """Sequence numbers sent twice."""
        with self._lock:
            return tuple(self._duplicated)

    @property
    def reordered(self) -> tuple[int, ...]:
        """Sequence numbers held back and sent after later ones."""
        with self._lock:
            return tuple(self._reordered)

    @property
    def stream_bytes(self) -> int:
        """Bytes of the source stream [bytes]."""
        return self.source.length

    @property
    def rate(self) -> float:
        """The stream's average rate at ``speed`` 1, ``frame_bytes / frame_period`` [bytes/s]."""
        return self.frame_bytes / self.frame_period

    # ------------------------------------------------------------------ life cycle
    def __enter__(self) -> "EmulatedDca1000":
        self._config_sock = _bound_socket(self.fpga_ip, self.config_port, "configuration")
        try:
            self._data_sock = _bound_socket(self.fpga_ip, self.data_port, "data")
            self._data_sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
        except BaseException:
            self._config_sock.close()
            raise
        self._server = threading.Thread(target=self._serve, name="emulated-dca1000-config", daemon=True)
        self._server.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop both threads and close the sockets (idempotent)."""
        self._stop.set()
        self._stream_stop.set()
        for thread in (self._stream, self._server):
            if thread is not None:
                thread.join(timeout=5.0)
        for sock in (self._config_sock, self._data_sock):
            if sock is not None:
                sock.close()
        self._config_sock = self._data_sock = None

    def wait_finished(self, timeout: float) -> bool:
        """Wait until the stream has ended (source sent, RECORD_STOP, or the link died).

        Parameters
        ----------
        timeout : float
            Longest wait [s].

        Returns
        -------
        bool
            Whether it ended.
        """
        return self._finished.wait(timeout)

    def send_async_status(self, *conditions: AsyncStatus) -> None:
        """Send an asynchronous SYSTEM_ERROR packet to the host's configuration port.

        Parameters
        ----------
        *conditions : AsyncStatus
            The conditions reported (e.g. ``AsyncStatus.RECORD_COMPLETED``).
        """
        if self._config_sock is not None and not self.died:
            self._config_sock.sendto(encode_response(Command.SYSTEM_ERROR, async_status_word(*conditions)),
                                     (self.host_ip, self.config_port))

    # ------------------------------------------------------------------ configuration port
    def _serve(self) -> None:
        sock = self._config_sock
        while not self._stop.is_set():
            ready, _, _ = select.select([sock], [], [], 0.05)
            if not ready:
                continue
            try:
                data, sender = sock.recvfrom(2048)
            except OSError:
                continue
            try:
                packet = decode_command(data)
            except MeasuredFormatError as exc:
                self.malformed.append(str(exc))
                continue
            self.commands.append(packet)
            if self.dead or self.died or sender[0] != self.host_ip:
                continue
            status = self._execute(packet)
            try:
                sock.sendto(encode_response(packet.command, status), sender)
            except OSError:
                pass

    def _execute(self, packet: CommandPacket) -> int:
        """Carry out a command; its response status.

        RECORD_START while a stream runs is answered (status 0) and the stream goes on; after a
        stream ended, it starts a new one from the source's first byte (sequence 1).
        """
        cmd = packet.command
        if cmd in self.refuse:
            return self.refuse[cmd]
        if cmd == Command.READ_FPGA_VERSION:
            return self.version.status()
        try:
            if cmd == Command.CONFIG_FPGA_GEN:
                self.fpga_config = FpgaConfig.from_payload(packet.payload)
            elif cmd == Command.CONFIG_PACKET_DATA:
                self.packet_config = PacketConfig.from_payload(packet.payload)
        except MeasuredFormatError as exc:
            self.malformed.append(str(exc))
            return 1
        if cmd == Command.RECORD_START and (self._stream is None or not self._stream.is_alive()):
            self._start_stream()
        elif cmd in (Command.RECORD_STOP, Command.RESET_FPGA):
            self._stream_stop.set()
        return 0

    # ------------------------------------------------------------------ data stream
    def _start_stream(self) -> None:
        self._stream_stop = threading.Event()
        self._finished.clear()
        self.streams_started += 1
        self._stream = threading.Thread(target=self._run_stream, name="emulated-dca1000-data", daemon=True)
        self._stream.start()

    def _due(self, t0: float, byte_count: int, delay: float) -> float:
        """Monotonic time [s] when the packet starting at ``byte_count`` may leave."""
        if math.isinf(self.speed):
            return t0
        frame, within = divmod(byte_count, self.frame_bytes)
        return t0 + (frame * self.frame_period + within // self.payload_size * delay) / self.speed

    def _send(self, seq: int, datagram: bytes) -> None:
        try:
            self._data_sock.sendto(datagram, (self.host_ip, self.data_port))
        except OSError:
            pass                                  # nobody listening: the wire does not care
        with self._lock:
            self._sent.append(seq)

    def _dies(self) -> bool:
        limit = self.faults.die_after
        if limit is not None and len(self._sent) >= limit:
            self.died = True
        return self.died

    def _run_stream(self) -> None:
        try:
            self._stream_packets()
        finally:
            self._finished.set()

    def _stream_packets(self) -> None:
        f, rng = self.faults, self.rng
        delay, t0 = self.packet_config.delay, time.monotonic()
        held: list[tuple[int, int, bytes]] = []           # (release after this many packets, seq, datagram)
        for count, (seq, byte_count, payload) in enumerate(self.source.packets(self.payload_size), start=1):
            due = self._due(t0, byte_count, delay)
            while not self._stream_stop.is_set() and due - time.monotonic() > 5e-4:
                self._stream_stop.wait(min(due - time.monotonic(), 0.05))
            if self._stream_stop.is_set() or self._dies():
                break
            u_loss, u_hold, u_dup = (rng.random(3) if f.random else (1.0, 1.0, 1.0))
            datagram = pack_header(seq, byte_count) + payload
            if seq in f.lost or u_loss < f.loss_probability:
                with self._lock:
                    self._lost.append(seq)
            elif u_hold < f.reorder_probability:
                held.append((count + int(rng.integers(1, f.reorder_window + 1)), seq, datagram))
                with self._lock:
                    self._reordered.append(seq)
            else:
                self._send(seq, datagram)
                if (seq in f.duplicates or u_dup < f.duplicate_probability) and not self._dies():
                    self._send(seq, datagram)
                    with self._lock:
                        self._duplicated.append(seq)
            for item in [h for h in held if h[0] <= count]:
                held.remove(item)
                if not self._dies():
                    self._send(item[1], item[2])
        self._flush_held(held)

    def _flush_held(self, held: list[tuple[int, int, bytes]]) -> None:
        """Send the packets still held back, or list them lost if the link died."""
        for _, seq, datagram in held:
            if self._dies():
                with self._lock:
                    self._lost.append(seq)
            else:
                self._send(seq, datagram)
