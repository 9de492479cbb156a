"""A live DCA1000 recording written in place: payloads at their byte offsets, lost packets zero-filled.

The DCA1000 sends the ADC stream as UDP datagrams, each a 10-byte header (``<u4`` sequence number
from 1, 48-bit byte count of the data sent before it; :mod:`risloc_rt.measured.dca1000.packets`,
DCA1000EVM user's guide, data-port packet format) and at most 1456 bytes of data.
:class:`RecordingWriter` turns them into what TI's DCA1000 CLI (``DCA1000EVM_CLI_Record``) writes
for a raw-mode capture:

- ``<prefix>_Raw_0.bin``, ``_Raw_1.bin``, ...: the payloads only, each at the byte count its header
  gives; a lost packet's bytes are zeros at their offset (nothing after them moves); a new file
  starts at the split size rounded down to a whole number of payloads (TI's CLI: ``maxRecFileSize_MB``,
  default 1024 MiB, so a file holds 1,073,741,760 bytes = 737,460 packets of 1456 bytes);
- ``<prefix>_Raw_LogFile.csv``: the CLI's packet log: the record configuration, one
  ``,offset,bytes,`` line per zero-filled run, and the summary (out-of-sequence count, first and
  last packet ID, received packets, zero-filled packets and bytes, start and end time, duration);
- ``lost_packets.csv`` (machine-readable, ours): ``first_sequence,count,stream_offset,num_bytes``
  per lost run (the fields of :class:`~risloc_rt.measured.dca1000.packets.DroppedPackets`).

Unlike :class:`~risloc_rt.measured.dca1000.split_files.SplitWriter` (which renames its files into
place at close), a live recording is written in place and handed to the operating system as it
goes: Ctrl-C, a crash or a lost link leaves every byte already written readable.
:attr:`RecordingWriter.final_bytes` is the stream prefix ``[0, final_bytes)`` that is in the files
and in which every packet arrived or was declared lost: a live reader may read frames up to it.

Reordering: a packet ahead of the stream position waits (at most ``reorder_window`` packets or
``reorder_timeout`` seconds) for the ones before it; when the wait ends the gap is declared lost and
zero-filled. A packet arriving after its place was zero-filled is counted ``late`` and dropped; a
packet seen twice is counted ``duplicates`` and dropped.
"""

from __future__ import annotations

import os
import time
from bisect import bisect_right
from pathlib import Path

from ..dca1000.packets import HEADER_BYTES, MAX_PAYLOAD, DroppedPackets, unpack_header
from ..dca1000.split_files import split_name
from ..errors import MeasuredFormatError

__all__ = ["DEFAULT_SPLIT_SIZE", "LOG_SUFFIX", "LOST_PACKETS_NAME", "RecordingWriter", "existing_recording",
           "log_name", "split_limit"]

#: TI's DCA1000 CLI default file size limit: ``maxRecFileSize_MB`` = 1024, in MiB [bytes].
DEFAULT_SPLIT_SIZE = 1024 * 1024 * 1024
#: The packet log's name after the prefix (TI's CLI: ``<prefix>_Raw_LogFile.csv``).
LOG_SUFFIX = "_Raw_LogFile.csv"
#: The machine-readable list of lost packets.
LOST_PACKETS_NAME = "lost_packets.csv"

_FLUSH_BYTES = 1 << 20
_FLUSH_INTERVAL = 0.05


def log_name(prefix: str) -> str:
    """The packet log's file name: ``f"{prefix}_Raw_LogFile.csv"``.

    Parameters
    ----------
    prefix : str
        The recording's prefix (``adc_data``).

    Returns
    -------
    str
    """
    return f"{prefix}{LOG_SUFFIX}"


