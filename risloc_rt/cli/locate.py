"""``risloc locate``: run the DSP on a capture file."""

from __future__ import annotations

import argparse
from contextlib import nullcontext
from pathlib import Path

from .._outputs import output_folder, safe_name
from ..io.capture_file import load_capture
from ..io.fused import check_distinct_ris, common_truth, format_fused, fuse_cases, fused_dict
from ..io.report import format_case, format_environment, report_capture, run_environment, write_result
from .common import (EXIT_NO_DETECTION, CliError, add_device_flag, add_estimator_flags, add_force_flag,
                     add_processing_flags, device_backend, estimator_options, processing_overrides)

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    """``risloc locate``: each capture localized; with several (one per RIS) their fixes fused.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        0 with a position, ``EXIT_NO_DETECTION`` when nothing was detected (by any RIS).
    """
    backend = device_backend(args)  # a missing GPU or a bad --device: one line before anything is read or written
    names = [safe_name(Path(p).stem) for p in args.capture]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise CliError(f"two capture files are named {twice[0]!r}: the results are kept by file name; rename one "
                       "(e.g. after its RIS: ris0.npz, ris1.npz)")
    captures = [_load(path, args) for path in args.capture]
    check_distinct_ris(names, captures)  # before any is localized
    env = run_environment(backend)
    out = Path(args.out) if args.out else None
    with (output_folder(out, force=args.force, flag="--out", expect=("result.json",)) if out else
          nullcontext()) as stage:
        results = []
        for name, capture in zip(names, captures):
            budget = None
            if capture.provenance.get("source") == "measurement":
                from ..measured.compare.uncertainty_budget import apply_budget as budget
            results.append(report_capture(name, capture, out_dir=stage, processing=processing_overrides(
                args, capture.processing), timing={}, budget=budget, backend=backend, **estimator_options(args)))
        fused = truth = None
        if len(results) > 1:
            fused = fuse_cases(results)
            truth = common_truth(results)
        if stage is not None:
            write_result(stage, results, device=env,
                         fused=None if len(results) == 1 else fused_dict(fused, truth))
    for result in results:
        print(format_case(result))
    if len(results) > 1:
        print(format_fused(fused, truth, moved=truth is None and all(r.truth is not None for r in results)))
    print(format_environment(env))
    if out is not None:
        print(f"wrote {out / 'result.json'} and plots under " + ", ".join(f"{out / n}/" for n in names))
    detected = fused is not None if len(results) > 1 else results[0].localization.detected
    return 0 if detected else EXIT_NO_DETECTION


def _load(path: str, args: argparse.Namespace):
    """One capture file, with ``--calibration`` applied.

    Parameters
    ----------
    path : str
        The capture file (.npz).
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    risloc_rt.model.Capture
    """
    capture = load_capture(path)
    if args.calibration is not None:
        from ..measured.compare.calibration_file import apply_to_capture, read_calibration

        capture = apply_to_capture(capture, read_calibration(args.calibration))
    return capture


def add_parser(sub) -> None:
    """Add ``locate`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    loc = sub.add_parser("locate", help="run the DSP on a capture file (several: one per RIS, fused)",
                         description="Detect the RIS return in a capture and localize the radar, with 1-sigma "
                                     "uncertainties and flags (docs/flags.md). Given the captures of several RISs "
                                     "(one sweep each, the radar where it was), their fixes are fused into one 3-D "
                                     "position with its covariance, a RIS that disagrees with the others left out "
                                     "(flag inconsistent-ris; docs/estimation.md 'Several RISs'). Exit status 0 with "
                                     f"a position, {EXIT_NO_DETECTION} when nothing was detected (no position), 2 for "
                                     "bad input.")
    loc.add_argument("capture", nargs="+", help="capture file(s) (.npz) from 'risloc simulate', 'risloc capture "
                                                "import' or a converter; several: one per RIS, named after it")
    loc.add_argument("--out", help="directory for result.json and plots (default: print only)")
    add_force_flag(loc, "a result.json or plot in --out")
    loc.add_argument("--calibration", metavar="FILE",
                     help="a calibration file from 'risloc calibrate': its tau_RB and range offset set the distance")
    add_processing_flags(loc)
    add_estimator_flags(loc)
    add_device_flag(loc)
    loc.set_defaults(func=_run)
