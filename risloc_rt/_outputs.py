"""The output policy of every ``risloc`` command: never replace a file risloc-rt did not write.

Three rules, one module (importable from every floor; the standard library only):

1. **Whose file is it.** Every folder a command writes an output into holds a small ledger,
   ``.risloc-outputs.json``, mapping each file name risloc-rt wrote there to the sha256 of the
   bytes it wrote. An existing file at an output path may be replaced only when the ledger names it
   with its present bytes, i.e. risloc-rt wrote it and nobody changed it since. Any other existing
   file (the user's, another program's, a risloc output edited by hand or copied in) is refused with
   :class:`OutputError`, one line naming the file and the flag, unless the command was given
   ``--force``. A folder where a file should go (or a file where a folder should go) is refused even
   with ``--force``. ``risloc scene build`` applies the same rule with its own, richer ledger
   (``build-manifest.json``, which also tells which stale files it may delete).
2. **All or nothing.** A command that writes several files (``locate --out``, ``demo --out``,
   ``compare -o``, ``simulate --format dca1000``) writes them into a hidden staging folder inside
   the target folder (:func:`output_folder`); only when every file is written are the conflicts
   checked and the files renamed into place, with ``SIGINT``/``SIGTERM`` held back for the few
   milliseconds of the renames. A failure, an error, Ctrl-C or SIGTERM (which ``risloc`` turns into
   the same unwinding) before that leaves the folder as it was (the staging folder is removed); SIGKILL during the renames can leave a mix, as in a scene
   build. A single file is written with :func:`risloc_rt._files.atomic_open` (old file or new,
   never half).
3. **Names from inputs stay inside.** An output name derived from an input (a capture's file name,
   a scene's name) goes through :func:`safe_name`, so ``..``, separators and control characters
   cannot put a file outside the output folder.

The ledger is rewritten atomically; two commands finishing in the same folder at the same moment
can lose one entry, which makes that file count as foreign next time (refused without
``--force``), never the other way round.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import ClassVar

from ._files import atomic_write_bytes, file_sha256

__all__ = ["LEDGER", "OutputError", "check_output_file", "output_file", "output_folder", "record_outputs",
           "safe_name", "written_by_risloc"]

#: The ledger file in each folder risloc-rt writes outputs into.
LEDGER = ".risloc-outputs.json"
_FORMAT = "risloc-outputs"
_STAGE_PREFIX = ".risloc-stage-"


class OutputError(ValueError):
    """An output path holds a file risloc-rt did not write (or a folder where a file goes); the
    message names it and says how to proceed (another name, or ``--force``)."""


def _read_ledger(folder: Path) -> dict[str, str]:
    """The ``{name: sha256}`` of ``folder``'s ledger; empty when missing or unreadable (then every
    file there counts as foreign, the safe side)."""
    try:
        doc = json.loads((folder / LEDGER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    files = doc.get("files") if isinstance(doc, dict) and doc.get("format") == _FORMAT else None
    if not isinstance(files, dict):
        return {}
    return {k: v for k, v in files.items() if isinstance(k, str) and isinstance(v, str)}


def written_by_risloc(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a regular file that its folder's ledger names with its present bytes.

    Parameters
    ----------
    path : path-like
        A file.

    Returns
    -------
    bool
        False for a missing file, a folder, a symbolic link (never written by risloc-rt), a file
        the ledger does not name, or one whose bytes changed since.
    """
    p = Path(path)
    if p.is_symlink() or not p.is_file():
        return False
    digest = _read_ledger(p.parent).get(p.name)
    return digest is not None and digest == file_sha256(p)


def check_output_file(path: str | os.PathLike[str], *, force: bool, flag: str) -> Path:
    """Refuse ``path`` as an output when it holds something risloc-rt may not replace.

    Parameters
    ----------
    path : path-like
        Where the command will write one file.
    force : bool
        The command's ``--force``: replace a foreign file.
    flag : str
        The option that named the path (``"-o"``, ``"--plot"``), for the message.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        ``path`` is a folder (always), or an existing file risloc-rt did not write, or wrote and
        somebody changed since (unless ``force``).
    """
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{flag} {p} is a folder; name a file to write")
    if (p.exists() or p.is_symlink()) and not force and not written_by_risloc(p):
        raise OutputError(f"{flag} {p} exists and risloc-rt did not write it (or it was changed since); "
                          "give another name, or --force to replace it")
    return p