def split_limit(split_size: int, payload_size: int = MAX_PAYLOAD) -> int:
    """Bytes in each split file but the last: ``split_size`` rounded down to whole payloads.

    TI's DCA1000 CLI cuts its raw-mode files at a multiple of the 1456-byte payload (so that no
    I/Q pair is split across two files).

    Parameters
    ----------
    split_size : int
        The file size limit [bytes].
    payload_size : int, default 1456
        Bytes of data per packet [bytes].

    Returns
    -------
    int
        The cut [bytes].

    Raises
    ------
    MeasuredFormatError
        A limit smaller than one payload.
    """
    if isinstance(split_size, bool) or not isinstance(split_size, int) or split_size < payload_size:
        raise MeasuredFormatError(f"split size {split_size!r} must be an integer of at least one packet "
                                  f"({payload_size} bytes); TI's default is {DEFAULT_SPLIT_SIZE} (1024 MiB)")
    return split_size // payload_size * payload_size


def existing_recording(folder: str | Path, prefix: str = "adc_data") -> list[str]:
    """Names of the files of a recording already in ``folder`` (split files, packet log, lost packets).

    Parameters
    ----------
    folder : path
        The folder to look in (need not exist).
    prefix : str, default "adc_data"
        The recording's prefix.

    Returns
    -------
    list of str
        Sorted file names; empty when the folder holds no recording.
    """
    folder = Path(folder)
    if not folder.is_dir():
        return []
    stem = f"{prefix}_Raw_"
    return sorted(q.name for q in folder.iterdir()
                  if (q.name.startswith(stem) and q.name.endswith(".bin") and q.name[len(stem):-4].isdigit())
                  or q.name in (log_name(prefix), LOST_PACKETS_NAME))


