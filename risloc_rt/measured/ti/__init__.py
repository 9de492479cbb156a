"""TI radar configurations: the chirp/frame description in SI units, mmWave SDK ``.cfg`` and mmWave Studio JSON.

Room 1 of :mod:`risloc_rt.measured` (imports only :mod:`..errors` and ``dsp``):

- :mod:`.chirp_config`: :class:`TiChirpConfig` (chirps, loops, frames, ADC) → ``dsp.RadarConfig``;
- :mod:`.sdk_cfg`: mmWave SDK 3.x ``.cfg`` parser and writer;
- :mod:`.studio_json`: mmWave Studio JSON export parser;
- :mod:`.config_file`: either file, by its suffix;
- :mod:`.devices`: the device families (IWR6843, xWR1843, xWR1642, …) and a ``.cfg`` checked against their limits.
"""

from .chirp_config import (ADC_FORMATS, AdcFormat, TiChirp, TiChirpConfig, device_steps, slope_step,
                           start_frequency_step)
from .config_file import load_config
from .devices import DEVICE_FAMILIES, DeviceCheck, DeviceFamily, check_device_config, device_family
from .sdk_cfg import ParsedSdkCfg, format_sdk_cfg, parse_sdk_cfg, read_sdk_cfg
from .studio_json import ParsedStudioJson, parse_studio_json, read_studio_json

__all__ = [
    "DEVICE_FAMILIES", "DeviceCheck", "DeviceFamily", "check_device_config", "device_family",
    "ADC_FORMATS", "AdcFormat", "ParsedSdkCfg", "ParsedStudioJson", "TiChirp", "TiChirpConfig", "format_sdk_cfg",
    "load_config", "parse_sdk_cfg", "parse_studio_json", "read_sdk_cfg", "read_studio_json", "device_steps", "slope_step",
    "start_frequency_step",
]