def record_outputs(folder: str | os.PathLike[str], names: list[str] | tuple[str, ...], *,
                   digests: dict[str, str] | None = None) -> None:
    """Add the files ``folder/name`` to ``folder``'s ledger with their sha256.

    Parameters
    ----------
    folder : path-like
        The folder holding the files (and the ledger).
    names : sequence of str
        File names inside ``folder`` (no separators), just written by risloc-rt.
    digests : dict of str -> str, optional
        Known sha256 of some of them (computed before they were moved into place); the others are
        hashed now.
    """
    root = Path(folder)
    ledger = _read_ledger(root)
    for name in names:
        if digests is not None and name in digests:
            ledger[name] = digests[name]
        elif (root / name).is_file():
            ledger[name] = file_sha256(root / name)
    doc = {"format": _FORMAT, "version": 1,
           "note": "files risloc-rt wrote here and their sha256; it replaces only these, unchanged, without --force",
           "files": dict(sorted(ledger.items()))}
    atomic_write_bytes(root / LEDGER, (json.dumps(doc, indent=1) + "\n").encode())


@contextmanager
def output_file(path: str | os.PathLike[str], *, force: bool, flag: str) -> Iterator[Path]:
    """Check ``path`` (:func:`check_output_file`), let the block write it beside, then move it in and record it.

    Enter the block before the expensive work, so a refused output costs nothing. The block
    writes the file to the path it is given: a hidden name beside ``path`` with the same suffix
    (``.NAME.*.risloc-tmp.SUFFIX``, or none when ``path`` has none, so writers that choose a
    format by the suffix or append one keep working). When the block ends without an exception,
    the file is hashed, then moved over ``path`` and recorded in the ledger with
    ``SIGINT``/``SIGTERM`` held back, so Ctrl-C can never leave a new file the ledger does not name
    (the rerun would be refused). On an exception the hidden file is removed and ``path`` is as it
    was.

    Parameters
    ----------
    path : path-like
    force : bool
    flag : str
        As for :func:`check_output_file`.

    Yields
    ------
    Path
        Where the block must write the file.
    """
    p = check_output_file(path, force=force, flag=flag)
    made = [d for d in (p.parent, *p.parent.parents) if not d.exists()]
    p.parent.mkdir(parents=True, exist_ok=True)
    if p.suffix:
        fd, name = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=f".risloc-tmp{p.suffix}")
    else:  # no suffix for a writer to read either: '.NAME-*', no dot after the first
        fd, name = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name.replace('.', '_')}-risloc-tmp-")
    os.close(fd)
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(name, 0o666 & ~mask)  # the mode an ordinary open gives, whether the writer replaces the file or not
    staged = Path(name)
    try:
        yield staged
        if staged.is_file() and staged.stat().st_size > 0:
            digest = file_sha256(staged)
            with _HoldSignals():
                if p.is_symlink():
                    p.unlink()
                os.replace(staged, p)
                record_outputs(p.parent, [p.name], digests={p.name: digest})
    finally:
        if staged.exists():
            staged.unlink()
        for d in made:  # folders made for an output that was never moved in
            try:
                d.rmdir()
            except OSError:
                break


class _HoldSignals:
    """Hold SIGINT and SIGTERM back for the duration of a ``with`` block, then deliver them.

    The Python-level handlers are swapped for one that only notes the signal (a signal mask would
    not do: the kernel hands a process-directed signal to any thread that does not block it, and
    CPython then runs the handler in the main thread at once). On exit the previous handlers come
    back and each noted signal is raised again, so Ctrl-C still ends the command, after the block.
    Outside the main thread (where handlers cannot be set) it does nothing.
    """

    _SIGNALS: ClassVar[tuple[int, ...]] = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self) -> None:
        self._pending: list[int] = []
        self._old: dict[int, object] = {}
        if threading.current_thread() is threading.main_thread():
            for sig in self._SIGNALS:
                self._old[sig] = signal.signal(sig, lambda signum, frame: self._pending.append(signum))

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)  # type: ignore[arg-type]
        for sig in dict.fromkeys(self._pending):
            signal.raise_signal(sig)


