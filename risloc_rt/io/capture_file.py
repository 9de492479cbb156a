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

import difflib
import errno
import json
import math
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig
from dsp.validation import as_finite_array
from dsp.budget import BudgetError, check_memory, dsp_memory

from .._files import atomic_open
from ..model.capture import Capture
from ..model.ris import RisConfig, check_ris_memory
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

    The cube keeps its dtype (complex128 or complex64). The file is written to a unique temporary
    file in the target folder (``tempfile.mkstemp``), flushed to disk, then renamed over ``path``
    with ``os.replace``: an interrupted write (Ctrl-C, SIGKILL, a full disk) never leaves a
    truncated capture behind, and concurrent writers to one path leave one complete file (the
    last to finish). The temporary file is removed when the write fails.
    """
    out = Path(path)
    if out.suffix != ".npz":
        out = out.with_name(out.name + ".npz")
    if out.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder; give a file name such as run.npz for the capture", str(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    cube = np.asarray(capture.cube)
    if cube.dtype not in (np.complex64, np.complex128):
        cube = cube.astype(np.complex128)
    with atomic_open(out, sync=True) as fh:
        np.savez(
            fh,
            cube=cube,
            beam_angles=np.asarray(capture.sweep.angles, dtype=np.float64),
            frame_index=np.asarray(capture.frame_index, dtype=np.int64),
            metadata=np.array(json.dumps(capture_metadata(capture), indent=1)),
        )
    return out


# ------------------------------------------------------------------------------------------ reading

#: Largest metadata JSON a capture may carry [characters].
MAX_METADATA_CHARS = 10_000_000

#: Physical range of each numeric metadata field: (low, high, unit); None bounds are open.
FIELD_RANGES: dict[str, dict[str, tuple[float | None, float | None, str]]] = {
    "radar": {
        "carrier_frequency": (1e8, 1e13, "Hz"), "bandwidth": (1e3, 1e12, "Hz"), "chirp_duration": (1e-8, 1.0, "s"),
        "sample_rate": (1e3, 1e11, "Hz"), "if_bandwidth": (1e3, 1e11, "Hz"), "num_samples": (1, 10_000_000, ""),
        "num_chirps": (1, 10_000_000, ""), "tx_power_dbm": (-150.0, 100.0, "dBm"),
        "antenna_gain_dbi": (-100.0, 100.0, "dBi"), "noise_power_dbm": (-300.0, 100.0, "dBm"),
        "chirp_period": (1e-8, 10.0, "s"), "frame_period": (1e-8, 1e4, "s"), "frames_per_beam": (1, 1_000_000, ""),
    },
    "processing": {
        "n_dft": (1, None, ""), "k_dft": (1, None, ""), "delta": (0.0, 1e-6, "s"), "min_range": (0.0, 1e5, "m"),
        "zoom_oversampling": (2, 1024, ""), "zoom_margin_db": (0.0, 200.0, "dB"),
    },
    "ris": {
        "num_rows": (1, 100_000, ""), "num_columns": (1, 100_000, ""), "element_spacing": (1e-6, 10.0, "m"),
        "amplification_db": (-200.0, 200.0, "dB"), "loopback_delay": (0.0, 1e-3, "s"),
    },
}
_INTEGER_FIELDS = {"num_samples", "num_chirps", "frames_per_beam", "n_dft", "k_dft", "zoom_oversampling",
                   "num_rows", "num_columns"}


def _suggest(name: str, options: Any) -> str:
    close = difflib.get_close_matches(str(name), list(options), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _check_fields(block: str, data: Any) -> None:
    """Types and physical ranges of the numeric fields of ``metadata[block]`` (before the constructors)."""
    if not isinstance(data, dict):
        raise CaptureFormatError(f"metadata {block!r} must be a JSON object, got {type(data).__name__}")
    for name, (low, high, unit) in FIELD_RANGES.get(block, {}).items():
        if name not in data or data[name] is None:
            continue
        value = data[name]
        where = f"metadata {block}.{name}={value!r}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise CaptureFormatError(f"{where} must be a number{f' [{unit}]' if unit else ''}, "
                                     f"not a {type(value).__name__}; write a plain JSON number")
        if name in _INTEGER_FIELDS and not float(value).is_integer():
            raise CaptureFormatError(f"{where} must be an integer")
        if not math.isfinite(float(value)):
            raise CaptureFormatError(f"{where} must be finite")
        u = f" {unit}" if unit else ""
        if (low is not None and value < low) or (high is not None and value > high):
            span = f"{low:g}{u} … {high:g}{u}" if high is not None else f">= {low:g}{u}"
            raise CaptureFormatError(f"{where} is outside the physical range {span}; check the unit "
                                     f"({unit or 'a count'}) and the value")


def _array_headers(p: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """``{array name: (shape, dtype)}`` of an ``.npz`` from the ``.npy`` headers alone (no data read)."""
    out: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    with zipfile.ZipFile(p) as zf:
        for info in zf.infolist():
            if not info.filename.endswith(".npy"):
                continue
            with zf.open(info) as fh:
                version = np.lib.format.read_magic(fh)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                elif version == (2, 0):
                    shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                else:
                    raise ValueError(f"unsupported .npy version {version} in {info.filename}")
            out[info.filename[:-4]] = (tuple(int(n) for n in shape), np.dtype(dtype))
    return out


def _check_arrays(p: Path, headers: dict[str, tuple[tuple[int, ...], np.dtype]]) -> None:
    missing = [k for k in _ARRAYS if k not in headers]
    if missing:
        raise CaptureFormatError(f"{p}: missing array(s) {missing}; a capture holds {list(_ARRAYS)}")
    shape, dtype = headers["cube"]
    if len(shape) != 3:
        raise CaptureFormatError(f"{p}: cube has shape {list(shape)}, expected [M, K, N] (beams, chirps, samples)")
    if dtype not in (np.dtype(np.complex64), np.dtype(np.complex128)):
        real = " (real-valued: real ADC sampling is not supported, see docs/robustness.md)" \
            if dtype.kind in "fiub" else ""
        raise CaptureFormatError(f"{p}: cube has dtype {dtype}{real}; a capture cube is complex64 or complex128 "
                                 "I/Q samples")
    check_memory(math.prod(shape) * dtype.itemsize, f"{p}: cube {list(shape)} {dtype}",
                 fix="this capture is larger than the memory limit allows")
    meta_shape, meta_dtype = headers["metadata"]
    if meta_dtype.kind != "U" or meta_shape != () or meta_dtype.itemsize // 4 > MAX_METADATA_CHARS:
        raise CaptureFormatError(f"{p}: metadata must be one JSON string of at most {MAX_METADATA_CHARS} characters, "
                                 f"got {meta_dtype} {list(meta_shape)}")
    for name, kinds in (("beam_angles", "f"), ("frame_index", "iu")):
        shape_a, dtype_a = headers[name]
        if dtype_a.kind not in kinds or len(shape_a) > 2 or math.prod(shape_a) > 10 * max(shape[0], 1) + 10:
            raise CaptureFormatError(f"{p}: {name} has dtype {dtype_a} and shape {list(shape_a)}; expected "
                                     f"{'float [M, 2]' if name == 'beam_angles' else 'int [M]'} with M={shape[0]}")
    check_memory(_arrays_memory(headers), f"{p}: the arrays "
                 + ", ".join(f"{name} {list(headers[name][0])} {headers[name][1]}" for name in _ARRAYS),
                 fix="this capture is larger than the memory limit allows (a compressed archive is read at its "
                     "decompressed size, the shapes above)")


def _arrays_memory(headers: dict[str, tuple[tuple[int, ...], np.dtype]]) -> int:
    """Bytes :func:`load_capture` allocates to read the arrays of a capture, from their ``.npy`` headers.

    ``Σ prod(shape) · itemsize`` over ``cube``, ``beam_angles``, ``frame_index`` and ``metadata``: each
    array is read once, at its declared (decompressed) size, whatever the archive's compressed
    size (a 2.4 MB deflated archive can declare 3.6 GB of zeros). Members that are not part of a
    capture are never read and do not count.
    """
    return sum(math.prod(headers[name][0]) * headers[name][1].itemsize for name in _ARRAYS if name in headers)


def load_capture(path: str | os.PathLike[str]) -> Capture:
    """Read a capture written by :func:`save_capture` (or by a measured-data converter).

    Every field is checked before the data are read: the array headers (shape, dtype, a cube
    within the memory limit of :mod:`dsp.budget`, and all the arrays read together at their
    decompressed size, ``Σ prod(shape) · itemsize``), the metadata's keys (unknown ones refused,
    with the nearest valid key suggested), types and physical ranges, the DSP's memory at
    the recommended processing (``n_dft``, ``k_dft``) and the RIS response's memory for the
    metadata's ``num_rows × num_columns`` and the cube's M beams
    (:func:`risloc_rt.model.ris.ris_response_memory`). A damaged file (flipped bytes, a
    truncated archive: zip CRC errors) is a :class:`CaptureFormatError`, never a traceback.

    Raises
    ------
    FileNotFoundError
        No such file.
    CaptureFormatError
        Not a capture, or a field is missing, malformed or out of range; the message names it.
    dsp.budget.BudgetError
        The arrays, processing the cube, or the RIS's response would exceed the memory limit.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"capture file {str(p)!r} does not exist")
    try:
        headers = _array_headers(p)
    except Exception as exc:  # noqa: BLE001 - a damaged zip container raises many types (struct.error, ...)
        raise CaptureFormatError(f"{p}: not a readable .npz capture ({type(exc).__name__}: {_short(exc)}); "
                                 "the file is damaged or not a capture: write it again") from None
    _check_arrays(p, headers)
    try:
        with np.load(p, allow_pickle=False) as archive:
            return _read(p, archive, headers["cube"][0])
    except (CaptureFormatError, BudgetError):
        raise
    except Exception as exc:  # noqa: BLE001 - damaged data inside a readable container, of any kind
        raise CaptureFormatError(f"{p}: the capture is damaged ({type(exc).__name__}: {_short(exc)}); "
                                 "write it again") from None


