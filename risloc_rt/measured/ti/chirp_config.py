"""The TI chirp/frame description of a capture (SI units) and its mapping onto ``dsp.RadarConfig``.

:class:`TiChirpConfig` holds what an mmWave SDK ``.cfg`` file or an mmWave Studio JSON export says
about the waveform and the ADC, converted to SI units (Hz, s, Hz/s). It is the single source the
raw-data layout (:class:`risloc_rt.measured.dca1000.raw_layout.RawLayout`), the ``.cfg`` writer and
:meth:`TiChirpConfig.to_radar_config` are built from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Literal

from dsp.validation import finite, integer, non_negative, positive

from ..errors import MeasuredFormatError

if TYPE_CHECKING:                       # dsp is imported where it is used, so parsing works without it
    import dsp

__all__ = ["ADC_BITS", "ADC_FORMATS", "AdcFormat", "STEP_TOLERANCE", "TiChirp", "TiChirpConfig", "device_steps",
           "slope_step", "start_frequency_step"]

AdcFormat = Literal["real", "complex1x", "complex2x"]
ADC_FORMATS: tuple[str, ...] = ("real", "complex1x", "complex2x")
ADC_BITS: tuple[int, ...] = (12, 14, 16)


def _band_reference(start_frequency: float) -> float:
    """Synthesizer reference of the part's band: 2.7 GHz (57-64 GHz parts), 3.6 GHz (76-81 GHz)."""
    return 2.7e9 if start_frequency < 70e9 else 3.6e9


def slope_step(start_frequency: float) -> float:
    """Programmable frequency-slope step of the device [Hz/s].

    ``f_ref·900/2^26`` per µs with f_ref = 2.7 GHz for 60 GHz parts (36.21 kHz/µs) and 3.6 GHz
    for 77 GHz parts (48.28 kHz/µs), the LSB of mmWaveLink's ``freqSlopeConst``.

    Parameters
    ----------
    start_frequency : float
        The profile's start frequency f_0 [Hz]; below 70 GHz a 60 GHz part, else a 77 GHz part.

    Returns
    -------
    float
        The slope step [Hz/s].
    """
    return _band_reference(start_frequency) * 900.0 / 2**26 * 1e6


def start_frequency_step(start_frequency: float) -> float:
    """Programmable start-frequency step ``f_ref/2^26`` [Hz] (40.2 Hz at 60 GHz, 53.6 Hz at 77 GHz).

    Parameters
    ----------
    start_frequency : float
        The profile's start frequency f_0 [Hz] (it tells the band).

    Returns
    -------
    float
        The start-frequency step [Hz].
    """
    return _band_reference(start_frequency) / 2**26


#: Relative tolerance [steps] of :func:`device_steps`: a value within 1e-6 of a step below a whole
#: number of steps is that number (a value written back from an exact multiple, e.g. by
#: ``format_sdk_cfg``, must not lose a step to the last bit of its decimal text).
STEP_TOLERANCE = 1e-6


def device_steps(value: float, step: float) -> int:
    """Whole device steps of ``value``, truncated toward zero as TI's firmware casts (C ``(int)``).

    Parameters
    ----------
    value : float
        The ``.cfg`` value [Hz/s or Hz].
    step : float
        The register's LSB (:func:`slope_step`, :func:`start_frequency_step`) [same unit].

    Returns
    -------
    int
        ``trunc(value/step)``, with :data:`STEP_TOLERANCE` for values written from exact multiples.
    """
    ratio = value / step
    return int(math.trunc(ratio + math.copysign(STEP_TOLERANCE, ratio)))


@dataclass(frozen=True)
class TiChirp:
    """One chirp of the loop (an mmWave ``chirpCfg`` entry expanded to a single index).

    Parameters
    ----------
    tx_mask : int
        Transmitters enabled during the chirp (bit i = TX i).
    start_frequency_offset : float, default 0
        ``startFreqVar`` added to the profile's start frequency [Hz].
    slope_offset : float, default 0
        ``freqSlopeVar`` added to the profile's slope [Hz/s].
    idle_time_offset : float, default 0
        ``idleTimeVar`` added to the profile's idle time [s].
    adc_start_time_offset : float, default 0
        ``adcStartTimeVar`` added to the profile's ADC start time [s].
    """

    tx_mask: int
    start_frequency_offset: float = 0.0
    slope_offset: float = 0.0
    idle_time_offset: float = 0.0
    adc_start_time_offset: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "tx_mask", integer(self.tx_mask, "tx_mask", minimum=0, maximum=0xFF, error=MeasuredFormatError))
        for name, unit in (("start_frequency_offset", "Hz"), ("slope_offset", "Hz/s"),
                           ("idle_time_offset", "s"), ("adc_start_time_offset", "s")):
            object.__setattr__(self, name, finite(getattr(self, name), name, unit, error=MeasuredFormatError))

    @property
    def varies(self) -> bool:
        """True when any per-chirp variation is non-zero."""
        return any((self.start_frequency_offset, self.slope_offset, self.idle_time_offset,
                    self.adc_start_time_offset))


