"""FMCW radar parameters (the UE) and the quantities derived from them."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import scipy.constants

from .validation import dataclass_from_dict, finite, positive, positive_int

__all__ = ["RadarConfig", "SPEED_OF_LIGHT", "db_to_linear", "linear_to_db"]

SPEED_OF_LIGHT: float = scipy.constants.c
"""Speed of light in vacuum [m/s]."""


def db_to_linear(value_db: Any) -> Any:
    """``10**(value_db/10)``: a power ratio in dB to a linear ratio."""
    return 10.0 ** (np.asarray(value_db, dtype=float) / 10.0)


def linear_to_db(value: Any) -> Any:
    """``10 log10(value)``: a linear power ratio to dB (``-inf`` for 0)."""
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.asarray(value, dtype=float))


@dataclass(frozen=True)
class RadarConfig:
    """A monostatic FMCW radar with complex (I/Q) sampling of the beat signal.

    The defaults are the seed paper's Table I, with the chirp duration read as 50 µs (the table
    prints "50 ms", a typo: see ``docs/conventions.md``).

    Parameters
    ----------
    carrier_frequency : float, default 60e9
        f_c in eq. (1) [Hz].
    bandwidth : float, default 3.4345e9
        Swept bandwidth B over the chirp duration [Hz].
    chirp_duration : float, default 50e-6
        T: ramp duration, which sets the slope S = B/T, and (unless ``chirp_period`` is given)
        chirp repetition interval, which sets the slow-time phase ``2π f_c ν k T`` of eq. (1) [s].
    num_samples : int, default 600
        N, ADC samples per chirp.
    sample_rate : float, default 10e6
        Complex ADC sample rate 1/T_s [Hz].
    if_bandwidth : float, default 10e6
        Bandwidth of the analogue IF (anti-alias) filter [Hz]; beat frequencies above it are
        attenuated before sampling. The signal model of eq. (1) does not use it.
    num_chirps : int, default 128
        K, chirps per frame (one frame per RIS beam).
    tx_power_dbm : float, default 20
        P, transmit power [dBm] (link budget only; the DSP does not use it).
    antenna_gain_dbi : float, default 4.7712
        G_trx, combined Tx and Rx antenna gain [dBi] (link budget only).
    noise_power_dbm : float, default -63.64
        σ_N², complex noise power per ADC sample [dBm] (simulation only).
    chirp_period : float or None, default None
        T_c, chirp repetition interval (ramp + idle time) [s]: the slow-time sample spacing.
        ``None`` means ``chirp_duration`` (back-to-back chirps, as eq. (1) and Table I assume).
        Must be >= ``chirp_duration``.
    frame_period : float or None, default None
        Time between the starts of consecutive frames [s]. ``None`` means ``K·T_c`` (no idle
        time between frames; the paper gives no frame period). Must be >= K·T_c.
    frames_per_beam : int, default 1
        Frames recorded while the RIS holds one beam (the paper: one frame per sweep angle);
        the cube keeps one frame per beam, this only sets the timing of the sweep.

    Notes
    -----
    The three timing fields were added after capture files existed: :meth:`from_dict` reads
    files without them (``require_all=True`` included) and gives them the defaults above.
    """

    carrier_frequency: float = 60e9
    bandwidth: float = 3.4345e9
    chirp_duration: float = 50e-6
    num_samples: int = 600
    sample_rate: float = 10e6
    if_bandwidth: float = 10e6
    num_chirps: int = 128
    tx_power_dbm: float = 20.0
    antenna_gain_dbi: float = 4.7712
    noise_power_dbm: float = -63.64
    chirp_period: float | None = None
    frame_period: float | None = None
    frames_per_beam: int = 1

    #: Fields a file written before they existed may lack; read with their defaults.
    OPTIONAL_ON_READ = ("chirp_period", "frame_period", "frames_per_beam")

    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        set_("carrier_frequency", positive(self.carrier_frequency, "carrier_frequency", "Hz"))
        set_("bandwidth", positive(self.bandwidth, "bandwidth", "Hz"))
        set_("chirp_duration", positive(self.chirp_duration, "chirp_duration", "s"))
        set_("num_samples", positive_int(self.num_samples, "num_samples"))
        set_("sample_rate", positive(self.sample_rate, "sample_rate", "Hz"))
        set_("if_bandwidth", positive(self.if_bandwidth, "if_bandwidth", "Hz"))
        set_("num_chirps", positive_int(self.num_chirps, "num_chirps"))
        set_("tx_power_dbm", finite(self.tx_power_dbm, "tx_power_dbm", "dBm"))
        set_("antenna_gain_dbi", finite(self.antenna_gain_dbi, "antenna_gain_dbi", "dBi"))
        set_("noise_power_dbm", finite(self.noise_power_dbm, "noise_power_dbm", "dBm"))
        if self.chirp_period is not None:
            set_("chirp_period", positive(self.chirp_period, "chirp_period", "s"))
            if self.chirp_period < self.chirp_duration:
                raise ValueError(
                    f"chirp_period={self.chirp_period:g} s is shorter than chirp_duration="
                    f"{self.chirp_duration:g} s; the repetition interval includes the ramp (use None "
                    "for back-to-back chirps)"
                )
        set_("frames_per_beam", positive_int(self.frames_per_beam, "frames_per_beam"))
        if self.frame_period is not None:
            set_("frame_period", positive(self.frame_period, "frame_period", "s"))
            if self.frame_period < self.num_chirps * self.chirp_interval * (1 - 1e-12):
                raise ValueError(
                    f"frame_period={self.frame_period:g} s is shorter than its K={self.num_chirps} chirps "
                    f"(K·T_c = {self.num_chirps * self.chirp_interval:g} s); use None for back-to-back frames"
                )
        if self.bandwidth >= self.carrier_frequency:
            raise ValueError(
                f"bandwidth={self.bandwidth:g} Hz must be smaller than "
                f"carrier_frequency={self.carrier_frequency:g} Hz"
            )

    # ----------------------------------------------------------------- derived quantities
    @property
    def wavelength(self) -> float:
        """λ = c / f_c [m]."""
        return SPEED_OF_LIGHT / self.carrier_frequency

    @property
    def slope(self) -> float:
        """Chirp slope S = B / T [Hz/s]."""
        return self.bandwidth / self.chirp_duration

    @property
    def sample_period(self) -> float:
        """T_s = 1 / sample_rate [s]."""
        return 1.0 / self.sample_rate

    @property
    def adc_window(self) -> float:
        """Sampled fast-time span N·T_s [s] (Table I: 60 µs, longer than T; see conventions)."""
        return self.num_samples * self.sample_period

    @property
    def sampled_bandwidth(self) -> float:
        """Bandwidth swept while sampling, S·N·T_s [Hz]; it sets the range resolution."""
        return self.slope * self.adc_window

    @property
    def max_delay(self) -> float:
        """Unambiguous round-trip delay 1/(S·T_s) [s]: complex sampling maps [0, max) to the DFT."""
        return 1.0 / (self.slope * self.sample_period)

    @property
    def max_range(self) -> float:
        """Unambiguous range c/(2·S·T_s) [m] (Table I: 21.8 m)."""
        return self.max_delay * SPEED_OF_LIGHT / 2.0

    @property
    def delay_resolution(self) -> float:
        """Rayleigh delay resolution of the unpadded fast-time DFT, 1/(S·N·T_s) [s]."""
        return 1.0 / self.sampled_bandwidth

    @property
    def range_resolution(self) -> float:
        """Range resolution c/(2·S·N·T_s) [m] (Table I: 3.64 cm)."""
        return self.delay_resolution * SPEED_OF_LIGHT / 2.0

    @property
    def chirp_interval(self) -> float:
        """T_c, the chirp repetition interval: ``chirp_period``, or T when it is None [s]."""
        return self.chirp_duration if self.chirp_period is None else self.chirp_period

    @property
    def frame_duration(self) -> float:
        """K·T_c, the span of one frame's chirps [s]."""
        return self.num_chirps * self.chirp_interval

    @property
    def frame_interval(self) -> float:
        """Start-to-start time of consecutive frames: ``frame_period`` or K·T_c [s]."""
        return self.frame_duration if self.frame_period is None else self.frame_period

    @property
    def beam_interval(self) -> float:
        """Start-to-start time of consecutive sweep beams, ``frames_per_beam · frame_interval`` [s]."""
        return self.frames_per_beam * self.frame_interval

    def sweep_duration(self, num_beams: int) -> float:
        """From the first chirp of the first beam's frame to the last chirp of the last beam's first frame
        (the frames :meth:`beam_times` dates) [s]: ``(M − 1) · beam_interval + frame_duration``."""
        return (positive_int(num_beams, "num_beams") - 1) * self.beam_interval + self.frame_duration

    def beam_times(self, num_beams: int) -> np.ndarray:
        """Centre time of each beam's (first) frame, from the start of the sweep [M] [s].

        ``t_m = m · beam_interval + frame_duration / 2``.
        """
        m = positive_int(num_beams, "num_beams")
        return np.arange(m) * self.beam_interval + 0.5 * self.frame_duration

    @property
    def max_delay_rate(self) -> float:
        """Unambiguous delay rate |ν| < 1/(2 f_c T_c) [s/s] (slow-time Nyquist)."""
        return 1.0 / (2.0 * self.carrier_frequency * self.chirp_interval)

    @property
    def max_velocity(self) -> float:
        """Unambiguous radial velocity |v| < λ/(4T) [m/s] (Table I: 25.0 m/s)."""
        return self.max_delay_rate * SPEED_OF_LIGHT / 2.0

    @property
    def velocity_resolution(self) -> float:
        """Velocity resolution λ/(2·K·T_c) [m/s] (Table I: 0.39 m/s)."""
        return self.wavelength / (2.0 * self.num_chirps * self.chirp_interval)

    @property
    def tx_power(self) -> float:
        """P [W]."""
        return float(db_to_linear(self.tx_power_dbm)) * 1e-3

    @property
    def antenna_gain(self) -> float:
        """G_trx, linear [unitless]."""
        return float(db_to_linear(self.antenna_gain_dbi))

    @property
    def noise_power(self) -> float:
        """σ_N² [W]."""
        return float(db_to_linear(self.noise_power_dbm)) * 1e-3

    def delay_grid(self, n_dft: int) -> np.ndarray:
        """Delay of each fast-time DFT bin, ``p / (N_DFT·S·T_s)``, p = 0…N_DFT-1, [N_DFT] [s]."""
        n = positive_int(n_dft, "n_dft")
        return np.arange(n) * (self.max_delay / n)

    def delay_rate_grid(self, k_dft: int) -> np.ndarray:
        """Delay rate ν of each slow-time DFT bin in FFT order, ``fftfreq(K_DFT, f_c T_c)`` [K_DFT] [s/s]."""
        k = positive_int(k_dft, "k_dft")
        return np.fft.fftfreq(k, d=self.carrier_frequency * self.chirp_interval)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary of the fields (SI units except the named dB fields)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, require_all: bool = False) -> "RadarConfig":
        """Inverse of :meth:`to_dict`; unknown (or, with ``require_all``, missing) keys raise.

        The timing fields of :attr:`OPTIONAL_ON_READ` may be missing even with ``require_all``
        (files written before they existed): they take their defaults.
        """
        if isinstance(data, dict):
            data = dict(data)
            defaults = {"chirp_period": None, "frame_period": None, "frames_per_beam": 1}
            for key in cls.OPTIONAL_ON_READ:
                data.setdefault(key, defaults[key])
        return dataclass_from_dict(cls, data, "radar", require_all=require_all)

