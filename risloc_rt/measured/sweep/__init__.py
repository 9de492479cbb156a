"""A recorded RIS sweep: the sweep schedule, the RIS's timing, alignment, self-interference removal, the import.

Room 3 of :mod:`risloc_rt.measured` (imports :mod:`..dca1000`, :mod:`..ti`, :mod:`..errors` and ``model``):

- :mod:`.ris_timing`: the RIS's program in radar time (sync, beams, a drifting clock): chirp states;
- :mod:`.schedule`: sweep schedule files of one RIS (``sweep.toml``: beams, frames per beam, first frame, RIS, truth);
- :mod:`.schedules`: several RISs in time division (``[[ris]]`` tables, their slots, ``[schedule]``);
- :mod:`.schedule_fields`: the TOML fields both read (one-line errors, memory checks) and the writer's values;
- :mod:`.leakage`: self-interference removal (Slepian range gate, RIS-off background subtraction);
- :mod:`.alignment`: ``first_frame = "auto"``: RIS power per frame, program fit, frames and confidence;
- :mod:`.importer`: raw recording + configuration + schedule → ``model.Capture``.
"""

from .alignment import (ASSEMBLE_MODES, DEFAULT_ASSEMBLE, SPAN_PREFERENCE, RisPowerSeries, ScheduleCheck, SweepAlignment,
                        check_first_frame, fit_alignment, manual_alignment, ris_power_series, select_chirps)
from .importer import DEFAULT_LEAKAGE, default_processing, import_capture, import_captures
from .leakage import DEFAULT_GATE_RANGE, LEAKAGE_METHODS, apply_range_gate, range_gate_basis, subtract_background
from .ris_timing import MAX_SYNC_CHIPS, OFF, SYNC, RisProgram, chirp_fractions, chirp_states
from .schedule import (SweepSchedule, format_sweep_schedule, parse_sweep_schedule, read_sweep_schedule,
                       write_sweep_schedule)
from .schedules import (SweepSchedules, format_sweep_schedules, parse_sweep_schedules, read_sweep_schedules,
                        write_sweep_schedules)

__all__ = [
    "ASSEMBLE_MODES", "DEFAULT_ASSEMBLE", "MAX_SYNC_CHIPS", "SPAN_PREFERENCE", "ScheduleCheck", "check_first_frame",
    "select_chirps",
    "DEFAULT_GATE_RANGE", "DEFAULT_LEAKAGE", "LEAKAGE_METHODS", "OFF", "RisPowerSeries", "RisProgram", "SYNC",
    "SweepAlignment", "SweepSchedule", "apply_range_gate", "chirp_fractions", "chirp_states", "default_processing",
    "fit_alignment", "format_sweep_schedule", "import_capture", "manual_alignment", "parse_sweep_schedule",
    "range_gate_basis", "read_sweep_schedule", "ris_power_series", "subtract_background", "write_sweep_schedule",
    "SweepSchedules", "format_sweep_schedules", "import_captures", "parse_sweep_schedules", "read_sweep_schedules",
    "write_sweep_schedules",
]
