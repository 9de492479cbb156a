"""mmWave Studio's JSON export (``*.mmwave.json``): the waveform, ADC and LVDS settings.

Path read (``mmWaveDevices`` may be a list of devices or a single object)::

    mmWaveDevices[i].rfConfig.rlChanCfg_t            rxChannelEn, txChannelEn
    mmWaveDevices[i].rfConfig.rlAdcOutCfg_t.fmt      b2AdcBits (0/1/2 = 12/14/16), b2AdcOutFmt (0/1/2)
    mmWaveDevices[i].rfConfig.rlProfiles[j].rlProfileCfg_t
        startFreqConst_GHz, idleTimeConst_usec, adcStartTimeConst_usec, rampEndTime_usec,
        freqSlopeConst_MHz_usec, txStartTime_usec, numAdcSamples, digOutSampleRate (ksps), rxGain_dB
    mmWaveDevices[i].rfConfig.rlChirps[j].rlChirpCfg_t
        chirpStartIdx, chirpEndIdx, profileId, startFreqVar_MHz, freqSlopeVar_KHz_usec,
        idleTimeVar_usec, adcStartTimeVar_usec, txEnable
    mmWaveDevices[i].rfConfig.rlFrameCfg_t           chirpStartIdx, chirpEndIdx, numLoops, numFrames,
                                                     framePeriodicity_msec
    mmWaveDevices[i].rawDataCaptureConfig.rlDevDataFmtCfg_t.iqSwapSel   (optional; 0 I first, 1 Q first on LVDS)
    mmWaveDevices[i].rawDataCaptureConfig.rlDevLaneEnable_t.laneEn      (optional, lane bit mask)

Masks and codes may be numbers or strings (``"0xF"``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import MeasuredFormatError
from .chirp_config import ADC_FORMATS, TiChirp, TiChirpConfig
from .sdk_cfg import MAX_CHIRP_INDEX, MAX_LOOPS

__all__ = ["ParsedStudioJson", "parse_studio_json", "read_studio_json"]


@dataclass(frozen=True)
class ParsedStudioJson:
    """Result of :func:`parse_studio_json`.

    Attributes
    ----------
    config : TiChirpConfig
        The waveform and ADC description, SI units.
    lanes : int or None
        LVDS lanes enabled (popcount of ``laneEn``), None when the export does not say.
    device_index : int
        Which entry of ``mmWaveDevices`` was read.
    source : str
        File name used in messages.
    """

    config: TiChirpConfig
    lanes: int | None
    device_index: int
    source: str


class _Node:
    """A JSON object with its dotted path, for error messages that say where a key is missing."""

    def __init__(self, value: Any, path: str, source: str) -> None:
        self.value, self.path, self.source = value, path, source

    def child(self, key: str | int, *, optional: bool = False) -> "_Node | None":
        v = self.value
        ok = (isinstance(key, int) and isinstance(v, list) and -len(v) <= key < len(v)) or \
             (isinstance(key, str) and isinstance(v, dict) and key in v)
        path = f"{self.path}[{key}]" if isinstance(key, int) else f"{self.path}.{key}".lstrip(".")
        if not ok:
            if optional:
                return None
            raise MeasuredFormatError(f"{self.source}: {path} is missing; is this an mmWave Studio JSON export?")
        return _Node(v[key], path, self.source)

    def number(self, key: str) -> float:
        node = self.child(key)
        v = node.value
        try:
            return float(int(v, 0)) if isinstance(v, str) and v.lower().startswith("0x") else float(v)
        except (TypeError, ValueError):
            raise MeasuredFormatError(f"{self.source}: {node.path}={v!r} is not a number") from None

    def integer(self, key: str) -> int:
        node = self.child(key)
        v = node.value
        try:
            if isinstance(v, str):
                return int(v, 0)
            if isinstance(v, float) and v.is_integer():
                return int(v)
            if isinstance(v, int) and not isinstance(v, bool):
                return v
        except ValueError:
            pass
        raise MeasuredFormatError(f"{self.source}: {node.path}={v!r} must be an integer (or '0x…' text)")


def _check_chirp_range(node: _Node, start: int, end: int) -> None:
    """``chirpStartIdx`` ≤ ``chirpEndIdx``, both within the devices' chirp configurations 0…511."""
    for what, idx in (("chirpStartIdx", start), ("chirpEndIdx", end)):
        if not 0 <= idx <= MAX_CHIRP_INDEX:
            raise MeasuredFormatError(f"{node.source}: {node.path}.{what}={idx} is outside 0…{MAX_CHIRP_INDEX} (the "
                                      f"devices hold {MAX_CHIRP_INDEX + 1} chirp configurations); fix the export")
    if end < start:
        raise MeasuredFormatError(f"{node.source}: {node.path}: chirpEndIdx={end} < chirpStartIdx={start}")


