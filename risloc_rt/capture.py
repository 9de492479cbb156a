"""Capture files: a beat cube with every parameter needed to process it (``docs/formats.md``).

A capture is a NumPy ``.npz`` archive (no pickled objects) with

* ``cube``        complex [M, K, N]  beat samples, beams × chirps × ADC samples [√W, or ADC
                                      units for measured data]
* ``beam_angles`` float [M, 2]        ``[az, el]`` of the RIS beam of each frame [rad]
* ``frame_index`` int [M]             index of each frame in the original recording
* ``metadata``    str                 JSON: format, version, radar, ris, processing,
                                      provenance, truth (or null)

Nothing is filled in from defaults on reading: a missing field is an error.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from dsp._validate import as_finite_array
from dsp.spectrum import check_cube

from .ris import RisConfig
from .scenario import Truth

__all__ = ["Capture", "CaptureFormatError", "FORMAT_NAME", "FORMAT_VERSION", "load_capture", "save_capture"]

FORMAT_NAME = "risloc-capture"
FORMAT_VERSION = 1
_ARRAYS = ("cube", "beam_angles", "frame_index", "metadata")
_META_KEYS = ("format", "version", "radar", "ris", "processing", "provenance", "truth")


class CaptureFormatError(ValueError):
    """A capture file is missing a field, has a wrong shape, or is not a capture at all."""


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

    def metadata(self) -> dict[str, Any]:
        """The JSON metadata block written to the file."""
        return {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "radar": self.radar.to_dict(),
            "ris": self.ris.to_dict(),
            "processing": self.processing.to_dict(),
            "provenance": self.provenance,
            "truth": None if self.truth is None else self.truth.to_dict(),
        }


def provenance(source: str, **extra: Any) -> dict[str, Any]:
    """A provenance block: ``source``, ``created`` (UTC now), ``software`` and ``extra`` keys."""
    from . import __version__

    return {"source": source,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "software": f"risloc-rt {__version__}", **extra}


def save_capture(capture: Capture, path: str | os.PathLike[str]) -> Path:
    """Write ``capture`` to ``path`` (``.npz`` is appended if missing); returns the path written.

    The cube keeps its dtype (complex128 or complex64); the file is written to a temporary name
    and renamed, so an interrupted write never leaves a truncated capture behind.
    """
    out = Path(path)
    if out.suffix != ".npz":
        out = out.with_name(out.name + ".npz")
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
    cube = np.asarray(capture.cube)
    if cube.dtype not in (np.complex64, np.complex128):
        cube = cube.astype(np.complex128)
    tmp = out.with_name(out.name + ".partial")
    with open(tmp, "wb") as fh:
        np.savez(
            fh,
            cube=cube,
            beam_angles=np.asarray(capture.sweep.angles, dtype=np.float64),
            frame_index=np.asarray(capture.frame_index, dtype=np.int64),
            metadata=np.array(json.dumps(capture.metadata(), indent=1)),
        )
    os.replace(tmp, out)
    return out


def load_capture(path: str | os.PathLike[str]) -> Capture:
    """Read a capture written by :func:`save_capture` (or by a measured-data converter).

    Raises
    ------
    FileNotFoundError
        No such file.
    CaptureFormatError
        Not a capture, or a field is missing or malformed; the message names it.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"capture file {str(p)!r} does not exist")
    try:
        archive = np.load(p, allow_pickle=False)
    except Exception as exc:  # zipfile / format errors of every kind
        raise CaptureFormatError(f"{p}: not a readable .npz capture ({exc})") from None
    with archive:
        missing = [k for k in _ARRAYS if k not in archive.files]
        if missing:
            raise CaptureFormatError(f"{p}: missing array(s) {missing}; a capture holds {list(_ARRAYS)}")
        try:
            meta = json.loads(str(archive["metadata"]))
        except (json.JSONDecodeError, ValueError) as exc:
            raise CaptureFormatError(f"{p}: metadata is not valid JSON ({exc})") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT_NAME:
            raise CaptureFormatError(f"{p}: metadata 'format' is not {FORMAT_NAME!r}; not a risloc capture")
        if meta.get("version") != FORMAT_VERSION:
            raise CaptureFormatError(
                f"{p}: capture version {meta.get('version')!r} is not supported (this is version {FORMAT_VERSION})"
            )
        missing = [k for k in _META_KEYS if k not in meta]
        if missing:
            raise CaptureFormatError(f"{p}: metadata is missing {missing}")
        try:
            radar = RadarConfig.from_dict(meta["radar"], require_all=True)
            ris = RisConfig.from_dict(meta["ris"], require_all=True)
            processing = ProcessingConfig.from_dict(meta["processing"], require_all=True)
            truth = None if meta["truth"] is None else Truth.from_dict(meta["truth"])
            sweep = BeamSweep(as_finite_array(archive["beam_angles"], "beam_angles", shape=(None, 2)))
            return Capture(
                cube=archive["cube"],
                sweep=sweep,
                radar=radar,
                ris=ris,
                processing=processing,
                frame_index=archive["frame_index"],
                provenance=dict(meta["provenance"]),
                truth=truth,
            )
        except (TypeError, ValueError) as exc:
            raise CaptureFormatError(f"{p}: {exc}") from None
