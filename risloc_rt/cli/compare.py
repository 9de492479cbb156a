"""``risloc compare CAPTURE --scene HALL -o DIR``: a measured capture against the ray-traced hall, as a page."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._outputs import output_folder
from .common import CliError, add_force_flag, add_trace_flags, trace_cache, trace_settings, vector

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    """``risloc compare``: the comparison page of a capture against the traced hall in ``-o``, and a summary line.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (CAPTURE, --scene, --baseline-scene, --ue [m], --calibration, -o, --force,
        trace flags).

    Returns
    -------
    int
        The exit status: 0 when the page is written;
        bad input raises ``CliError`` or ``MeasuredFormatError`` (exit 2).
    """
    out = Path(args.output)
    with output_folder(out, force=args.force, flag="-o", expect=("index.html", "comparison.json")) as stage:
        comparison, baseline, sweep_mean, position, source = _compare(args, stage)
    s = comparison.summary
    if baseline is not None:
        b = baseline.summary
        print(f"against the baseline scene {args.baseline_scene}: power residual rms {_num(b['power_residual_rms_db'])} "
              f"-> {_num(s['power_residual_rms_db'])} dB, delay residual rms {_num(b['delay_residual_rms_mm'])} -> "
              f"{_num(s['delay_residual_rms_mm'])} mm, P_ave rms difference {_num(b['pave_rms_difference_db'])} -> "
              f"{_num(s['pave_rms_difference_db'])} dB")
    print(f"wrote {out / 'index.html'} and the figures beside it: {s['peaks']} measured peak(s) at the best beam "
          f"{comparison.beam}, {s['explained']} explained by traced paths, {s['unexplained']} unexplained; delay "
          f"residual rms {_num(s['delay_residual_rms_mm'])} mm, power residual rms {_num(s['power_residual_rms_db'])}"
          f" dB; P_ave rms difference {_num(s['pave_rms_difference_db'])} dB; radar at "
          f"{[round(float(v), 3) for v in position]} m ({source})")
    before = ""
    if "baseline" in sweep_mean:
        before = (f" (baseline scene: {_num(sweep_mean['baseline']['power_residual_rms_db'])} dB, "
                  f"{_num(sweep_mean['baseline']['delay_residual_rms_mm'])} mm)")
    print(f"sweep mean over {sweep_mean['beams']} beams: {len(sweep_mean['peaks'])} static peak(s), power residual rms "
          f"{_num(sweep_mean['power_residual_rms_db'])} dB, delay residual rms "
          f"{_num(sweep_mean['delay_residual_rms_mm'])} mm{before}")
    return 0


def _num(v) -> str:
    """A number of the summary for the console (``nan`` when the comparison has none)."""
    return f"{float('nan') if v is None else v:.2f}"


def _compare(args: argparse.Namespace, stage: Path):
    """The comparison of ``args.capture`` with the traced hall, its page written into ``stage``.

    Returns
    -------
    (Comparison, Comparison or None, dict, ndarray, str)
        The comparison, the one against ``--baseline-scene`` (None without it), the sweep mean's static peaks
        (``comparison.json``'s ``sweep_mean``), the radar position used [m] and where it came from.
    """
    from ..io.capture_file import load_capture
    from ..io.report import process_capture
    from ..measured.compare.calibration_file import read_calibration
    from ..measured.compare.comparison import compare_capture
    from ..measured.compare.comparison_page import sweep_mean_document, write_comparison
    from ..measured.compare.sweep_mean_peaks import sweep_mean_residuals
    from ..measured.compare.traced_hall import hall_model, ue_position_of

    capture = load_capture(args.capture)
    cal = None if args.calibration is None else read_calibration(args.calibration)
    ue = None if args.ue is None else vector(args.ue, "--ue")
    estimate = None
    if ue is None and capture.truth is None:
        loc, _ = process_capture(capture)
        estimate = loc.position
        if estimate is None:
            raise CliError(f"{args.capture} has no truth and no position could be estimated (nothing detected); "
                           "give the radar's position with --ue X,Y,Z")
    position, source = ue_position_of(capture, ue, estimate=estimate)
    ris = None
    if cal is not None:
        from dataclasses import replace

        ris = replace(capture.ris, loopback_delay=cal.loopback_delay, amplification_db=cal.amplification_db)
    models = {scene: hall_model(capture, scene, position, ue_source=source, ris=ris, trace=trace_settings(args),
                                cache=trace_cache(args)) for scene in dict.fromkeys([args.scene, args.baseline_scene])
              if scene is not None}
    comparison = compare_capture(capture, models[args.scene], calibration=cal)
    sweep_mean = sweep_mean_residuals(capture, models[args.scene], comparison, cal)
    baseline = base_mean = None
    if args.baseline_scene is not None:  # the same capture, calibration and noise seed against the other hall
        baseline = compare_capture(capture, models[args.baseline_scene], calibration=cal)
        base_mean = sweep_mean_residuals(capture, models[args.baseline_scene], baseline, cal)
    sweep_mean = sweep_mean_document(sweep_mean, base_mean)
    write_comparison(comparison, stage, baseline=baseline, sweep_mean=sweep_mean)
    return comparison, baseline, sweep_mean, position, source


def add_parser(sub) -> None:
    """Add ``compare`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    p = sub.add_parser("compare", help="compare a measured capture with the ray-traced hall (HTML page, figures, JSON)",
                       description="Measured vs ray-traced: range profiles, delay-Doppler maps and the sweep power, "
                                   "every measured peak associated with a traced path (docs/measured-captures.md).")
    p.add_argument("capture", help="capture file (.npz), e.g. from 'risloc capture import'")
    p.add_argument("--scene", required=True, help="the hall (name in scenes/ or folder)")
    p.add_argument("--ue", metavar="X,Y,Z", help="the radar's position [m] (default: the capture's truth, else the "
                                                 "estimate)")
    p.add_argument("--calibration", metavar="FILE", help="a calibration file from 'risloc calibrate'")
    p.add_argument("--baseline-scene", metavar="HALL",
                   help="also compare against this hall (e.g. the one a 'calibrate --materials' folder was fitted "
                        "from): its residuals beside --scene's, before -> after, in the page and comparison.json")
    p.add_argument("-o", "--output", required=True, help="folder for index.html, comparison.json and the PNG figures")
    add_force_flag(p, "a page file in -o")
    add_trace_flags(p)
    p.set_defaults(func=_run)
