"""A beat cube with everything needed to process it: the one object simulation and measurement hand to the DSP.

The file format is :mod:`risloc_rt.io.capture_file`.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from dsp.spectrum import check_cube

from .._version import __version__
from .ris import RisConfig
from .scenario import Truth

__all__ = ["Capture", "provenance"]


@dataclass(frozen=True)
class Capture:
    """A beat cube and everything needed to process it.

    Attributes
    ----------
    cube : complex array [M, K, N]
        Beat samples (beams, chirps, samples) [√W for simulated data].
    sweep : BeamSweep
        Beam angle of each of the M frames.
    radar : RadarConfig
    ris : RisConfig
    processing : ProcessingConfig
        The processing the producer recommends; ``risloc locate`` may override it.
    frame_index : int array [M]
        Index of each frame in the original recording (0…M-1 for simulations; measured data
        skips the RIS on/off synchronisation frames).
    provenance : dict
        Where the data came from: ``source`` ("simulation" or "measurement"), ``created``
        (ISO 8601 UTC), ``software``, and producer-specific keys (seed, scenario, device...).
    truth : Truth or None
        Ground truth, when known.
    """

    cube: np.ndarray
    sweep: BeamSweep
    radar: RadarConfig
    ris: RisConfig
    processing: ProcessingConfig
    frame_index: np.ndarray
    provenance: dict[str, Any] = field(default_factory=dict)
    truth: Truth | None = None

    def __post_init__(self) -> None:
        dtype = getattr(self.cube, "dtype", None)
        if dtype is None or not np.issubdtype(dtype, np.complexfloating):
            kind = "a list" if dtype is None else f"{dtype} (real-valued)" if dtype.kind in "fiub" else str(dtype)
            raise TypeError(
                f"cube must be a complex array [M, K, N] of I/Q beat samples (complex64 or complex128), got {kind}; "
                "real-sampled ADC data (TI adcCfg real) cannot be localized as if it were complex: its spectrum has "
                "mirror images at negative beat frequencies that alias onto the range axis. Record complex (I/Q) "
                "data, or convert real samples to the analytic signal first (scipy.signal.hilbert along the "
                "sample axis, docs/robustness.md) and say so in the provenance"
            )
        cube = check_cube(self.cube, self.radar)
        if self.sweep.num_beams != cube.shape[0]:
            raise ValueError(
                f"cube has {cube.shape[0]} frames but sweep has {self.sweep.num_beams} beam angles; "
                "every frame needs its beam angle"
            )
        idx = np.asarray(self.frame_index)
        if idx.shape != (cube.shape[0],) or not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"frame_index must be an integer array [{cube.shape[0]}], got {idx.dtype} {list(idx.shape)}")
        if "source" not in self.provenance:
            raise ValueError("provenance must say its 'source' ('simulation' or 'measurement')")
        self.processing.check_against(self.radar.num_samples, self.radar.num_chirps)


def provenance(source: str, **extra: Any) -> dict[str, Any]:
    """A provenance block: ``source``, ``created`` (UTC now), ``software`` and ``extra`` keys."""
    return {"source": source,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "software": f"risloc-rt {__version__}", **extra}
