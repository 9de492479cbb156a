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

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from dsp._validate import as_finite_array

from ..model.capture import Capture
from ..model.ris import RisConfig
from ..model.scenario import Truth

__all__ = ["CaptureFormatError", "FORMAT_NAME", "FORMAT_VERSION", "capture_metadata", "load_capture", "save_capture"]

FORMAT_NAME = "risloc-capture"
FORMAT_VERSION = 1
_ARRAYS = ("cube", "beam_angles", "frame_index", "metadata")
_META_KEYS = ("format", "version", "radar", "ris", "processing", "provenance", "truth")


class CaptureFormatError(ValueError):
    """A capture file is missing a field, has a wrong shape, or is not a capture at all."""


def capture_metadata(capture: Capture) -> dict[str, Any]:
    """The JSON metadata block of ``capture``'s file."""
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "radar": capture.radar.to_dict(),
        "ris": capture.ris.to_dict(),
        "processing": capture.processing.to_dict(),
        "provenance": capture.provenance,
        "truth": None if capture.truth is None else capture.truth.to_dict(),
    }


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
            metadata=np.array(json.dumps(capture_metadata(capture), indent=1)),
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
