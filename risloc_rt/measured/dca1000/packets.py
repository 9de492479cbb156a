"""Packet-recorded DCA1000 data: UDP payloads, each behind a 10-byte header.

Record layout (little-endian)::

    offset 0  uint32  sequence number (1 for the first packet of a capture, +1 per packet sent)
    offset 4  uint48  byte count: bytes of ADC data sent before this packet
    offset 10 bytes   payload (≤ 1456 bytes; every packet but a capture's last has the same size)

The payloads concatenated form the raw sample stream; packets do not respect frame boundaries.
A packet lost on the link leaves a gap in the sequence numbers and the byte count: the reader
zero-fills the gap at the byte count's offset (so nothing after it shifts) and reports it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from ..errors import MeasuredFormatError
from .split_files import SplitWriter

__all__ = ["HEADER_BYTES", "MAX_PAYLOAD", "DroppedPackets", "PacketIssue", "PacketRecorder",
           "detect_payload_size", "iter_packet_stream", "pack_header", "packet_stream_length", "unpack_header"]

HEADER_BYTES = 10
MAX_PAYLOAD = 1456
_ZERO_BLOCK = 1 << 22


@dataclass(frozen=True)
class DroppedPackets:
    """Consecutive packets missing from a capture (zero-filled in the stream).

    Packet form: a gap in the headers' sequence numbers and byte count, certain. Raw form
    (``probable=True``): whole packets of exact zero words on the payload grid of a stream whose
    other words show ADC noise (:mod:`.zero_packets`); a raw-mode file has no headers to prove it.

    Attributes
    ----------
    first_sequence : int
        Sequence number of the first missing packet (raw form: the number it would have had,
        ``stream_offset // payload + 1``).
    count : int
        Packets missing.
    stream_offset : int
        Byte offset in the sample stream where the zeros start.
    num_bytes : int
        Bytes zero-filled.
    probable : bool, default False
        Found as zeros in a raw-mode stream, not from packet headers.
    """

    first_sequence: int
    count: int
    stream_offset: int
    num_bytes: int
    probable: bool = False


@dataclass(frozen=True)
class PacketIssue:
    """A packet that could not be placed: late, duplicated or with an inconsistent header."""

    file: str
    record_offset: int
    sequence: int
    byte_count: int
    message: str


def pack_header(sequence: int, byte_count: int) -> bytes:
    """The 10-byte header: ``<u4`` sequence number, 48-bit little-endian byte count.

    Parameters
    ----------
    sequence : int
        Sequence number (1 for a capture's first packet).
    byte_count : int
        Bytes of ADC data sent before this packet [bytes].

    Returns
    -------
    bytes
        The header, 10 bytes.
    """
    return int(sequence).to_bytes(4, "little") + int(byte_count).to_bytes(6, "little")


def unpack_header(header: bytes | memoryview) -> tuple[int, int]:
    """The 10-byte header's (sequence number, byte count) (:func:`pack_header`'s inverse).

    Parameters
    ----------
    header : bytes
        At least :data:`HEADER_BYTES` bytes; the first ten are read.

    Returns
    -------
    (int, int)
        Sequence number and bytes of ADC data sent before the packet [bytes].
    """
    return int.from_bytes(header[:4], "little"), int.from_bytes(header[4:HEADER_BYTES], "little")


def detect_payload_size(head: bytes) -> int | None:
    """Payload size of a packet-recorded capture from its first bytes, or None if it is not one.

    The first header must satisfy ``sequence ≥ 1`` and ``byte_count = (sequence − 1)·P`` and the
    next one (and the third, when ``head`` holds it) ``byte_count = (sequence − 1)·P`` with a
    larger sequence number, for one even P ≤ 1462. Plain sample data passes this by chance with
    negligible probability.

    Parameters
    ----------
    head : bytes
        The capture's first bytes (three packets' worth decides best).

    Returns
    -------
    int or None
        The payload size P [bytes], or None for plain samples.
    """
    if len(head) < HEADER_BYTES:
        return None
    seq0, bc0 = unpack_header(head)
    if seq0 < 1:
        return None
    for p in range(2, 1464, 2):
        if bc0 != (seq0 - 1) * p:
            continue
        ok, checked = True, 0
        for k in (1, 2):
            at = k * (HEADER_BYTES + p)
            if at + HEADER_BYTES > len(head):
                break
            seq, bc = unpack_header(head[at:at + HEADER_BYTES])
            if seq <= seq0 or bc != (seq - 1) * p:
                ok = False
                break
            checked += 1
        if ok and checked:
            return p
    return None


def packet_stream_length(files: Sequence[Path], payload_size: int) -> int:
    """Bytes of sample stream a packet-recorded capture holds: last byte count + last payload.

    Reads only the last header of the last file (every file holds whole packets of
    ``payload_size`` bytes, the capture's final packet may be shorter).

    Parameters
    ----------
    files : sequence of Path
        The split files in stream order.
    payload_size : int
        Bytes per payload [bytes].

    Returns
    -------
    int
        The stream's length including zero-filled gaps [bytes].
    """
    rec = HEADER_BYTES + payload_size
    last = Path(files[-1])
    size = last.stat().st_size
    full, rem = divmod(size, rec)
    if 0 < rem <= HEADER_BYTES:
        raise MeasuredFormatError(f"{last} ends inside a packet header ({rem} bytes after {full} packets of {rec}): "
                                  "the file is cut or the payload size is wrong; pass payload_size=")
    if rem:
        at, length = full * rec, rem - HEADER_BYTES
    elif full:
        at, length = (full - 1) * rec, payload_size
    else:
        raise MeasuredFormatError(f"{last} is empty")
    with open(last, "rb") as fh:
        fh.seek(at)
        seq, bc = unpack_header(fh.read(HEADER_BYTES))
    if bc != (seq - 1) * payload_size:
        raise MeasuredFormatError(f"{last}: last packet header (sequence {seq}, byte count {bc}) does not match "
                                  f"{payload_size}-byte payloads; the payload size is not constant or the file is "
                                  "not packet-recorded (pass form='raw')")
    return bc + length


def _records(path: Path, payload_size: int, block_packets: int) -> Iterator[tuple[int, np.ndarray, np.ndarray, list]]:
    """(record offset, sequence [M], byte count [M], payloads) per block of one file."""
    rec = HEADER_BYTES + payload_size
    dtype = np.dtype([("seq", "<u4"), ("bc_lo", "<u4"), ("bc_hi", "<u2"), ("payload", "u1", (payload_size,))])
    buf = bytearray(block_packets * rec)
    offset = 0
    with open(path, "rb", buffering=0) as fh:
        while True:
            n = fh.readinto(buf)
            if not n:
                return
            full, rem = divmod(n, rec)
            r = np.frombuffer(buf, dtype=dtype, count=full)
            seq = r["seq"].astype(np.int64)
            bc = r["bc_lo"].astype(np.int64) | (r["bc_hi"].astype(np.int64) << 32)
            payloads = [r["payload"]]
            if rem:                                   # the capture's final, shorter packet
                if rem <= HEADER_BYTES:
                    raise MeasuredFormatError(f"{path} ends inside a packet header at byte {offset + full * rec}")
                s, b = unpack_header(bytes(buf[full * rec:full * rec + HEADER_BYTES]))
                seq, bc = np.append(seq, s), np.append(bc, b)
                payloads.append(np.frombuffer(buf, np.uint8, rem - HEADER_BYTES, full * rec + HEADER_BYTES)[None])
            yield offset, seq, bc, payloads
            offset += n
            if rem:
                if fh.read(1):
                    raise MeasuredFormatError(f"{path}: a short packet at byte {offset - rem} is followed by more data: "
                                              "payloads are not all the same size; pass payload_size=")
                return


def iter_packet_stream(files: Sequence[Path], payload_size: int, *, block_packets: int = 2048
                       ) -> Iterator[tuple[np.ndarray, DroppedPackets | PacketIssue | None]]:
    """The sample stream of a packet-recorded capture, with lost packets zero-filled.

    Parameters
    ----------
    files : sequence of Path
        The split files in stream order.
    payload_size : int
        Bytes per payload [bytes].
    block_packets : int, default 2048
        Packets read at a time (sets the memory used).

    Yields
    ------
    (ndarray of uint8, DroppedPackets or PacketIssue or None)
        The next contiguous piece of the stream (zeros for a gap) and its event: a
        :class:`DroppedPackets` for a gap, a :class:`PacketIssue` for a late, duplicated or
        inconsistent packet (then the data is empty), else None.
    """
    pos, expected = 0, None
    for path in files:
        for rec_off, seq, bc, payloads in _records(Path(path), payload_size, block_packets):
            lengths = np.concatenate([np.full(p.shape[0], p.shape[1]) for p in payloads]).astype(np.int64)
            if expected is None:
                expected = int(seq[0]) if int(bc[0]) == 0 else 1
            m = len(seq)
            fast = (bc[0] == pos and seq[0] == expected and np.all(np.diff(seq) == 1)
                    and np.all(np.diff(bc) == lengths[:-1]))
            if fast:
                for p in payloads:
                    yield np.ascontiguousarray(p).reshape(-1), None
                pos, expected = int(bc[-1] + lengths[-1]), int(seq[-1]) + 1
                continue
            rows = [(p, j) for p in payloads for j in range(p.shape[0])]
            for k in range(m):
                s, b, length = int(seq[k]), int(bc[k]), int(lengths[k])
                p, j = rows[k]
                where = rec_off + k * (HEADER_BYTES + payload_size)
                if b < pos:
                    yield np.empty(0, np.uint8), PacketIssue(str(path), where, s, b,
                                                             f"late or duplicate packet {s} (byte count {b} < stream "
                                                             f"position {pos}) ignored; its bytes stay zero-filled")
                    continue
                if b > pos:
                    missing = s - expected
                    if missing < 1 or b - pos != missing * payload_size:
                        raise MeasuredFormatError(
                            f"{path}: packet at byte {where} (sequence {s}, byte count {b}) does not follow the "
                            f"previous one (next sequence {expected}, stream position {pos}); the headers are "
                            "inconsistent or payload sizes vary: pass payload_size= or form='raw'")
                    event = DroppedPackets(first_sequence=expected, count=missing, stream_offset=pos, num_bytes=b - pos)
                    gap = b - pos
                    while gap:
                        n = min(gap, _ZERO_BLOCK)
                        yield np.zeros(n, np.uint8), event
                        event, gap = None, gap - n
                    pos = b
                elif s != expected:
                    yield np.empty(0, np.uint8), PacketIssue(str(path), where, s, b,
                                                             f"sequence {s} where {expected} was expected at the right "
                                                             "byte count; placed by its byte count")
                yield np.ascontiguousarray(p[j]), None
                pos, expected = b + length, s + 1


class PacketRecorder:
    """Writes a sample stream as DCA1000 packets (header + payload), dropping the packets asked.

    Parameters
    ----------
    writer : SplitWriter
        Destination; packets are never cut across files.
    payload_size : int, default 1456
        Bytes per payload (even, ≤ 1456); the stream's last packet may be shorter.
    drop : set of int
        Sequence numbers of packets to leave out (emulated link losses).
    drop_probability : float, default 0
        Independent loss probability of each other packet; needs ``rng``.
    rng : numpy.random.Generator, optional
    """

    def __init__(self, writer: SplitWriter, *, payload_size: int = MAX_PAYLOAD, drop: frozenset[int] = frozenset(),
                 drop_probability: float = 0.0, rng: np.random.Generator | None = None) -> None:
        if payload_size % 2 or not 2 <= payload_size <= MAX_PAYLOAD:
            raise MeasuredFormatError(f"payload_size={payload_size} must be even and in [2, {MAX_PAYLOAD}] bytes")
        if drop_probability and rng is None:
            raise MeasuredFormatError("drop_probability > 0 needs rng=numpy.random.default_rng(seed)")
        self.writer, self.payload_size = writer, payload_size
        self.drop, self.drop_probability, self.rng = frozenset(drop), float(drop_probability), rng
        self._pending = bytearray()
        self._seq, self._sent = 1, 0
        self.dropped: list[int] = []

    def _emit(self, payload: memoryview) -> None:
        lost = self._seq in self.drop or (self.drop_probability and self.rng.random() < self.drop_probability)
        if lost:
            self.dropped.append(self._seq)
        else:
            self.writer.write(pack_header(self._seq, self._sent) + bytes(payload), whole=True)
        self._seq += 1
        self._sent += len(payload)

    def write(self, data: bytes | memoryview | np.ndarray) -> None:
        """Append stream bytes; full packets are emitted as they fill.

        Parameters
        ----------
        data : bytes, memoryview or ndarray
            The next bytes of the sample stream.
        """
        self._pending += memoryview(data).cast("B")
        p = self.payload_size
        n = len(self._pending) // p
        view = memoryview(self._pending)
        for k in range(n):
            self._emit(view[k * p:(k + 1) * p])
        view.release()
        del self._pending[:n * p]

    def close(self) -> tuple[Path, ...]:
        """Emit the last (short) packet and close the files.

        Returns
        -------
        tuple of Path
            The split files written, in order.
        """
        if self._pending:
            self._emit(memoryview(bytes(self._pending)))
            self._pending.clear()
        return self.writer.close()