def _short(exc: BaseException, limit: int = 300) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _read(p: Path, archive: Any, cube_shape: tuple[int, ...]) -> Capture:
    try:
        meta = json.loads(str(archive["metadata"]))
    except (json.JSONDecodeError, ValueError, RecursionError) as exc:
        raise CaptureFormatError(f"{p}: metadata is not valid JSON ({_short(exc)})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_NAME:
        raise CaptureFormatError(f"{p}: metadata 'format' is not {FORMAT_NAME!r}; not a risloc capture")
    if meta.get("version") != FORMAT_VERSION:
        raise CaptureFormatError(
            f"{p}: capture version {meta.get('version')!r} is not supported (this is version {FORMAT_VERSION})"
        )
    unknown = [k for k in meta if k not in _META_KEYS]
    if unknown:
        raise CaptureFormatError(f"{p}: unknown metadata key {unknown[0]!r}{_suggest(unknown[0], _META_KEYS)}; "
                                 f"the metadata holds exactly {list(_META_KEYS)}")
    missing = [k for k in _META_KEYS if k not in meta]
    if missing:
        raise CaptureFormatError(f"{p}: metadata is missing {missing}")
    for block in ("radar", "ris", "processing"):
        _check_fields(block, meta[block])
    if not isinstance(meta["provenance"], dict):
        raise CaptureFormatError(f"{p}: metadata 'provenance' must be a JSON object")
    if meta["truth"] is not None and not isinstance(meta["truth"], dict):
        raise CaptureFormatError(f"{p}: metadata 'truth' must be a JSON object or null")
    try:
        radar = RadarConfig.from_dict(meta["radar"], require_all=True)
        ris = RisConfig.from_dict(meta["ris"], require_all=True)
        processing = ProcessingConfig.from_dict(meta["processing"], require_all=True)
        truth = None if meta["truth"] is None else Truth.from_dict(meta["truth"])
    except (TypeError, ValueError) as exc:
        raise CaptureFormatError(f"{p}: {_short(exc)}") from None
    check_memory(dsp_memory(cube_shape, n_dft=processing.n_dft, k_dft=processing.k_dft),
                 f"{p}: processing n_dft={processing.n_dft}, k_dft={processing.k_dft} on the cube",
                 fix="lower processing.n_dft/k_dft in the metadata (the paper uses 2N-1 and about 37K)")
    # The link-budget check of 'risloc locate' evaluates the RIS response for every beam of the cube.
    check_ris_memory(ris, cube_shape[0], where=f"{p}: metadata ris",
                     fix="check ris.num_rows and ris.num_columns in the metadata (the paper's RIS has 16 x 4 elements)")
    try:
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
        raise CaptureFormatError(f"{p}: {_short(exc)}") from None
