"""The ``risloc`` command line: one module per verb, each a thin layer over the library.

``demo``, ``simulate``, ``locate``, ``trace`` and ``scene`` (``build``, ``check``, ``show``).
Every error is one line on stderr (``risloc VERB: error: ...``) with exit status 2.
"""

from __future__ import annotations

import sys
from typing import Sequence

__all__ = ["build_parser", "main"]


def build_parser():
    """The argument parser of ``risloc``."""
    import argparse

    from . import demo, locate, scene, simulate, trace

    parser = argparse.ArgumentParser(prog="risloc", description="RIS-enabled self-localization of an FMCW radar")
    sub = parser.add_subparsers(dest="command", required=True)
    demo.add_parser(sub)
    simulate.add_parser(sub)
    trace.add_parser(sub)
    scene.add_parser(sub)
    locate.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``risloc``; returns the exit status."""
    from ..hall.raytrace.backend import BackendError
    from ..io.capture_file import CaptureFormatError
    from .common import CliError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except (CliError, CaptureFormatError, FileNotFoundError, ValueError, TypeError, BackendError) as exc:
        print(f"risloc {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
