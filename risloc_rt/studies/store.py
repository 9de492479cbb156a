"""A study folder: its manifest, the append-only run log, and the Parquet table made from it.

    DIR/study.json      the spec and its key (written atomically when the study starts)
    DIR/runs.jsonl      one JSON line per finished run, appended batch by batch and fsync'd
    DIR/runs.parquet    the log as a table, one row per run, sorted by (point, run), with the
                        point's parameters as columns (rewritten atomically at the end)
    DIR/summary.json    per-point statistics (``summary.py``)

Crash safety: a line is written whole with one ``write`` and then fsync'd; after a SIGKILL the
log ends, at worst, in a torn last line (no newline), which :meth:`RunLog.open` cuts off before
appending (it is the study's own file); any other bad line is an error and the file is left as it
is. A restart reads the finished (point, run) pairs and runs only the rest. A kept log (``--force``
on another study's folder) is never overwritten (:func:`keep_log`).
"""

from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path
from typing import Any, Callable, Iterable

from .._files import atomic_write_bytes
from .spec import StudySpec

__all__ = ["RunLog", "RunLogError", "StudyFolderError", "check_stream", "keep_log", "devices_path",
           "read_devices", "open_study_folder", "study_device", "write_parquet", "read_runs_table",
           "HOST_STREAMS", "HOST_STREAM", "host_noise"]

MANIFEST = "study.json"
LOG = "runs.jsonl"
TABLE = "runs.parquet"
SUMMARY = "summary.json"

#: A study folder's noise streams drawn on the host (its manifest's ``noise_stream``) and the stream of
#: :func:`risloc_rt.model.beat.add_noise` that draws each: ``"host"`` NumPy's float32 ziggurat (folders made
#: before the Box–Muller stream, and manifests without the key), ``"host-boxmuller"`` float32 Box–Muller
#: (2-2.5x cheaper). The third stream, ``"cuda"``, is cuRAND's on a GPU.
HOST_STREAMS = {"host": "fast", "host-boxmuller": "boxmuller"}
#: The host stream of a new study folder.
HOST_STREAM = "host-boxmuller"


def host_noise(stream: str) -> str:
    """The :func:`risloc_rt.model.beat.add_noise` stream that draws a study stream's noise on the host.

    Parameters
    ----------
    stream : {"host", "host-boxmuller", "cuda"}
        A study folder's noise stream (:data:`HOST_STREAMS`; ``"cuda"``: a GPU draws it, and a host
        that runs such a batch draws :data:`HOST_STREAM`'s).

    Returns
    -------
    {"fast", "boxmuller"}

    Raises
    ------
    ValueError
        An unknown stream.
    """
    if stream == "cuda":
        return HOST_STREAMS[HOST_STREAM]
    if stream not in HOST_STREAMS:
        raise ValueError(f"noise stream {stream!r} is not a study stream; use one of {', '.join(HOST_STREAMS)} or cuda")
    return HOST_STREAMS[stream]


class StudyFolderError(ValueError):
    """The output folder belongs to something else (another study, or not a study at all)."""


class RunLogError(ValueError):
    """A line of ``runs.jsonl`` other than a torn last line is not a run row; the file is left as it is."""


def keep_log(log: Path, key: str) -> Path:
    """Move ``log`` aside as ``runs-<key>.jsonl`` in its folder, never over an existing file.

    If that name is taken (the same study was kept before), ``runs-<key>-2.jsonl``, ``-3``, ... is
    used: a kept log is never overwritten.

    Parameters
    ----------
    log : Path
        The run log to keep (it must exist).
    key : str
        The key of the study that wrote it (``"unreadable"`` when its manifest could not be read).

    Returns
    -------
    Path
        Where the log now is.
    """
    stem = "runs-" + "".join(c if c.isalnum() or c in "-_." else "_" for c in key)
    for n in range(1, 100_000):
        target = log.with_name(f"{stem}{'' if n == 1 else f'-{n}'}.jsonl")
        try:
            os.link(log, target)  # fails if target exists: no race can overwrite a kept log
        except FileExistsError:
            continue
        except OSError:  # a file system without hard links
            if target.exists():
                continue
            os.rename(log, target)
            return target
        os.unlink(log)
        return target
    raise StudyFolderError(f"{str(log.parent)!r} holds too many kept logs; use a new --out folder")


