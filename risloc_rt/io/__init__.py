"""Files and figures: capture files, ``result.json`` and the console report, PNG plots.

Floor 4 of ``docs/architecture.md``. matplotlib is imported only when a plot is drawn
(:mod:`risloc_rt.io.plots`).
"""

from .capture_file import CaptureFormatError, load_capture, save_capture
from .report import CaseResult, estimation_errors, format_case, process_capture, report_capture, write_result

__all__ = ["CaptureFormatError", "CaseResult", "estimation_errors", "format_case", "load_capture", "process_capture",
           "report_capture", "save_capture", "write_result"]
