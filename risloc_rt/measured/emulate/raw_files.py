"""Experiment emulator, binary side: a complex cube → the DCA1000 files and ``.cfg`` a radar would give.

Signal chain, per sample (hardware I/Q domain, ``s = conj(y)`` for a cube ``y`` in the paper's
convention, ``s = y`` for ``convention="ti"``)::

    I = Re s                                          Q = g·(Im s·cos φ + Re s·sin φ)     (I/Q imbalance)
    I += Re d + n_I                                   Q += Im d + n_Q                     (DC offset, noise)
    code = clip(rint(x / full_scale · 2^(b−1)), −2^(b−1), 2^(b−1) − 1)                    (b-bit ADC)

then the codes are laid out (:mod:`~risloc_rt.measured.dca1000.raw_layout`: lanes, I/Q swap), written raw or as
packets (sequence numbers, losses), cut at a file-size limit and optionally truncated. A packet lost in
the raw form leaves its ``payload_size`` bytes zero at their place on the packet grid, as the DCA1000's
recording does (no header tells it; the reader finds it as a probable loss).

The ``.cfg`` written says ``adcbufCfg … SampleSwap 1``: the only value TI's SDK demos accept, which
sets the on-chip ADC buffer's word order (mmWave SDK user's guide), not the LVDS stream; a real SDK
capture made with it has I first on the LVDS lanes (the corner-reflector capture). A Q-first file
(``Recording.iq_swap=True``, what Studio's ``iqSwapSel = 1`` gives) cannot be stated in an SDK
``.cfg``; its comment line says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

from dsp.validation import finite, integer, non_negative, positive

from ..._files import atomic_write_bytes
from ..dca1000.packets import HEADER_BYTES, MAX_PAYLOAD, PacketRecorder
from ..dca1000.raw_layout import Convention, RawLayout, encode_frames
from ..dca1000.split_files import SplitWriter
from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig
from ..ti.sdk_cfg import format_sdk_cfg

#: ``adcbufCfg`` SampleSwap the emulated ``.cfg`` states: 1, the only value TI's SDK demos accept (ADC buffer
#: "Q in LSB, I in MSB"); it does not set the LVDS order the files are written in.
SDK_SAMPLE_SWAP = True

__all__ = ["SDK_SAMPLE_SWAP", "AdcImpairments", "EmulatedCapture", "QuantizedCube", "Recording", "quantize_cube", "write_raw_capture"]


@dataclass(frozen=True)
class AdcImpairments:
    """Analogue front-end and ADC impairments (each off by default).

    Parameters
    ----------
    full_scale : float, default 1.0
        Input amplitude of the largest ADC code, in the cube's unit (volts, or 1.0 for
        full-scale-normalized cubes). One LSB is ``full_scale / 2^(b−1)``.
    dc_offset : complex, default 0
        Offset added to I + jQ in the hardware domain [cube units].
    iq_gain_imbalance_db : float, default 0
        Gain of the Q path relative to the I path, 20·log10 g [dB].
    iq_phase_imbalance : float, default 0
        Phase error φ of the Q path [rad].
    noise_rms : float, default 0
        Standard deviation of white Gaussian noise added to each of I and Q [cube units]; needs
        an explicit ``rng``.
    """

    full_scale: float = 1.0
    dc_offset: complex = 0j
    iq_gain_imbalance_db: float = 0.0
    iq_phase_imbalance: float = 0.0
    noise_rms: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "full_scale", positive(self.full_scale, "full_scale", "cube units", error=MeasuredFormatError))
        object.__setattr__(self, "dc_offset", complex(self.dc_offset))
        finite(self.iq_gain_imbalance_db, "iq_gain_imbalance_db", "dB", error=MeasuredFormatError)
        finite(self.iq_phase_imbalance, "iq_phase_imbalance", "rad", error=MeasuredFormatError)
        non_negative(self.noise_rms, "noise_rms", "cube units", error=MeasuredFormatError)

    @property
    def iq_gain_ratio(self) -> float:
        """g = 10^(dB/20), Q-path gain over I-path gain [unitless]."""
        return 10.0 ** (self.iq_gain_imbalance_db / 20.0)


@dataclass(frozen=True)
class Recording:
    """How the DCA1000 records the stream.

    Parameters
    ----------
    form : {"raw", "packets"}, default "raw"
        Plain samples, or packets with the 10-byte header (mmWave Studio's ``_Raw_`` files).
    lanes : {2, 4}, default 2
        LVDS interleave (2: xWR16xx/18xx/68xx, 4: xWR14xx).
    iq_swap : bool, default False
        Write Q before I.
    payload_size : int, default 1456
        Packet payload [bytes]: the packets of the packet form, the loss grid of the raw form.
    drop_packets : tuple of int
        Sequence numbers (1-based) of packets lost on the link: left out of the packet form,
        zero-filled in place in the raw form (packet j holds stream bytes ``[(j−1)·P, j·P)``).
    drop_probability : float, default 0
        Independent loss probability of every packet (either form); needs ``rng``.
    max_file_size : int or None
        Split the recording into ``<prefix>_Raw_<i>.bin`` files of at most this size [bytes].
    truncate_bytes : int, default 0
        Bytes missing at the end of the stream (a capture stopped mid-frame).
    prefix : str, default "adc_data"
        File prefix.
    """

    form: Literal["raw", "packets"] = "raw"
    lanes: int = 2
    iq_swap: bool = False
    payload_size: int = MAX_PAYLOAD
    drop_packets: tuple[int, ...] = ()
    drop_probability: float = 0.0
    max_file_size: int | None = None
    truncate_bytes: int = 0
    prefix: str = "adc_data"

    def __post_init__(self) -> None:
        if self.form not in ("raw", "packets"):
            raise MeasuredFormatError(f"form={self.form!r} must be 'raw' or 'packets'")
        object.__setattr__(self, "drop_packets", tuple(integer(s, "drop_packets[]", minimum=1, error=MeasuredFormatError)
                                                       for s in self.drop_packets))
        p = non_negative(self.drop_probability, "drop_probability", "1", error=MeasuredFormatError)
        if p >= 1:
            raise MeasuredFormatError(f"drop_probability={p} must be < 1")
        if self.payload_size % 2 or not 2 <= self.payload_size <= MAX_PAYLOAD:
            raise MeasuredFormatError(f"payload_size={self.payload_size} must be even and in [2, {MAX_PAYLOAD}] bytes")
        integer(self.truncate_bytes, "truncate_bytes", minimum=0, error=MeasuredFormatError)
        if self.max_file_size is not None:
            integer(self.max_file_size, "max_file_size", minimum=2, error=MeasuredFormatError)


@dataclass(frozen=True)
class QuantizedCube:
    """ADC codes of :func:`quantize_cube`.

    Attributes
    ----------
    i, q : ndarray of int16, [F, K, V, N]
        Hardware I and Q codes (``q`` None for a real ADC).
    clipped : int
        Samples (I or Q words) that hit a rail.
    adc_bits : int
    """

    i: np.ndarray
    q: np.ndarray | None
    clipped: int
    adc_bits: int

    def as_complex(self, convention: Convention = "paper") -> np.ndarray:
        """The codes as the reader returns them: complex64 ``I ∓ jQ`` (paper: −, ti: +).

        Parameters
        ----------
        convention : {"paper", "ti"}, default "paper"
            Sign of Q.

        Returns
        -------
        ndarray of complex64, [F, K, V, N]
            ADC counts.
        """
        out = self.i.astype(np.complex64)
        if self.q is not None:
            out.imag = -self.q if convention == "paper" else self.q
        return out


def quantize_cube(cube: np.ndarray, *, adc_bits: int = 16, real: bool = False,
                  impairments: AdcImpairments = AdcImpairments(), convention: Convention = "paper",
                  rng: np.random.Generator | None = None) -> QuantizedCube:
    """Apply the front-end impairments and the ADC to ``cube`` (module docstring has the chain).

    Parameters
    ----------
    cube : array_like, complex [F, K, V, N]
        Beat samples in cube units (see ``AdcImpairments.full_scale``), in ``convention``.
    adc_bits : {12, 14, 16}
    real : bool
        Real ADC: only I is sampled (the real part of the hardware signal).
    impairments : AdcImpairments
    convention : {"paper", "ti"}
    rng : numpy.random.Generator, optional
        Needed when ``impairments.noise_rms > 0``.

    Returns
    -------
    QuantizedCube
        The int16 I and Q codes ``[F, K, V, N]`` [ADC counts] and the count of words at a rail.
    """
    if adc_bits not in (12, 14, 16):
        raise MeasuredFormatError(f"adc_bits={adc_bits!r} must be 12, 14 or 16")
    y = np.asarray(cube)
    if y.ndim != 4:
        raise MeasuredFormatError(f"cube has shape {list(y.shape)}, expected [F, K, V, N]")
    s = np.conj(y) if convention == "paper" else y
    imp = impairments
    i_a = s.real.astype(np.float64)
    q_a = None
    if not real:
        g, phi = imp.iq_gain_ratio, imp.iq_phase_imbalance
        q_a = g * (s.imag * np.cos(phi) + s.real * np.sin(phi))
    if imp.noise_rms:
        if rng is None:
            raise MeasuredFormatError("noise_rms > 0 needs rng=numpy.random.default_rng(seed)")
        i_a = i_a + rng.normal(0.0, imp.noise_rms, i_a.shape)
        if q_a is not None:
            q_a = q_a + rng.normal(0.0, imp.noise_rms, q_a.shape)
    lo, hi = -(2 ** (adc_bits - 1)), 2 ** (adc_bits - 1) - 1
    scale = 2 ** (adc_bits - 1) / imp.full_scale
    clipped = 0
    codes = []
    for x, offset in ((i_a, imp.dc_offset.real), (q_a, imp.dc_offset.imag)):
        if x is None:
            codes.append(None)
            continue
        c = np.rint((x + offset) * scale)
        clipped += int(np.count_nonzero((c < lo) | (c > hi)))
        codes.append(np.clip(c, lo, hi).astype(np.int16))
    return QuantizedCube(i=codes[0], q=codes[1], clipped=clipped, adc_bits=adc_bits)


def _zero_fill_lost(stream: np.ndarray, recording: Recording,
                    rng: np.random.Generator | None) -> tuple[np.ndarray, tuple[int, ...]]:
    """Raw form: zero the bytes of the lost packets on the ``payload_size`` grid; (stream, lost sequence numbers)."""
    P = recording.payload_size
    packets = -(-stream.size // P)
    lost = {s for s in recording.drop_packets if s <= packets}
    if recording.drop_probability:
        if rng is None:
            raise MeasuredFormatError("drop_probability > 0 needs rng=numpy.random.default_rng(seed)")
        lost |= {int(j) + 1 for j in np.flatnonzero(rng.random(packets) < recording.drop_probability)}
    if not lost:
        return stream, ()
    out = stream.copy()
    for s in sorted(lost):
        out[(s - 1) * P:s * P] = 0
    return out, tuple(sorted(lost))


@dataclass(frozen=True)
class EmulatedCapture:
    """What :func:`write_raw_capture` wrote.

    Attributes
    ----------
    files : tuple of Path
        The ``_Raw_<i>.bin`` files, in order.
    cfg_path : Path
        The matching mmWave SDK ``.cfg``.
    config : TiChirpConfig
        The configuration written (``num_frames`` = F).
    layout : RawLayout
    quantized : QuantizedCube
        The codes before the recording's losses: what a reader must give back.
    dropped_sequences : tuple of int
        Sequence numbers of the packets lost: left out (packet form) or zero-filled in place (raw form).
    stream_bytes : int
        Bytes of sample stream written (after truncation).
    """

    files: tuple[Path, ...]
    cfg_path: Path
    config: TiChirpConfig
    layout: RawLayout
    quantized: QuantizedCube
    dropped_sequences: tuple[int, ...] = field(default=())
    stream_bytes: int = 0


def write_raw_capture(cube: np.ndarray, config: TiChirpConfig, folder: str | Path, *,
                      recording: Recording = Recording(), impairments: AdcImpairments = AdcImpairments(),
                      convention: Convention = "paper", rng: np.random.Generator | None = None,
                      overwrite: bool = False) -> EmulatedCapture:
    """Write ``cube`` as the DCA1000 files of a capture made with ``config``, plus its ``.cfg``.

    Every file is written atomically; the split files appear together, only once all are
    complete (:class:`~risloc_rt.measured.dca1000.split_files.SplitWriter`).

    Parameters
    ----------
    cube : array_like, complex [F, K, V, N]
        Frames, loops (``config.num_loops``), virtual channels (``config.num_virtual``, chirp of
        the loop major, receiver minor), samples (``config.num_samples``), in cube units.
    config : TiChirpConfig
        Waveform and ADC; written to ``<prefix>.cfg`` with ``num_frames = F``.
    folder : path
        Existing folder; existing ``<prefix>_Raw_<i>.bin`` files are refused unless ``overwrite``.
    recording : Recording
        Raw or packet form, lanes, I/Q swap, losses, split size, truncation.
    impairments : AdcImpairments
        Full scale, DC offset, I/Q imbalance, noise.
    convention : {"paper", "ti"}
        Sign convention of ``cube``.
    rng : numpy.random.Generator, optional
        Needed for noise or random packet loss.
    overwrite : bool, default False
        Replace existing split files (and the ``.cfg``) of the same names.

    Returns
    -------
    EmulatedCapture
        The files written, the ``.cfg`` path, the configuration (``num_frames`` = F), the layout,
        the codes before the losses, the packets left out and the stream's length [bytes].
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MeasuredFormatError(f"output folder {folder} does not exist")
    y = np.asarray(cube)
    layout = RawLayout.from_config(config, lanes=recording.lanes, iq_swap=recording.iq_swap)
    F = y.shape[0] if y.ndim == 4 else 0
    if y.ndim != 4 or y.shape != layout.cube_shape(F) or F < 1:
        raise MeasuredFormatError(f"cube has shape {list(y.shape)}, expected {list(layout.cube_shape(max(F, 1)))} "
                                  "[frames, loops, virtual channels, samples] for this config")
    quant = quantize_cube(y, adc_bits=config.adc_bits, real=not config.is_complex, impairments=impairments,
                          convention=convention, rng=rng)
    words = encode_frames(quant.i, quant.q, layout)
    stream = words.view(np.uint8)
    if recording.truncate_bytes >= stream.size:
        raise MeasuredFormatError(f"truncate_bytes={recording.truncate_bytes} removes the whole stream "
                                  f"({stream.size} bytes)")
    stream = stream[:stream.size - recording.truncate_bytes]
    cfg = replace(config.with_frames(F), iq_swap=SDK_SAMPLE_SWAP)
    cfg_path = folder / f"{recording.prefix}.cfg"
    if cfg_path.exists() and not overwrite:
        raise MeasuredFormatError(f"{cfg_path} exists; risloc does not overwrite a capture: give a new or empty "
                                  "folder, remove it, or pass overwrite=True")
    if recording.form == "raw":
        stream, dropped = _zero_fill_lost(stream, recording, rng)
        with SplitWriter(folder, recording.prefix, max_file_size=recording.max_file_size,
                         overwrite=overwrite) as writer:
            writer.write(stream.data)
            files = writer.close()
    else:
        writer = SplitWriter(folder, recording.prefix, max_file_size=recording.max_file_size,
                             record_size=HEADER_BYTES + recording.payload_size, overwrite=overwrite)
        with writer:
            rec = PacketRecorder(writer, payload_size=recording.payload_size, drop=frozenset(recording.drop_packets),
                                 drop_probability=recording.drop_probability, rng=rng)
            rec.write(stream.data)
            files = rec.close()
        dropped = tuple(rec.dropped)
    order = ("LVDS order Q first (iq_swap=True), which an SDK .cfg cannot state: read it with iq_swap=True"
             if layout.iq_swap else "LVDS order I first; adcbufCfg SampleSwap 1 is the ADC buffer's order")
    atomic_write_bytes(cfg_path, format_sdk_cfg(
        cfg, comment=f"written by risloc_rt.measured.emulate.raw_files: {layout.describe()}; {order}").encode("utf-8"))
    return EmulatedCapture(files=files, cfg_path=cfg_path, config=cfg, layout=layout, quantized=quant,
                           dropped_sequences=dropped, stream_bytes=int(stream.size))
