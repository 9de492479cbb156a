"""The ``risloc`` command line: one module per verb, each a thin layer over the library.

``demo``, ``simulate``, ``locate``, ``trace``, ``scene`` (``build``, ``check``, ``show``), ``capture`` and
``study`` (``sweep``, ``map``), ``speed``, ``track``.

One error style (``docs/robustness.md``): every error is one line on stderr,
``risloc VERB: error: ...``, naming what is wrong and how to fix it. Exit status 2 for bad input
(a wrong argument, a missing or malformed file, a value out of range, a path that cannot be
written), 1 for a failure of the run itself (out of memory, a ray-tracer failure, a full disk),
130 when interrupted (Ctrl-C); outputs are written atomically, so an interrupted run leaves no
partial file. ``RISLOC_DEBUG=1`` prints the traceback as well.
"""

from __future__ import annotations

import argparse
import errno
import os
import re
import sys
from typing import Any, Sequence

__all__ = ["build_parser", "main", "join_negative_values", "value_options", "EXIT_BAD_INPUT", "EXIT_FAILURE",
           "EXIT_INTERRUPTED"]

#: Exit status for bad input (arguments, files, values).
EXIT_BAD_INPUT = 2
#: Exit status for a failure of the run (memory, ray tracer, disk).
EXIT_FAILURE = 1
#: Exit status after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130
#: Exit status after SIGTERM (128 + SIGTERM: ``kill``, ``timeout``, a batch system's time limit).
EXIT_TERMINATED = 143

#: A value that starts with '-' but is a number or a comma-separated list of numbers (``-6,1,2``).
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


class _Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line, ``PROG: error: ...``, exit status 2."""

    def error(self, message: str) -> Any:  # noqa: D102 - argparse API
        hint = f"; see '{self.prog} --help'"
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {_one_line(message)}{hint}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``risloc``.

    Returns
    -------
    argparse.ArgumentParser
        Every verb a sub-command; its errors are one line with exit status 2.
    """
    from . import calibrate, capture, compare, demo, locate, scene, simulate, speed, study, trace, track

    parser = _Parser(prog="risloc", description="RIS-enabled self-localization of an FMCW radar")
    sub = parser.add_subparsers(dest="command", required=True)
    demo.add_parser(sub)
    simulate.add_parser(sub)
    trace.add_parser(sub)
    scene.add_parser(sub)
    locate.add_parser(sub)
    capture.add_parser(sub)
    calibrate.add_parser(sub)
    compare.add_parser(sub)
    study.add_parser(sub)
    speed.add_parser(sub)
    track.add_parser(sub)
    return parser


