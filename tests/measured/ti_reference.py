"""A test-side DCA1000 decoder and encoder written from TI's documents, sharing no code with ``risloc_rt``.

This module imports numpy and the standard library only: never ``risloc_rt`` or ``dsp``
(``tests/measured/test_reference_decoder.py`` checks it). Every constant is written out here.
The reader's tests judge ``risloc_rt.measured`` against it, so that the project's emulator and
reader (which share reshapes, the header packer and constants) do not judge each other
(docs/style.md, item 16).

Sources, and what each rule below comes from:

[SWRA581] TI application report SWRA581, "Mmwave Radar Device ADC Raw Data Capture"
    (first issued as "xWR1xxx ADC Raw Data Capture"; section numbers of that 2017 issue):
    section 4 ("xWR12xx and xWR14xx Radar Studio Data Format": four LVDS lanes, one receiver per
    lane, the lanes interleaved sample by sample), section 5 ("xWR16xx Radar Studio Data Format": two LVDS lanes, per receiver and
    chirp the complex samples as ``I0 I1 Q0 Q1 I2 I3 Q2 Q3 ...``; real data as ``x0 x1 ...``),
    section 6 (the MATLAB reader: samples are signed 16-bit little-endian words; a chirp holds
    every enabled receiver in ascending order, chirps follow in transmission order).
[DCA1000UG] TI "DCA1000EVM Data Capture Card" user's guide (SPRUIJ4A), the data port's raw-mode
    packet format and the file storage format (stored with or without the packet header): a 4-byte
    sequence number (the first packet is 1), a 6-byte byte count (the ADC bytes sent before this
    packet), then at most 1456 bytes of ADC data; little-endian.
[STUDIO] TI mmWave Studio user's guide, DCA1000 capture: the recorded files are
    ``adc_data_Raw_0.bin``, ``adc_data_Raw_1.bin``, ... (one stream cut at a size limit), and
    the packet reorder and zero-fill post-processing step puts each packet at its byte count and
    fills a lost packet's bytes with zeros (so nothing after a loss moves).
[MMWAVELINK] mmWaveLink ``rl_device.h`` (shipped in the mmWave SDK and DFP), ``rlDevDataFmtCfg_t``
    (mmWave Studio's JSON ``rawDataCaptureConfig.rlDevDataFmtCfg_t``): ``iqSwapSel`` 0 = I first,
    1 = Q first (``RL_DEV_I_FIRST`` / ``RL_DEV_Q_FIRST``); ``rlDeviceSetDataFmtConfig`` "sets
    LVDS/CSI2 data output format".
[SDKUG] TI mmWave SDK 3.x user's guide, CLI command ``adcbufCfg <subFrameIdx> <adcOutputFmt>
    <SampleSwap> <ChanInterleave> <ChirpThreshold>``: SampleSwap is the *ADCBUF* (on-chip ADC
    buffer) I/Q swap selection, 0 = I in LSB, Q in MSB; 1 = Q in LSB, I in MSB; the demos support
    only 1. It describes the buffer the on-chip DSP/HWA reads, not the LVDS stream.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

#: [DCA1000UG] bytes of a raw-data packet header: 4 (sequence number) + 6 (byte count).
HEADER_BYTES = 10
#: [DCA1000UG] largest ADC payload of one packet, and the card's default payload [bytes].
MAX_PAYLOAD = 1456
#: [SWRA581 s.6] bytes of one ADC word (signed 16-bit, little-endian).
WORD_BYTES = 2


@dataclass(frozen=True)
class Shape:
    """What the configuration says about one frame.

    N samples per chirp and receiver, R receivers (ascending), C chirps per loop (transmission
    order), K loops; complex or real; 2 lanes (xWR16xx/18xx/68xx) or 4 (xWR14xx); q_first: the
    LVDS stream carries Q before I ([MMWAVELINK] iqSwapSel = 1).
    """

    N: int
    R: int
    C: int
    K: int
    complex_: bool = True
    lanes: int = 2
    q_first: bool = False

    @property
    def chirp_words(self) -> int:
        """int16 words of one chirp, every receiver: N·R (real) or 2·N·R (complex)."""
        return self.N * self.R * (2 if self.complex_ else 1)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame: 2 · chirp words · C · K."""
        return WORD_BYTES * self.chirp_words * self.C * self.K


