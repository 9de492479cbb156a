"""Streaming reader of DCA1000 raw ADC captures (raw mode or packet-recorded, split files).

>>> info = open_raw("adc_data_Raw_0.bin", layout)            # sizes checked, nothing decoded
>>> for block in iter_frames(info, frames_per_block=8):       # memory: a few frames
...     block.cube                                              # complex64 [f, K, V, N]
>>> capture = read_raw("adc_data_Raw_0.bin", layout)          # everything at once: capture.cube [F, K, V, N]

Axis order of every cube: frames F, loops K (chirps per virtual channel), virtual channels V
(chirp-of-the-loop major, receiver minor), samples N; ADC counts, complex64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Literal, Sequence

import numpy as np

from dsp.budget import check_memory
from dsp.validation import integer

from ..errors import MeasuredFormatError
from .packets import (HEADER_BYTES, MAX_PAYLOAD, DroppedPackets, PacketIssue, detect_payload_size, iter_packet_stream,
                      packet_stream_length)
from .raw_layout import Convention, RawLayout, decode_frames
from .split_files import capture_files, iter_file_bytes
from .zero_packets import scan_zero_packets

__all__ = ["CaptureInfo", "Form", "FrameBlock", "RawCapture", "iter_frames", "open_raw", "read_raw"]

Form = Literal["auto", "raw", "packets"]
_MIB = 1 << 20


@dataclass(frozen=True)
class CaptureInfo:
    """What a capture holds, learned from its sizes and headers before any sample is decoded.

    Attributes
    ----------
    files : tuple of Path
        Split files in stream order.
    form : {"raw", "packets"}
        Plain samples, or packet-recorded (10-byte headers).
    payload_size : int or None
        Packet payload [bytes] (packet form only).
    layout : RawLayout
    stream_bytes : int
        Sample-stream bytes (packet form: including zero-filled gaps).
    num_frames : int
        Complete frames, F.
    truncated_bytes : int
        Bytes of an incomplete final frame (reported and dropped); 0 when none.
    configured_frames : int or None
        Frames the configuration asked for (``frameCfg`` numFrames; None for 0 = until stopped).
    notes : tuple of str
        Findings that do not stop reading (a truncated final frame, fewer frames than configured,
        all-zero packets in a digitally silent raw stream).
    probable_dropped : tuple of DroppedPackets
        Raw form: probable lost packets, whole packets of exact zeros on the payload grid of a
        stream that shows ADC noise (``probable=True``; :mod:`.zero_packets`). Empty for the
        packet form, whose gaps come from the headers while reading.
    """

    files: tuple[Path, ...]
    form: Literal["raw", "packets"]
    payload_size: int | None
    layout: RawLayout
    stream_bytes: int
    num_frames: int
    truncated_bytes: int
    configured_frames: int | None
    notes: tuple[str, ...]
    probable_dropped: tuple[DroppedPackets, ...] = ()


@dataclass(frozen=True)
class FrameBlock:
    """A run of consecutive frames from :func:`iter_frames`.

    Attributes
    ----------
    first_frame : int
        Index of ``cube[0]`` in the capture.
    cube : ndarray of complex64, [f, K, V, N]
    damaged : ndarray of bool, [f]
        Frames holding zero-filled bytes of lost packets (packet form) or probable lost packets
        (raw form).
    dropped : tuple of DroppedPackets
        Gaps starting in this block (``probable=True``: found as zeros in a raw stream).
    issues : tuple of PacketIssue
        Late, duplicate or inconsistent packets met while reading this block.
    """

    first_frame: int
    cube: np.ndarray
    damaged: np.ndarray
    dropped: tuple[DroppedPackets, ...]
    issues: tuple[PacketIssue, ...]


@dataclass(frozen=True)
class RawCapture:
    """A whole capture in memory (:func:`read_raw`).

    Attributes
    ----------
    cube : ndarray of complex64, [F, K, V, N]
        ADC counts; frames, loops, virtual channels, samples.
    info : CaptureInfo
    damaged_frames : tuple of int
        Frames holding zero-filled bytes (lost or probably lost packets).
    dropped : tuple of DroppedPackets
        Lost packets; ``probable=True`` for those found as zeros in a raw-mode stream.
    issues : tuple of PacketIssue
    convention : {"paper", "ti"}
    """

    cube: np.ndarray
    info: CaptureInfo
    damaged_frames: tuple[int, ...]
    dropped: tuple[DroppedPackets, ...]
    issues: tuple[PacketIssue, ...]
    convention: str

    @property
    def dropped_packets(self) -> int:
        """Packets lost in total (certain and probable)."""
        return sum(d.count for d in self.dropped)

    @property
    def probable_dropped_packets(self) -> int:
        """Packets probably lost: whole packets of zeros in a raw-mode stream."""
        return sum(d.count for d in self.dropped if d.probable)


def _split_missing(files: Sequence[Path], total: int, expected_bytes: int | None) -> bool:
    """The data stops short of ``expected_bytes`` and the last file ends at a recorder's size limit, not a stop:
    exactly k MiB (mmWave Studio) or the last whole 1456-byte packet under k MiB (TI's DCA1000 CLI,
    ``maxRecFileSize_MB``)."""
    size = Path(files[-1]).stat().st_size
    return bool(expected_bytes) and total < expected_bytes and size > 0 and (-size) % _MIB < MAX_PAYLOAD


def _likely_causes(total: int, layout: RawLayout, files: Sequence[Path], expected: int | None) -> str:
    """Human hints for a size that does not fit the configuration."""
    fb = layout.frame_bytes
    hints = []
    ref = expected * fb if expected else fb
    for ratio, why in ((2.0, "the data is complex but the config says real (adcCfg adcOutputFmt)"),
                       (0.5, "the data is real but the config says complex (adcCfg adcOutputFmt)")):
        if total == ref * ratio or (not expected and total % int(fb * ratio) == 0 and total % fb):
            hints.append(why)
    R, C = layout.num_rx, layout.chirps_per_loop
    candidates = [(r, C) for r in range(1, 9)] + [(R, c) for c in range(1, 13)]
    for r, c in candidates:
        if (r, c) != (R, C) and total * R * C == ref * r * c:
            hints.append(f"{r} rx x {c} chirps/loop were recorded, not {R} x {C} (channelCfg, chirpCfg, frameCfg)")
            break
    if _split_missing(files, total, expected * fb if expected else None):
        last = Path(files[-1])
        size = last.stat().st_size
        hints.append(f"a split file after {last.name} is missing ({last.name} ends at a size limit: {size} bytes, "
                     f"{'exactly' if size % _MIB == 0 else 'the last whole packet under'} {-(-size // _MIB)} MiB)")
    if not hints:
        hints.append("check numAdcSamples, channelCfg masks, chirps per loop and numLoops against the capture, "
                      "and that no split file is missing")
    return "; ".join(hints)


#: Largest share of a packet-recorded stream that may be lost (zero-filled) before the headers are refused.
MAX_LOST_FRACTION = 0.5
#: Bytes per complex64 sample of a decoded cube.
CUBE_ITEM_BYTES = 8


def _check_zero_fill(files: Sequence[Path], sizes: Sequence[int], payload_size: int, total: int) -> None:
    """Refuse packet headers that declare a stream mostly made of lost packets.

    The last header says how long the stream is (``byte count + payload``); the files hold
    ``Σ whole packets · P`` + the final short payload. A stream more than :data:`MAX_LOST_FRACTION`
    lost is not a lossy link but a corrupt or hostile header (a sequence jump to 2³² declares
    ~6 TB): reading it would zero-fill that much.
    """
    rec = HEADER_BYTES + payload_size
    present = 0
    for size in sizes:
        full, rem = divmod(size, rec)
        present += full * payload_size + max(rem - HEADER_BYTES, 0)
    lost = total - present
    if lost > MAX_LOST_FRACTION * total:
        last = Path(files[-1])
        raise MeasuredFormatError(
            f"{last}: the last packet header declares a stream of {total:,} bytes but the files hold {present:,} bytes "
            f"of payload: {lost / total:.1%} would be lost packets, zero-filled (more than "
            f"{MAX_LOST_FRACTION:.0%}); the header is corrupt, a split file is missing, or the file is not "
            "packet-recorded (pass form='raw')")


def open_raw(path: str | Path | Sequence[str | Path], layout: RawLayout, *, form: Form = "auto",
             payload_size: int | None = None, expected_frames: int | None = None,
             find_zero_packets: bool = True) -> CaptureInfo:
    """Find a capture's files, tell raw from packet-recorded, and check the size against ``layout``.

    Parameters
    ----------
    path : path or sequence of paths
        A file (``…_Raw_0.bin`` collects its split siblings) or the files in order.
    layout : RawLayout
        From the configuration (:meth:`RawLayout.from_config`).
    form : {"auto", "raw", "packets"}, default "auto"
        ``"auto"`` takes the packet form when the first bytes are consistent DCA1000 headers.
    payload_size : int, optional
        Packet payload [bytes]; detected from the first headers when not given. Raw form: the
        packet grid of the lost-packet search (default 1456, the DCA1000's payload).
    expected_frames : int, optional
        Frames the configuration asked for (``frameCfg`` numFrames; 0 or None: unknown).
    find_zero_packets : bool, default True
        Raw form: scan the stream once for probable lost packets (whole packets of exact zeros
        on the payload grid, with noise elsewhere; :func:`~.zero_packets.scan_zero_packets`).

    Returns
    -------
    CaptureInfo
        The files, form, payload size, stream length [bytes], complete frames, notes and the
        probable lost packets of a raw stream.

    Raises
    ------
    MeasuredFormatError
        Less than one frame of data, more data than ``expected_frames`` frames, a missing split
        file, or a packet file whose headers do not parse; the message gives the expected and
        actual sizes and the likely cause.
    """
    files = capture_files(path)
    if form not in ("auto", "raw", "packets"):
        raise MeasuredFormatError(f"form={form!r} must be 'auto', 'raw' or 'packets'")
    with open(files[0], "rb") as fh:
        head = fh.read(3 * (HEADER_BYTES + 1462) + HEADER_BYTES)
    if payload_size is not None:
        payload_size = integer(payload_size, "payload_size", minimum=2, maximum=1462, error=MeasuredFormatError)
    detected = detect_payload_size(head) if form != "raw" and payload_size is None else payload_size
    if form == "packets" and detected is None:
        raise MeasuredFormatError(f"{files[0]}: the first bytes are not a DCA1000 packet header; "
                                  "if the file holds plain samples pass form='raw'")
    resolved = "packets" if (form == "packets" or (form == "auto" and detected is not None)) else "raw"
    sizes = [f.stat().st_size for f in files]
    if resolved == "packets":
        rec = HEADER_BYTES + detected
        for f, s in zip(files[:-1], sizes[:-1]):
            if s % rec:
                raise MeasuredFormatError(f"{f}: {s} bytes is not a whole number of {rec}-byte packets; split files "
                                          "of a packet capture end between packets (wrong payload_size?)")
        total = packet_stream_length(files, detected)
        _check_zero_fill(files, sizes, detected, total)
    else:
        total = sum(sizes)
    expected = int(expected_frames) if expected_frames else None
    fb = layout.frame_bytes
    where = str(files[0]) + (f" (+{len(files) - 1} split files)" if len(files) > 1 else "")
    if total < fb:
        raise MeasuredFormatError(
            f"{where}: {total} bytes of samples, less than one frame of {fb} bytes ({layout.describe()}); "
            f"likely cause: {_likely_causes(total, layout, files, expected)}")
    if expected is not None and total > expected * fb:
        raise MeasuredFormatError(
            f"{where}: {total} bytes of samples, expected {expected * fb} ({expected} frames x {fb} bytes, "
            f"{layout.describe()}); likely cause: {_likely_causes(total, layout, files, expected)}")
    notes = []
    if expected is not None and total < expected * fb:
        if _split_missing(files, total, expected * fb):
            hint = _likely_causes(total, layout, files, expected)
            raise MeasuredFormatError(f"{where}: {total} bytes of samples, expected {expected * fb} "
                                      f"({expected} frames x {fb} bytes); likely cause: {hint}")
        notes.append(f"{total // fb} complete frames of the {expected} configured (capture stopped early)")
    frames, truncated = divmod(total, fb)
    if truncated:
        notes.append(f"final frame {frames} is truncated ({truncated} of {fb} bytes) and dropped")
    probable: tuple[DroppedPackets, ...] = ()
    if resolved == "raw" and find_zero_packets:
        grid = payload_size or MAX_PAYLOAD
        if grid % 2:
            raise MeasuredFormatError(f"payload_size={grid} must be even (whole int16 words per packet)")
        scan = scan_zero_packets(files, length=min(total, -(-frames * fb // grid) * grid), payload_size=grid)
        probable = scan.dropped
        if scan.note():
            notes.append(scan.note())
    return CaptureInfo(files=files, form=resolved, payload_size=detected if resolved == "packets" else None,
                       layout=layout, stream_bytes=total, num_frames=frames, truncated_bytes=truncated,
                       configured_frames=expected, notes=tuple(notes), probable_dropped=probable)


def _stream(info: CaptureInfo, block: int) -> Iterator[tuple[np.ndarray, DroppedPackets | PacketIssue | None]]:
    if info.form == "packets":
        yield from iter_packet_stream(info.files, info.payload_size)
        return
    for view in iter_file_bytes(info.files, block):
        yield np.frombuffer(view, np.uint8), None


def iter_frames(info: CaptureInfo, *, frames_per_block: int = 8, convention: Convention = "paper",
                max_frames: int | None = None) -> Iterator[FrameBlock]:
    """Decode a capture block by block; memory stays at a few blocks whatever the file size.

    Parameters
    ----------
    info : CaptureInfo
        From :func:`open_raw`.
    frames_per_block : int, default 8
        Frames per yielded block (the last may be shorter).
    convention : {"paper", "ti"}, default "paper"
        Sign of Q (:func:`~.raw_layout.decode_frames`).
    max_frames : int, optional
        Stop after this many frames.

    Yields
    ------
    FrameBlock
        ``cube`` complex64 ``[f, K, V, N]``. The truncated final frame, if any, is never yielded.
    """
    fpb = integer(frames_per_block, "frames_per_block", minimum=1, error=MeasuredFormatError)
    layout, fb = info.layout, info.layout.frame_bytes
    last = info.num_frames if max_frames is None else min(info.num_frames, integer(max_frames, "max_frames",
                                                                                        minimum=0, error=MeasuredFormatError))
    f = max(min(fpb, last), 1)
    check_memory(f * (fb + CUBE_ITEM_BYTES * layout.num_loops * layout.num_virtual * layout.num_samples),
                 f"{info.files[0]}: one block of {f} frame(s) of {fb:,} bytes ({layout.describe()}) and its complex64 "
                 "cube", fix="lower frames_per_block, or check numAdcSamples, numLoops and the chirps per loop")
    buf = np.empty(f * fb, np.uint8)
    fill, frame0 = 0, 0
    damaged: set[int] = set()
    dropped: list[DroppedPackets] = []
    issues: list[PacketIssue] = []

    def emit(nframes: int) -> FrameBlock:
        nonlocal dropped, issues
        cube = decode_frames(buf[:nframes * fb].view("<i2"), layout, convention=convention)
        end = frame0 + nframes
        mine = tuple(d for d in dropped if d.stream_offset < end * fb)
        dropped = [d for d in dropped if d.stream_offset >= end * fb]
        block = FrameBlock(first_frame=frame0, cube=cube,
                           damaged=np.array([f in damaged for f in range(frame0, end)], dtype=bool),
                           dropped=mine, issues=tuple(issues))
        issues = []
        return block

    if last == 0:
        return
    for event in info.probable_dropped:               # raw form: found by open_raw's scan, in stream order
        dropped.append(event)
        damaged.update(range(event.stream_offset // fb,
                             min((event.stream_offset + event.num_bytes - 1) // fb + 1, last)))
    for data, event in _stream(info, 1 << 22):
        if isinstance(event, DroppedPackets):
            dropped.append(event)
            # frames past ``last`` are never read: a gap declared to reach 2^47 bytes marks only those up to it
            damaged.update(range(event.stream_offset // fb,
                                 min((event.stream_offset + event.num_bytes - 1) // fb + 1, last)))
        elif isinstance(event, PacketIssue):
            issues.append(event)
        while data.size:
            n = min(data.size, buf.size - fill)
            buf[fill:fill + n] = data[:n]
            fill, data = fill + n, data[n:]
            whole = min(fill // fb, last - frame0)
            if fill == buf.size or frame0 + whole >= last:
                yield emit(whole)
                frame0 += whole
                if frame0 >= last:
                    return
                fill = 0
    if fill // fb:
        yield emit(min(fill // fb, last - frame0))


def read_raw(path: str | Path | Sequence[str | Path], layout: RawLayout, *, form: Form = "auto",
             payload_size: int | None = None, expected_frames: int | None = None,
             convention: Convention = "paper", max_frames: int | None = None,
             find_zero_packets: bool = True) -> RawCapture:
    """Read a whole capture into ``complex64 [F, K, V, N]`` (see :func:`open_raw`, :func:`iter_frames`).

    Lost packets are zero-filled in place and listed (in a raw-mode stream, whole packets of zeros
    are listed as probable losses); a truncated final frame is dropped and noted in ``info.notes``. For files larger than memory use :func:`iter_frames`.

    Parameters
    ----------
    path : path or sequence of paths
        A file (``…_Raw_0.bin`` collects its split siblings) or the files in order.
    layout : RawLayout
        From the configuration (:meth:`RawLayout.from_config`).
    form : {"auto", "raw", "packets"}, default "auto"
        Plain samples or packet-recorded; ``"auto"`` detects it.
    payload_size : int, optional
        Packet payload [bytes]; detected when not given.
    expected_frames : int, optional
        Frames the configuration asked for (``frameCfg`` numFrames; 0 or None: unknown).
    convention : {"paper", "ti"}, default "paper"
        Sign of Q (:func:`~.raw_layout.decode_frames`).
    max_frames : int, optional
        Read only the first frames.
    find_zero_packets : bool, default True
        Raw form: report probable lost packets (:func:`open_raw`).

    Returns
    -------
    RawCapture
        ``cube`` complex64 ``[F, K, V, N]`` [ADC counts], the capture's info, damaged frames, lost
        packets and packet issues.

    Raises
    ------
    dsp.budget.BudgetError
        The cube (``8·F·K·V·N`` bytes) and one block being decoded would exceed the memory limit.
    """
    info = open_raw(path, layout, form=form, payload_size=payload_size, expected_frames=expected_frames,
                    find_zero_packets=find_zero_packets)
    nf = info.num_frames if max_frames is None else min(info.num_frames, max_frames)
    shape = layout.cube_shape(nf)
    fpb = 16
    block_bytes = min(fpb, max(nf, 1)) * (layout.frame_bytes + CUBE_ITEM_BYTES * math.prod(shape[1:]))
    check_memory(CUBE_ITEM_BYTES * math.prod(shape) + block_bytes,
                 f"{info.files[0]}: {nf:,} frames of {info.stream_bytes:,} bytes of {info.form} stream read whole as "
                 f"complex64 {list(shape)} (and one block of {fpb} frames being decoded)",
                 fix="read it block by block (iter_frames) or pass max_frames")
    cube = np.empty(shape, np.complex64)
    damaged, dropped, issues = [], [], []
    for block in iter_frames(info, convention=convention, max_frames=nf, frames_per_block=fpb):
        cube[block.first_frame:block.first_frame + len(block.cube)] = block.cube
        damaged += [block.first_frame + i for i in np.flatnonzero(block.damaged)]
        dropped += block.dropped
        issues += block.issues
    return RawCapture(cube=cube, info=info, damaged_frames=tuple(damaged), dropped=tuple(dropped),
                      issues=tuple(issues), convention=convention)
