"""The signal model: scenario → paths → eq. (1) beat cube → capture (numpy only).

Floor 1 of ``docs/architecture.md``: imports ``dsp`` and nothing else of risloc-rt.
"""

from .beat import add_noise, beat_cube
from .builder import RisMisconfiguredWarning, analytic_scenario
from .capture import Capture, provenance
from .link_budget import carrier_phase, one_way_free_space_gain, point_target_gain, ris_loopback_gain
from .paths import PathSet, select_paths, shift_paths
from .plate import Plate, plate_rcs, plate_scattering
from .ris import RisConfig, RisMode, ris_response
from .scenario import PAPER_CASES, PointTarget, Scenario, Truth, analytic_paths, paper_scenario
from .simulate import simulate

__all__ = [
    "Capture", "PAPER_CASES", "PathSet", "Plate", "PointTarget", "RisConfig", "RisMisconfiguredWarning", "RisMode",
    "Scenario", "Truth", "add_noise", "analytic_paths", "analytic_scenario", "beat_cube", "carrier_phase", "one_way_free_space_gain", "paper_scenario",
    "plate_rcs", "plate_scattering", "point_target_gain", "provenance", "ris_loopback_gain", "ris_response",
    "select_paths", "shift_paths", "simulate",
]