def _staged_files(stage: Path) -> list[Path]:
    """Every regular file under ``stage``, relative, in a stable order (links are not followed)."""
    found = []
    for dirpath, dirnames, filenames in os.walk(stage):
        dirnames.sort()
        for name in sorted(filenames):
            full = Path(dirpath) / name
            if full.name != LEDGER and full.is_file() and not full.is_symlink():
                found.append(full.relative_to(stage))
    return found


def _conflicts(root: Path, rels: list[Path], *, force: bool) -> list[str]:
    """The outputs under ``root`` that may not be replaced: folders always, foreign files without force."""
    bad = []
    for rel in rels:
        target = root / rel
        for parent in list(rel.parents)[:-1]:
            if (root / parent).is_symlink():
                bad.append(f"{root / parent} is a symbolic link (outputs go into real folders only)")
            elif (root / parent).exists() and not (root / parent).is_dir():
                bad.append(f"{root / parent} is a file where a folder is needed")
        if target.is_dir() and not target.is_symlink():
            bad.append(f"{target} is a folder")
        elif (target.exists() or target.is_symlink()) and not force and not written_by_risloc(target):
            bad.append(f"{target} exists and risloc-rt did not write it")
    return bad


@contextmanager
def output_folder(folder: str | os.PathLike[str], *, force: bool, flag: str,
                  expect: tuple[str, ...] = ()) -> Iterator[Path]:
    """Stage a multi-file output and move it into ``folder`` as a whole (the module's rule 2).

    Parameters
    ----------
    folder : path-like
        The output folder; created when missing (and removed again when the block fails and
        nothing else was put in it).
    force : bool
        The command's ``--force``: replace foreign files (never a folder).
    flag : str
        The option that named the folder (``"--out"``), for messages.
    expect : tuple of str
        Relative paths the command will surely write (``"result.json"``): checked on entry, so a
        refusal comes before the work.

    Yields
    ------
    Path
        A new, empty hidden folder inside ``folder``: the block writes every output there, under
        the relative path it must have in ``folder``.

    Raises
    ------
    OutputError
        ``folder`` is a file; or an output would replace a folder, or a file risloc-rt did not write
        (unless ``force``): on entry for ``expect``, else after the block, before anything is moved.
    """
    root = Path(folder)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{flag} {root} is a file; name a folder for the outputs")
    early = _conflicts(root, [Path(e) for e in expect], force=force) if root.is_dir() else []
    if early:
        raise OutputError(f"{flag} {root}: {early[0]}; give another folder, or --force to replace it")
    created = not root.exists()
    root.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(dir=root, prefix=_STAGE_PREFIX))
    try:
        yield stage
        rels = _staged_files(stage)
        bad = _conflicts(root, rels, force=force)
        if bad:
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            raise OutputError(f"{flag} {root}: {bad[0]}{more}; nothing was written: give another folder, "
                              "or --force to replace it")
        digests = {rel: file_sha256(stage / rel) for rel in rels}  # before the signals are held: big files take time
        with _HoldSignals():
            by_folder: dict[Path, dict[str, str]] = {}
            for rel in rels:
                target = root / rel
                target.parent.mkdir(parents=True, exist_ok=True)
                if target.is_symlink():
                    target.unlink()
                os.replace(stage / rel, target)
                by_folder.setdefault(target.parent, {})[target.name] = digests[rel]
            for where, names in by_folder.items():
                record_outputs(where, list(names), digests=names)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            try:
                root.rmdir()  # only when empty: nothing was moved in
            except OSError:
                pass


_UNSAFE = re.compile(r"[\x00-\x1f\x7f/\\]")


def safe_name(text: str, *, fallback: str = "case") -> str:
    """``text`` made into one harmless path component, for output names derived from inputs.

    Separators (``/``, ``\\``) and control characters become ``_``; a name that is empty, ``.``,
    ``..`` or starts with a dot (hidden, or a way up) gets a leading ``_``; it is cut to 120
    characters. Ordinary names come back unchanged.

    Parameters
    ----------
    text : str
        The name as the input gives it (``Path(capture).stem``, a scene's name).
    fallback : str
        Used when ``text`` is empty.

    Returns
    -------
    str
    """
    name = _UNSAFE.sub("_", str(text)) or fallback
    if name.startswith("."):
        name = "_" + name
    return name[:120]