def _clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def devices_path(folder: Path, key: str) -> Path:
    """Where a study folder records what ran the runs of the study ``key``: ``devices-<key>.json``.

    One file per study key, like a kept log (``runs-<key>.jsonl``): a study forced into the folder of
    another leaves that study's record as it was.

    Parameters
    ----------
    folder : Path
        The study (or map) folder.
    key : str
        The study's key.

    Returns
    -------
    Path
    """
    return Path(folder) / f"devices-{key}.json"


def read_devices(path: Path) -> list[dict[str, Any]]:
    """The devices a record (:func:`devices_path`) lists, first seen first; [] when it is absent or unreadable.

    Parameters
    ----------
    path : Path
        ``devices-<key>.json``.

    Returns
    -------
    list of dict
        :func:`risloc_rt.io.report.run_environment` objects.
    """
    try:
        devices = json.loads(Path(path).read_text()).get("devices")
    except (OSError, ValueError, AttributeError):
        return []
    return [d for d in devices if isinstance(d, dict)] if isinstance(devices, list) else []


class RunLog:
    """The append-only JSON-lines log of finished runs.

    Parameters
    ----------
    path : Path
        ``runs.jsonl``.
    devices_file : Path, optional
        Where :meth:`record_device` keeps what ran the runs (:func:`devices_path`); read by :meth:`open`.
        None: kept in memory only.

    Attributes
    ----------
    rows : dict of (int, int) to dict
        The runs read or appended, by (point, run); the first row of a pair wins.
    devices : list of dict
        What ran them, every sitting's (:func:`risloc_rt.io.report.run_environment` objects).
    noise_stream : str
        The noise stream this sitting's runs draw (:func:`open_study_folder` sets it: the folder's).
    """

    def __init__(self, path: Path, *, devices_file: Path | None = None) -> None:
        self.path = path
        self.rows: dict[tuple[int, int], dict[str, Any]] = {}
        self.devices_file = devices_file
        self.devices: list[dict[str, Any]] = []
        self.noise_stream = HOST_STREAM
        self._fh: Any = None

    def open(self) -> "RunLog":
        """Read what is there (cutting off a torn last line) and open for appending.

        Only a torn tail, the last line without its newline (a kill during a write), is cut off. Any
        other line that is not a run row (bad JSON, no ``point``/``run``) is an error, and the file is
        left byte-identical: the rows after it are runs that must not be lost.

        Returns
        -------
        RunLog
            ``self``.

        Raises
        ------
        RunLogError
            A line other than a torn last line is not a run row (the message names file and line).
        """
        if self.path.exists():
            data = self.path.read_bytes()
            lines = data.split(b"\n")
            torn = lines.pop()  # b"" when the file ends with its newline, else a line cut by a kill
            for number, line in enumerate(lines, 1):
                try:
                    row = json.loads(line)
                    key = (row["point"], row["run"])
                    if not all(type(v) is int and v >= 0 for v in key):  # not 1.7, "1", true, Infinity, 1e999
                        raise ValueError(f"point and run must be whole numbers >= 0, not {key!r}")
                except (ValueError, KeyError, TypeError, IndexError) as exc:
                    raise RunLogError(
                        f"{str(self.path)!r} line {number} is not a run row ({type(exc).__name__}: "
                        f"{' '.join(str(exc).split())[:120]}); the log is append-only and was changed by "
                        "something else; it was left as it is: repair or remove that line (or use a new --out "
                        "folder) and rerun") from None
                self.rows.setdefault(key, row)
            if torn:  # only the last line, written without its newline, is the study's to cut off
                with open(self.path, "r+b") as fh:
                    fh.truncate(len(data) - len(torn))
                    os.fsync(fh.fileno())
        self._fh = open(self.path, "ab")
        if self.devices_file is not None:
            self.devices = read_devices(self.devices_file)
        return self

    def done(self) -> set[tuple[int, int]]:
        """The finished runs.

        Returns
        -------
        set of (int, int)
            (point, run) pairs in the log.
        """
        return set(self.rows)

    def append(self, rows: Iterable[dict[str, Any]]) -> None:
        """Append rows (one write, then fsync): after a crash either all or a cut-off tail remain.

        Parameters
        ----------
        rows : iterable of dict
            Run rows (:func:`risloc_rt.studies.kernel.run_once`); non-finite floats are written as null.
        """
        rows = list(rows)
        if not rows:
            return
        blob = b"".join(json.dumps({k: _clean(v) for k, v in r.items()}, sort_keys=True).encode() + b"\n"
                        for r in rows)
        self._fh.write(blob)
        self._fh.flush()
        os.fsync(self._fh.fileno())
        for r in rows:
            self.rows.setdefault((int(r["point"]), int(r["run"])), r)

    def record_device(self, device: dict[str, Any]) -> None:
        """Record that ``device`` ran runs of this study, before its first rows are appended.

        A new device is written to the folder's record (``devices_file``, atomically, synced), so every
        row in the log has its device recorded, whichever sitting ran it: a study continued later, or
        rerun with nothing left to run, still names it in its summary (before, only the last sitting's
        batches were named, and a finished study's rerun named none). The record is absent until the
        first batch: a stopped study's folder is then always a state of the finished one.

        Parameters
        ----------
        device : dict
            :func:`risloc_rt.io.report.run_environment` of the process that ran the runs.
        """
        if device in self.devices:
            return
        self.devices.append(device)
        if self.devices_file is not None:
            atomic_write_bytes(self.devices_file, json.dumps({"devices": self.devices}, indent=1,
                                                             sort_keys=True).encode() + b"\n", sync=True)

    def close(self) -> None:
        """Close the file (the rows read stay available)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def _stderr(message: str) -> None:
    import sys

    print(message, file=sys.stderr)


def study_device(device: str | None, *, local: bool) -> tuple[str, str]:
    """A study's device, checked before any folder is made, and the noise stream its runs draw.

    Parameters
    ----------
    device : {"cpu", "cuda", "auto"} or None
        ``--device`` (None: ``$RISLOC_DEVICE``, else ``cpu``).
    local : bool
        The runs go to this machine's workers: ``cuda`` without CuPy or a GPU is refused here, with
        one line (on a Dask cluster the workers resolve it on their own machines).

    Returns
    -------
    device : str
        The checked name, passed to the workers.
    stream : {"host-boxmuller", "cuda"}
        The host's stream (:data:`HOST_STREAM`, the CPU and array_api_strict) or cuRAND's on a GPU;
        ``auto`` is resolved on this machine. A folder whose runs were drawn on the older host stream
        continues on it (:func:`check_stream`).

    Raises
    ------
    dsp.DeviceError
        An unknown name, or ``cuda`` where it cannot run (``local``).
    """
    from dsp import backend_for, cuda_available, device_choice

    device = device_choice(device)
    if local:
        backend_for(device)
    resolved = device if device != "auto" else ("cuda" if cuda_available()[0] else "cpu")
    return device, "cuda" if resolved == "cuda" else HOST_STREAM


def check_stream(out: Path, manifest: dict[str, Any], stream: str, log: Path) -> str:
    """The noise stream that continues a study folder; refuse one whose rows were drawn on another device.

    Parameters
    ----------
    out : Path
        The folder (for the message).
    manifest : dict
        Its manifest as read (``noise_stream`` absent: written before devices existed, the host's
        ziggurat, ``"host"``).
    stream : str
        This sitting's stream (:func:`study_device`).
    log : Path
        The folder's run log (a missing or empty one holds no runs).

    Returns
    -------
    str
        ``stream``, or the folder's own host stream when its runs were drawn on another one and this
        sitting runs on the host too (a folder started before the Box–Muller stream keeps its
        ziggurat: one stream per table).

    Raises
    ------
    StudyFolderError
        The folder holds runs of a GPU and this sitting is on the CPU, or the other way round, or its
        manifest names a stream this version does not know.
    """
    old = str(manifest.get("noise_stream", "host"))
    if old == stream or not (log.exists() and log.stat().st_size > 0):
        return stream
    if old in HOST_STREAMS and stream in HOST_STREAMS:
        return old
    if old != "cuda" and old not in HOST_STREAMS:
        raise StudyFolderError(f"{str(out)!r} holds runs of the noise stream {old!r}, which this version of "
                               "risloc-rt does not draw; use a new --out (or the version that made the folder)")
    was = "a GPU (--device cuda)" if old == "cuda" else "the CPU (--device cpu)"
    raise StudyFolderError(f"{str(out)!r} holds runs whose noise was drawn on {was}; continue it with that "
                           "device, or use a new --out (a table of both streams would mix two random streams)")


def open_study_folder(out: Path, spec: StudySpec, *, force: bool = False,
                      notice: Callable[[str], None] | None = None, stream: str = HOST_STREAM) -> RunLog:
    """Create or reopen ``out`` for ``spec``; refuse a folder of another study (or not a study) without ``force``.

    With ``force`` a previous study's log is kept, renamed ``runs-<its key>.jsonl`` (``-2``, ``-3``, ...
    if that name is taken, :func:`keep_log`), and ``notice`` says where; nothing is deleted or overwritten.

    Parameters
    ----------
    out : Path
        The study folder.
    spec : StudySpec
        The study (its key is written to ``study.json``).
    force : bool
        Use a folder that holds another study, or other files.
    notice : callable, optional
        Receives the one-line note naming where a previous study's log was kept (default: stderr).
    stream : {"host-boxmuller", "host", "cuda"}
        The noise stream of this sitting's runs (:func:`study_device`); a folder whose runs were
        drawn on another device is refused, one drawn on another host stream continues on it
        (:func:`check_stream`).

    Returns
    -------
    RunLog
        The folder's run log, open for appending; its ``noise_stream`` is the stream its runs draw.

    Raises
    ------
    StudyFolderError
        ``out`` is a file, or holds another study or other files, and ``force`` is not given.
    """
    out = Path(out)
    manifest = out / MANIFEST
    if out.exists() and not out.is_dir():
        raise StudyFolderError(f"--out {str(out)!r} is a file, not a folder; choose a new folder")
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text())
            old_key = str(old["key"])
        except (ValueError, KeyError, TypeError):
            old_key = "unreadable"
        if old_key == spec.key:
            stream = check_stream(out, old, stream, out / LOG)
        if old_key != spec.key:
            if not force:
                raise StudyFolderError(
                    f"{str(out)!r} holds another study ({old.get('spec', {}).get('name', '?') if old_key != 'unreadable' else 'unreadable manifest'}, "
                    f"key {old_key}); use a new --out folder, or --force to start this study there (the old log is kept "
                    f"as runs-{old_key}.jsonl, or runs-{old_key}-N.jsonl if that name is taken)")
            if (out / LOG).exists():
                kept = keep_log(out / LOG, old_key)
                (notice or _stderr)(f"note: {str(out)!r} held another study (key {old_key}); its run log is kept "
                                    f"as {str(kept)!r}")
    elif out.is_dir() and any(out.iterdir()) and not force:
        raise StudyFolderError(f"{str(out)!r} is not empty and holds no study; use a new --out folder "
                               "(or --force to write the study's files next to what is there)")
    out.mkdir(parents=True, exist_ok=True)
    from .. import __version__

    atomic_write_bytes(manifest, json.dumps({"key": spec.key, "spec": spec.to_dict(), "risloc_rt": __version__,
                                             "noise_stream": stream},
                                            indent=1, sort_keys=True).encode() + b"\n", sync=True)
    log = RunLog(out / LOG, devices_file=devices_path(out, spec.key)).open()
    log.noise_stream = stream
    return log


def write_parquet(path: Path, rows: list[dict[str, Any]], points: list[dict[str, Any]], *,
                  study_seed: int, runs: int) -> Path:
    """The run table (one row per run, runs < ``runs``) with each point's parameters, atomically.

    Parameters
    ----------
    path : Path
        ``runs.parquet``.
    rows : list of dict
        The run rows (any order; runs >= ``runs`` are left out).
    points : list of dict
        The study's points: their parameters become ``param_*`` columns.
    study_seed : int
        Written as the ``study_seed`` column.
    runs : int
        Runs per point.

    Returns
    -------
    Path
        ``path``.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = sorted((r for r in rows if int(r["run"]) < runs), key=lambda r: (int(r["point"]), int(r["run"])))
    names = sorted({k for r in rows for k in r})
    cols: dict[str, list[Any]] = {k: [r.get(k) for r in rows] for k in names}
    for k in ("point", "run"):
        cols[k] = [int(v) for v in cols.get(k, [])]
    cols["study_seed"] = [study_seed] * len(rows)
    for name in (points[0] if points else {}):
        cols[f"param_{name}"] = [points[int(r["point"])][name] for r in rows]
    for k, v in cols.items():
        if k not in ("flags",) and v and all(x is None or isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) \
                and any(isinstance(x, float) or x is None for x in v) and k not in ("point", "run", "study_seed"):
            cols[k] = [float("nan") if x is None else float(x) for x in v]
    table = pa.table(cols)
    buf = io.BytesIO()
    pq.write_table(table, buf)
    return atomic_write_bytes(path, buf.getvalue(), sync=True)


def read_runs_table(path: str | Path) -> Any:
    """The Parquet run table as a ``pyarrow.Table``.

    Parameters
    ----------
    path : path-like
        ``runs.parquet`` of a study folder.

    Returns
    -------
    pyarrow.Table
        One row per run (columns in ``docs/studies.md``).
    """
    import pyarrow.parquet as pq

    return pq.read_table(path)
