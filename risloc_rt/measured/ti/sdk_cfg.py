"""mmWave SDK 3.x ``.cfg`` files (the CLI commands sent to the radar): parse and write.

Only the commands that describe the waveform and the ADC are mapped (``channelCfg``, ``adcCfg``,
``adcbufCfg``, ``profileCfg``, ``chirpCfg``, ``frameCfg``, ``dfeDataOutputMode``); the processing
chain's commands (``cfarCfg``, ``guiMonitor``, …) are recognised and skipped. ``lvdsStreamCfg`` is
listed as skipped too (it says nothing about the waveform) but its fields are kept in
:attr:`ParsedSdkCfg.lvds_stream`, and ``adcbufCfg``'s ChirpThreshold in
:attr:`ParsedSdkCfg.chirp_threshold`, for the device check (``risloc_rt.measured.ti.devices``). Field orders follow
the SDK 3.5 CLI (``docs/measured-captures.md`` has the table).

``adcbufCfg``'s SampleSwap is the on-chip ADC buffer's I/Q order (mmWave SDK user's guide), kept in
``TiChirpConfig.iq_swap``; it does not say in which order the LVDS stream (the DCA1000 file) carries
I and Q, so the reader does not apply it (``dca1000.inspection.file_iq_swap``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import MeasuredFormatError
from .chirp_config import ADC_FORMATS, TiChirp, TiChirpConfig

__all__ = ["LvdsStreamCfg", "MAX_CHIRP_INDEX", "MAX_LOOPS", "ParsedSdkCfg", "format_sdk_cfg", "parse_sdk_cfg",
           "read_sdk_cfg"]

#: Argument counts of the mapped commands in mmWave SDK 3.x (adcbufCfg: 4 in SDK 1.x).
ARGUMENT_COUNTS: dict[str, tuple[int, ...]] = {
    "dfeDataOutputMode": (1,), "channelCfg": (3,), "adcCfg": (2,), "adcbufCfg": (4, 5),
    "profileCfg": (14,), "chirpCfg": (8,), "frameCfg": (7,), "lowPower": (2,),
}
#: Commands of the SDK demos that say nothing about the raw data; skipped.
SKIPPED = frozenset({
    "sensorStop", "sensorStart", "flushCfg", "guiMonitor", "cfarCfg", "cfarFovCfg", "aoaFovCfg",
    "multiObjBeamForming", "clutterRemoval", "calibDcRangeSig", "extendedMaxVelocity", "bpmCfg",
    "lvdsStreamCfg", "compRangeBiasAndRxChanPhase", "measureRangeBiasAndRxChanPhase",
    "CQRxSatMonitor", "CQSigImgMonitor", "analogMonitor", "calibData", "idlePowerCycle",
    "dynamicRACfarCfg", "staticRACfarCfg", "dynamicRangeAngleCfg", "dynamic2DAngleCfg",
    "staticRangeAngleCfg", "antGeometry0", "antGeometry1", "antPhaseRot", "fovCfg", "SceneryParam",
    "GatingParam", "StateParam", "AllocationParam", "MaxAcceleration", "trackingCfg",
    "presenceBoundaryBox", "sensorPosition", "boundaryBox", "staticBoundaryBox", "mpdBoundaryBox",
    "clusterCfg", "gatingParam", "stateParam", "allocationParam", "maxAcceleration", "zoneDef",
    "nearFieldCfg", "rangeSelCfg", "vitalSignsCfg", "motionDetection", "configDataPort",
    "queryDemoStatus", "mmwDemoCfg", "compressionCfg", "heatmapGenCfg", "intfMitigCfg", "gpAdcMeasConfig",
})


#: Highest chirp-configuration index of the xWR14xx/16xx/18xx/68xx devices (512 chirp configurations).
MAX_CHIRP_INDEX = 511
#: Most loops a frameCfg may ask for on these devices.
MAX_LOOPS = 255

@dataclass(frozen=True)
class LvdsStreamCfg:
    """``lvdsStreamCfg <subFrameIdx> <enableHeader> <dataFmt> <enableSW>`` (mmWave SDK 3.x user's guide, CLI).

    Parameters
    ----------
    enable_header : bool
        An HSI header before each chirp's data on LVDS.
    data_format : int
        The hardware stream: 0 off, 1 ADC samples, 4 CP + ADC + CQ.
    enable_sw : bool
        The demo's software (processed) data streamed after each frame.
    line : int
        The ``.cfg`` line number, for messages.
    """

    enable_header: bool
    data_format: int
    enable_sw: bool
    line: int = 0


@dataclass(frozen=True)
class ParsedSdkCfg:
    """Result of :func:`parse_sdk_cfg`.

    Attributes
    ----------
    config : TiChirpConfig
        The waveform and ADC description, SI units.
    skipped : tuple of (int, str)
        ``(line number, command)`` of the recognised commands that were not used.
    source : str
        The file name (or ``"<text>"``) the errors quote.
    chirp_threshold : int or None
        ``adcbufCfg``'s ChirpThreshold (chirps gathered in the ADC buffer), None without ``adcbufCfg``.
    lvds_stream : LvdsStreamCfg or None
        ``lvdsStreamCfg``'s fields, None when the file has none.
    """

    config: TiChirpConfig
    skipped: tuple[tuple[int, str], ...]
    source: str
    chirp_threshold: int | None = None
    lvds_stream: LvdsStreamCfg | None = None


def _number(tok: str, where: str, field: str) -> float:
    try:
        return float(tok)
    except ValueError:
        raise MeasuredFormatError(f"{where}: {field}={tok!r} is not a number") from None


def _integer(tok: str, where: str, field: str) -> int:
    try:
        return int(tok, 0)
    except ValueError:
        try:
            value = float(tok)
        except ValueError:
            value = None
        if value is not None and value.is_integer():
            return int(value)
        raise MeasuredFormatError(f"{where}: {field}={tok!r} must be an integer (decimal or 0x hex)") from None


def read_sdk_cfg(path: str | Path, *, strict: bool = True) -> ParsedSdkCfg:
    """:func:`parse_sdk_cfg` of a file (UTF-8 or ASCII).

    Parameters
    ----------
    path : path
        The mmWave SDK ``.cfg``.
    strict : bool, default True
        Unknown commands raise; with ``False`` they are skipped and listed.

    Returns
    -------
    ParsedSdkCfg
        The configuration in SI units, the skipped commands and the file name the errors quote.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise MeasuredFormatError(f"cannot read the config {path}: {exc.strerror}") from None
    return parse_sdk_cfg(text, source=str(path), strict=strict)


@dataclass(frozen=True)
class _CfgCommands:
    """The mapped commands of a ``.cfg``, by line, before their fields are read.

    ``single`` holds the commands given once (``channelCfg``, ``adcCfg``, …), ``profiles`` the
    ``profileCfg`` lines by profile id, ``chirps`` every ``chirpCfg`` line in file order; each as
    ``(line number, arguments)``.
    """

    source: str
    single: dict[str, tuple[int, list[str]]]
    profiles: dict[int, tuple[int, list[str]]]
    chirps: tuple[tuple[int, list[str]], ...]
    skipped: tuple[tuple[int, str], ...]
    lvds: tuple[int, list[str]] | None = None

    def where(self, command: str) -> str:
        """``source:line`` of a command given once."""
        return f"{self.source}:{self.single[command][0]}"


@dataclass(frozen=True)
class _FrameCommand:
    """``frameCfg``'s fields: the loop's chirp indices, loops, frames, period [s]; ``where`` for messages."""

    where: str
    start_idx: int
    end_idx: int
    num_loops: int
    num_frames: int
    period: float


def _command_lines(text: str, source: str, strict: bool) -> _CfgCommands:
    """Sort the lines into commands: skipped, refused (advanced frame, unknown, wrong argument count) or kept."""
    found: dict[str, tuple[int, list[str]]] = {}
    profiles: dict[int, tuple[int, list[str]]] = {}
    chirp_lines: list[tuple[int, list[str]]] = []
    skipped: list[tuple[int, str]] = []
    lvds: tuple[int, list[str]] | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("%", 1)[0].strip()
        if not line:
            continue
        cmd, *args = line.split()
        where = f"{source}:{lineno}"
        if cmd in SKIPPED:
            skipped.append((lineno, cmd))
            if cmd == "lvdsStreamCfg":
                lvds = (lineno, args)
            continue
        if cmd in ("advFrameCfg", "subFrameCfg"):
            raise MeasuredFormatError(f"{where}: {cmd} (advanced frame) is not supported; "
                                      "use a legacy frameCfg with dfeDataOutputMode 1")
        if cmd not in ARGUMENT_COUNTS:
            if strict:
                raise MeasuredFormatError(f"{where}: unknown command {cmd!r} (not an mmWave SDK 3.x CLI command); "
                                          "fix the typo, remove it, or pass strict=False to skip it")
            skipped.append((lineno, cmd))
            continue
        counts = ARGUMENT_COUNTS[cmd]
        if len(args) not in counts:
            hint = (" (a newer MCU+ SDK cfg, e.g. for AWR294x? only SDK 3.x field orders are supported)"
                    if len(args) > max(counts) else "")
            raise MeasuredFormatError(f"{where}: {cmd} takes {' or '.join(map(str, counts))} arguments in mmWave "
                                      f"SDK 3.x, got {len(args)}{hint}")
        if cmd == "profileCfg":
            pid = _integer(args[0], where, "profileId")
            if pid in profiles:
                raise MeasuredFormatError(f"{where}: profileCfg {pid} defined again (first at line "
                                          f"{profiles[pid][0]}); keep one")
            profiles[pid] = (lineno, args)
        elif cmd == "chirpCfg":
            chirp_lines.append((lineno, args))
        else:
            if cmd in found:
                raise MeasuredFormatError(f"{where}: {cmd} given again (first at line {found[cmd][0]}); keep one")
            found[cmd] = (lineno, args)
    return _CfgCommands(source=source, single=found, profiles=profiles, chirps=tuple(chirp_lines),
                        skipped=tuple(skipped), lvds=lvds)


def _check_required(cmds: _CfgCommands) -> None:
    """Every command a raw capture needs is there, and the output mode (when given) is frame-based."""
    source = cmds.source
    for cmd in ("channelCfg", "adcCfg", "frameCfg"):
        if cmd not in cmds.single:
            raise MeasuredFormatError(f"{source}: no {cmd} line; a raw capture needs channelCfg, adcCfg, "
                                      "profileCfg, chirpCfg and frameCfg")
    if not cmds.profiles:
        raise MeasuredFormatError(f"{source}: no profileCfg line; add the profile the chirps use")
    if not cmds.chirps:
        raise MeasuredFormatError(f"{source}: no chirpCfg line; add one chirpCfg per chirp of the loop")
    if "dfeDataOutputMode" in cmds.single:
        ln, args = cmds.single["dfeDataOutputMode"]
        mode = _integer(args[0], f"{source}:{ln}", "modeType")
        if mode != 1:
            raise MeasuredFormatError(f"{source}:{ln}: dfeDataOutputMode {mode} is not supported "
                                      "(only 1, frame-based chirps)")


def _channel_masks(cmds: _CfgCommands) -> tuple[int, int]:
    """``channelCfg``: (rxChannelEn, txChannelEn) bit masks."""
    args = cmds.single["channelCfg"][1]
    w = cmds.where("channelCfg")
    rx_mask, tx_mask = _integer(args[0], w, "rxChannelEn"), _integer(args[1], w, "txChannelEn")
    if rx_mask <= 0 or rx_mask > 0xFF:
        raise MeasuredFormatError(f"{w}: channelCfg rxChannelEn={args[0]} enables no receiver")
    return rx_mask, tx_mask


def _adc_format(cmds: _CfgCommands) -> tuple[int, str, bool]:
    """``adcCfg`` and ``adcbufCfg``, checked against each other: (ADC bits, ADC format, I/Q swap flag)."""
    ln, args = cmds.single["adcCfg"]
    w = cmds.where("adcCfg")
    bits_code, fmt_code = _integer(args[0], w, "numADCBits"), _integer(args[1], w, "adcOutputFmt")
    if bits_code not in (0, 1, 2):
        raise MeasuredFormatError(f"{w}: adcCfg numADCBits={bits_code} must be 0, 1 or 2 (12, 14, 16 bits)")
    if fmt_code not in (0, 1, 2):
        raise MeasuredFormatError(f"{w}: adcCfg adcOutputFmt={fmt_code} must be 0 (real), 1 (complex1x) "
                                  "or 2 (complex2x)")
    adc_format = ADC_FORMATS[fmt_code]
    iq_swap = False
    if "adcbufCfg" in cmds.single:
        args2 = cmds.single["adcbufCfg"][1]
        w2 = cmds.where("adcbufCfg")
        off = 1 if len(args2) == 5 else 0
        buf_fmt = _integer(args2[off], w2, "adcOutputFmt")
        if buf_fmt not in (0, 1):
            raise MeasuredFormatError(f"{w2}: adcbufCfg adcOutputFmt={buf_fmt} must be 0 (complex) or 1 (real)")
        if (buf_fmt == 1) != (adc_format == "real"):
            raise MeasuredFormatError(
                f"{w2}: adcbufCfg says {'real' if buf_fmt else 'complex'} samples but adcCfg (line {ln}) says "
                f"{adc_format}; make them agree")
        # SampleSwap (mmWave SDK 3.x user's guide, CLI adcbufCfg): the ADC *buffer*'s I/Q order, 0 = I in LSB,
        # Q in MSB; 1 = Q in LSB, I in MSB (the only value the SDK demos accept). It sets how the on-chip DSP/HWA
        # reads the buffer, not the LVDS stream the DCA1000 records (the corner-reflector capture, made with 1, has
        # I first): recorded in TiChirpConfig.iq_swap, and not applied by the reader's defaults.
        swap = _integer(args2[off + 1], w2, "sampleSwap")
        if swap not in (0, 1):
            raise MeasuredFormatError(f"{w2}: adcbufCfg sampleSwap={swap} must be 0 (I in LSB) or 1 (Q in LSB)")
        iq_swap = swap == 1
    return (12, 14, 16)[bits_code], adc_format, iq_swap


def _chirp_threshold(cmds: _CfgCommands) -> int | None:
    """``adcbufCfg``'s last field, ChirpThreshold (SDK 3.x: 5 arguments, SDK 1.x: 4), or None without it."""
    if "adcbufCfg" not in cmds.single:
        return None
    args = cmds.single["adcbufCfg"][1]
    return _integer(args[-1], cmds.where("adcbufCfg"), "chirpThreshold")


def _lvds_stream(cmds: _CfgCommands) -> LvdsStreamCfg | None:
    """``lvdsStreamCfg <subFrameIdx> <enableHeader> <dataFmt> <enableSW>``, or None without it."""
    if cmds.lvds is None:
        return None
    line, args = cmds.lvds
    where = f"{cmds.source}:{line}"
    if len(args) != 4:
        raise MeasuredFormatError(f"{where}: lvdsStreamCfg takes 4 arguments in mmWave SDK 3.x (subFrameIdx "
                                  f"enableHeader dataFmt enableSW), got {len(args)}")
    header, fmt, sw = (_integer(a, where, f) for a, f in zip(args[1:], ("enableHeader", "dataFmt", "enableSW")))
    return LvdsStreamCfg(enable_header=bool(header), data_format=fmt, enable_sw=bool(sw), line=line)


def _frame_command(cmds: _CfgCommands) -> _FrameCommand:
    """``frameCfg``: the loop's chirp indices, loops and frames checked against the devices' limits."""
    args = cmds.single["frameCfg"][1]
    wf = cmds.where("frameCfg")
    start_idx, end_idx = _integer(args[0], wf, "chirpStartIdx"), _integer(args[1], wf, "chirpEndIdx")
    num_loops, num_frames = _integer(args[2], wf, "numLoops"), _integer(args[3], wf, "numFrames")
    period = _number(args[4], wf, "framePeriodicity") / 1e3
    for what, idx in (("chirpStartIdx", start_idx), ("chirpEndIdx", end_idx)):
        if not 0 <= idx <= MAX_CHIRP_INDEX:
            raise MeasuredFormatError(f"{wf}: frameCfg {what}={idx} is outside 0…{MAX_CHIRP_INDEX} (the devices hold "
                                      f"{MAX_CHIRP_INDEX + 1} chirp configurations)")
    if end_idx < start_idx:
        raise MeasuredFormatError(f"{wf}: frameCfg chirpEndIdx={end_idx} < chirpStartIdx={start_idx}")
    if not 1 <= num_loops <= MAX_LOOPS:
        raise MeasuredFormatError(f"{wf}: frameCfg numLoops={num_loops} must be 1…{MAX_LOOPS}")
    if num_frames < 0:
        raise MeasuredFormatError(f"{wf}: frameCfg numFrames={num_frames} must be >= 0 (0 = until stopped)")
    return _FrameCommand(where=wf, start_idx=start_idx, end_idx=end_idx, num_loops=num_loops, num_frames=num_frames,
                         period=period)


def _chirps_by_index(cmds: _CfgCommands) -> dict[int, tuple[int, list[str]]]:
    """Every chirp index the ``chirpCfg`` lines define → its line (ranges expanded, each index defined once)."""
    by_index: dict[int, tuple[int, list[str]]] = {}
    for lnc, a in cmds.chirps:
        wc = f"{cmds.source}:{lnc}"
        lo, hi = _integer(a[0], wc, "startIdx"), _integer(a[1], wc, "endIdx")
        if not (0 <= lo <= MAX_CHIRP_INDEX and 0 <= hi <= MAX_CHIRP_INDEX):
            raise MeasuredFormatError(f"{wc}: chirpCfg startIdx={lo}, endIdx={hi} must lie in 0…{MAX_CHIRP_INDEX} "
                                      f"(the devices hold {MAX_CHIRP_INDEX + 1} chirp configurations)")
        if hi < lo:
            raise MeasuredFormatError(f"{wc}: chirpCfg endIdx={hi} < startIdx={lo}")
        for idx in range(lo, hi + 1):
            if idx in by_index:
                raise MeasuredFormatError(f"{wc}: chirp {idx} defined again (first at line {by_index[idx][0]})")
            by_index[idx] = (lnc, a)
    return by_index


def _loop_chirps(cmds: _CfgCommands, frame: _FrameCommand, tx_mask: int) -> tuple[tuple[TiChirp, ...], int]:
    """The chirps of the frame's loop (offsets in SI units) and the one profile id they all use."""
    by_index = _chirps_by_index(cmds)
    chirps: list[TiChirp] = []
    profile_ids: set[int] = set()
    for idx in range(frame.start_idx, frame.end_idx + 1):
        if idx not in by_index:
            raise MeasuredFormatError(f"{frame.where}: frameCfg uses chirp {idx}, which no chirpCfg defines")
        lnc, a = by_index[idx]
        wc = f"{cmds.source}:{lnc}"
        pid = _integer(a[2], wc, "profileId")
        if pid not in cmds.profiles:
            raise MeasuredFormatError(f"{wc}: chirpCfg uses profile {pid}, which no profileCfg defines")
        profile_ids.add(pid)
        mask = _integer(a[7], wc, "txEnable")
        if mask & ~tx_mask:
            raise MeasuredFormatError(f"{wc}: chirpCfg txEnable=0b{mask:b} uses transmitters that channelCfg "
                                      f"(line {cmds.single['channelCfg'][0]}) does not enable (0b{tx_mask:b})")
        chirps.append(TiChirp(tx_mask=mask, start_frequency_offset=_number(a[3], wc, "startFreqVar"),
                              slope_offset=_number(a[4], wc, "freqSlopeVar") * 1e9,
                              idle_time_offset=_number(a[5], wc, "idleTimeVar") / 1e6,
                              adc_start_time_offset=_number(a[6], wc, "adcStartTimeVar") / 1e6))
    if len(profile_ids) > 1:
        raise MeasuredFormatError(f"{frame.where}: the frame's chirps use profiles {sorted(profile_ids)}; only one "
                                  "profile per frame is supported")
    return tuple(chirps), profile_ids.pop()


def parse_sdk_cfg(text: str, *, source: str = "<text>", strict: bool = True) -> ParsedSdkCfg:
    """Parse an mmWave SDK 3.x ``.cfg`` into a :class:`TiChirpConfig`.

    Parameters
    ----------
    text : str
        The file's content: one ``command arg arg …`` per line; ``%`` starts a comment.
    source : str
        Name used in error messages.
    strict : bool, default True
        Unknown commands raise (they usually mean another SDK or a typo); with ``False`` they are
        skipped and listed in :attr:`ParsedSdkCfg.skipped`.

    Returns
    -------
    ParsedSdkCfg
        The configuration in SI units (Hz, s, Hz/s), the skipped commands and ``source``.

    Raises
    ------
    MeasuredFormatError
        A missing required command, a wrong argument count, a non-numeric field, an unknown
        command (``strict``), or inconsistent commands; the message names the line.
    """
    cmds = _command_lines(text, source, strict)
    _check_required(cmds)
    rx_mask, tx_mask = _channel_masks(cmds)
    adc_bits, adc_format, iq_swap = _adc_format(cmds)
    frame = _frame_command(cmds)
    chirps, profile_id = _loop_chirps(cmds, frame, tx_mask)
    lnp, p = cmds.profiles[profile_id]
    wp = f"{source}:{lnp}"
    try:
        config = TiChirpConfig(
            start_frequency=_number(p[1], wp, "startFreq") * 1e9,
            idle_time=_number(p[2], wp, "idleTime") / 1e6,
            adc_start_time=_number(p[3], wp, "adcStartTime") / 1e6,
            ramp_end_time=_number(p[4], wp, "rampEndTime") / 1e6,
            slope=_number(p[7], wp, "freqSlopeConst") * 1e12,
            tx_start_time=_number(p[8], wp, "txStartTime") / 1e6,
            num_samples=_integer(p[9], wp, "numAdcSamples"),
            sample_rate=_number(p[10], wp, "digOutSampleRate") * 1e3,
            rx_gain_db=_number(p[13], wp, "rxGain"),
            rx_mask=rx_mask, tx_mask=tx_mask, chirps=chirps, num_loops=frame.num_loops,
            num_frames=frame.num_frames, frame_periodicity=frame.period, adc_bits=adc_bits,
            adc_format=adc_format, iq_swap=iq_swap)
    except MeasuredFormatError as exc:
        raise MeasuredFormatError(f"{wp}: profileCfg: {exc}") from None
    return ParsedSdkCfg(config=config, skipped=cmds.skipped, source=source, chirp_threshold=_chirp_threshold(cmds),
                        lvds_stream=_lvds_stream(cmds))


def _g(value: float) -> str:
    """Shortest text that reads back as the same float."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def format_sdk_cfg(config: TiChirpConfig, *, comment: str | None = None) -> str:
    """The mmWave SDK 3.x ``.cfg`` text of ``config`` (the inverse of :func:`parse_sdk_cfg`).

    Writes ``sensorStop``, ``flushCfg``, ``dfeDataOutputMode 1``, ``channelCfg``, ``adcCfg``,
    ``adcbufCfg -1 …``, ``lowPower 0 0``, ``profileCfg 0 …``, one ``chirpCfg`` per chirp of the
    loop, ``frameCfg`` and ``sensorStart``; ``comment`` lines go first, after ``%``.
    Transmit power, phase shifter and HPF corners are written as 0.

    Parameters
    ----------
    config : TiChirpConfig
        SI units inside; written in the file's units (GHz, µs, MHz/µs, ksps, ms).
    comment : str, optional
        Lines written first, each after ``%``.

    Returns
    -------
    str
        The file's text, one command per line, ending with a newline.
    """
    c = config
    lines = [f"% {ln}" for ln in (comment or "").splitlines()]
    lines += ["sensorStop", "flushCfg", "dfeDataOutputMode 1",
              f"channelCfg {c.rx_mask} {c.tx_mask} 0",
              f"adcCfg {(12, 14, 16).index(c.adc_bits)} {ADC_FORMATS.index(c.adc_format)}",
              f"adcbufCfg -1 {0 if c.is_complex else 1} {int(c.iq_swap)} 1 1",
              "lowPower 0 0",
              "profileCfg 0 " + " ".join([
                  _g(c.start_frequency / 1e9), _g(c.idle_time * 1e6), _g(c.adc_start_time * 1e6),
                  _g(c.ramp_end_time * 1e6), "0", "0", _g(c.slope / 1e12), _g(c.tx_start_time * 1e6),
                  str(c.num_samples), _g(c.sample_rate / 1e3), "0", "0",
                  _g(c.rx_gain_db if c.rx_gain_db is not None else 30)])]
    for i, ch in enumerate(c.chirps):
        lines.append(f"chirpCfg {i} {i} 0 {_g(ch.start_frequency_offset)} {_g(ch.slope_offset / 1e9)} "
                     f"{_g(ch.idle_time_offset * 1e6)} {_g(ch.adc_start_time_offset * 1e6)} {ch.tx_mask}")
    lines.append(f"frameCfg 0 {c.chirps_per_loop - 1} {c.num_loops} {c.num_frames} "
                 f"{_g(c.frame_periodicity * 1e3)} 1 0")
    lines.append("sensorStart")
    return "\n".join(lines) + "\n"
