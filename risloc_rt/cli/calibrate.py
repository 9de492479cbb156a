"""``risloc calibrate``: the radar/RIS constants of one capture, or the hall's materials from several.

- ``risloc calibrate CAPTURE --scene HALL -o calibration.toml``: the radar's range offset, the
  RIS's τ_RB and ζ, the noise floor and the power offset, fitted against the ray-traced hall
  (``docs/formats.md``, "Calibration files").
- ``risloc calibrate CAPTURE [CAPTURE...] --scene HALL --materials NAME,... --out DIR``: the named
  materials' ε_r and σ [S/m] at the carrier, fitted to the explained peak powers of captures at
  known radar positions by gradients through the ray tracer, written as a new scene folder with
  the fit's provenance (:mod:`risloc_rt.cli.calibrate_materials`, ``docs/calibration-materials.md``).
"""

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
        The parsed command line (CAPTURE..., --scene, --ue [m], -o, --force, --max-range-offset [m], trace flags;
        with --materials: --out, --scattering, --calibration, --fixed, --max-iter, --model-sigma [dB],
        --peak-prominence/--peak-floor [dB]).

    Returns
    -------
    int
        The exit status: 0 when the file is written;
        bad input raises ``CliError`` or ``MeasuredFormatError`` (exit 2).
    """
    if args.materials is not None:
        from .calibrate_materials import run_materials

        return run_materials(args)
    if getattr(args, "scattering", None) is not None:
        raise CliError("--scattering names materials whose scattering coefficient a material fit fits: give --materials "
                       "NAME,... (and --out DIR) with it")
    if args.out is not None:
        raise CliError("--out names the fitted scene folder of a material fit: give --materials NAME,... with it, or "
                       "-o FILE for the radar/RIS calibration")
    if args.output is None:
        raise CliError("give -o calibration.toml (radar/RIS constants of one capture) or --materials NAME,... --out DIR "
                       "(the hall's materials)")
    if len(args.capture) != 1 or args.calibration or (args.ue is not None and len(args.ue) > 1):
        raise CliError("-o calibrates one capture (one CAPTURE, at most one --ue, no --calibration); several captures "
                       "are for --materials")
    args.capture = args.capture[0]
    args.ue = None if args.ue is None else args.ue[0]
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
                                     "'risloc simulate/locate/compare --calibration FILE' use the file. With "
                                     "--materials NAME,... --out DIR: fit those materials' eps_r and sigma to the "
                                     "explained peak powers of one or more captures at known radar positions and "
                                     "write a new scene folder (docs/calibration-materials.md).")
    cal.add_argument("capture", nargs="+", help="capture file(s) (.npz) from 'risloc capture import' (one for -o, "
                                                "one or more for --materials)")
    cal.add_argument("--scene", required=True, help="the hall (name in scenes/ or folder) the capture was made in")
    cal.add_argument("--ue", metavar="X,Y,Z", action="append",
                     help="the radar's position [m] (default: the capture's truth); with --materials once per capture")
    cal.add_argument("-o", "--output", help="calibration file to write (.toml or .json)")
    add_force_flag(cal, "an existing -o file (with --out: an earlier fitted scene folder)")
    cal.add_argument("--materials", metavar="NAME,NAME",
                     help="fit these materials' eps_r and sigma [and, with --scattering, S] (names as in the scene XML without 'mat-', e.g. "
                          "concrete-200mm) instead of the radar/RIS constants; needs --out")
    cal.add_argument("--out", metavar="DIR", help="with --materials: the new scene folder (spec with the fitted "
                                                  "materials, scene files, material-fit.json); must not exist")
    cal.add_argument("--calibration", metavar="FILE", action="append",
                     help="with --materials: a capture's radar/RIS calibration from 'risloc calibrate -o'; once for "
                          "all captures or once per capture")
    cal.add_argument("--scattering", metavar="NAME,NAME",
                     help="with --materials: fit these materials' scattering coefficient S too (a subset of "
                          "--materials), stated by its profile likelihood over the full simulator (diffuse returns "
                          "included) and written to the fitted spec's scattering_coefficient; without it S stays the "
                          "scene's. The --calibration's power offset must not come from the same walls (a "
                          "calibration against the smooth hall absorbs their loss: docs/calibration-materials.md)")
    cal.add_argument("--fixed", metavar="NAME:eps_r|NAME:sigma", action="append", default=[],
                     help="with --materials: hold this parameter at the scene's value (e.g. eps_r known from elsewhere "
                          "when the peaks see only |Gamma|^2 at normal incidence); repeatable")
    cal.add_argument("--max-iter", type=int, default=30, metavar="N",
                     help="with --materials: most Levenberg-Marquardt iterations (default: %(default)s)")
    cal.add_argument("--model-sigma", type=float, default=0.3, metavar="DB",
                     help="with --materials: the ray tracer's model error per peak power [dB], in quadrature with "
                          "each peak's noise (default: %(default)s)")
    cal.add_argument("--peak-profile", choices=["sweep-mean", "best-beam"], default="sweep-mean",
                     help="with --materials: read the static peaks from the complex mean over the sweep's beams "
                          "(default; 61 beams average the noise down ~18 dB) or from the best beam's range profile, "
                          "as compare does (docs/calibration-materials.md)")
    cal.add_argument("--allow-weak", action="store_true",
                     help="with --materials: write the fitted scene even when a parameter's 1-sigma is only a local "
                          "figure (the profile check's 'weak'): material-fit.json marks it and states its "
                          "profile-likelihood intervals; default: refuse")
    cal.add_argument("--peak-prominence", type=float, default=6.0, metavar="DB",
                     help="with --materials: a measured peak's prominence [dB] (default: %(default)s)")
    cal.add_argument("--peak-floor", type=float, default=12.0, metavar="DB",
                     help="with --materials: a measured peak's height above the profile's median [dB] "
                          "(default: %(default)s)")
    cal.add_argument("--max-range-offset", type=float, default=0.3, metavar="M",
                     help="range offsets searched, +-M metres (default: %(default)s)")
    add_trace_flags(cal)
    cal.set_defaults(func=_run)