def read_studio_json(path: str | Path, *, device_index: int = 0) -> ParsedStudioJson:
    """:func:`parse_studio_json` of a file.

    Parameters
    ----------
    path : path
        The mmWave Studio JSON export.
    device_index : int, default 0
        Device of ``mmWaveDevices`` to read.

    Returns
    -------
    ParsedStudioJson
        The configuration in SI units, the LVDS lanes (or None), the device read and the file name.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise MeasuredFormatError(f"cannot read the config {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise MeasuredFormatError(f"{path}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    return parse_studio_json(data, source=str(path), device_index=device_index)


def _raw_capture_config(dev: _Node, source: str) -> tuple[bool, int | None]:
    """``rawDataCaptureConfig``: (Q first on LVDS, lanes enabled or None); both optional."""
    raw = dev.child("rawDataCaptureConfig", optional=True)
    iq_swap, lanes = False, None
    if raw is None:
        return iq_swap, lanes
    dfmt = raw.child("rlDevDataFmtCfg_t", optional=True)
    if dfmt is not None and dfmt.child("iqSwapSel", optional=True) is not None:
        # mmWaveLink rl_device.h, rlDevDataFmtCfg_t: 0 = I first (RL_DEV_I_FIRST), 1 = Q first (RL_DEV_Q_FIRST);
        # rlDeviceSetDataFmtConfig sets the LVDS/CSI2 output format, so this is the file's order.
        sel = dfmt.integer("iqSwapSel")
        if sel not in (0, 1):
            raise MeasuredFormatError(f"{source}: {dfmt.path}.iqSwapSel={sel} must be 0 (I first) or 1 (Q first)")
        iq_swap = sel == 1
    lane = raw.child("rlDevLaneEnable_t", optional=True)
    if lane is not None and lane.child("laneEn", optional=True) is not None:
        lanes = bin(lane.integer("laneEn")).count("1")
    return iq_swap, lanes


def parse_studio_json(data: dict, *, source: str = "<json>", device_index: int = 0) -> ParsedStudioJson:
    """Map an mmWave Studio JSON export onto a :class:`TiChirpConfig`.

    Parameters
    ----------
    data : dict
        The decoded JSON document.
    source : str
        Name used in error messages.
    device_index : int, default 0
        Device of ``mmWaveDevices`` to read (cascade boards list several).

    Returns
    -------
    ParsedStudioJson
        The configuration in SI units (Hz, s, Hz/s), the LVDS lanes (or None), the device read, ``source``.

    Raises
    ------
    MeasuredFormatError
        A missing key (named by its path), a non-numeric field, several profiles in the frame,
        a frame using chirps no ``rlChirps`` entry defines, a chirp index outside the devices'
        0…511 or ``numLoops`` outside 1…255 (as :func:`~.sdk_cfg.parse_sdk_cfg`; ranges are never
        expanded, so ``chirpEndIdx = 1e10`` costs no memory).
    """
    root = _Node(data, "", source)
    devices = root.child("mmWaveDevices")
    dev = devices.child(device_index) if isinstance(devices.value, list) else devices
    rf = dev.child("rfConfig")
    chan = rf.child("rlChanCfg_t")
    rx_mask, tx_mask = chan.integer("rxChannelEn"), chan.integer("txChannelEn")
    fmt = rf.child("rlAdcOutCfg_t").child("fmt")
    bits_code, fmt_code = fmt.integer("b2AdcBits"), fmt.integer("b2AdcOutFmt")
    if bits_code not in (0, 1, 2):
        raise MeasuredFormatError(f"{source}: {fmt.path}.b2AdcBits={bits_code} must be 0, 1 or 2 (12/14/16 bits)")
    if fmt_code not in (0, 1, 2):
        raise MeasuredFormatError(f"{source}: {fmt.path}.b2AdcOutFmt={fmt_code} must be 0 (real), "
                                  "1 (complex1x) or 2 (complex2x)")
    frame = rf.child("rlFrameCfg_t")
    start_idx, end_idx = frame.integer("chirpStartIdx"), frame.integer("chirpEndIdx")
    _check_chirp_range(frame, start_idx, end_idx)
    num_loops = frame.integer("numLoops")
    if not 1 <= num_loops <= MAX_LOOPS:
        raise MeasuredFormatError(f"{source}: {frame.path}.numLoops={num_loops} must be 1…{MAX_LOOPS}")

    # rlChirps ranges are kept as ranges (a later entry overrides an earlier one), never expanded
    # index by index: the frame's loop (at most MAX_CHIRP_INDEX + 1 chirps) is all that is built.
    chirp_nodes = rf.child("rlChirps")
    ranges: list[tuple[int, int, _Node]] = []
    for j in range(len(chirp_nodes.value) if isinstance(chirp_nodes.value, list) else 0):
        c = chirp_nodes.child(j).child("rlChirpCfg_t")
        lo, hi = c.integer("chirpStartIdx"), c.integer("chirpEndIdx")
        _check_chirp_range(c, lo, hi)
        ranges.append((lo, hi, c))
    chirps, profile_ids = [], set()
    for idx in range(start_idx, end_idx + 1):
        c = next((node for lo, hi, node in reversed(ranges) if lo <= idx <= hi), None)
        if c is None:
            raise MeasuredFormatError(f"{source}: {frame.path} uses chirp {idx}, which no rlChirps entry defines")
        profile_ids.add(c.integer("profileId"))
        chirps.append(TiChirp(tx_mask=c.integer("txEnable"),
                              start_frequency_offset=c.number("startFreqVar_MHz") * 1e6,
                              slope_offset=c.number("freqSlopeVar_KHz_usec") * 1e9,
                              idle_time_offset=c.number("idleTimeVar_usec") / 1e6,
                              adc_start_time_offset=c.number("adcStartTimeVar_usec") / 1e6))
    if len(profile_ids) > 1:
        raise MeasuredFormatError(f"{source}: the frame's chirps use profiles {sorted(profile_ids)}; "
                                  "only one profile per frame is supported")
    pid = profile_ids.pop()
    profiles = rf.child("rlProfiles")
    prof = None
    for j in range(len(profiles.value) if isinstance(profiles.value, list) else 0):
        p = profiles.child(j).child("rlProfileCfg_t")
        if p.integer("profileId") == pid:
            prof = p
    if prof is None:
        raise MeasuredFormatError(f"{source}: {profiles.path} has no profile {pid}, which the chirps use")

    iq_swap, lanes = _raw_capture_config(dev, source)
    gain = prof.child("rxGain_dB", optional=True)
    try:
        config = TiChirpConfig(
            start_frequency=prof.number("startFreqConst_GHz") * 1e9,
            idle_time=prof.number("idleTimeConst_usec") / 1e6,
            adc_start_time=prof.number("adcStartTimeConst_usec") / 1e6,
            ramp_end_time=prof.number("rampEndTime_usec") / 1e6,
            slope=prof.number("freqSlopeConst_MHz_usec") * 1e12,
            tx_start_time=prof.number("txStartTime_usec") / 1e6,
            num_samples=prof.integer("numAdcSamples"),
            sample_rate=prof.number("digOutSampleRate") * 1e3,
            rx_gain_db=None if gain is None else prof.number("rxGain_dB"),
            rx_mask=rx_mask, tx_mask=tx_mask, chirps=tuple(chirps), num_loops=num_loops,
            num_frames=frame.integer("numFrames"), frame_periodicity=frame.number("framePeriodicity_msec") / 1e3,
            adc_bits=(12, 14, 16)[bits_code], adc_format=ADC_FORMATS[fmt_code], iq_swap=iq_swap)
    except MeasuredFormatError as exc:
        raise MeasuredFormatError(f"{source}: {dev.path or 'mmWaveDevices'}: {exc}") from None
    return ParsedStudioJson(config=config, lanes=lanes, device_index=device_index, source=source)