def _chirp_to_iq(w: np.ndarray, s: Shape) -> tuple[np.ndarray, np.ndarray]:
    """One chirp's words -> (first, second) components ``[R, N]`` (second is zeros for real data)."""
    N, R = s.N, s.R
    first = np.zeros((R, N), np.int64)
    second = np.zeros((R, N), np.int64)
    if s.lanes == 2:
        # [SWRA581 s.5] receiver after receiver; each holds its N samples.
        for r in range(R):
            if not s.complex_:
                first[r] = w[r * N:(r + 1) * N]                       # x0 x1 x2 ...
                continue
            block = w[r * 2 * N:(r + 1) * 2 * N]
            quads = block.reshape(N // 2, 4)                          # groups "A(2m) A(2m+1) B(2m) B(2m+1)"
            first[r, 0::2], first[r, 1::2] = quads[:, 0], quads[:, 1]
            second[r, 0::2], second[r, 1::2] = quads[:, 2], quads[:, 3]
        return first, second
    # [SWRA581 s.4] four lanes, lane r = receiver r; the card interleaves the lanes word by word:
    # complex: per sample n, the first component of rx0..rx(R-1), then the second of rx0..rx(R-1).
    per = 2 * R if s.complex_ else R
    for n in range(N):
        group = w[n * per:(n + 1) * per]
        first[:, n] = group[:R]
        if s.complex_:
            second[:, n] = group[R:2 * R]
    return first, second


def decode(stream: bytes, s: Shape) -> tuple[np.ndarray, np.ndarray]:
    """Whole frames of a raw stream -> hardware (I, Q) codes ``[F, K, C·R, N]`` (int64; Q = 0 when real).

    Virtual channel ``v = c·R + r`` (chirp of the loop c in transmission order, receiver r).
    A trailing partial frame is ignored.
    """
    # [SWRA581 s.6] signed little-endian 16-bit words (reading them unsigned corrupts them).
    words = np.frombuffer(stream[:len(stream) - len(stream) % WORD_BYTES], dtype="<i2").astype(np.int64)
    F = len(stream) // s.frame_bytes
    V = s.C * s.R
    i_out = np.zeros((F, s.K, V, s.N), np.int64)
    q_out = np.zeros((F, s.K, V, s.N), np.int64)
    cw = s.chirp_words
    at = 0
    for f in range(F):
        for k in range(s.K):
            for c in range(s.C):
                first, second = _chirp_to_iq(words[at:at + cw], s)
                at += cw
                i_part, q_part = (second, first) if (s.q_first and s.complex_) else (first, second)
                i_out[f, k, c * s.R:(c + 1) * s.R] = i_part
                q_out[f, k, c * s.R:(c + 1) * s.R] = q_part
    return i_out, q_out


def ti_complex(stream: bytes, s: Shape) -> np.ndarray:
    """``I + jQ`` ``[F, K, V, N]`` as TI's tools show it (a target's beat tone at a positive frequency)."""
    i, q = decode(stream, s)
    return i + 1j * q


def encode(i: np.ndarray, q: np.ndarray | None, s: Shape) -> bytes:
    """Hardware (I, Q) codes ``[F, K, C·R, N]`` -> the raw stream's bytes, written word by word."""
    i = np.asarray(i)
    F = i.shape[0]
    out: list[int] = []
    for f in range(F):
        for k in range(s.K):
            for c in range(s.C):
                for_rx = [(int(c * s.R + r)) for r in range(s.R)]
                if s.lanes == 2:
                    for v in for_rx:                                  # [SWRA581 s.5]
                        if not s.complex_:
                            out += [int(x) for x in i[f, k, v]]
                            continue
                        a, b = (q, i) if s.q_first else (i, q)
                        for m in range(0, s.N, 2):
                            out += [int(a[f, k, v, m]), int(a[f, k, v, m + 1]),
                                    int(b[f, k, v, m]), int(b[f, k, v, m + 1])]
                else:
                    for n in range(s.N):                              # [SWRA581 s.4]
                        if not s.complex_:
                            out += [int(i[f, k, v, n]) for v in for_rx]
                            continue
                        a, b = (q, i) if s.q_first else (i, q)
                        out += [int(a[f, k, v, n]) for v in for_rx] + [int(b[f, k, v, n]) for v in for_rx]
    return struct.pack(f"<{len(out)}h", *out)


# ------------------------------------------------------------------------------------------ packets
def header(sequence: int, byte_count: int) -> bytes:
    """[DCA1000UG] ``<u32`` sequence number, then the byte count as 6 little-endian bytes."""
    return struct.pack("<I", sequence) + struct.pack("<Q", byte_count)[:6]


def packetize(stream: bytes, *, payload: int = MAX_PAYLOAD, lost: frozenset[int] = frozenset()) -> bytes:
    """The packet-recorded form of ``stream``: header + payload per packet, leaving out sequence numbers ``lost``."""
    parts = []
    for seq, at in enumerate(range(0, len(stream), payload), start=1):
        if seq not in lost:
            parts.append(header(seq, at) + stream[at:at + payload])
    return b"".join(parts)


def zero_fill_raw(stream: bytes, *, payload: int = MAX_PAYLOAD, lost: frozenset[int] = frozenset()) -> bytes:
    """[STUDIO] what a raw-mode file holds when packets ``lost`` (1-based) are lost: their bytes zero, nothing moved."""
    out = bytearray(stream)
    for seq in lost:
        start = (seq - 1) * payload
        end = min(start + payload, len(out))
        out[start:end] = bytes(end - start)
    return bytes(out)


@dataclass(frozen=True)
class Lost:
    """A gap in a packet-recorded file: sequence numbers ``first .. first+count-1``, ``num_bytes`` at ``offset``."""

    first: int
    count: int
    offset: int
    num_bytes: int


def depacketize(data: bytes, payload: int) -> tuple[bytes, list[Lost]]:
    """A packet-recorded file -> (the sample stream with lost packets zero-filled at their byte count, the gaps)."""
    stream = bytearray()
    gaps: list[Lost] = []
    at, expected = 0, 1
    while at < len(data):
        seq, = struct.unpack("<I", data[at:at + 4])
        count = int.from_bytes(data[at + 4:at + 10], "little")
        body = data[at + HEADER_BYTES:at + HEADER_BYTES + payload]
        if count < len(stream):                                       # late or duplicate: already placed
            at += HEADER_BYTES + len(body)
            continue
        if count > len(stream):                                       # [STUDIO] zero-fill the gap
            gaps.append(Lost(expected, seq - expected, len(stream), count - len(stream)))
            stream += bytes(count - len(stream))
        stream += body
        expected = seq + 1
        at += HEADER_BYTES + len(body)
    return bytes(stream), gaps


def zero_packets(stream: bytes, *, payload: int = MAX_PAYLOAD) -> list[int]:
    """Sequence numbers (1-based) of the whole packets on the ``payload`` grid of a raw stream that are all zeros."""
    return [j + 1 for j in range(len(stream) // payload) if not any(stream[j * payload:(j + 1) * payload])]


# -------------------------------------------------------------------------------------- split files
def split_names(prefix: str, count: int) -> list[str]:
    """[STUDIO] ``<prefix>_Raw_0.bin``, ``<prefix>_Raw_1.bin``, ..."""
    return [f"{prefix}_Raw_{i}.bin" for i in range(count)]


def read_split(folder, prefix: str) -> bytes:
    """The files ``<prefix>_Raw_<i>.bin`` in ``folder`` concatenated in index order (i = 0, 1, ... without a gap)."""
    import pathlib

    folder = pathlib.Path(folder)
    chunks = []
    for name in split_names(prefix, 10_000):
        path = folder / name
        if not path.is_file():
            break
        chunks.append(path.read_bytes())
    return b"".join(chunks)
