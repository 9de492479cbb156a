"""On-disk cache of ray traces: one compressed ``.npz`` file per (scene content, poses, frequency, settings).

A hit returns the stored arrays bit for bit. The key covers everything that changes the
paths: the scene's content hash (XML and mesh bytes), the radar and RIS positions, the radar
velocity, the frequency, the solver settings, the sionna-rt/mitsuba/drjit versions and the
cache format. Every entry carries its own checksum (sha256 over the names, dtypes, shapes and
bytes of its arrays, :func:`arrays_checksum`): a file that cannot be read (truncated, corrupt,
another format) or whose arrays do not match their checksum (damaged: bit rot, a partial copy, an
edit that did not update the checksum) counts as a miss with a :class:`TraceCacheWarning`, is
re-traced, and is overwritten by the next store. The checksum is unkeyed: it catches corruption,
not tampering — whoever can write the cache folder can write a consistent entry with its checksum. Files are
written to a unique temporary name and renamed, so a crash mid-write never leaves a half-written
entry under the final name.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..._files import atomic_open
from ..traced import TracedPaths
from .backend import package_versions
from .result import TraceResult, TraceSettings

__all__ = ["CACHE_FORMAT_VERSION", "TraceCache", "TraceCacheWarning", "arrays_checksum", "default_cache_dir",
           "trace_key"]

#: Bump when the file layout or the meaning of a stored array changes (2: per-entry checksum).
CACHE_FORMAT_VERSION = 2


class TraceCacheWarning(UserWarning):
    """A trace cache entry was unreadable or failed its checksum; it is traced again."""


def arrays_checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 (hex) over every array's name, dtype, shape and bytes, in name order."""
    digest = hashlib.sha256(b"risloc-rt trace cache entry\0")
    for name in sorted(arrays):
        arr = np.ascontiguousarray(arrays[name])
        head = json.dumps([name, arr.dtype.str, list(arr.shape)]).encode("utf-8")
        digest.update(len(head).to_bytes(8, "little") + head)
        data = arr.tobytes()
        digest.update(len(data).to_bytes(8, "little") + data)
    return digest.hexdigest()

_log = logging.getLogger(__name__)


def default_cache_dir() -> Path:
    """``$RISLOC_CACHE_DIR``, else ``~/.cache/risloc-rt/traces``."""
    env = os.environ.get("RISLOC_CACHE_DIR")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "risloc-rt" / "traces"


