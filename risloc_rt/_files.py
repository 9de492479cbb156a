"""Atomic file writes, the one way risloc-rt writes a file (importable from every floor).

:func:`atomic_open` yields a binary file handle on a unique temporary file in the target's folder
(``tempfile.mkstemp``) and, when the ``with`` block ends without an exception, moves it over the
target with ``os.replace``. A reader never sees half a file, concurrent writers never share a
temporary file (the last to finish wins, complete), and an exception, Ctrl-C or a failed write
removes the temporary file. After SIGKILL a hidden ``.NAME.*.tmp`` may remain, never a truncated
``NAME``. The file gets the permissions an ordinary ``open`` would give (0666 less the umask).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Iterator

__all__ = ["atomic_open", "atomic_write_bytes", "file_sha256", "stage_bytes"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_open(path: str | os.PathLike[str], *, sync: bool = False) -> Iterator[BinaryIO]:
    """Open ``path`` for writing, atomically: see the module docstring.

    Parameters
    ----------
    path : path-like
        The target file; its folder is created if missing.
    sync : bool, default False
        ``fsync`` the data before the rename (captures and cache entries: survive a power cut).
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
            if sync:
                fh.flush()
                os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, out)
        tmp = None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, sync: bool = False) -> Path:
    """Write ``data`` to ``path`` with :func:`atomic_open`; returns the path."""
    with atomic_open(path, sync=sync) as fh:
        fh.write(data)
    return Path(path)


def stage_bytes(path: str | os.PathLike[str], data: bytes, *, suffix: str = ".tmp") -> Path:
    """Write ``data`` to a new hidden file beside ``path`` and return it; nothing is replaced.

    The first half of :func:`atomic_open`, for a caller that moves several files into place
    together (a scene build): the file is ``.NAME.*SUFFIX`` in the target's folder (created if
    missing), with the permissions an ordinary ``open`` gives; a failed write removes it.
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_umask())
    except BaseException:
        os.unlink(tmp)
        raise
    return Path(tmp)


def file_sha256(path: str | os.PathLike[str]) -> str:
    """The SHA-256 of a file's bytes (hex), read in 4 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()