class RecordingWriter:
    """Consumes DCA1000 data datagrams and writes the raw-mode recording in place (module docstring).

    Parameters
    ----------
    folder : path
        The recording's folder (created when missing); refused when it already holds a recording.
    prefix : str, default "adc_data"
        File prefix (TI's CLI and mmWave Studio: ``adc_data``).
    split_size : int, default :data:`DEFAULT_SPLIT_SIZE`
        File size limit [bytes]; each file but the last holds ``split_limit(split_size)`` bytes.
    payload_size : int, default 1456
        Bytes of data per full packet [bytes] (the split files' grid).
    lanes : int, default 2
        LVDS lanes, written in the packet log's configuration.
    max_bytes : int, optional
        Stream bytes to keep [bytes] (``frames × frame size``); data beyond is not written and
        :attr:`full` turns true.
    reorder_window : int, default 256
        Packets that may wait ahead of a gap before the gap is declared lost.
    reorder_timeout : float, default 0.1
        Longest wait of a packet ahead of a gap [s] (checked by :meth:`tick`).
    clock : callable, default ``time.monotonic``
        Monotonic time [s].

    Attributes
    ----------
    final_bytes : int
        Stream bytes ``[0, final_bytes)`` written and final [bytes].
    final_time : float or None
        ``clock()`` when ``final_bytes`` last grew [s].
    received_packets, received_bytes : int
        Datagrams placed in the stream, and their payload bytes [bytes].
    duplicates, late, malformed, out_of_sequence : int
        Datagrams dropped as duplicates, as late (their place already zero-filled), as too short,
        and datagrams whose sequence number did not follow the previous one received (TI's count).
    lost : list of DroppedPackets
        The zero-filled runs, in stream order.
    files : list of Path
        The split files, in order.

    Raises
    ------
    MeasuredFormatError
        A folder that already holds a recording, or a bad split size (one line).
    """

    def __init__(self, folder: str | Path, prefix: str = "adc_data", split_size: int = DEFAULT_SPLIT_SIZE,
                 payload_size: int = MAX_PAYLOAD, *, lanes: int = 2, max_bytes: int | None = None,
                 reorder_window: int = 256, reorder_timeout: float = 0.1, clock=time.monotonic) -> None:
        if payload_size % 2 or not 2 <= payload_size <= MAX_PAYLOAD:
            raise MeasuredFormatError(f"payload size {payload_size} must be even and in [2, {MAX_PAYLOAD}] bytes")
        self.folder, self.prefix, self.payload_size = Path(folder), prefix, int(payload_size)
        self.split_size, self.cut = int(split_size), split_limit(split_size, payload_size)
        self.reorder_window, self.reorder_timeout, self._clock = int(reorder_window), float(reorder_timeout), clock
        self.max_bytes = None if max_bytes is None else int(max_bytes)
        found = existing_recording(self.folder, prefix)
        if found:
            raise MeasuredFormatError(f"{self.folder} already holds a recording ({', '.join(found[:3])}); risloc does "
                                      "not overwrite one: give a new or empty --out folder")
        self.folder.mkdir(parents=True, exist_ok=True)
        self.final_bytes, self.final_time = 0, None
        self.received_packets = self.received_bytes = 0
        self.duplicates = self.late = self.malformed = self.out_of_sequence = 0
        self.lost: list[DroppedPackets] = []
        self.files: list[Path] = []
        self.first_sequence = self.last_sequence = None
        self.start_wall = self.end_wall = None
        self._oos_span = (0, 0)
        self._lost_offsets: list[int] = []
        self._buffer = bytearray()
        self._placed, self._next_seq = 0, 1
        self._pending: dict[int, tuple[int, bytes, float]] = {}
        self._fd, self._file_size = None, 0
        self._last_flush = clock()
        self.closed = False
        self._log = open(self.folder / log_name(prefix), "x", encoding="ascii", newline="")
        self._lost_csv = open(self.folder / LOST_PACKETS_NAME, "x", encoding="ascii", newline="")
        self._log.write(f"Start record configuration : \n,\nLog mode : Raw\nLVDS lane mode : {int(lanes)} lane"
                        f"\nRecord stop mode : Infinite\nMax file size (MB) : {self.split_size // (1 << 20)},"
                        "\n,*DT 1,")
        self._log.flush()
        self._lost_csv.write("first_sequence,count,stream_offset,num_bytes\n")
        self._lost_csv.flush()

    # -- datagrams ---------------------------------------------------------------------------------

    def write(self, datagram: bytes) -> None:
        """Place one data datagram (header + payload) in the stream.

        Parameters
        ----------
        datagram : bytes
            What the data port received: 10-byte header and up to 1456 bytes of data.
        """
        if len(datagram) <= HEADER_BYTES:
            self.malformed += 1
            return
        seq, offset = unpack_header(datagram)
        if self.full:
            return
        if self.last_sequence is None:
            self.first_sequence, self.start_wall = seq, time.time()
        elif seq != self.last_sequence + 1:
            self.out_of_sequence += 1
            self._oos_span = (self.last_sequence, seq)
        self.last_sequence, self.end_wall = seq, time.time()
        if offset == self._placed:
            self._append(seq, memoryview(datagram)[HEADER_BYTES:])
            if self._pending:
                self._drain()
        elif offset > self._placed:
            if offset in self._pending:
                self.duplicates += 1
            else:
                self._pending[offset] = (seq, bytes(datagram[HEADER_BYTES:]), self._clock())
                if len(self._pending) > self.reorder_window:
                    self._declare_gap()
        elif self._in_lost(offset):
            self.late += 1
        else:
            self.duplicates += 1
        if len(self._buffer) >= _FLUSH_BYTES:
            self.flush()

    def _append(self, seq: int, payload) -> None:
        if self.max_bytes is not None and self._placed + len(payload) > self.max_bytes:
            payload = payload[:max(0, self.max_bytes - self._placed)]
        self._buffer += payload
        self._placed += len(payload)
        self._next_seq = seq + 1
        self.received_packets += 1
        self.received_bytes += len(payload)

    def _drain(self) -> None:
        """Place the waiting packets that now follow the stream position."""
        while self._placed in self._pending:
            seq, payload, _ = self._pending.pop(self._placed)
            self._append(seq, payload)

    def _in_lost(self, offset: int) -> bool:
        k = bisect_right(self._lost_offsets, offset) - 1
        return k >= 0 and offset < self.lost[k].stream_offset + self.lost[k].num_bytes

    def _declare_gap(self) -> None:
        """Zero-fill the stream up to the first waiting packet, record the loss, place what follows."""
        offset = min(self._pending)
        seq = self._pending[offset][0]
        gap = offset - self._placed
        if self.max_bytes is not None:
            gap = min(gap, self.max_bytes - self._placed)
        count = seq - self._next_seq
        if count < 1:                        # headers that disagree: count the payloads the gap holds
            count = max(1, -(-gap // self.payload_size))
        event = DroppedPackets(first_sequence=self._next_seq, count=count, stream_offset=self._placed, num_bytes=gap)
        self.lost.append(event)
        self._lost_offsets.append(event.stream_offset)
        self._buffer += bytes(gap)
        self._placed += gap
        if self._placed < offset:                # the limit fell inside the gap: nothing after it is kept
            self._pending.clear()
            return
        self._log.write(f"\n,{event.stream_offset},{event.num_bytes},")
        self._log.flush()
        self._lost_csv.write(f"{event.first_sequence},{event.count},{event.stream_offset},{event.num_bytes}\n")
        self._lost_csv.flush()
        self._drain()

    def tick(self) -> None:
        """Housekeeping while datagrams are scarce: end over-long waits, flush the staged bytes.

        Call it a few times a second (:func:`~risloc_rt.measured.live.record.record` does): a
        packet that has waited longer than ``reorder_timeout`` ahead of a gap makes the gap lost,
        and bytes staged longer than 50 ms go to the files.
        """
        now = self._clock()
        while self._pending and now - min(t for _, _, t in self._pending.values()) > self.reorder_timeout:
            self._declare_gap()
        if self._buffer and now - self._last_flush > _FLUSH_INTERVAL:
            self.flush()

    # -- files ---------------------------------------------------------------------------------------

    def _open_next(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
        path = self.folder / split_name(self.prefix, len(self.files))
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.files.append(path)
        self._file_size = 0

    def flush(self) -> None:
        """Write the staged bytes to the split files (handed to the OS; :attr:`final_bytes` grows)."""
        self._last_flush = self._clock()
        if not self._buffer:
            return
        view, done = memoryview(self._buffer), 0
        try:
            while done < len(view):
                if self._fd is None or self._file_size >= self.cut:
                    self._open_next()
                n = os.write(self._fd, view[done:done + min(len(view) - done, self.cut - self._file_size)])
                done += n
                self._file_size += n
                self.final_bytes += n
        finally:
            view.release()
            del self._buffer[:done]
        self.final_time = self._last_flush

    @property
    def full(self) -> bool:
        """Whether ``max_bytes`` stream bytes are placed (nothing more is written)."""
        return self.max_bytes is not None and self._placed >= self.max_bytes

    @property
    def waiting(self) -> int:
        """Packets waiting ahead of a gap."""
        return len(self._pending)

    @property
    def stream_bytes(self) -> int:
        """Stream bytes placed so far, final or staged [bytes]."""
        return self._placed

    def close(self) -> None:
        """Declare the remaining gaps lost, write everything, close the files and finish the log.

        Idempotent. A gap after the last packet received (the stream's end) cannot be seen and is
        not zero-filled: the recording ends with the last byte that arrived.
        """
        if self.closed:
            return
        self.closed = True
        try:
            while self._pending:
                self._declare_gap()
            self.flush()
        finally:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
            self._lost_csv.close()
            try:
                self._log.write(self._summary())
            finally:
                self._log.close()

    def _summary(self) -> str:
        zero_packets = sum(d.count for d in self.lost)
        zero_bytes = sum(d.num_bytes for d in self.lost)
        start = self.start_wall if self.start_wall is not None else time.time()
        end = self.end_wall if self.end_wall is not None else start
        return (f"\nRaw Data :\nOut of sequence count - {self.out_of_sequence}"
                f"\nOut of sequence seen from {self._oos_span[0]} to {self._oos_span[1]}"
                f"\nFirst Packet ID - {self.first_sequence or 0}\nLast Packet ID - {self.last_sequence or 0}"
                f"\nNumber of received packets - {self.received_packets}"
                f"\nNumber of zero filled packets - {zero_packets}\nNumber of zero filled bytes - {zero_bytes}"
                f"\nCapture start time - {time.ctime(start)}\nCapture end time - {time.ctime(end)}"
                f"\nDuration(sec) - {int(end - start)}")

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
