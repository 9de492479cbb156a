"""``risloc locate``: run the DSP on a capture file."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..io.capture_file import load_capture
from ..io.report import format_case, report_capture, write_result
from .common import add_processing_flags, processing_overrides

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    capture = load_capture(args.capture)
    processing = processing_overrides(args, capture.processing)
    out = Path(args.out) if args.out else None
    result = report_capture(Path(args.capture).stem, capture, out_dir=out, processing=processing, timing={})
    print(format_case(result))
    if out is not None:
        print(f"wrote {write_result(out, [result])} and plots under {out}/")
    return 0


def add_parser(sub) -> None:
    """Add ``locate`` to an ``add_subparsers()`` object."""
    loc = sub.add_parser("locate", help="run the DSP on a capture file")
    loc.add_argument("capture", help="capture file (.npz) from 'risloc simulate' or a converter")
    loc.add_argument("--out", help="directory for result.json and plots (default: print only)")
    add_processing_flags(loc)
    loc.set_defaults(func=_run)
