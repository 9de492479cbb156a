"""Probable lost packets of a raw-mode DCA1000 stream: whole packets of exact zeros on the packet grid.

A raw-mode file has no packet headers, but the DCA1000 recording step zero-fills a lost packet's
bytes at its place (TI mmWave Studio user's guide, the packet reorder and zero-fill step), so a
loss leaves ``P`` bytes of zeros starting at a multiple of ``P`` (the payload, 1456 bytes by
default: TI DCA1000EVM user's guide, raw-data packet format). The grid is known without headers:
the card's first packet carries the stream's first byte, so packet ``j`` holds bytes
``[j·P, (j+1)·P)`` of the stream (split files are one stream, cut anywhere).

Criterion (:func:`scan_zero_packets`):

1. a **candidate** is a whole packet on that grid whose ``P/2`` int16 words are all exactly 0;
2. the capture shows **noise**: among the words outside the candidates (at least one packet's
   worth) at most :data:`NOISE_MAX_ZERO_FRACTION` = 1/2 are exactly 0.

An ADC whose input carries Gaussian noise of σ ≥ 1 LSB per word gives a 0 with probability
``p0 = erf(0.5/(σ√2)) ≤ 0.383``; a candidate then arises by chance with probability
``p0^(P/2) ≤ 0.383^728 ≈ 10^-303`` per packet, and rule 2 fails by chance (fraction > 1/2 with
≥ 728 words, binomial σ ≤ 0.018) with probability < 10^-10 (rule 2 holds for any noise above
0.74 LSB rms, where p0 = 1/2). A digitally silent stream (a
noise-free emulation, ``--no-noise``: zeros everywhere) fails rule 2 and is not called lossy; its
all-zero packets are only noted.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .packets import MAX_PAYLOAD, DroppedPackets

__all__ = ["NOISE_MAX_ZERO_FRACTION", "ZeroScan", "scan_zero_packets"]

#: Largest share of exact-zero words outside the candidate packets that still shows ADC noise.
NOISE_MAX_ZERO_FRACTION = 0.5


@dataclass(frozen=True)
class ZeroScan:
    """What :func:`scan_zero_packets` found.

    Attributes
    ----------
    payload_size : int
        The packet grid P [bytes].
    dropped : tuple of DroppedPackets
        Runs of consecutive all-zero packets, ``probable=True``; empty without noise evidence.
    zero_packets : int
        All-zero whole packets (candidates), reported or not.
    words_outside, zeros_outside : int
        int16 words outside the candidates, and how many of them are exactly 0.
    noise_evidence : bool
        Rule 2 holds (the stream is not digitally silent).
    """

    payload_size: int
    dropped: tuple[DroppedPackets, ...]
    zero_packets: int
    words_outside: int
    zeros_outside: int
    noise_evidence: bool

    @property
    def zero_fraction(self) -> float:
        """Share of exact-zero words outside the candidates (NaN when there are none)."""
        return self.zeros_outside / self.words_outside if self.words_outside else float("nan")

    def note(self) -> str | None:
        """One line for a capture's notes when all-zero packets were seen but not reported, else None.

        Returns
        -------
        str or None
        """
        if not self.zero_packets or self.noise_evidence:
            return None
        return (f"{self.zero_packets} whole {self.payload_size}-byte packets of exact zeros on the packet grid, but "
                f"the rest of the stream shows no ADC noise ({self.zero_fraction:.0%} exact zeros; "
                f"{self.words_outside} words): digital silence, not reported as lost packets")


def scan_zero_packets(files: Sequence[Path], *, length: int, payload_size: int = MAX_PAYLOAD,
                      block_packets: int = 4096) -> ZeroScan:
    """Find the probable lost packets of a raw-mode stream (criterion in the module docstring).

    Parameters
    ----------
    files : sequence of Path
        The split files in stream order (raw form).
    length : int
        Stream bytes to scan [bytes] (the frames that will be decoded; a final partial packet
        counts towards the noise evidence, never as a candidate).
    payload_size : int, default 1456
        The packet grid P [bytes], even.
    block_packets : int, default 4096
        Packets examined at a time (sets the memory used).

    Returns
    -------
    ZeroScan
    """
    P = int(payload_size)
    words_per = P // 2
    buf = np.empty(block_packets * P, np.uint8)
    fill = pos = 0
    zero_idx: list[np.ndarray] = []
    words_out = zeros_out = 0

    def examine(nbytes: int, first_packet: int) -> None:
        nonlocal words_out, zeros_out
        whole, rem = divmod(nbytes, P)
        if whole:
            w = buf[:whole * P].view("<i2").reshape(whole, words_per)
            cand = ~w.any(axis=1)
            ncand = int(np.count_nonzero(cand))
            zero_idx.append(first_packet + np.flatnonzero(cand))
            words_out += words_per * (whole - ncand)
            zeros_out += int(w.size - np.count_nonzero(w)) - words_per * ncand
        if rem >= 2:                                   # the stream's final, partial packet
            tail = buf[whole * P:whole * P + rem - rem % 2].view("<i2")
            words_out += tail.size
            zeros_out += int(tail.size - np.count_nonzero(tail))

    packet0 = 0
    view = memoryview(buf)
    for path in files:                                # read straight into the packet-aligned buffer
        with open(path, "rb", buffering=0) as fh:
            while pos < length:
                n = fh.readinto(view[fill:min(buf.size, fill + length - pos)])
                if not n:
                    break
                fill, pos = fill + n, pos + n
                if fill == buf.size:
                    examine(fill, packet0)
                    packet0 += block_packets
                    fill = 0
    view.release()
    if fill:
        examine(fill, packet0)
    idx = np.concatenate(zero_idx) if zero_idx else np.empty(0, np.int64)
    evidence = words_out >= words_per and zeros_out <= NOISE_MAX_ZERO_FRACTION * words_out
    runs: list[DroppedPackets] = []
    if evidence and idx.size:
        breaks = np.flatnonzero(np.diff(idx) != 1) + 1
        for run in np.split(idx, breaks):
            j0 = int(run[0])
            runs.append(DroppedPackets(first_sequence=j0 + 1, count=int(run.size), stream_offset=j0 * P,
                                       num_bytes=int(run.size) * P, probable=True))
    return ZeroScan(payload_size=P, dropped=tuple(runs), zero_packets=int(idx.size), words_outside=words_out,
                    zeros_outside=zeros_out, noise_evidence=bool(evidence))
