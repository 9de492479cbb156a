"""TI radar device families and the check of a configuration against their limits (raw ADC capture over LVDS).

A :class:`DeviceFamily` holds what TI's documents state about one chip family: RF band, receivers and
transmitters, the LVDS lanes the DCA1000 captures, ADC output rates, the ADC buffer a chirp must fit
in, the LVDS lane rate; :data:`DCA1000_ETHERNET_RATE` the capture board's Ethernet throughput.
:func:`check_device_config` works out the recording's data format, chirp and frame sizes and data
rate from a :class:`TiChirpConfig` and raises one :class:`MeasuredFormatError` line per violated limit.

Sources (each figure below names its own):

- the device data sheets: IWR6843 (SWRS219, "RF Specification", "Receive Subsystem": IF band-pass up
  to 10 MHz; "LVDS Interface Configuration": two data lanes, a bit clock and a frame clock, at most
  900 Mbps per lane = 450 MHz DDR clock), IWR6843AOP (SWRS237: the same chip with the antennas in the
  package), IWR1843/AWR1843 (SWRS228, IF up to 10 MHz), IWR1642/AWR1642 (SWRS212/SWRS203, IF up to
  5 MHz, two transmitters), IWR1443 (four LVDS lanes);
- TI's mmWaveLink header ``rl_sensor.h`` (``rlProfileCfg_t``): ``digOutSampleRate``'s maximum by the
  device's IF bandwidth (10 MHz: 25 Msps real and complex 2x, 12.5 Msps complex 1x; 5 MHz: 12.5 and
  6.25 Msps; 15 MHz: 37.5 and 18.75 Msps) and ``numAdcSamples``'s ADC-buffer rule (all enabled
  receivers' samples of a chirp, 2 bytes per real and 4 per complex sample, must fit: 1024 complex
  samples with 4 Rx, i.e. 16 KiB);
- the mmWave SDK 3.x user's guide (CLI ``adcbufCfg``: ``ChirpThreshold`` chirps are collected in the
  ADC buffer's ping half before they are sent on; ``lvdsStreamCfg``);
- the DCA1000EVM user's guide (SPRUIJ4): 2-lane (xWR16xx/18xx/68xx) or 4-lane (xWR12xx/14xx) LVDS
  capture, Gigabit Ethernet to the host, data packets of at most 1456 bytes. Its throughput figure
  was not found in the material searched: :data:`DCA1000_ETHERNET_RATE` is the 600 Mbps TI's support
  forum gives for the DCA1000EVM ("DCA1000 EVM supports up to 600 Mbps", TI E2E thread 927693).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ..errors import MeasuredFormatError
from .chirp_config import TiChirpConfig
from .sdk_cfg import LvdsStreamCfg, ParsedSdkCfg

__all__ = ["DCA1000_ETHERNET_RATE", "DCA1000_PAYLOAD_BYTES", "DEVICE_FAMILIES", "DeviceCheck", "DeviceFamily",
           "check_device_config", "device_family"]

#: The DCA1000EVM's data throughput to the host [bit/s] (TI E2E thread 927693: "supports up to 600 Mbps";
#: the DCA1000EVM user's guide states a Gigabit Ethernet link, 1e9 bit/s on the wire).
DCA1000_ETHERNET_RATE = 600e6
#: Most ADC data bytes in one DCA1000 data packet (DCA1000EVM user's guide, raw mode: 4-byte sequence
#: number, 6-byte byte count, up to 1456 data bytes).
DCA1000_PAYLOAD_BYTES = 1456


@dataclass(frozen=True)
class DeviceFamily:
    """One TI mmWave chip family as the raw-data capture sees it (figures from TI's documents).

    Parameters
    ----------
    name : str
        Family name, e.g. ``"IWR6843"`` or ``"xWR1843"``.
    aliases : tuple of str
        Lower-case spellings :func:`device_family` accepts (parts and boards: ``"iwr6843isk"``).
    band : tuple of float
        RF band (lowest, highest frequency) a chirp must stay in [Hz] (data sheet, "Features").
    num_rx : int
        Receivers (data sheet).
    num_tx : int
        Transmitters (data sheet).
    lvds_lanes : int
        LVDS data lanes the DCA1000 captures (data sheet "LVDS Interface Configuration"; DCA1000EVM
        user's guide).
    max_complex_sample_rate : float
        Most complex-1x ADC output samples per second [Hz] (``rl_sensor.h`` by the IF bandwidth).
    max_real_sample_rate : float
        Most real (and complex-2x) ADC output samples per second [Hz] (same table).
    if_bandwidth : float
        The IF band-pass's widest bandwidth [Hz] (data sheet, "Receive Subsystem").
    adc_buffer_bytes : int
        Bytes of the ADC buffer's ping half that ``adcbufCfg``'s ChirpThreshold chirps (all enabled
        receivers) must fit in [bytes] (``rl_sensor.h``, ``numAdcSamples``).
    max_lvds_lane_rate : float
        Most bits per second on one LVDS data lane [bit/s] (data sheet "LVDS Interface Configuration").
    ethernet_rate : float
        The DCA1000's throughput to the host [bit/s] (:data:`DCA1000_ETHERNET_RATE`).
    sources : str
        The documents the figures come from, for messages and the docs.
    """

    name: str
    aliases: tuple[str, ...]
    band: tuple[float, float]
    num_rx: int
    num_tx: int
    lvds_lanes: int
    max_complex_sample_rate: float
    max_real_sample_rate: float
    if_bandwidth: float
    adc_buffer_bytes: int
    max_lvds_lane_rate: float
    ethernet_rate: float = DCA1000_ETHERNET_RATE
    sources: str = ""

    def max_sample_rate(self, adc_format: str) -> float:
        """Most ADC output samples per second for ``adc_format`` [Hz].

        Parameters
        ----------
        adc_format : {"real", "complex1x", "complex2x"}
            ``adcCfg`` adcOutputFmt.

        Returns
        -------
        float
            :attr:`max_complex_sample_rate` for complex 1x, else :attr:`max_real_sample_rate` [Hz].
        """
        return self.max_complex_sample_rate if adc_format == "complex1x" else self.max_real_sample_rate


_SIXTY_GHZ = (60e9, 64e9)        # IWR6843 data sheet: "60- to 64-GHz"
_SEVENTY_SEVEN_GHZ = (76e9, 81e9)  # xWR1443/1642/1843 data sheets: "76- to 81-GHz"

#: The families :func:`device_family` knows, by name.
DEVICE_FAMILIES: dict[str, DeviceFamily] = {f.name: f for f in (
    DeviceFamily(
        name="IWR6843", aliases=("iwr6843", "iwr6843isk", "iwr6843isk-ods", "iwr6843ods", "iwr6843aop",
                                 "iwr6843aopevm", "awr6843", "awr6843aop", "xwr6843", "6843", "xwr68xx"),
        band=_SIXTY_GHZ, num_rx=4, num_tx=3, lvds_lanes=2, max_complex_sample_rate=12.5e6,
        max_real_sample_rate=25e6, if_bandwidth=10e6, adc_buffer_bytes=16384, max_lvds_lane_rate=900e6,
        sources="IWR6843 data sheet SWRS219 (ISK) / SWRS237 (AOP: same chip, antennas on package); "
                "mmWaveLink rl_sensor.h rlProfileCfg_t"),
    DeviceFamily(
        name="xWR1843", aliases=("xwr1843", "iwr1843", "awr1843", "iwr1843boost", "awr1843boost", "iwr1843aop",
                                 "awr1843aop", "1843", "xwr18xx"),
        band=_SEVENTY_SEVEN_GHZ, num_rx=4, num_tx=3, lvds_lanes=2, max_complex_sample_rate=12.5e6,
        max_real_sample_rate=25e6, if_bandwidth=10e6, adc_buffer_bytes=16384, max_lvds_lane_rate=900e6,
        sources="IWR1843 data sheet SWRS228, AWR1843 data sheet; mmWaveLink rl_sensor.h rlProfileCfg_t"),
    DeviceFamily(
        name="xWR1642", aliases=("xwr1642", "iwr1642", "awr1642", "iwr1642boost", "awr1642boost",
                                 "iwr1642ods", "1642", "xwr16xx"),
        band=_SEVENTY_SEVEN_GHZ, num_rx=4, num_tx=2, lvds_lanes=2, max_complex_sample_rate=6.25e6,
        max_real_sample_rate=12.5e6, if_bandwidth=5e6, adc_buffer_bytes=16384, max_lvds_lane_rate=900e6,
        sources="IWR1642 data sheet SWRS212, AWR1642 data sheet SWRS203; mmWaveLink rl_sensor.h rlProfileCfg_t"),
    DeviceFamily(
        name="xWR1443", aliases=("xwr1443", "iwr1443", "awr1443", "iwr1443boost", "awr1443boost", "1443",
                                 "xwr14xx"),
        band=_SEVENTY_SEVEN_GHZ, num_rx=4, num_tx=3, lvds_lanes=4, max_complex_sample_rate=18.75e6,
        max_real_sample_rate=37.5e6, if_bandwidth=15e6, adc_buffer_bytes=16384, max_lvds_lane_rate=600e6,
        sources="IWR1443 data sheet (4 LVDS lanes, IF 15 MHz); mmWaveLink rl_sensor.h rlProfileCfg_t; "
                "LVDS lane rate 600 Mbps not confirmed in the material searched"),
)}


def device_family(name: str) -> DeviceFamily:
    """The :class:`DeviceFamily` of a part or board name, in any usual spelling.

    Parameters
    ----------
    name : str
        ``"IWR6843"``, ``"iwr6843isk"``, ``"IWR6843AOP"``, ``"xwr1843"``, ``"AWR1642"``, ``"IWR1443BOOST"`` …
        (case, ``-``/``_``/spaces and an ``EVM``/``BOOST`` suffix do not matter).

    Returns
    -------
    DeviceFamily
        The family.

    Raises
    ------
    MeasuredFormatError
        An unknown name; the message lists the known families.
    """
    def norm(text: str) -> str:
        return re.sub(r"[\s_\-]", "", text).lower()

    key = norm(str(name))
    for candidate in (key, re.sub(r"(evm|boost)$", "", key)):
        for family in DEVICE_FAMILIES.values():
            if candidate == norm(family.name) or candidate in {norm(a) for a in family.aliases}:
                return family
    known = ", ".join(f"{f.name} ({'/'.join(a for a in f.aliases[1:3])})" for f in DEVICE_FAMILIES.values())
    raise MeasuredFormatError(f"unknown radar device {name!r}; known families: {known}")


@dataclass(frozen=True)
class DeviceCheck:
    """What a configuration asks of a device and its DCA1000 recording (result of :func:`check_device_config`).

    Parameters
    ----------
    family : str
        The device family's name.
    lanes : int
        LVDS lanes the DCA1000 must capture (its ``CONFIG_FPGA_GEN`` LVDS mode).
    adc_bits : int
        ADC resolution (12, 14 or 16); every sample is stored as a 16-bit word.
    adc_format : str
        ``"real"``, ``"complex1x"`` or ``"complex2x"``.
    bytes_per_sample : int
        Bytes of one sample of one receiver: 2 (real) or 4 (complex I and Q) [bytes].
    bytes_per_chirp : int
        Bytes of one chirp, all enabled receivers [bytes].
    frame_bytes : int
        Bytes of one frame [bytes].
    data_rate : float
        Frame size / frame periodicity [bytes/s].
    burst_rate : float
        Bytes of a chirp / the chirp's duration (idle + ramp), the rate while chirping [bytes/s].
    lvds_duty : float
        Share of the LVDS lanes' capacity (lanes × lane rate) the chirps use while chirping (≤ 1).
    ethernet_duty : float
        Share of the DCA1000's Ethernet throughput the data rate uses (≤ 1).
    packets_per_frame : float
        Frame size / the DCA1000's 1456-byte packet payload (a whole number means no packet straddles frames).
    lvds_header : bool or None
        ``lvdsStreamCfg``'s enableHeader (None when the ``.cfg`` has no ``lvdsStreamCfg``).
    """

    family: str
    lanes: int
    adc_bits: int
    adc_format: str
    bytes_per_sample: int
    bytes_per_chirp: int
    frame_bytes: int
    data_rate: float
    burst_rate: float
    lvds_duty: float
    ethernet_duty: float
    packets_per_frame: float
    lvds_header: bool | None = None

    @property
    def is_complex(self) -> bool:
        """True for complex 1x and 2x samples (I and Q words)."""
        return self.adc_format != "real"

    def describe(self) -> str:
        """One line: lanes, format, sizes, rate and the link shares, in MB/s and %.

        Returns
        -------
        str
            E.g. ``IWR6843: 2 LVDS lanes, 16-bit complex1x, 4096 B/chirp, 786432 B/frame, 19.7 MB/s …``.
        """
        return (f"{self.family}: {self.lanes} LVDS lanes, {self.adc_bits}-bit {self.adc_format}, "
                f"{self.bytes_per_chirp} B/chirp, {self.frame_bytes} B/frame, {self.data_rate / 1e6:.3g} MB/s "
                f"({100 * self.ethernet_duty:.3g} % of the DCA1000 Ethernet, {100 * self.lvds_duty:.3g} % of "
                f"the LVDS lanes while chirping)")


def _band_violation(cfg: TiChirpConfig, family: DeviceFamily) -> str | None:
    """The sweep's lowest and highest frequency against the band, or None."""
    lo, hi = family.band
    starts = [cfg.start_frequency + c.start_frequency_offset for c in cfg.chirps]
    ends = [f0 + (cfg.slope + c.slope_offset) * cfg.ramp_end_time for f0, c in zip(starts, cfg.chirps)]
    low, high = min(starts + ends), max(starts + ends)
    if low < lo * (1 - 1e-12) or high > hi * (1 + 1e-12):
        return (f"the chirps sweep {low / 1e9:.4g}-{high / 1e9:.4g} GHz, outside the {family.name}'s "
                f"{lo / 1e9:g}-{hi / 1e9:g} GHz band (data sheet); change profileCfg startFreq, freqSlopeConst "
                "or rampEndTime")
    return None


def _antenna_violations(cfg: TiChirpConfig, family: DeviceFamily) -> list[str]:
    """Receivers and transmitters the configuration enables that the chip does not have."""
    bad = []
    if cfg.rx_mask >> family.num_rx:
        bad.append(f"channelCfg rxChannelEn=0b{cfg.rx_mask:b} enables receivers the {family.name} does not have "
                   f"(it has {family.num_rx}: mask at most 0b{(1 << family.num_rx) - 1:b}, data sheet)")
    if cfg.tx_mask >> family.num_tx:
        bad.append(f"channelCfg txChannelEn=0b{cfg.tx_mask:b} enables transmitters the {family.name} does not have "
                   f"(it has {family.num_tx}: mask at most 0b{(1 << family.num_tx) - 1:b}, data sheet)")
    return bad


def _sizes(cfg: TiChirpConfig, family: DeviceFamily) -> tuple[int, int, int]:
    """(bytes per sample, bytes per chirp, bytes per frame): every sample a 16-bit word, I and Q for complex."""
    per_sample = 4 if cfg.is_complex else 2
    per_chirp = cfg.num_samples * cfg.num_rx * per_sample
    return per_sample, per_chirp, per_chirp * cfg.chirps_per_frame


def check_device_config(cfg: TiChirpConfig | ParsedSdkCfg, family: DeviceFamily | str, *,
                        chirp_threshold: int | None = None, lvds_stream: LvdsStreamCfg | None = None,
                        ethernet_rate: float | None = None) -> DeviceCheck:
    """Check a configuration against a device family's limits and work out its recording's sizes and rates.

    Checked, each with its source (see the module docstring): the sweep inside the RF band; no more
    receivers/transmitters than the chip has; the ADC output rate at most the IF bandwidth's maximum
    for the format; ``chirp_threshold`` chirps of all enabled receivers inside the ADC buffer's ping
    half; the ADC window inside the ramp; a frame no longer than its period; the 2-lane interleave's
    even sample count; a frame of whole 16-bit words on every lane; the chirps' data within the LVDS
    lanes' rate while chirping; the frame rate within the DCA1000's Ethernet throughput;
    ``lvdsStreamCfg`` (when given) streaming plain ADC samples without the HSI header.

    Parameters
    ----------
    cfg : TiChirpConfig or ParsedSdkCfg
        The configuration (SI units); a parsed ``.cfg`` also gives its ChirpThreshold and ``lvdsStreamCfg``.
    family : DeviceFamily or str
        The device, or its name for :func:`device_family`.
    chirp_threshold : int, optional
        ``adcbufCfg``'s ChirpThreshold (chirps gathered in the ADC buffer before they are sent); default
        the parsed ``.cfg``'s, else 1.
    lvds_stream : LvdsStreamCfg, optional
        ``lvdsStreamCfg``'s fields, checked when given; default the parsed ``.cfg``'s.
    ethernet_rate : float, optional
        The DCA1000's throughput to check against [bit/s]; default the family's (600 Mbps).

    Returns
    -------
    DeviceCheck
        Lanes, data format, chirp and frame sizes [bytes], data rate [bytes/s] and the links' duty.

    Raises
    ------
    MeasuredFormatError
        The first violated limit, one line naming the limit, its source and the fix.
    """
    family = device_family(family) if isinstance(family, str) else family
    if isinstance(cfg, ParsedSdkCfg):
        chirp_threshold = cfg.chirp_threshold if chirp_threshold is None else chirp_threshold
        lvds_stream = cfg.lvds_stream if lvds_stream is None else lvds_stream
        cfg = cfg.config
    chirp_threshold = 1 if chirp_threshold is None else chirp_threshold
    bad = [msg for msg in (_band_violation(cfg, family),) if msg] + _antenna_violations(cfg, family)
    limit = family.max_sample_rate(cfg.adc_format)
    if cfg.sample_rate > limit * (1 + 1e-9):
        bad.append(f"profileCfg digOutSampleRate={cfg.sample_rate / 1e3:g} ksps exceeds the {family.name}'s "
                   f"{limit / 1e3:g} ksps for {cfg.adc_format} samples (IF bandwidth "
                   f"{family.if_bandwidth / 1e6:g} MHz, "
                   "data sheet and rl_sensor.h); lower the sample rate")
    per_sample, per_chirp, frame_bytes = _sizes(cfg, family)
    if chirp_threshold < 1 or per_chirp * chirp_threshold > family.adc_buffer_bytes:
        bad.append(f"{chirp_threshold} chirp(s) of {cfg.num_samples} samples x {cfg.num_rx} Rx x {per_sample} bytes = "
                   f"{per_chirp * chirp_threshold} bytes do not fit the {family.name}'s {family.adc_buffer_bytes}-byte "
                   "ADC buffer (rl_sensor.h numAdcSamples, adcbufCfg ChirpThreshold); lower numAdcSamples, the "
                   "receivers or the chirp threshold")
    bad += _timing_violations(cfg, family, per_chirp, frame_bytes, lvds_stream)
    eth = family.ethernet_rate if ethernet_rate is None else ethernet_rate
    period = cfg.frame_periodicity
    data_rate = frame_bytes / period if period > 0 else math.inf
    if data_rate * 8 > eth:
        bad.append(f"{frame_bytes} bytes every {period * 1e3:g} ms = {data_rate * 8 / 1e6:.4g} Mbps exceeds the "
                   f"DCA1000's {eth / 1e6:g} Mbps Ethernet throughput (DCA1000EVM); lengthen frameCfg "
                   "framePeriodicity or shrink the frame")
    if bad:
        more = f" (and {len(bad) - 1} more: {'; '.join(bad[1:])})" if len(bad) > 1 else ""
        raise MeasuredFormatError(bad[0] + more)
    burst = max(per_chirp / (cfg.chirp_period + c.idle_time_offset) for c in cfg.chirps)
    return DeviceCheck(family=family.name, lanes=family.lvds_lanes, adc_bits=cfg.adc_bits, adc_format=cfg.adc_format,
                       bytes_per_sample=per_sample, bytes_per_chirp=per_chirp, frame_bytes=frame_bytes,
                       data_rate=data_rate, burst_rate=burst,
                       lvds_duty=burst * 8 / (family.lvds_lanes * family.max_lvds_lane_rate),
                       ethernet_duty=data_rate * 8 / eth, packets_per_frame=frame_bytes / DCA1000_PAYLOAD_BYTES,
                       lvds_header=None if lvds_stream is None else lvds_stream.enable_header)


def _timing_violations(cfg: TiChirpConfig, family: DeviceFamily, per_chirp: int, frame_bytes: int,
                       lvds_stream: LvdsStreamCfg | None) -> list[str]:
    """Frame timing, the lanes' word layout, the LVDS rate while chirping and ``lvdsStreamCfg``."""
    bad = []
    if cfg.frame_periodicity <= 0:
        bad.append("frameCfg framePeriodicity is 0 ms; give the frame period")
    elif cfg.frame_active_time > cfg.frame_periodicity * (1 + 1e-9):
        bad.append(f"the frame's chirps take {cfg.frame_active_time * 1e3:.4g} ms, longer than frameCfg "
                   f"framePeriodicity={cfg.frame_periodicity * 1e3:g} ms (mmWave SDK user's guide: the frame must "
                   "fit its period); lengthen the period or use fewer loops")
    window_end = cfg.adc_start_time + cfg.adc_sampling_time
    if window_end > cfg.ramp_end_time * (1 + 1e-9):
        bad.append(f"the ADC samples until {window_end * 1e6:.4g} us (adcStartTime + numAdcSamples/digOutSampleRate), "
                   f"after the ramp ends at rampEndTime={cfg.ramp_end_time * 1e6:.4g} us (TI's profile rule, E2E "
                   "thread 736001); lengthen rampEndTime or use fewer samples")
    lanes = family.lvds_lanes
    if lanes == 2 and cfg.is_complex and cfg.num_samples % 2:
        bad.append(f"numAdcSamples={cfg.num_samples} is odd: 2-lane complex data interleaves sample pairs "
                   "(I0 I1 Q0 Q1, DCA1000EVM user's guide); use an even sample count")
    word = 2 * (lanes if lanes == 2 else 1)
    if frame_bytes % word:
        bad.append(f"a frame of {frame_bytes} bytes is not a whole number of {word}-byte words across the "
                   f"{lanes} LVDS lanes (16-bit words per lane); change numAdcSamples or the loops")
    for i, chirp in enumerate(cfg.chirps):
        duration = cfg.chirp_period + chirp.idle_time_offset
        need = per_chirp * 8 / duration
        if need > lanes * family.max_lvds_lane_rate:
            bad.append(f"chirp {i}: {per_chirp} bytes in {duration * 1e6:.4g} us = {need / 1e6:.4g} Mbps exceeds "
                       f"{lanes} LVDS lanes x {family.max_lvds_lane_rate / 1e6:g} Mbps (data sheet, LVDS interface); "
                       "lengthen idleTime or use fewer samples/receivers")
            break
    if lvds_stream is not None:
        if lvds_stream.data_format != 1:
            bad.append(f"lvdsStreamCfg dataFmt={lvds_stream.data_format}: the DCA1000 records plain ADC samples "
                       "only with dataFmt 1 (ADC, mmWave SDK user's guide); set it to 1")
        if lvds_stream.enable_header:
            bad.append("lvdsStreamCfg enableHeader=1 puts an HSI header before each chirp's LVDS data, which the "
                       "raw-file reader does not expect; set enableHeader to 0")
        if lvds_stream.enable_sw:
            bad.append("lvdsStreamCfg enableSW=1 appends the demo's software data to each frame on LVDS, which the "
                       "raw-file reader does not expect; set enableSW to 0")
    return bad
