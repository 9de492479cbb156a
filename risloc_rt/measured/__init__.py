"""Measured TI DCA1000 captures: raw ADC reader, configuration parsers, inspection and a binary emulator.

Pure numpy/scipy (plus ``dsp``); never imports the rest of ``risloc_rt``. Formats, byte layouts
and error messages: ``docs/measured-captures.md``.

Axis order: the reader returns ``complex64 [F, K, V, N]``: frames, loops (chirps per virtual
channel), virtual channels (chirp of the TDM loop major, receiver minor: ``v = c·R + r``),
ADC samples, in ADC counts, with the project's sign convention (``I − jQ``) unless
``convention="ti"``. :func:`combine_channels` gives the localization cube ``[F, K, N]``.

>>> from risloc_rt import measured
>>> cfg = measured.read_sdk_cfg("profile.cfg").config              # TiChirpConfig, SI units
>>> layout = measured.RawLayout.from_config(cfg, lanes=2)
>>> capture = measured.read_raw("adc_data_Raw_0.bin", layout, expected_frames=cfg.num_frames)
>>> cube = measured.combine_channels(capture.cube, channels=0)      # [F, K, N]
>>> radar = cfg.to_radar_config()                                   # dsp.RadarConfig
>>> report = measured.inspect_capture("adc_data_Raw_0.bin", "profile.cfg"); print(report.to_json())
"""

from .channels import combine_channels
from .dca1000 import CaptureInfo, FrameBlock, RawCapture, iter_frames, open_raw, read_raw
from .emulate_raw import (AdcImpairments, EmulatedCapture, QuantizedCube, Recording, quantize_cube,
                          write_raw_capture)
from .errors import MeasuredFormatError
from .files import capture_files
from .inspect import CaptureInspection, Flag, Peak, inspect_capture, load_config, plot_inspection
from .layout import RawLayout, decode_frames, encode_frames
from .packets import DroppedPackets, PacketIssue, detect_payload_size, pack_header
from .sdk_cfg import ParsedSdkCfg, format_sdk_cfg, parse_sdk_cfg, read_sdk_cfg
from .studio_json import ParsedStudioJson, parse_studio_json, read_studio_json
from .ti_config import TiChirp, TiChirpConfig, slope_step, start_frequency_step

__all__ = [
    "AdcImpairments", "CaptureInfo", "CaptureInspection", "DroppedPackets", "EmulatedCapture", "Flag",
    "FrameBlock", "MeasuredFormatError", "PacketIssue", "ParsedSdkCfg", "ParsedStudioJson", "Peak",
    "QuantizedCube", "RawCapture", "RawLayout", "Recording", "TiChirp", "TiChirpConfig", "capture_files",
    "combine_channels", "decode_frames", "detect_payload_size", "encode_frames", "format_sdk_cfg",
    "inspect_capture", "iter_frames", "load_config", "open_raw", "pack_header", "parse_sdk_cfg",
    "parse_studio_json", "plot_inspection", "quantize_cube", "read_raw", "read_sdk_cfg", "read_studio_json",
    "slope_step", "start_frequency_step", "write_raw_capture",
]
