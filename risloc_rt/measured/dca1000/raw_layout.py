"""Byte layout of DCA1000 raw ADC data: one frame's int16 words ↔ the complex cube ``[F, K, V, N]``.

A frame holds ``num_loops`` loops of ``chirps_per_loop`` chirps; each chirp carries every enabled
receiver. Within a chirp (little-endian signed int16 words):

* 2 lanes (xWR16xx/18xx/68xx), receiver after receiver, N samples each:
  complex ``I0 I1 Q0 Q1 I2 I3 Q2 Q3 …``; real ``x0 x1 x2 …``.
* 4 lanes (xWR14xx), one lane per receiver, sample after sample:
  complex ``I0(rx0) … I0(rx R-1) Q0(rx0) … Q0(rx R-1) I1(rx0) …``; real ``x0(rx0) … x0(rx R-1) x1(rx0) …``.

``iq_swap`` exchanges I and Q. The decoded cube is ``complex64 [F, K, V, N]``: frames, loops
(chirps per virtual channel), virtual channels ``v = c·R + r`` (chirp of the loop c in
transmission order, receiver r in ascending index), samples. ``convention="paper"`` returns
``I − jQ`` (the project's eq. (1) sign, ``docs/conventions.md``), ``"ti"`` returns ``I + jQ``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from dsp.validation import integer

from ..errors import MeasuredFormatError
from ..ti.chirp_config import ADC_FORMATS, AdcFormat, TiChirpConfig

__all__ = ["Convention", "RawLayout", "decode_frames", "encode_frames"]

Convention = Literal["paper", "ti"]


@dataclass(frozen=True)
class RawLayout:
    """How the bytes of a raw capture map onto samples.

    Parameters
    ----------
    num_samples : int
        N, ADC samples per chirp and receiver.
    num_rx : int
        R, receivers in the file.
    chirps_per_loop : int
        C, chirps per loop (TDM-MIMO transmitter slots).
    num_loops : int
        K, loops per frame.
    adc_format : {"real", "complex1x", "complex2x"}, default "complex1x"
        Complex formats store an I and a Q word per sample; real one word.
    lanes : {2, 4}, default 2
        LVDS lanes: 2 for xWR16xx/18xx/68xx, 4 for xWR14xx (lane = receiver, R <= 4).
    iq_swap : bool, default False
        The file stores Q before I.
    """

    num_samples: int
    num_rx: int
    chirps_per_loop: int
    num_loops: int
    adc_format: AdcFormat = "complex1x"
    lanes: int = 2
    iq_swap: bool = False

    def __post_init__(self) -> None:
        for name in ("num_samples", "num_rx", "chirps_per_loop", "num_loops"):
            object.__setattr__(self, name, integer(getattr(self, name), name, minimum=1, error=MeasuredFormatError))
        if self.adc_format not in ADC_FORMATS:
            raise MeasuredFormatError(f"adc_format={self.adc_format!r} must be one of {ADC_FORMATS}")
        if self.lanes not in (2, 4):
            raise MeasuredFormatError(f"lanes={self.lanes!r} must be 2 (xWR16xx/18xx/68xx) or 4 (xWR14xx)")
        if self.lanes == 4 and self.num_rx > 4:
            raise MeasuredFormatError(f"4-lane (xWR14xx) data carries one receiver per lane; num_rx={self.num_rx} > 4")
        if self.lanes == 2 and self.is_complex and self.num_samples % 2:
            raise MeasuredFormatError(f"2-lane complex data interleaves sample pairs (I0 I1 Q0 Q1); "
                                      f"num_samples={self.num_samples} must be even")
        object.__setattr__(self, "iq_swap", bool(self.iq_swap))

    @classmethod
    def from_config(cls, config: TiChirpConfig, *, lanes: int = 2, iq_swap: bool = False) -> "RawLayout":
        """The layout of a capture made with ``config`` (``iq_swap`` is the file's, not the config's flag)."""
        return cls(num_samples=config.num_samples, num_rx=config.num_rx, chirps_per_loop=config.chirps_per_loop,
                   num_loops=config.num_loops, adc_format=config.adc_format, lanes=lanes, iq_swap=iq_swap)

    @property
    def is_complex(self) -> bool:
        """True for complex1x/complex2x."""
        return self.adc_format != "real"

    @property
    def num_virtual(self) -> int:
        """V = C·R virtual channels."""
        return self.chirps_per_loop * self.num_rx

    @property
    def words_per_sample(self) -> int:
        """int16 words per sample: 2 (complex) or 1 (real)."""
        return 2 if self.is_complex else 1

    @property
    def chirp_bytes(self) -> int:
        """Bytes of one chirp (all receivers)."""
        return 2 * self.words_per_sample * self.num_samples * self.num_rx

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame: ``2 · (2 or 1) · N · R · C · K``."""
        return self.chirp_bytes * self.chirps_per_loop * self.num_loops

    @property
    def frame_words(self) -> int:
        """int16 words of one frame."""
        return self.frame_bytes // 2

    def cube_shape(self, num_frames: int) -> tuple[int, int, int, int]:
        """The decoded cube's shape ``(F, K, V, N)``.

        Parameters
        ----------
        num_frames : int
            F, frames.

        Returns
        -------
        tuple of 4 int
        """
        return (num_frames, self.num_loops, self.num_virtual, self.num_samples)

    def describe(self) -> str:
        """One line, e.g. ``256 complex1x samples x 4 rx x 3 chirps/loop x 64 loops, 2 lanes = … bytes/frame``.

        Returns
        -------
        str
        """
        return (f"{self.num_samples} {self.adc_format} samples x {self.num_rx} rx x {self.chirps_per_loop} "
                f"chirps/loop x {self.num_loops} loops, {self.lanes} lanes{', I/Q swapped' if self.iq_swap else ''}"
                f" = {self.frame_bytes} bytes/frame")


