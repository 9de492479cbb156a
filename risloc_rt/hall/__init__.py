"""The ray-traced hall: trace → hall echoes, RIS loop-back leg pairs, panel reflection → pruned paths.

Floor 3 of ``docs/architecture.md``. Only :mod:`risloc_rt.hall.raytrace` imports sionna-rt,
mitsuba and drjit, lazily; everything it hands on is numpy (:class:`TracedPaths`).
"""

from .antenna import RadarAntenna
from .pruning import AliasWarning, ModelSettings, PruneReport, prune_paths
from .scenario import HallPaths, HallScenario, hall_paths, hall_scenario
from .traced import TracedPaths

__all__ = ["AliasWarning", "HallPaths", "HallScenario", "ModelSettings", "PruneReport", "RadarAntenna", "TracedPaths",
           "hall_paths", "hall_scenario", "prune_paths"]