@dataclass(frozen=True)
class TiChirpConfig:
    """A TI single-profile, frame-based (legacy frame) chirp configuration, SI units inside.

    Parameters
    ----------
    start_frequency : float
        Profile start frequency f_0 [Hz] (``profileCfg`` startFreq, GHz in the file).
    slope : float
        Frequency slope S as programmed [Hz/s] (``freqSlopeConst``, MHz/µs in the file).
    idle_time : float
        Idle time before each ramp [s].
    adc_start_time : float
        Time from the ramp start to the first ADC sample [s].
    ramp_end_time : float
        Ramp duration [s].
    num_samples : int
        ADC samples per chirp and receiver, N (complex samples in the complex modes).
    sample_rate : float
        ADC output sample rate f_s (``digOutSampleRate``, ksps in the file) [Hz].
    rx_mask : int
        Enabled receivers (bit i = RX i), ``channelCfg`` rxChannelEn.
    tx_mask : int
        Enabled transmitters, ``channelCfg`` txChannelEn.
    chirps : tuple of TiChirp
        The chirps of one loop in transmission order (``frameCfg`` chirpStartIdx…chirpEndIdx);
        with TDM-MIMO each enables one transmitter.
    num_loops : int
        Loops per frame: chirps per virtual channel per frame, K.
    num_frames : int
        Frames to transmit; 0 means until stopped.
    frame_periodicity : float
        Frame period [s] (ms in the file).
    adc_bits : {12, 14, 16}
        ADC resolution; samples are stored as signed int16 in every case.
    adc_format : {"real", "complex1x", "complex2x"}
        ``adcCfg`` adcOutputFmt 0/1/2.
    iq_swap : bool, default False
        The configuration's I/Q swap flag (``adcbufCfg`` sampleSwap, Studio ``iqSwapSel``).
        Recorded only: it does not reliably tell a file's I/Q order (``docs/measured-captures.md``).
    tx_start_time : float, default 0
        Tx start time relative to the ramp [s].
    rx_gain_db : float or None
        Rx gain [dB], nominal.
    """

    start_frequency: float
    slope: float
    idle_time: float
    adc_start_time: float
    ramp_end_time: float
    num_samples: int
    sample_rate: float
    rx_mask: int
    tx_mask: int
    chirps: tuple[TiChirp, ...]
    num_loops: int
    num_frames: int
    frame_periodicity: float
    adc_bits: int = 16
    adc_format: AdcFormat = "complex1x"
    iq_swap: bool = False
    tx_start_time: float = 0.0
    rx_gain_db: float | None = None

    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        set_("start_frequency", positive(self.start_frequency, "start_frequency", "Hz", error=MeasuredFormatError))
        set_("slope", positive(self.slope, "slope", "Hz/s", error=MeasuredFormatError))
        set_("idle_time", non_negative(self.idle_time, "idle_time", "s", error=MeasuredFormatError))
        set_("adc_start_time", non_negative(self.adc_start_time, "adc_start_time", "s", error=MeasuredFormatError))
        set_("ramp_end_time", positive(self.ramp_end_time, "ramp_end_time", "s", error=MeasuredFormatError))
        set_("tx_start_time", finite(self.tx_start_time, "tx_start_time", "s", error=MeasuredFormatError))
        set_("num_samples", integer(self.num_samples, "num_samples", minimum=1, error=MeasuredFormatError))
        set_("sample_rate", positive(self.sample_rate, "sample_rate", "Hz", error=MeasuredFormatError))
        set_("rx_mask", integer(self.rx_mask, "rx_mask", minimum=1, maximum=0xFF, error=MeasuredFormatError))
        set_("tx_mask", integer(self.tx_mask, "tx_mask", minimum=0, maximum=0xFF, error=MeasuredFormatError))
        set_("num_loops", integer(self.num_loops, "num_loops", minimum=1, error=MeasuredFormatError))
        set_("num_frames", integer(self.num_frames, "num_frames", minimum=0, error=MeasuredFormatError))
        set_("frame_periodicity", non_negative(self.frame_periodicity, "frame_periodicity", "s", error=MeasuredFormatError))
        set_("chirps", tuple(self.chirps))
        if not self.chirps or not all(isinstance(c, TiChirp) for c in self.chirps):
            raise MeasuredFormatError("chirps must be a non-empty tuple of TiChirp (one per chirp of the loop)")
        for i, chirp in enumerate(self.chirps):
            if chirp.tx_mask & ~self.tx_mask:
                raise MeasuredFormatError(
                    f"chirp {i} enables tx_mask=0b{chirp.tx_mask:b}, outside the enabled "
                    f"tx_mask=0b{self.tx_mask:b}: enable those transmitters in channelCfg or fix chirpCfg")
        if self.adc_bits not in ADC_BITS:
            raise MeasuredFormatError(f"adc_bits={self.adc_bits!r} must be one of {ADC_BITS}")
        if self.adc_format not in ADC_FORMATS:
            raise MeasuredFormatError(f"adc_format={self.adc_format!r} must be one of {ADC_FORMATS}")
        set_("iq_swap", bool(self.iq_swap))
        if self.rx_gain_db is not None:
            set_("rx_gain_db", finite(self.rx_gain_db, "rx_gain_db", "dB", error=MeasuredFormatError))

    # ------------------------------------------------------------------ counts
    @property
    def rx_channels(self) -> tuple[int, ...]:
        """Indices of the enabled receivers, ascending (the file's receiver order)."""
        return tuple(i for i in range(8) if self.rx_mask >> i & 1)

    @property
    def num_rx(self) -> int:
        """Enabled receivers R."""
        return len(self.rx_channels)

    @property
    def chirps_per_loop(self) -> int:
        """Chirps per loop C (the TDM-MIMO transmitter slots)."""
        return len(self.chirps)

    @property
    def chirps_per_frame(self) -> int:
        """Chirps per frame, ``num_loops · chirps_per_loop``."""
        return self.num_loops * self.chirps_per_loop

    @property
    def num_virtual(self) -> int:
        """Virtual channels V = C·R, ordered chirp-of-the-loop major, receiver minor."""
        return self.chirps_per_loop * self.num_rx

    @property
    def tx_order(self) -> tuple[int, ...]:
        """Tx mask of each chirp of the loop, in transmission order (e.g. TX0, TX2, TX1)."""
        return tuple(c.tx_mask for c in self.chirps)

    @property
    def is_complex(self) -> bool:
        """True for the complex1x and complex2x ADC formats."""
        return self.adc_format != "real"

    # ------------------------------------------------------------------ timing
    @property
    def chirp_period(self) -> float:
        """Idle plus ramp time of one chirp (profile values) [s]."""
        return self.idle_time + self.ramp_end_time

    @property
    def loop_period(self) -> float:
        """Time between two chirps of the same virtual channel, Σ over the loop of (idle + ramp) [s]."""
        return sum(self.chirp_period + c.idle_time_offset for c in self.chirps)

    @property
    def frame_active_time(self) -> float:
        """Chirping time of one frame, ``num_loops · loop_period`` [s]."""
        return self.num_loops * self.loop_period

    @property
    def adc_sampling_time(self) -> float:
        """ADC window N / f_s [s]."""
        return self.num_samples / self.sample_rate

    @property
    def ramp_bandwidth(self) -> float:
        """Bandwidth swept by the whole ramp, S · ramp_end_time [Hz]."""
        return self.slope * self.ramp_end_time

    @property
    def sampled_bandwidth(self) -> float:
        """Bandwidth swept while sampling, S · N / f_s [Hz]; it sets the range resolution."""
        return self.slope * self.adc_sampling_time

    @property
    def quantized_slope(self) -> float:
        """The slope the device actually programs: S truncated to :func:`slope_step` [Hz/s].

        TI's firmware converts the ``.cfg`` value to its register with a C cast, which truncates:
        ``trunc(S[MHz/µs] · 2^26 / (f_ref[MHz] · 900))`` steps (:func:`device_steps`). A ``.cfg``
        slope of 68.69 MHz/µs is 1896.9991 steps of 36.21 kHz/µs, so the device sweeps
        68.6538 MHz/µs: −0.054 %, −7 mm at 13 m if the file's value were used.
        """
        step = slope_step(self.start_frequency)
        return device_steps(self.slope, step) * step

    @property
    def quantized_start_frequency(self) -> float:
        """The start frequency the device programs: f_0 truncated to :func:`start_frequency_step` [Hz]
        (``trunc(f_0[GHz] · 2^26 / f_ref[GHz])`` steps of 40.2 Hz at 60 GHz, as :attr:`quantized_slope`)."""
        step = start_frequency_step(self.start_frequency)
        return device_steps(self.start_frequency, step) * step

    def band_centre(self, *, quantized: bool = True) -> float:
        """Frequency at the middle of the ADC window, ``f_0 + S·(adc_start_time + N/(2 f_s))`` [Hz].

        The slow-time phase of a moving target advances at the frequency the samples are taken at:
        the 2-D transform's Doppler sees the window's centre (the Hann window is symmetric), not
        f_0 — 62.13 GHz for an IWR6843 profile starting at 60 GHz with 68.69 MHz/µs, 6 µs ADC start
        and 256 samples at 10 Msps (3.5 % in velocity).

        Parameters
        ----------
        quantized : bool, default True
            Use the device's truncated f_0 and S (:attr:`quantized_start_frequency`,
            :attr:`quantized_slope`) rather than the file's values.

        Returns
        -------
        float
            [Hz].
        """
        f0 = self.quantized_start_frequency if quantized else self.start_frequency
        slope = self.quantized_slope if quantized else self.slope
        return f0 + slope * (self.adc_start_time + self.adc_sampling_time / 2)

    def device_issues(self) -> tuple[str, ...]:
        """Timing a real device would refuse or that makes the data suspect (empty when none).

        Returns
        -------
        tuple of str
            One sentence per issue: an ADC window longer than the ramp, a sweep outside the device's
            band, a frame longer than its period, varying chirps, chirps that are not plain TDM.
        """
        issues = []
        window = self.ramp_end_time - self.adc_start_time
        if self.adc_sampling_time > window * (1 + 1e-9):
            issues.append(f"ADC window N/f_s = {self.adc_sampling_time * 1e6:.3f} us is longer than "
                          f"ramp_end_time - adc_start_time = {window * 1e6:.3f} us: samples fall outside the ramp")
        f_end = self.start_frequency + self.ramp_bandwidth
        low, high = (57e9, 64e9) if self.start_frequency < 70e9 else (76e9, 81e9)
        if self.start_frequency < low or f_end > high:
            issues.append(f"the ramp sweeps {self.start_frequency / 1e9:.3f}-{f_end / 1e9:.3f} GHz, "
                          f"outside the device band {low / 1e9:g}-{high / 1e9:g} GHz")
        if self.frame_periodicity and self.frame_active_time > self.frame_periodicity:
            issues.append(f"frame active time {self.frame_active_time * 1e3:.3f} ms exceeds the frame period "
                          f"{self.frame_periodicity * 1e3:.3f} ms")
        if any(c.varies for c in self.chirps):
            issues.append("chirps of the loop vary start frequency, slope, idle or ADC start time: "
                          "the mapping uses the profile values")
        if any(bin(c.tx_mask).count("1") != 1 for c in self.chirps) and self.chirps_per_loop > 1:
            issues.append("some chirps enable no or several transmitters: virtual channels are not plain TDM")
        return tuple(issues)

    # ------------------------------------------------------------------ mapping
    def to_radar_config(self, *, carrier: Literal["start", "center"] = "center", quantize_slope: bool = True,
                        **radar_fields: Any) -> "dsp.RadarConfig":
        """The project's radar parameters (``dsp.RadarConfig``) for this configuration.

        The ramp sets the slope, the TDM loop the slow-time spacing: ``chirp_duration`` T =
        ``ramp_end_time`` and ``bandwidth`` B = S·T (so S = B/T is the programmed slope and B the
        swept RF bandwidth), ``chirp_period`` T_c = :attr:`loop_period` (the time between two
        chirps of one virtual channel, which sets the velocity axis), ``frame_period`` = the
        frame periodicity (when it is set and holds the frame's chirps).

        Parameters
        ----------
        carrier : {"center", "start"}, default "center"
            f_c = the frequency at the middle of the ADC window ``f_0 + S·(adc_start_time +
            N/(2 f_s))`` (:meth:`band_centre`: the frequency the slow-time phase advances at, which
            sets the velocity, the delay rate and the wavelength), or the start frequency f_0
            (velocities too high by the ratio, 3.5 % for a typical IWR6843 profile).
        quantize_slope : bool, default True
            Use the slope and start frequency the device programs (:attr:`quantized_slope`,
            :attr:`quantized_start_frequency`: truncated, as TI's firmware does) rather than the
            values written in the file. Convert bins to metres with the quantized ones.
        **radar_fields
            Other ``RadarConfig`` fields (``tx_power_dbm``, ``noise_power_dbm``, …), nominal.

        Returns
        -------
        dsp.RadarConfig
            ``num_samples`` = N, ``sample_rate`` = f_s, ``num_chirps`` = num_loops,
            ``if_bandwidth`` = f_s (complex) or f_s/2 (real). With a real ADC the DSP's complex
            model only holds for beat frequencies in [0, f_s/2).
        """
        import dsp

        slope = self.quantized_slope if quantize_slope else self.slope
        if carrier == "start":
            fc = self.quantized_start_frequency if quantize_slope else self.start_frequency
        elif carrier == "center":
            fc = self.band_centre(quantized=quantize_slope)
        else:
            raise MeasuredFormatError(f"carrier={carrier!r} must be 'start' or 'center'")
        frame = self.frame_periodicity if self.frame_periodicity and \
            self.frame_periodicity >= self.num_loops * self.loop_period else None
        fields = dict(carrier_frequency=fc, bandwidth=slope * self.ramp_end_time, chirp_duration=self.ramp_end_time,
                      chirp_period=self.loop_period, frame_period=frame,
                      num_samples=self.num_samples, sample_rate=self.sample_rate,
                      if_bandwidth=self.sample_rate if self.is_complex else self.sample_rate / 2,
                      num_chirps=self.num_loops)
        fields.update(radar_fields)
        try:
            return dsp.RadarConfig(**fields)
        except ValueError as exc:
            raise MeasuredFormatError(f"cannot map the TI configuration onto dsp.RadarConfig ({exc}); "
                                      "check the profileCfg/chirpCfg/frameCfg values it names") from None

    @classmethod
    def from_radar(cls, radar: "dsp.RadarConfig", *, rx_mask: int = 0b1111, tx_order: tuple[int, ...] = (1,),
                   adc_start_time: float = 6e-6, ramp_margin: float = 1e-6, num_frames: int = 0,
                   frame_periodicity: float | None = None, adc_bits: int = 16,
                   adc_format: AdcFormat = "complex1x") -> "TiChirpConfig":
        """A TI configuration that reproduces ``radar``'s f_c, S, f_s, N, K and chirp spacing.

        The loop holds one chirp per entry of ``tx_order`` (Tx masks); the chirp spacing
        ``radar.chirp_interval`` is split evenly among them as idle + ramp, the ramp being
        ``adc_start_time + N/f_s + ramp_margin``. The start frequency is chosen so that the ADC
        window's centre is ``radar.carrier_frequency`` (f_0 = f_c − S·(adc_start_time + N/(2 f_s)):
        :meth:`to_radar_config` maps the carrier back to that centre). The values are written as
        given; a device programs them truncated to its steps (:attr:`quantized_slope`), so pass a
        radar whose slope and carrier are already on them (``risloc_rt.measured.dca1000_radar``)
        for a lossless round trip. Raises if T is too short for that ramp (Table I: 600 samples at
        10 Msps need 60 µs, more than its 50 µs chirp).
        """
        tx_order = tuple(tx_order)
        ramp = adc_start_time + radar.adc_window + ramp_margin
        per_chirp = radar.chirp_interval / max(len(tx_order), 1)
        if ramp > per_chirp * (1 + 1e-12):
            raise MeasuredFormatError(
                f"radar.chirp_interval={radar.chirp_interval * 1e6:.3f} us leaves {per_chirp * 1e6:.3f} us per chirp, "
                f"less than the ramp adc_start_time + N/f_s + margin = {ramp * 1e6:.3f} us; "
                "lower num_samples, raise sample_rate or lengthen chirp_period")
        chirps = tuple(TiChirp(tx_mask=m) for m in tx_order)
        tx_mask = 0
        for m in tx_order:
            tx_mask |= m
        period = radar.frame_interval if frame_periodicity is None else frame_periodicity
        start = radar.carrier_frequency - radar.slope * (adc_start_time + radar.adc_window / 2)
        return cls(start_frequency=start, slope=radar.slope, idle_time=per_chirp - ramp,
                   adc_start_time=adc_start_time, ramp_end_time=ramp, num_samples=radar.num_samples,
                   sample_rate=radar.sample_rate, rx_mask=rx_mask, tx_mask=tx_mask, chirps=chirps,
                   num_loops=radar.num_chirps, num_frames=num_frames, frame_periodicity=period,
                   adc_bits=adc_bits, adc_format=adc_format)

    def with_frames(self, num_frames: int) -> "TiChirpConfig":
        """A copy with another ``num_frames``.

        Parameters
        ----------
        num_frames : int
            Frames to transmit; 0 means until stopped.

        Returns
        -------
        TiChirpConfig
        """
        return replace(self, num_frames=num_frames)