def _split_iq(words: np.ndarray, layout: RawLayout, num_frames: int) -> tuple[np.ndarray, np.ndarray | None]:
    """int16 words → (first, second) component arrays ``[F, K, C, R, N]`` (second is None for real data)."""
    F, K, C, R, N = num_frames, layout.num_loops, layout.chirps_per_loop, layout.num_rx, layout.num_samples
    if layout.lanes == 2:
        if not layout.is_complex:
            return words.reshape(F, K, C, R, N), None
        w = words.reshape(F, K, C, R, N // 2, 2, 2)          # pair, (I|Q), lane
        return w[..., 0, :].reshape(F, K, C, R, N), w[..., 1, :].reshape(F, K, C, R, N)
    if not layout.is_complex:
        return np.moveaxis(words.reshape(F, K, C, N, R), 4, 3), None
    w = words.reshape(F, K, C, N, 2, R)                        # sample, (I|Q), lane = receiver
    return np.moveaxis(w[..., 0, :], 4, 3), np.moveaxis(w[..., 1, :], 4, 3)


def decode_frames(words: np.ndarray, layout: RawLayout, *, convention: Convention = "paper",
                  out: np.ndarray | None = None) -> np.ndarray:
    """Decode whole frames of int16 words into ``complex64 [F, K, V, N]`` in ADC counts.

    Parameters
    ----------
    words : ndarray of int16, [F · frame_words]
        Little-endian signed samples as stored (``numpy.frombuffer(b, "<i2")``).
    layout : RawLayout
    convention : {"paper", "ti"}, default "paper"
        ``"paper"``: ``I − jQ``, a target's beat tone at the project's negative frequency
        ``−Sτ``; ``"ti"``: ``I + jQ`` as TI's tools show it. Real data has Q = 0.
    out : ndarray of complex64, optional
        Destination ``[F, K, V, N]``.

    Returns
    -------
    ndarray of complex64, [F, K, V, N]
        ADC counts (``out`` when given).
    """
    words = np.asarray(words)
    if words.dtype != np.dtype("<i2"):
        raise MeasuredFormatError(f"words must be little-endian int16, got {words.dtype}: raw samples are signed")
    if words.size % layout.frame_words:
        raise MeasuredFormatError(f"{words.size} words is not a whole number of {layout.frame_words}-word frames")
    F = words.size // layout.frame_words
    first, second = _split_iq(words, layout, F)
    i, q = (second, first) if (layout.iq_swap and second is not None) else (first, second)
    shape = layout.cube_shape(F)
    if out is None:
        out = np.empty(shape, dtype=np.complex64)
    elif out.shape != shape or out.dtype != np.complex64 or not out.flags.c_contiguous:
        raise MeasuredFormatError(f"out must be C-contiguous complex64 {list(shape)}")
    K, C, R, N = layout.num_loops, layout.chirps_per_loop, layout.num_rx, layout.num_samples
    parts = out.reshape(F, K, C, R, N).view(np.float32).reshape(F, K, C, R, N, 2)   # views, no copy
    parts[..., 0] = i
    if q is None:
        parts[..., 1] = 0.0
    elif convention == "paper":
        np.negative(q, out=parts[..., 1], casting="unsafe")
    elif convention == "ti":
        parts[..., 1] = q
    else:
        raise MeasuredFormatError(f"convention={convention!r} must be 'paper' or 'ti'")
    return out


def encode_frames(i: np.ndarray, q: np.ndarray | None, layout: RawLayout) -> np.ndarray:
    """The inverse of :func:`decode_frames`: hardware I and Q codes → the file's int16 words.

    Parameters
    ----------
    i, q : ndarray of int16, [F, K, V, N]
        In-phase and quadrature ADC codes as the radar produces them (TI convention, before any
        swap); ``q`` is None for real data.
    layout : RawLayout

    Returns
    -------
    ndarray of ``<i2``, [F · frame_words]
    """
    i = np.asarray(i)
    F = i.shape[0]
    if i.shape != layout.cube_shape(F):
        raise MeasuredFormatError(f"i has shape {list(i.shape)}, expected {list(layout.cube_shape(F))}")
    if layout.is_complex and (q is None or np.shape(q) != i.shape):
        raise MeasuredFormatError("complex layouts need q with the shape of i")
    words = np.empty(F * layout.frame_words, dtype="<i2")
    K, C, R, N = layout.num_loops, layout.chirps_per_loop, layout.num_rx, layout.num_samples
    i5 = i.reshape(F, K, C, R, N)
    if not layout.is_complex:
        dest = words.reshape(F, K, C, R, N) if layout.lanes == 2 else \
            np.moveaxis(words.reshape(F, K, C, N, R), 4, 3)
        dest[...] = i5
        return words
    q5 = np.asarray(q).reshape(F, K, C, R, N)
    first, second = (q5, i5) if layout.iq_swap else (i5, q5)
    if layout.lanes == 2:
        w = words.reshape(F, K, C, R, N // 2, 2, 2)
        w[..., 0, :] = first.reshape(F, K, C, R, N // 2, 2)
        w[..., 1, :] = second.reshape(F, K, C, R, N // 2, 2)
    else:
        w = words.reshape(F, K, C, N, 2, R)
        np.moveaxis(w[..., 0, :], 4, 3)[...] = first
        np.moveaxis(w[..., 1, :], 4, 3)[...] = second
    return words
