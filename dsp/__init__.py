"""Shared DSP and localization stack of risloc-rt: numpy/scipy (its whole-cube steps also on CuPy, ``dsp.xp``).

It runs the same on simulated and measured beat cubes and never imports ``risloc_rt``.

Axis order: a beat cube is ``complex [M, K, N]`` (beams, chirps, ADC samples) in √W; a
delay-Doppler map is ``[K_DFT, N_DFT]``. SI units and radians throughout
(``docs/conventions.md``).
"""

from .beamscan import BeamScan, scan_beams
from .crb import SweepBound, position_std, rician_information, sweep_crb, tone_frequency_crb
from .detection import Detection, check_beat_cube, detect, detect_batch
from .flags import FLAG_CODES, INSPECTION_CODES, Flag
from .floor_bounce import FloorLadder, floor_ladder, rung_spacing
from .fusion import FusedFix, RisFix, fuse_fixes
from .geometry import RisPose, angles_from_direction, direction_from_angles
from .localization import Alternative
from .localize import Localization, NoPositionError, localize, self_localize
from .moving_clutter import ClutterCancellation, MovingEcho, cancel_moving_clutter
from .pattern import BeamPattern
from .qualify import Uncertainty, elevation_for_height
from .aod_fit import AodFit, PatternFit, fit_aod, pattern_fit
from .refine import RefinedEstimate, refine_estimate
from .residual import beam_dtft, residual_test
from .processing import ProcessingConfig, window_vector
from .radar import SPEED_OF_LIGHT, RadarConfig, db_to_linear, linear_to_db
from .spectrum import DelayDopplerMap, DelayProfile, delay_doppler_map, delay_profile
from .sweep import BeamSweep
from .threads import limit_threads, thread_count
from .xp import DEVICE_ENV, ArrayBackend, DeviceError, backend_for, cuda_available, device_choice, numpy_backend, strict_backend

__all__ = [
    "FloorLadder",
    "floor_ladder",
    "rung_spacing",
    "FusedFix",
    "RisFix",
    "fuse_fixes",
    "ArrayBackend",
    "DEVICE_ENV",
    "DeviceError",
    "backend_for",
    "cuda_available",
    "device_choice",
    "detect_batch",
    "numpy_backend",
    "strict_backend",
    "Alternative",
    "ClutterCancellation",
    "MovingEcho",
    "cancel_moving_clutter",
    "AodFit",
    "BeamPattern",
    "Detection",
    "FLAG_CODES",
    "INSPECTION_CODES",
    "Flag",
    "NoPositionError",
    "PatternFit",
    "RefinedEstimate",
    "SweepBound",
    "Uncertainty",
    "beam_dtft",
    "check_beat_cube",
    "detect",
    "pattern_fit",
    "elevation_for_height",
    "fit_aod",
    "position_std",
    "refine_estimate",
    "rician_information",
    "residual_test",
    "sweep_crb",
    "thread_count",
    "tone_frequency_crb",
    "BeamScan",
    "BeamSweep",
    "DelayDopplerMap",
    "DelayProfile",
    "Localization",
    "ProcessingConfig",
    "RadarConfig",
    "RisPose",
    "SPEED_OF_LIGHT",
    "angles_from_direction",
    "db_to_linear",
    "delay_doppler_map",
    "delay_profile",
    "direction_from_angles",
    "linear_to_db",
    "limit_threads",
    "localize",
    "scan_beams",
    "self_localize",
    "window_vector",
]
