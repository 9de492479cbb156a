"""``risloc capture inspect RAW --config CFG``: what a raw capture holds and whether it looks healthy.

:func:`inspect_capture` streams the capture once (memory: a few frames) and returns a
:class:`CaptureInspection`: counts, the range–Doppler peak, lost packets, clipping, impulsive
samples (glitches), DC offset, I/Q imbalance and I/Q order, each problem as a named flag with its
remedy.
:func:`plot_inspection` draws the range profile and the range–Doppler map.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.constants
import scipy.signal

from dsp.budget import check_memory
from dsp.flags import Flag
from dsp.impulses import IMPULSE_CREST_DB, screen_impulses

from ...plotting import new_figure, save_figure
from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig
from ..ti.config_file import load_config
from .raw_layout import RawLayout
from .reader import CaptureInfo, Form, iter_frames, open_raw

__all__ = ["CaptureInspection", "Peak", "file_iq_swap", "inspect_capture", "plot_inspection"]


#: Peak bytes per sample of a block while it is inspected: the raw words and the complex64 cube
#: (12 B), I and Q as float64 (16 B), the windowed cube, both transforms and the power (complex128
#: and float64, ~48 B); 75 B measured (tracemalloc, 4 vs 16 frames per block).
INSPECT_BYTES_PER_SAMPLE = 80


def _db(x):
    """10·log10(x) [dB]."""
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(x)


@dataclass(frozen=True)
class Peak:
    """Strongest range–Doppler cell.

    Attributes
    ----------
    range_bin : int
        Bin of the N-point fast-time DFT (N = samples per chirp), 0 … N−1.
    doppler_bin : int
        Signed slow-time bin, −K/2 … K/2−1; 0 = zero velocity, positive = receding.
    snr_db : float
        Range-profile peak over its median [dB].
    range : float or None
        ``range_bin · c/(2 S N T_s)`` with the quantized slope [m] (None without a configuration).
    velocity : float or None
        ``doppler_bin · λ/(2 K T_loop)`` [m/s], positive receding.
    """

    range_bin: int
    doppler_bin: int
    snr_db: float
    range: float | None
    velocity: float | None


@dataclass(frozen=True)
class CaptureInspection:
    """Result of :func:`inspect_capture`; ``to_json()`` is what the CLI prints.

    Attributes
    ----------
    files, form, layout, config
        What was read and how (config None when a layout was given directly).
    frames : int
        Complete frames in the capture; ``frames_read`` of them were analysed.
    truncated_bytes : int
        Bytes of a dropped, incomplete final frame.
    dropped_packets : int
        Packets lost (zero-filled), certain and probable; ``damaged_frames`` lists the frames
        holding the zeros.
    peak : Peak
    range_profile : ndarray, [N]
        Mean power per range bin over frames, loops and channels, window-normalised [counts²].
    range_doppler : ndarray, [K, N]
        Mean power per (Doppler, range) cell, Doppler ascending as ``doppler_bins`` [counts²].
    doppler_bins : ndarray of int, [K]
        Signed Doppler bin of each row of ``range_doppler``.
    clipped_words, clipped_fraction
        I or Q words at an ADC rail, and their share of all words.
    dc_offset : complex
        Mean of I + jQ (hardware I/Q) [counts].
    iq_gain_imbalance_db, iq_phase_imbalance
        ``10 log10(var Q / var I)`` [dB] and ``asin(cov(I,Q)/(σ_I σ_Q))`` [rad]; meaningful on
        noise-like or many-tone data (each ~0 for a balanced receiver).
    positive_frequency_excess_db
        Power at positive over negative beat frequencies (bins 1…N/2−1 vs N/2+1…N−1) [dB]; TI data
        decoded right puts targets at positive ones (NaN for real data).
    flags : tuple of Flag
    notes : tuple of str
    probable_dropped_packets : int
        Of ``dropped_packets``, those found as whole packets of zeros in a raw-mode stream.
    impulsive_samples : int
        Lone ADC samples more than 20 dB above their chirp's median power (glitches,
        :mod:`dsp.impulses`); ``impulsive_frames`` lists the frames that hold them and
        ``impulsive_largest_db`` the largest excess [dB] (NaN when none).
    config_iq_swap : bool or None
        The configuration's swap flag (``adcbufCfg`` SampleSwap or Studio ``iqSwapSel``; None
        without a configuration), recorded next to the order the file was read with.
    """

    files: tuple[Path, ...]
    form: str
    layout: RawLayout
    config: TiChirpConfig | None
    frames: int
    frames_read: int
    truncated_bytes: int
    dropped_packets: int
    damaged_frames: tuple[int, ...]
    peak: Peak
    range_profile: np.ndarray
    range_doppler: np.ndarray
    doppler_bins: np.ndarray
    clipped_words: int
    clipped_fraction: float
    dc_offset: complex
    iq_gain_imbalance_db: float
    iq_phase_imbalance: float
    positive_frequency_excess_db: float
    flags: tuple[Flag, ...]
    notes: tuple[str, ...]
    probable_dropped_packets: int = 0
    config_iq_swap: bool | None = None
    impulsive_samples: int = 0
    impulsive_frames: tuple[int, ...] = ()
    impulsive_largest_db: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON summary (no arrays): counts, peak, impairments, flags.

        Returns
        -------
        dict
            SI units (m, m/s), radians, dB and ADC counts, as the attributes say.
        """
        lay = self.layout
        return {
            "files": [str(f) for f in self.files], "form": self.form,
            "frames": self.frames, "frames_read": self.frames_read, "chirps": lay.num_loops,
            "chirps_per_loop": lay.chirps_per_loop, "samples": lay.num_samples, "rx": lay.num_rx,
            "channels": lay.num_virtual, "adc_format": lay.adc_format, "lanes": lay.lanes, "iq_swap": lay.iq_swap,
            "peak": {"range_bin": self.peak.range_bin, "doppler_bin": self.peak.doppler_bin,
                     "snr_db": round(self.peak.snr_db, 2), "range": self.peak.range, "velocity": self.peak.velocity},
            "config_iq_swap": self.config_iq_swap,
            "dropped_packets": self.dropped_packets, "probable_dropped_packets": self.probable_dropped_packets,
            "damaged_frames": list(self.damaged_frames),
            "truncated_bytes": self.truncated_bytes,
            "clipping": {"words": self.clipped_words, "fraction": self.clipped_fraction},
            "impulsive_samples": {"count": self.impulsive_samples, "frames": list(self.impulsive_frames),
                                  "largest_db": (None if np.isnan(self.impulsive_largest_db)
                                                 else round(self.impulsive_largest_db, 2))},
            "dc_offset": {"i": self.dc_offset.real, "q": self.dc_offset.imag},
            "iq_imbalance": {"gain_db": self.iq_gain_imbalance_db, "phase": self.iq_phase_imbalance},
            "positive_frequency_excess_db": (None if np.isnan(self.positive_frequency_excess_db)
                                             else self.positive_frequency_excess_db),
            "flags": [f.to_dict() for f in self.flags],
            "notes": list(self.notes),
        }

    def to_json(self, *, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON text.

        Parameters
        ----------
        indent : int or None, default 2
            ``json.dumps``'s indent; None for one line.

        Returns
        -------
        str
        """
        return json.dumps(self.to_dict(), indent=indent)


def file_iq_swap(config: str | Path | TiChirpConfig, *, iq_swap: bool | None = None) -> bool:
    """The I/Q order to read a capture with: ``iq_swap`` when given, else the configuration's LVDS order.

    - mmWave Studio ``.json``: its ``rlDevDataFmtCfg_t.iqSwapSel`` (mmWaveLink ``rl_device.h``:
      0 = I first, 1 = Q first; ``rlDeviceSetDataFmtConfig`` sets the LVDS/CSI2 output format).
    - mmWave SDK ``.cfg`` or a parsed ``TiChirpConfig``: False (I first). ``adcbufCfg``
      SampleSwap is the ADC *buffer*'s word order for the on-chip DSP/HWA (mmWave SDK user's
      guide: "Q in LSB, I in MSB", the only value the demos accept), not the LVDS order; the
      corner-reflector capture, made with it, has I first.

    Parameters
    ----------
    config : path or TiChirpConfig
    iq_swap : bool, optional
        An explicit order overrides the configuration.

    Returns
    -------
    bool
        True: the file stores Q before I.
    """
    if iq_swap is not None:
        return bool(iq_swap)
    if isinstance(config, TiChirpConfig):
        return False
    if Path(config).suffix.lower() == ".json":
        return bool(load_config(config)[0].iq_swap)
    return False


def _layout_of(config: str | Path | TiChirpConfig | RawLayout, lanes: int | None,
               iq_swap: bool | None) -> tuple[RawLayout, TiChirpConfig | None]:
    """The file's layout and the configuration (None for a bare layout) of :func:`inspect_capture`'s ``config``."""
    if isinstance(config, RawLayout):
        layout = config if lanes is None and iq_swap is None else RawLayout(
            config.num_samples, config.num_rx, config.chirps_per_loop, config.num_loops, config.adc_format,
            lanes or config.lanes, config.iq_swap if iq_swap is None else bool(iq_swap))
        return layout, None
    file_lanes = None
    if isinstance(config, TiChirpConfig):
        cfg = config
        swap = file_iq_swap(cfg, iq_swap=iq_swap)
    else:
        cfg, file_lanes = load_config(config)
        swap = bool(cfg.iq_swap) if iq_swap is None and Path(config).suffix.lower() == ".json" else bool(iq_swap)
    return RawLayout.from_config(cfg, lanes=lanes or file_lanes or 2, iq_swap=swap), cfg


@dataclass(frozen=True)
class _CaptureSums:
    """One pass over a capture: the range–Doppler power and the sums the I/Q statistics need.

    ``range_doppler [K, N]``: mean power per cell over the frames read and the channels, window
    normalised, Doppler ascending [counts²]; ``s1 = (Σ I, Σ Q)``, ``s2 = (Σ I², Σ Q², Σ I·Q)``
    over ``count`` samples [counts, counts²]; ``words``: I/Q words per sample (2 complex, 1 real).
    """

    range_doppler: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    count: int
    words: int
    clipped: int
    frames_read: int
    dropped: int
    probable: int
    damaged: tuple[int, ...]
    impulsive: int = 0
    impulsive_frames: tuple[int, ...] = ()
    impulsive_db: float = float("nan")


def _stream_sums(info: CaptureInfo, layout: RawLayout, bits: int, window: str, frames_per_block: int,
                 max_frames: int | None) -> _CaptureSums:
    """Stream the capture once: range–Doppler power (eq. (2DDFT)), I/Q sums, rail hits, lost packets."""
    N, K = layout.num_samples, layout.num_loops
    lo, hi = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    wn = scipy.signal.get_window(window, N, fftbins=True)
    wk = scipy.signal.get_window(window, K, fftbins=True)
    gain = (wn.sum() * wk.sum()) ** 2
    rd = np.zeros((K, N))
    s1 = np.zeros(2)
    s2 = np.zeros(3)                                  # Σ I², Σ Q², Σ I·Q
    count = clipped = frames_read = dropped = probable = impulsive = 0
    damaged: list[int] = []
    impulsive_frames: set[int] = set()
    impulsive_db = float("nan")
    for block in iter_frames(info, frames_per_block=frames_per_block, max_frames=max_frames):
        y = block.cube                                # complex64 [f, K, V, N], paper convention
        i_hw, q_hw = y.real.astype(np.float64), -y.imag.astype(np.float64)
        s1 += (i_hw.sum(), q_hw.sum())
        s2 += ((i_hw * i_hw).sum(), (q_hw * q_hw).sum(), (i_hw * q_hw).sum())
        count += i_hw.size
        words = (i_hw, q_hw) if layout.is_complex else (i_hw,)
        clipped += sum(int(np.count_nonzero((w <= lo) | (w >= hi))) for w in words)
        # lone samples far above their chirp (glitches): each (frame, loop) a row, each channel its chirp
        _, screen = screen_impulses(y.reshape(len(y) * K, layout.num_virtual, N))
        if screen.count:
            impulsive += screen.count
            impulsive_frames.update(block.first_frame + int(r) // K for r in screen.samples[:, 0])
            impulsive_db = float(np.fmax(impulsive_db, screen.largest_db))
        # eq. (2DDFT) sign: e^{+j2πpn/N}, e^{+j2πqk/K} (numpy's ifft times the length)
        z = np.fft.ifft(np.fft.ifft(y * wn, axis=-1) * wk[:, None, None], axis=1) * (N * K)
        rd += (np.abs(z) ** 2).sum(axis=(0, 2)) / gain
        frames_read += len(y)
        dropped += sum(d.count for d in block.dropped)
        probable += sum(d.count for d in block.dropped if d.probable)
        damaged += [block.first_frame + int(i) for i in np.flatnonzero(block.damaged)]
    if frames_read == 0:
        raise MeasuredFormatError("no frame to inspect (max_frames=0?)")
    rd /= frames_read * layout.num_virtual
    rd = np.fft.fftshift(rd, axes=0)
    return _CaptureSums(range_doppler=rd, s1=s1, s2=s2, count=count, words=2 if layout.is_complex else 1,
                        clipped=clipped, frames_read=frames_read, dropped=dropped, probable=probable,
                        damaged=tuple(damaged), impulsive=impulsive, impulsive_frames=tuple(sorted(impulsive_frames)),
                        impulsive_db=impulsive_db)


def _iq_statistics(sums: _CaptureSums, profile: np.ndarray,
                   is_complex: bool) -> tuple[complex, float, float, float]:
    """(DC offset [counts], I/Q gain imbalance [dB], I/Q phase imbalance [rad], positive-frequency excess [dB])."""
    N = profile.size
    count = sums.count
    mean_i, mean_q = sums.s1 / count
    var_i, var_q = sums.s2[0] / count - mean_i ** 2, sums.s2[1] / count - mean_q ** 2
    cov = sums.s2[2] / count - mean_i * mean_q
    if is_complex and var_i > 0 and var_q > 0:
        g_db = float(10 * np.log10(var_q / var_i))
        phase = float(np.arcsin(np.clip(cov / np.sqrt(var_i * var_q), -1, 1)))
        pos, neg = profile[1:N // 2].sum(), profile[N // 2 + 1:].sum()
        excess = float(_db(pos / max(neg, 1e-300)))
    else:
        g_db, phase, excess = 0.0, 0.0, float("nan")
    return complex(mean_i, mean_q), g_db, phase, excess


def _inspection_flags(sums: _CaptureSums, info: CaptureInfo, cfg: TiChirpConfig | None, bits: int, dc: complex,
                      g_db: float, phase: float, excess: float, peak_bin: int, min_range_bin: int) -> tuple[Flag, ...]:
    """Each problem the inspection found as a flag with its remedy (codes: ``dsp.INSPECTION_CODES``)."""
    full = 2.0 ** (bits - 1)
    dropped, damaged = sums.dropped, list(sums.damaged)
    flags = []
    if dropped:
        certain = dropped - sums.probable
        parts = [f"{certain} packets lost"] if certain else []
        if sums.probable:
            parts.append(f"{sums.probable} probable lost packets (whole packets of exact zeros on the packet grid of "
                         "a raw-mode stream, which an ADC with noise cannot give)")
        what = " and ".join(parts)
        flags.append(Flag("dropped-packets", f"{what}; frames {damaged[:10]}"
                          f"{' …' if len(damaged) > 10 else ''} hold zeros in their place: leave them out"))
    if info.truncated_bytes:
        flags.append(Flag("truncated-frame", f"final frame incomplete ({info.truncated_bytes} bytes), dropped"))
    if sums.clipped:
        flags.append(Flag("clipping", f"{sums.clipped} of {sums.count * sums.words} ADC words at a rail: lower the "
                          "Rx gain (profileCfg rxGain) or move away from strong reflectors"))
    if sums.impulsive:
        frames = list(sums.impulsive_frames)
        flags.append(Flag("impulsive-samples", f"{sums.impulsive} lone ADC sample(s) stood up to {sums.impulsive_db:.0f} dB "
                          f"above their chirp's median power (a beat signal stays within {IMPULSE_CREST_DB:.0f} dB: a "
                          f"glitch of the ADC or its link) in frames {frames[:10]}{' …' if len(frames) > 10 else ''}: "
                          "localization zeroes them; check the link for bit errors"))
    if abs(dc) > 0.01 * full:
        flags.append(Flag("dc-offset", f"DC offset {abs(dc) / full:.1%} of full scale: remove the mean per chirp"))
    if abs(g_db) > 1.0 or abs(phase) > np.deg2rad(5):
        flags.append(Flag("iq-imbalance", f"I/Q imbalance {g_db:+.2f} dB, {np.rad2deg(phase):+.1f} deg: images "
                          "of strong targets appear mirrored in range"))
    if not np.isnan(excess) and excess < 0:
        read = "Q first" if info.layout.iq_swap else "I first"
        cfg_says = ("" if cfg is None else f" (read {read}; the configuration's swap flag is {int(cfg.iq_swap)}, "
                    "which for an SDK .cfg describes the on-chip ADC buffer, not the file)")
        flags.append(Flag("iq-order", f"{-excess:.1f} dB more power at negative beat frequencies: I and Q are "
                          f"probably swapped (iq_swap={not info.layout.iq_swap}) or the lane interleave is wrong "
                          f"(lanes=){cfg_says}"))
    if peak_bin <= 1 and min_range_bin == 0:
        flags.append(Flag("peak-at-dc", "the strongest return is at range bin 0-1 (DC offset or Tx-Rx leakage): "
                          "pass min_range_bin="))
    if cfg is not None:
        flags += [Flag("device-timing", msg) for msg in cfg.device_issues()]
    return tuple(flags)


def inspect_capture(raw: str | Path | Sequence[str | Path], config: str | Path | TiChirpConfig | RawLayout, *,
                    lanes: int | None = None, iq_swap: bool | None = None, form: Form = "auto",
                    payload_size: int | None = None, max_frames: int | None = None, window: str = "hann",
                    min_range_bin: int = 0, frames_per_block: int = 4) -> CaptureInspection:
    """Inspect a DCA1000 raw capture.

    Parameters
    ----------
    raw : path or sequence of paths
        ``adc_data_Raw_0.bin`` (split siblings are found) or the files in order.
    config : path, TiChirpConfig or RawLayout
        An mmWave SDK ``.cfg``, an mmWave Studio ``.json``, a parsed configuration, or a bare
        layout (then no metres, no m/s and no frame-count check).
    lanes : {2, 4}, optional
        LVDS lanes; default: the Studio JSON's ``laneEn``, else 2 (xWR16xx/18xx/68xx).
    iq_swap : bool, optional
        The file stores Q first. Default (None): a Studio ``.json``'s ``iqSwapSel`` (it sets the
        LVDS order), else False: an SDK ``.cfg``'s ``adcbufCfg`` SampleSwap sets the on-chip ADC
        buffer's order, not the file's (:func:`file_iq_swap`); a bare ``RawLayout`` keeps its own.
    form : {"auto", "raw", "packets"}, default "auto"
    payload_size : int, optional
        Packet payload [bytes]; detected when omitted.
    max_frames : int, optional
        Analyse only the first frames (all are still counted).
    window : str, default "hann"
        ``scipy.signal.get_window`` name for both DFTs (periodic).
    min_range_bin : int, default 0
        Ignore range bins below this when finding the peak (Tx→Rx leakage, DC).
    frames_per_block : int, default 4
        Frames decoded at a time (sets the memory used).

    Returns
    -------
    CaptureInspection
        Counts, the peak (bins; metres and m/s with a configuration), the range profile and
        range–Doppler map [counts²], clipping, DC offset [counts], I/Q imbalance [dB, rad] and
        the flags.
    """
    layout, cfg = _layout_of(config, lanes, iq_swap)
    info = open_raw(raw, layout, form=form, payload_size=payload_size,
                    expected_frames=cfg.num_frames if cfg is not None else None)
    N, K = layout.num_samples, layout.num_loops
    if not 0 <= min_range_bin < N:
        raise MeasuredFormatError(f"min_range_bin={min_range_bin} must be in [0, {N})")
    bits = cfg.adc_bits if cfg is not None else 16
    f = max(min(frames_per_block, info.num_frames), 1)
    check_memory(f * K * layout.num_virtual * N * INSPECT_BYTES_PER_SAMPLE,
                 f"{info.files[0]}: inspecting {f} frame(s) of {K} loops x {layout.num_virtual} channels x {N} samples "
                 f"at a time ({INSPECT_BYTES_PER_SAMPLE} B per sample)",
                 fix="lower frames_per_block, or check numAdcSamples, numLoops and the chirps per loop")
    sums = _stream_sums(info, layout, bits, window, frames_per_block, max_frames)
    rd = sums.range_doppler
    doppler_bins = np.arange(K) - K // 2
    profile = rd.mean(axis=0)
    p = min_range_bin + int(np.argmax(profile[min_range_bin:]))
    q = int(doppler_bins[int(np.argmax(rd[:, p]))])
    snr_db = float(_db(profile[p] / max(np.median(profile), 1e-300)))
    rng_m = vel = None
    if cfg is not None:
        radar = cfg.to_radar_config()
        rng_m = float(p * radar.range_resolution)
        vel = float(q / (K * radar.carrier_frequency * radar.chirp_interval) * scipy.constants.c / 2)
    dc, g_db, phase, excess = _iq_statistics(sums, profile, layout.is_complex)
    flags = _inspection_flags(sums, info, cfg, bits, dc, g_db, phase, excess, p, min_range_bin)
    peak = Peak(range_bin=p, doppler_bin=q, snr_db=snr_db, range=rng_m, velocity=vel)
    return CaptureInspection(
        files=info.files, form=info.form, layout=layout, config=cfg, frames=info.num_frames,
        frames_read=sums.frames_read, truncated_bytes=info.truncated_bytes, dropped_packets=sums.dropped,
        damaged_frames=sums.damaged, peak=peak, range_profile=profile, range_doppler=rd,
        doppler_bins=doppler_bins, clipped_words=sums.clipped,
        clipped_fraction=sums.clipped / (sums.count * sums.words),
        dc_offset=dc, iq_gain_imbalance_db=g_db, iq_phase_imbalance=phase, positive_frequency_excess_db=excess,
        flags=flags, notes=info.notes, probable_dropped_packets=sums.probable,
        config_iq_swap=None if cfg is None else bool(cfg.iq_swap), impulsive_samples=sums.impulsive,
        impulsive_frames=sums.impulsive_frames, impulsive_largest_db=sums.impulsive_db)


def plot_inspection(result: CaptureInspection, path: str | Path | None = None, *, dynamic_range_db: float = 60.0):
    """Range profile and range–Doppler map of an inspection (:mod:`risloc_rt.plotting`; matplotlib loaded here only).

    Parameters
    ----------
    result : CaptureInspection
    path : path, optional
        Write the figure there atomically (PNG, PDF, … by suffix; PNG when there is none).
    dynamic_range_db : float, default 60
        Colour range of the map below its maximum [dB].

    Returns
    -------
    matplotlib.figure.Figure
        On its own Agg canvas (pyplot's state and the backend are left alone).
    """
    fig, (ax1, ax2) = new_figure(figsize=(10, 4), nrows=1, ncols=2)
    fig.set_layout_engine("constrained")
    prof_db = _db(np.maximum(result.range_profile, 1e-30))
    ax1.plot(np.arange(prof_db.size), prof_db)
    ax1.axvline(result.peak.range_bin, color="r", ls=":", label=f"peak bin {result.peak.range_bin}")
    ax1.set(xlabel="range bin", ylabel="power [dB counts²]", title="range profile")
    ax1.legend()
    rd_db = _db(np.maximum(result.range_doppler, 1e-30))
    top = rd_db.max()
    d = result.doppler_bins
    im = ax2.imshow(rd_db, aspect="auto", origin="lower", vmin=top - dynamic_range_db, vmax=top,
                    extent=(-0.5, rd_db.shape[1] - 0.5, d[0] - 0.5, d[-1] + 0.5))
    ax2.plot(result.peak.range_bin, result.peak.doppler_bin, "r+", ms=12)
    ax2.set(xlabel="range bin", ylabel="Doppler bin (+ receding)", title="range-Doppler map")
    fig.colorbar(im, ax=ax2, label="dB")
    if path is not None:
        save_figure(fig, path, tight=False)
    return fig
