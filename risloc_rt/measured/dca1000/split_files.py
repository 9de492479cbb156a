"""Split capture files: ``<prefix>_Raw_0.bin``, ``<prefix>_Raw_1.bin``, … found, read and written as one stream.

mmWave Studio and the DCA1000 command-line tool start a new file when one reaches the size limit
(Studio: ``adc_data_Raw_0.bin``, ``adc_data_Raw_1.bin``, …). The files are one byte stream cut at
the limit; raw-mode files may be cut anywhere, packet-recorded files between packets.
"""

from __future__ import annotations

import re
from contextlib import ExitStack
from pathlib import Path
from typing import Iterator, Sequence

from ..._files import atomic_open
from ..errors import MeasuredFormatError

__all__ = ["SplitWriter", "capture_files", "iter_file_bytes", "split_name"]

_SPLIT = re.compile(r"^(?P<stem>.*_Raw_)(?P<index>\d+)(?P<suffix>\.bin)$")


def split_name(prefix: str, index: int) -> str:
    """File name of split ``index``: ``f"{prefix}_Raw_{index}.bin"``.

    Parameters
    ----------
    prefix : str
        The capture's prefix (Studio: ``adc_data``).
    index : int
        0 for the first file.

    Returns
    -------
    str
    """
    return f"{prefix}_Raw_{index}.bin"


def capture_files(path: str | Path | Sequence[str | Path]) -> tuple[Path, ...]:
    """The files of a capture, in stream order.

    Parameters
    ----------
    path : path or sequence of paths
        One file: if its name is ``…_Raw_<i>.bin``, the siblings ``…_Raw_<j>.bin`` are collected
        and ordered by j, which must run 0, 1, 2, … without a gap. A sequence is taken as given.

    Returns
    -------
    tuple of Path
        The files in stream order.

    Raises
    ------
    MeasuredFormatError
        A missing file, or a gap in the split numbering (the missing name is given).
    """
    if isinstance(path, (str, Path)):
        p = Path(path)
        if not p.is_file():
            raise MeasuredFormatError(f"raw capture {p} does not exist or is not a file")
        m = _SPLIT.match(p.name)
        if not m:
            return (p,)
        stem, suffix = m["stem"], m["suffix"]
        found = {}
        for q in p.parent.iterdir():
            mq = _SPLIT.match(q.name)
            if mq and mq["stem"] == stem and mq["suffix"] == suffix and q.is_file():
                found[int(mq["index"])] = q
        indices = sorted(found)
        expected = list(range(len(indices)))
        if indices != expected:
            missing = sorted(set(range(max(indices) + 1)) - set(indices))
            raise MeasuredFormatError(
                f"split file {p.parent / (stem + str(missing[0]) + suffix)} is missing (found indices "
                f"{indices}); copy every split file of the capture into {p.parent}")
        return tuple(found[i] for i in indices)
    files = tuple(Path(q) for q in path)
    if not files:
        raise MeasuredFormatError("no capture files given")
    for q in files:
        if not q.is_file():
            raise MeasuredFormatError(f"raw capture {q} does not exist or is not a file")
    return files


def iter_file_bytes(files: Sequence[Path], block: int) -> Iterator[memoryview]:
    """Bytes of ``files`` concatenated, in blocks of at most ``block`` bytes (one reused buffer).

    Parameters
    ----------
    files : sequence of Path
        In stream order.
    block : int
        Largest block [bytes].

    Yields
    ------
    memoryview
        The next bytes; valid until the next one is read.
    """
    buf = bytearray(block)
    view = memoryview(buf)
    for path in files:
        with open(path, "rb", buffering=0) as fh:
            while True:
                n = fh.readinto(view)
                if not n:
                    break
                yield view[:n]


class SplitWriter:
    """Writes a byte stream to ``<folder>/<prefix>_Raw_<i>.bin``, starting a new file at ``max_file_size``.

    The files are written **atomically, all together**: each goes to a hidden temporary file in
    the folder (``risloc_rt._files.atomic_open``) and every one is renamed into place only when
    :meth:`close` is reached without an error; an exception (or Ctrl-C) leaves no split file,
    half-written or otherwise. Existing split files of the prefix are refused unless
    ``overwrite``: a stale ``_Raw_3.bin`` next to a new two-file capture would be read as its
    continuation.

    Parameters
    ----------
    folder : path
        Existing folder.
    prefix : str
        File prefix (Studio: ``adc_data``).
    max_file_size : int or None
        Size limit of one file [bytes]; None writes a single file.
    record_size : int or None
        Write records of this size whole (packet-recorded form): a file holds as many whole
        records as fit. None cuts at exactly ``max_file_size`` bytes (raw form).
    overwrite : bool, default False
        Replace existing split files of the same names.
    """

    def __init__(self, folder: str | Path, prefix: str, *, max_file_size: int | None = None,
                 record_size: int | None = None, overwrite: bool = False) -> None:
        self.folder, self.prefix = Path(folder), prefix
        self.limit = max_file_size
        if max_file_size is not None and record_size is not None and max_file_size < record_size:
            raise MeasuredFormatError(f"max_file_size={max_file_size} is smaller than one packet ({record_size} bytes)")
        if max_file_size is not None and max_file_size < 2:
            raise MeasuredFormatError(f"max_file_size={max_file_size} must be >= 2 bytes")
        if not overwrite and self.folder.is_dir():
            stale = sorted(q.name for q in self.folder.iterdir()
                           if (m := _SPLIT.match(q.name)) and m["stem"] == f"{prefix}_Raw_")
            if stale:
                raise MeasuredFormatError(
                    f"{self.folder} already holds {', '.join(stale[:3])}; risloc does not overwrite a capture: give "
                    "a new or empty folder, remove those files, or pass overwrite=True")
        self.files: list[Path] = []
        self._stack = ExitStack()
        self._fh = None
        self._size = 0

    def _open_next(self) -> None:
        if self._fh is not None:
            self._fh.close()               # its temporary file is renamed into place at close()
        path = self.folder / split_name(self.prefix, len(self.files))
        self._fh = self._stack.enter_context(atomic_open(path))
        self.files.append(path)
        self._size = 0

    def write(self, data: bytes | memoryview, *, whole: bool = False) -> None:
        """Append ``data``; with ``whole`` (a packet) it is never cut across two files.

        Parameters
        ----------
        data : bytes or memoryview
            The next bytes of the stream.
        whole : bool, default False
            Keep ``data`` in one file (a packet of the packet-recorded form).
        """
        if self._fh is None:
            self._open_next()
        data = memoryview(data).cast("B")
        if self.limit is None:
            self._fh.write(data)
            self._size += len(data)
            return
        if whole:
            if self._size + len(data) > self.limit and self._size > 0:
                self._open_next()
            self._fh.write(data)
            self._size += len(data)
            return
        while len(data):
            room = self.limit - self._size
            if room <= 0:
                self._open_next()
                continue
            part = data[:room]
            self._fh.write(part)
            self._size += len(part)
            data = data[len(part):]

    def close(self) -> tuple[Path, ...]:
        """Finish: every split file is renamed into place.

        Returns
        -------
        tuple of Path
            The split files, in order.
        """
        if self._fh is None:
            self._open_next()
        self._stack.close()
        return tuple(self.files)

    def __enter__(self) -> "SplitWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.__exit__(*exc)         # an exception: every temporary file is removed, nothing renamed
