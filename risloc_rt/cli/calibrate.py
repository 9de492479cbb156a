"""``risloc calibrate CAPTURE --scene HALL -o calibration.toml``: the radar's range offset, the RIS's τ_RB and ζ,
the noise floor and the power offset, fitted against the ray-traced hall (``docs/formats.md``, "Calibration files")."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._outputs import output_file
from .common import CliError, add_force_flag, add_trace_flags, trace_cache, trace_settings, vector

__all__ = ["add_parser"]


def _run(args: argparse.Namespace) -> int:
    """``risloc calibrate``: fit the calibration against the traced hall, write ``-o``, print the five values [SI].

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (CAPTURE, --scene, --ue [m], -o, --force, --max-range-offset [m], trace flags).

    Returns
    -------
    int
        The exit status: 0 when the file is written;
        bad input raises ``CliError`` or ``MeasuredFormatError`` (exit 2).
    """
    from ..io.capture_file import load_capture
    from ..measured.compare.calibration_file import write_calibration
    from ..measured.compare.calibration_fit import calibrate_capture
    from ..measured.compare.traced_hall import hall_model, ue_position_of

    out = Path(args.output)
    if out.suffix not in (".toml", ".json"):
        raise CliError(f"-o {args.output}: name a .toml or .json file (e.g. -o calibration.toml)")
    with output_file(out, force=args.force, flag="-o") as target:
        capture = load_capture(args.capture)
        ue, source = ue_position_of(capture, None if args.ue is None else vector(args.ue, "--ue"))
        model = hall_model(capture, args.scene, ue, ue_source=source, trace=trace_settings(args),
                           cache=trace_cache(args))
        cal = calibrate_capture(capture, model.traced.paths, max_range_offset=args.max_range_offset)
        write_calibration(cal, target)
    print(f"calibrated {args.capture} against {model.scenario.scene_xml.parent.name} (radar at "
          f"{[round(float(x), 3) for x in ue]} m, {source}): wrote {out}")
    rows = [("range offset", cal.range_offset * 1e3, cal.range_offset_std * 1e3, "mm"),
            ("RIS loop-back delay tau_RB", cal.loopback_delay * 1e9, cal.loopback_delay_std * 1e9, "ns"),
            ("RIS amplification zeta", cal.amplification_db, cal.amplification_db_std, "dB"),
            ("noise power", cal.noise_power_dbm, cal.noise_power_dbm_std, "dBm"),
            ("power offset (ADC counts^2 per W)", cal.power_offset_db, cal.power_offset_db_std, "dB")]
    for name, value, std, unit in rows:
        print(f"  {name:36s} {value:+12.4f} ± {std:.2g} {unit}")
    return 0


def add_parser(sub) -> None:
    """Add ``calibrate`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    cal = sub.add_parser("calibrate", help="fit range offset, tau_RB, zeta, noise floor and power offset of a capture "
                                           "against a ray-traced hall",
                         description="Fit the radar's internal range offset, the RIS's loop-back delay and "
                                     "amplification, the noise floor and the receiver's power offset to a measured "
                                     "capture of a static radar at a known position, with 1-sigma uncertainties; "
                                     "'risloc simulate/locate/compare --calibration FILE' use the file.")
    cal.add_argument("capture", help="capture file (.npz) from 'risloc capture import'")
    cal.add_argument("--scene", required=True, help="the hall (name in scenes/ or folder) the capture was made in")
    cal.add_argument("--ue", metavar="X,Y,Z", help="the radar's position [m] (default: the capture's truth)")
    cal.add_argument("-o", "--output", required=True, help="calibration file to write (.toml or .json)")
    add_force_flag(cal, "an existing -o file")
    cal.add_argument("--max-range-offset", type=float, default=0.3, metavar="M",
                     help="range offsets searched, +-M metres (default: %(default)s)")
    add_trace_flags(cal)
    cal.set_defaults(func=_run)
