"""``risloc locate``: run the DSP on a capture file."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._outputs import output_folder, safe_name
from ..io.capture_file import load_capture
from ..io.report import format_case, format_environment, report_capture, run_environment, write_result
from .common import (EXIT_NO_DETECTION, add_device_flag, add_estimator_flags, add_force_flag, add_processing_flags,
                     device_backend, estimator_options, processing_overrides)

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    backend = device_backend(args)  # a missing GPU or a bad --device: one line before anything is read or written
    capture = load_capture(args.capture)
    if args.calibration is not None:
        from ..measured.compare.calibration_file import apply_to_capture, read_calibration

        capture = apply_to_capture(capture, read_calibration(args.calibration))
    processing = processing_overrides(args, capture.processing)
    name = safe_name(Path(args.capture).stem)
    budget = None
    if capture.provenance.get("source") == "measurement":
        from ..measured.compare.uncertainty_budget import apply_budget as budget
    if not args.out:
        result = report_capture(name, capture, out_dir=None, processing=processing, timing={}, budget=budget,
                                backend=backend, **estimator_options(args))
        print(format_case(result))
        print(format_environment(run_environment(backend)))
        return 0 if result.localization.detected else EXIT_NO_DETECTION
    out = Path(args.out)
    with output_folder(out, force=args.force, flag="--out", expect=("result.json",)) as stage:
        result = report_capture(name, capture, out_dir=stage, processing=processing, timing={}, budget=budget,
                                backend=backend, **estimator_options(args))
        env = run_environment(backend)
        write_result(stage, [result], device=env)
    print(format_case(result))
    print(format_environment(env))
    print(f"wrote {out / 'result.json'} and plots under {out / name}/")
    return 0 if result.localization.detected else EXIT_NO_DETECTION


def add_parser(sub) -> None:
    """Add ``locate`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    loc = sub.add_parser("locate", help="run the DSP on a capture file",
                         description="Detect the RIS return in a capture and localize the radar, with 1-sigma "
                                     "uncertainties and flags (docs/flags.md). Exit status 0 with a position, "
                                     f"{EXIT_NO_DETECTION} when nothing was detected (no position), 2 for bad input.")
    loc.add_argument("capture", help="capture file (.npz) from 'risloc simulate' or a converter")
    loc.add_argument("--out", help="directory for result.json and plots (default: print only)")
    add_force_flag(loc, "a result.json or plot in --out")
    loc.add_argument("--calibration", metavar="FILE",
                     help="a calibration file from 'risloc calibrate': its tau_RB and range offset set the distance")
    add_processing_flags(loc)
    add_estimator_flags(loc)
    add_device_flag(loc)
    loc.set_defaults(func=_run)
