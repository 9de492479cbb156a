"""Measured TI DCA1000 captures: raw ADC reader, configuration parsers, inspection, sweep import and emulators.

The package is built in rooms whose imports point one way (a room imports the rooms before it,
never one after; ``tests/measured/test_measured_rooms.py`` checks it):

0. :mod:`.errors` — :class:`MeasuredFormatError` and the text-file reader;
1. :mod:`.ti` — TI radar configurations: :class:`TiChirpConfig`, mmWave SDK ``.cfg``, Studio JSON;
2. :mod:`.dca1000` — raw data: byte layouts, split files, packets, the streaming reader, channels, inspection;
3. :mod:`.sweep` — a recorded RIS sweep: schedule, RIS timing, alignment, leakage removal, the import;
4. :mod:`.emulate` — experiment emulators: raw files, an experiment's folder, a whole recording;
5. :mod:`.compare` — against the traced hall: hall model, calibration file and fit, comparison and its page
   (not re-exported here: it loads ``hall`` and ``io``);
6. :mod:`.live` — recording from a radar and a DCA1000 on Linux: the radar's CLI port, the DCA1000
   control link, the data receiver, the recording writer, live sweeps (not re-exported here: it
   opens serial ports and sockets; ``pyserial`` is imported only when a port is opened).

Rooms 0-2 and :mod:`.emulate.raw_files` are numpy/scipy (plus ``dsp``) only; the sweep import
(``import_capture``) and the experiment emulators build and take a ``risloc_rt.model.Capture``
(floor 5 may import the floors below). Formats, byte layouts and error messages:
``docs/measured-captures.md``; sweep schedules: ``docs/formats.md``.

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

from .dca1000.channels import combine_channels
from .dca1000.inspection import CaptureInspection, Peak, file_iq_swap, inspect_capture, plot_inspection
from .dca1000.packets import DroppedPackets, PacketIssue, detect_payload_size, pack_header
from .dca1000.raw_layout import RawLayout, decode_frames, encode_frames
from .dca1000.reader import CaptureInfo, FrameBlock, RawCapture, iter_frames, open_raw, read_raw
from .dca1000.split_files import capture_files
from .emulate.experiment import EmulatedExperiment, dca1000_radar, emulate_capture
from .emulate.raw_files import (AdcImpairments, EmulatedCapture, QuantizedCube, Recording, quantize_cube,
                                write_raw_capture)
from .emulate.recording import EmulatedRecording, RecordingPlan, emulate_recording
from .emulate.time_division import EmulatedTimeDivision, emulate_time_division
from .errors import MeasuredFormatError
from .sweep.alignment import RisPowerSeries, SweepAlignment, fit_alignment, manual_alignment, ris_power_series
from .sweep.importer import default_processing, import_capture, import_captures
from .sweep.leakage import LEAKAGE_METHODS, apply_range_gate, range_gate_basis, subtract_background
from .sweep.ris_timing import RisProgram, chirp_states
from .sweep.schedule import (SweepSchedule, format_sweep_schedule, parse_sweep_schedule, read_sweep_schedule,
                             write_sweep_schedule)
from .sweep.schedules import (SweepSchedules, format_sweep_schedules, parse_sweep_schedules, read_sweep_schedules,
                              write_sweep_schedules)
from .ti.chirp_config import TiChirp, TiChirpConfig, device_steps, slope_step, start_frequency_step
from .ti.config_file import load_config
from .ti.sdk_cfg import ParsedSdkCfg, format_sdk_cfg, parse_sdk_cfg, read_sdk_cfg
from .ti.studio_json import ParsedStudioJson, parse_studio_json, read_studio_json

__all__ = [
    "EmulatedRecording", "LEAKAGE_METHODS", "RecordingPlan", "RisPowerSeries", "RisProgram", "SweepAlignment",
    "apply_range_gate", "chirp_states", "emulate_recording", "fit_alignment", "manual_alignment", "range_gate_basis",
    "ris_power_series", "subtract_background",
    "AdcImpairments", "CaptureInfo", "CaptureInspection", "DroppedPackets", "EmulatedCapture", "EmulatedExperiment",
    "SweepSchedule", "dca1000_radar", "default_processing", "emulate_capture", "format_sweep_schedule",
    "import_capture", "parse_sweep_schedule", "read_sweep_schedule", "write_sweep_schedule",
    "FrameBlock", "MeasuredFormatError", "PacketIssue", "ParsedSdkCfg", "ParsedStudioJson", "Peak",
    "QuantizedCube", "RawCapture", "RawLayout", "Recording", "TiChirp", "TiChirpConfig", "capture_files",
    "combine_channels", "decode_frames", "detect_payload_size", "encode_frames", "format_sdk_cfg",
    "file_iq_swap", "inspect_capture", "iter_frames", "load_config", "open_raw", "pack_header", "parse_sdk_cfg",
    "parse_studio_json", "plot_inspection", "quantize_cube", "read_raw", "read_sdk_cfg", "read_studio_json",
    "device_steps", "slope_step", "start_frequency_step", "write_raw_capture",
    "EmulatedTimeDivision", "SweepSchedules", "emulate_time_division", "format_sweep_schedules", "import_captures",
    "parse_sweep_schedules", "read_sweep_schedules", "write_sweep_schedules",
]
