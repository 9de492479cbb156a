"""Experiment emulators: what a real DCA1000 experiment leaves on disk, synthesised (tests, benchmarks, demos).

Room 4 of :mod:`risloc_rt.measured` (imports :mod:`..sweep`, :mod:`..dca1000`, :mod:`..ti`, :mod:`..errors`
and ``model``):

- :mod:`.raw_files`: a cube ``[F, K, V, N]`` → DCA1000 raw files + ``.cfg``, with ADC impairments;
- :mod:`.experiment`: a simulated ``Capture`` → the folder of one sweep (raw files, ``.cfg``, ``sweep.toml``);
- :mod:`.recording`: a scenario → a whole recording (lead frames, RIS sync, a drifting RIS clock, leakage).
"""

from .experiment import EmulatedExperiment, dca1000_radar, emulate_capture, full_scale
from .raw_files import AdcImpairments, EmulatedCapture, QuantizedCube, Recording, quantize_cube, write_raw_capture
from .recording import EmulatedRecording, RecordingPlan, emulate_recording

__all__ = [
    "AdcImpairments", "EmulatedCapture", "EmulatedExperiment", "EmulatedRecording", "QuantizedCube", "Recording",
    "RecordingPlan", "dca1000_radar", "emulate_capture", "emulate_recording", "full_scale", "quantize_cube",
    "write_raw_capture",
]