def _floats(values: Any) -> Any:
    """Nested lists of ``repr(float64)`` strings: exact and platform-independent."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim == 0:
        return repr(float(arr))
    return [_floats(v) for v in arr]


def trace_key(
    *,
    scene_hash: str,
    radar_position: Any,
    ris_positions: Any,
    radar_velocity: Any,
    frequency: float,
    settings: TraceSettings,
) -> str:
    """SHA-256 (hex) of a canonical JSON of everything that determines a trace.

    Parameters
    ----------
    scene_hash : str
        :func:`risloc_rt.hall.raytrace.scene_content_hash` of the scene.
    radar_position : float array [3]
        [m].
    ris_positions : float array [R, 3]
        [m]; R may be 0.
    radar_velocity : float array [3]
        [m/s].
    frequency : float
        [Hz].
    settings : TraceSettings

    Notes
    -----
    Floats enter as ``repr`` of float64 (shortest round-trip text), so any change of any bit
    changes the key; keys are sorted and the JSON is written without spaces.
    """
    payload = {
        "format": CACHE_FORMAT_VERSION,
        "scene": str(scene_hash),
        "radar_position": _floats(radar_position),
        "ris_positions": _floats(np.asarray(ris_positions, dtype=np.float64).reshape(-1, 3)),
        "radar_velocity": _floats(radar_velocity),
        "frequency": _floats(frequency),
        "settings": settings.to_dict(),
        "versions": package_versions(),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _entry_checksum(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> str:
    """The checksum of an entry: its arrays and its metadata (without the checksum itself)."""
    return arrays_checksum({**arrays, "\0meta": np.array(json.dumps(meta, sort_keys=True))})


class TraceCache:
    """Directory of cached :class:`TraceResult` files, ``<directory>/<key>.npz``.

    Parameters
    ----------
    directory : path-like, optional
        Where the files live (created on the first store); default :func:`default_cache_dir`.
    """

    def __init__(self, directory: str | os.PathLike[str] | None = None) -> None:
        self._directory = Path(directory).expanduser() if directory is not None else default_cache_dir()

    @property
    def directory(self) -> Path:
        """The cache directory."""
        return self._directory

    def __repr__(self) -> str:
        return f"TraceCache({str(self._directory)!r})"

    def path_for(self, key: str) -> Path:
        """File that holds (or would hold) the entry ``key``."""
        if not key or not all(c in "0123456789abcdef" for c in key):
            raise ValueError(f"key={key!r} must be a lowercase hex digest from trace_key()")
        return self._directory / f"{key}.npz"

    def load(self, key: str) -> TraceResult | None:
        """The stored result for ``key`` (``cache_hit`` True), or None when absent or unreadable."""
        path = self.path_for(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                if meta.get("format") != CACHE_FORMAT_VERSION or meta.get("key") != key:
                    raise ValueError(f"format {meta.get('format')!r} / key mismatch")
                arrays = {name: data[name] for name in data.files if name != "meta"}
                unsigned = {k: v for k, v in meta.items() if k != "checksum"}
                if _entry_checksum(arrays, unsigned) != meta.get("checksum"):
                    raise ValueError("its arrays do not match the entry's checksum (damaged)")
                traced = [
                    TracedPaths.from_arrays({name.split("/", 1)[1]: arrays[name] for name in arrays
                                             if name.startswith(f"{prefix}/")})
                    for prefix in ["mono"] + [f"leg{i}" for i in range(int(meta["num_legs"]))]
                ]
                return TraceResult(
                    monostatic=traced[0],
                    legs=tuple(traced[1:]),
                    scene_hash=str(meta["scene_hash"]),
                    cache_hit=True,
                    timing={k: float(v) for k, v in meta["timing"].items()},
                    settings=TraceSettings(**meta["settings"]),
                    radar_velocity=np.array([float(v) for v in meta["radar_velocity"]]),
                )
        except Exception as exc:  # corrupt, damaged or foreign file: a miss, overwritten by the next store
            message = (f"ignoring trace cache file {path} ({type(exc).__name__}: {' '.join(str(exc).split())[:200]}); "
                       "tracing again")
            _log.debug(message)
            warnings.warn(message, TraceCacheWarning, stacklevel=2)
            return None

    def store(self, key: str, result: TraceResult) -> Path | None:
        """Write ``result`` under ``key`` atomically; returns the path (None if writing failed).

        A failure to write (read-only or full disk) warns and returns None instead of raising: the
        trace itself succeeded.
        """
        path = self.path_for(key)
        arrays: dict[str, np.ndarray] = {}
        for prefix, paths in [("mono", result.monostatic)] + [(f"leg{i}", p) for i, p in enumerate(result.legs)]:
            for name, value in paths.to_arrays().items():
                arrays[f"{prefix}/{name}"] = np.asarray(value)
        meta = {
            "format": CACHE_FORMAT_VERSION,
            "key": key,
            "scene_hash": result.scene_hash,
            "num_legs": len(result.legs),
            "settings": result.settings.to_dict(),
            "timing": result.timing,
            "radar_velocity": [repr(float(v)) for v in result.radar_velocity],
        }
        meta["checksum"] = _entry_checksum(arrays, meta)
        arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
        try:
            with atomic_open(path, sync=True) as f:
                np.savez_compressed(f, **arrays)  # deflate: half the bytes (a carried cache, issue 21)
        except OSError as exc:
            warnings.warn(f"could not write trace cache file {path}: {exc}", RuntimeWarning, stacklevel=2)
            return None
        return path

