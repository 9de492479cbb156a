"""Experiment emulators: what a real DCA1000 experiment leaves on disk, synthesised (tests, benchmarks, demos).

Room 4 of :mod:`risloc_rt.measured` (imports :mod:`..sweep`, :mod:`..dca1000`, :mod:`..ti`, :mod:`..errors`
and ``model``):

- :mod:`.raw_files`: a cube ``[F, K, V, N]`` → DCA1000 raw files + ``.cfg``, with ADC impairments;
- :mod:`.experiment`: a simulated ``Capture`` → the folder of one sweep (raw files, ``.cfg``, ``sweep.toml``);
- :mod:`.recording`: a scenario → a whole recording (lead frames, RIS sync, a drifting RIS clock, leakage);
- :mod:`.time_division`: one capture per RIS → a recording of several RISs, each sweeping in its own slot;
- :mod:`.dca1000_server`: a DCA1000 on loopback (config protocol, data stream at the real rate, faults);
- :mod:`.radar_cli_server`: the radar's CLI port on a pseudo-terminal (prompts, ``Done``, refusals, silence).
"""

from .dca1000_server import EmulatedDca1000, StreamFaults
from .experiment import EmulatedExperiment, dca1000_radar, emulate_capture, full_scale
from .radar_cli_server import EmulatedRadarCli
from .raw_files import AdcImpairments, EmulatedCapture, QuantizedCube, Recording, quantize_cube, write_raw_capture
from .recording import EmulatedRecording, RecordingPlan, emulate_recording
from .time_division import EmulatedTimeDivision, emulate_time_division, idle_frame

__all__ = [
    "EmulatedDca1000", "EmulatedRadarCli", "StreamFaults",
    "AdcImpairments", "EmulatedCapture", "EmulatedExperiment", "EmulatedRecording", "EmulatedTimeDivision", "QuantizedCube", "Recording",
    "RecordingPlan", "dca1000_radar", "emulate_capture", "emulate_recording", "full_scale", "quantize_cube",
    "write_raw_capture", "emulate_time_division", "idle_frame",
]