def value_options(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string (of ``parser`` and its sub-parsers) that takes exactly one value.

    :func:`join_negative_values` needs them to keep ``--ue -1,2,1.2`` one value.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``risloc`` parser (:func:`build_parser`) or any of its sub-parsers.

    Returns
    -------
    set of str
        Option strings such as ``"--ue"`` and ``"-o"``.
    """
    out: set[str] = set()
    for action in parser._actions:  # argparse has no public walk over its actions
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                out |= value_options(child)
        elif action.option_strings and action.nargs is None:
            out.update(action.option_strings)
    return out


def join_negative_values(argv: Sequence[str], value_options: set[str]) -> list[str]:
    """``--ue -6,1,2`` -> ``--ue=-6,1,2``: a negative value after an option that takes one.

    argparse takes ``-6,1,2`` for an option (only plain negative numbers such as ``-6`` are
    recognised), so coordinates with a negative first component would need ``--ue=-6,1,2``;
    this makes the form a user writes work as written.

    Parameters
    ----------
    argv : sequence of str
        The command line (without the program name).
    value_options : set of str
        The option strings that take exactly one value.

    Returns
    -------
    list of str
        ``argv`` with each such option and its negative value joined by ``=``; nothing after ``--``
        is touched.
    """
    out: list[str] = []
    args = list(argv)
    i = 0
    while i < len(args):
        token = args[i]
        if (token in value_options and i + 1 < len(args) and _NEGATIVE_VALUE.match(args[i + 1])):
            out.append(f"{token}={args[i + 1]}")
            i += 2
            continue
        if token == "--":
            out.extend(args[i:])
            break
        out.append(token)
        i += 1
    return out


def _one_line(message: Any) -> str:
    """``message`` as one line (newlines and runs of spaces collapsed)."""
    return " ".join(str(message).split())


def _command(args: argparse.Namespace | None) -> str:
    if args is None:
        return "risloc"
    verb = getattr(args, "command", None) or ""
    sub = (getattr(args, "scene_command", None) or getattr(args, "capture_command", None)
           or getattr(args, "study_command", None))
    return " ".join(["risloc", verb] + ([sub] if sub else []))


def _interrupted_outputs(args: argparse.Namespace | None) -> str:
    """What an interrupted verb left on disk, for its one-line Ctrl-C message."""
    recording = getattr(args, "capture_command", None) == "record" or getattr(args, "live", False)
    if recording:  # written in place as it arrived (measured.live.recording_writer), not atomically
        return ("the recording in --out holds what arrived, readable as it is, its lost packets zero-filled and "
                "listed in lost_packets.csv")
    return "each file it wrote is complete (atomic writes), a multi-file output may lack some: run it again"


def _classify(exc: BaseException) -> tuple[int, str]:
    """Exit status and one-line message of an exception escaping a verb."""
    from ..hall.raytrace.backend import BackendError

    if isinstance(exc, MemoryError):
        return EXIT_FAILURE, ("out of memory" + (f" ({_one_line(exc)})" if str(exc) else "") +
                              "; reduce the sizes (samples, chirps, DFT lengths, --samples, --depth) or free memory")
    if isinstance(exc, BackendError):
        return EXIT_FAILURE, _one_line(exc)
    if isinstance(exc, OSError):
        name = f" {exc.filename!r}" if getattr(exc, "filename", None) else ""
        reason = exc.strerror or _one_line(exc)
        if exc.errno in (errno.ENOENT, errno.EACCES, errno.EPERM, errno.EISDIR, errno.ENOTDIR, errno.EROFS,
                         errno.ENAMETOOLONG, errno.EEXIST, errno.ELOOP):
            return EXIT_BAD_INPUT, (f"cannot use{name}: {reason}; check that the path exists (for inputs) "
                                    "or that its folder is writable (for outputs)")
        if exc.errno is None and isinstance(exc, FileNotFoundError):
            return EXIT_BAD_INPUT, _one_line(exc)
        return EXIT_FAILURE, f"I/O failure on{name}: {reason}; check the disk (space, permissions) and retry"
    if isinstance(exc, (ValueError, TypeError, LookupError)):
        return EXIT_BAD_INPUT, _one_line(exc)
    if isinstance(exc, RuntimeError):
        return EXIT_FAILURE, (f"the run failed: {type(exc).__name__}: {_one_line(exc)[:400]}; "
                              "try smaller settings (--samples, --depth) or report it with RISLOC_DEBUG=1")
    return EXIT_FAILURE, (f"internal error {type(exc).__name__}: {_one_line(exc)[:400]}; "
                          "please report it with the output of RISLOC_DEBUG=1")


def _redeliver_interrupt(previous: Any, state: dict[str, Any]) -> Any:
    """A ``sys.unraisablehook`` that re-delivers a Ctrl-C swallowed in a ``__del__`` or callback.

    Python cannot raise an exception out of a finalizer: a ``KeyboardInterrupt`` that lands there
    would print "Exception ignored ..." with a traceback and the run would go on. This hook prints
    nothing for it and interrupts the main thread again, so the interrupt reaches :func:`main`.
    Once Ctrl-C has been received (``state["interrupted"]``), it also silences the finalizers of
    objects whose construction the interrupt cut short (an ``AttributeError`` in the ``__del__`` of a
    half-built object, e.g. pyparsing's ``Forward`` while matplotlib is imported): they are the
    interrupt's consequence, and the one line says what happened.
    """
    import _thread

    def hook(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            _thread.interrupt_main()
        elif not state.get("interrupted"):
            previous(unraisable)

    return hook


def _note_interrupt(state: dict[str, Any]) -> Any:
    """A ``SIGINT`` (and ``SIGTERM``) handler: note the interrupt in ``state``, then raise ``KeyboardInterrupt`` as
    Python's does, so the verb unwinds as after Ctrl-C (staging folders removed, workers stopped)."""
    import signal

    def handler(signum: int, frame: Any) -> None:
        state["interrupted"] = True
        if signum == signal.SIGTERM:
            state["terminated"] = True
        raise KeyboardInterrupt

    return handler


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``risloc``: parse, run the verb, turn every error into one line on stderr.

    The console script calls this with nothing imported but this light module: every heavy import
    (the verbs, NumPy, SciPy, the ray tracer) happens inside the handler, so Ctrl-C at any moment,
    even during start-up, ends with one line on stderr and exit status 130, never a traceback.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: ``sys.argv[1:]``). Without ``argv`` (``risloc`` as a program) a
        second Ctrl-C after the first, or one while the process exits, is ignored, and a Ctrl-C
        that lands in a finalizer is re-delivered; with ``argv`` (a call from Python) the
        process's signal handling is left as it was.

    Returns
    -------
    int
        The exit status: 0, :data:`EXIT_FAILURE` (1), :data:`EXIT_BAD_INPUT` (2),
        :data:`EXIT_INTERRUPTED` (130), or a verb's own (``EXIT_NO_DETECTION``, 3).
    """
    import signal
    import threading

    program = argv is None and threading.current_thread() is threading.main_thread()
    state: dict[str, Any] = {"args": None, "interrupted": False}
    if program:
        sys.unraisablehook = _redeliver_interrupt(sys.unraisablehook, state)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _note_interrupt(state))
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:  # killed, the staging folders stayed behind
            signal.signal(signal.SIGTERM, _note_interrupt(state))
    try:
        return _main(list(sys.argv[1:] if argv is None else argv), state)
    except KeyboardInterrupt:
        state["interrupted"] = True
        if program:  # the one line below must not be cut by a second Ctrl-C
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        what = "terminated (SIGTERM)" if state.get("terminated") else "interrupted"
        print(f"{_command(state['args'])}: {what}; {_interrupted_outputs(state['args'])}", file=sys.stderr)
        return EXIT_TERMINATED if state.get("terminated") else EXIT_INTERRUPTED
    finally:
        if program:  # Ctrl-C while the interpreter shuts down would print a traceback
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a ``KeyboardInterrupt`` is in ``exc``'s chain of causes and contexts."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, KeyboardInterrupt):
            return True
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return False


def _main(raw: list[str], state: dict[str, Any]) -> int:
    """:func:`main` without the Ctrl-C handling: imports the verbs, parses, runs, reports errors."""
    try:
        parser = build_parser()
        state["args"] = parser.parse_args(join_negative_values(raw, value_options(parser)))
        return int(state["args"].func(state["args"]))
    except SystemExit as exc:  # argparse: --help (0) and usage errors (2, already printed as one line)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - the one place every error becomes one line
        if state.get("interrupted") or _caused_by_interrupt(exc):
            # Ctrl-C that Python turned into another error on its way out (Python 3.11 wraps an exception
            # raised in a descriptor's __set_name__ while a class is made, e.g. a dataclass during an
            # import, in a RuntimeError): it is still an interrupt, exit 130 with its one line
            raise KeyboardInterrupt from None
        from .common import CliError

        if isinstance(exc, CliError):
            print(f"{_command(state['args'])}: error: {_one_line(exc)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        if os.environ.get("RISLOC_DEBUG"):
            import traceback

            traceback.print_exc()
        status, message = _classify(exc)
        print(f"{_command(state['args'])}: error: {message}", file=sys.stderr)
        return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
