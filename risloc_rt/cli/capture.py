"""``risloc capture inspect``: what a raw TI DCA1000 capture holds, before anything is localized;
``risloc capture import``: a recorded RIS sweep (raw + config + sweep schedule) → a capture file."""

from __future__ import annotations

import argparse
import json

import numpy as np

from .common import CliError

__all__ = ["add_parser"]


def _layout_or_config(args: argparse.Namespace):
    if args.config is not None:
        if args.layout is not None:
            raise CliError("give --config CFG or --layout, not both")
        return args.config
    if args.layout is None:
        raise CliError("say how the file is laid out: --config CFG (mmWave SDK .cfg or Studio .json) or "
                       "--layout SAMPLES,RX,CHIRPS_PER_LOOP,LOOPS (e.g. 256,4,3,64)")
    from ..measured import RawLayout

    try:
        n, rx, cpl, loops = (int(x) for x in args.layout.split(","))
    except ValueError:
        raise CliError(f"--layout {args.layout!r} must be four integers SAMPLES,RX,CHIRPS_PER_LOOP,LOOPS, "
                       "e.g. 256,4,3,64") from None
    return RawLayout(num_samples=n, num_rx=rx, chirps_per_loop=cpl, num_loops=loops, adc_format=args.adc_format,
                     lanes=args.lanes or 2, iq_swap=args.iq_swap)


def _inspect(args: argparse.Namespace) -> int:
    from ..measured import inspect_capture, plot_inspection

    result = inspect_capture(args.raw, _layout_or_config(args), lanes=args.lanes, iq_swap=args.iq_swap,
                             form=args.form, max_frames=args.max_frames, min_range_bin=args.min_range_bin)
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
    else:
        d = result.to_dict()
        peak = d["peak"]
        where = "" if peak["range"] is None else f" = {peak['range']:.3f} m, {peak['velocity']:+.3f} m/s"
        print(f"{', '.join(d['files'])} ({d['form']}): {d['frames']} frame(s) x {d['chirps']} loops x "
              f"{d['channels']} channel(s) x {d['samples']} samples, {d['adc_format']}, {d['lanes']} lanes")
        print(f"  peak: range bin {peak['range_bin']}, Doppler bin {peak['doppler_bin']}{where}, "
              f"{peak['snr_db']:.1f} dB above the median bin")
        print(f"  dropped packets {d['dropped_packets']}, truncated bytes {d['truncated_bytes']}, clipped words "
              f"{d['clipping']['words']} ({100 * d['clipping']['fraction']:.3g} %), DC offset "
              f"{d['dc_offset']['i']:+.1f}{d['dc_offset']['q']:+.1f}j counts, I/Q imbalance "
              f"{d['iq_imbalance']['gain_db']:+.2f} dB / {d['iq_imbalance']['phase']:+.4f} rad")
        for flag in d["flags"]:
            print(f"  flag {flag['name']}: {flag['message']}")
    if args.plot:
        plot_inspection(result, args.plot)
        print(f"wrote {args.plot}")
    return 0


def _import(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..io.capture_file import save_capture
    from ..measured import import_capture

    out = Path(args.output)
    if out.suffix != ".npz" and out.with_name(out.name + ".npz").exists():
        raise CliError(f"-o {args.output} would be written as {out.name}.npz, which exists; name the file "
                       f"itself (-o {out.name}.npz) to replace it")
    target = out if out.suffix == ".npz" else out.with_name(out.name + ".npz")
    for name, given in (("RAW", args.raw), ("--config", args.config), ("--sweep", args.sweep)):
        if Path(given).exists() and target.exists() and target.resolve() == Path(given).resolve():
            raise CliError(f"-o {args.output} is the {name} input; give another file name for the capture")
    capture = import_capture(args.raw, args.config, args.sweep, lanes=args.lanes, iq_swap=args.iq_swap,
                             form=args.form)
    path = save_capture(capture, target)
    reader = capture.provenance["reader"]
    M, K, N = capture.cube.shape
    az = capture.sweep.angles[:, 0]
    truth = "none" if capture.truth is None else f"distance {capture.truth.distance:.4f} m"
    print(f"wrote {path}: {M} beams (frames {capture.frame_index[0]}..{capture.frame_index[-1]} of "
          f"{reader['frames_recorded']}, az {np.rad2deg(az[0]):+.2f}..{np.rad2deg(az[-1]):+.2f} deg) x {K} chirps x "
          f"{N} samples, channel {reader['channel']}, {len(reader['dropped_packets'])} dropped-packet run(s), "
          f"{len(reader['damaged_beams'])} damaged beam(s); truth: {truth}")
    return 0


def add_parser(sub) -> None:
    """Add ``capture`` (with ``inspect``) to an ``add_subparsers()`` object."""
    capture = sub.add_parser("capture", help="measured TI DCA1000 captures: inspect raw data, import a RIS sweep",
                             description="Measured captures (docs/measured-captures.md).")
    verbs = capture.add_subparsers(dest="capture_command", required=True, metavar="{inspect,import}")
    ins = verbs.add_parser("inspect", help="frames, chirps, channels, the range-Doppler peak, dropped packets, "
                                           "clipping, DC offset and I/Q imbalance of a raw capture")
    ins.add_argument("raw", help="adc_data_Raw_0.bin (its _Raw_1, _Raw_2 ... siblings are found)")
    ins.add_argument("--config", help="the radar configuration: mmWave SDK .cfg or mmWave Studio .json")
    ins.add_argument("--layout", metavar="SAMPLES,RX,CHIRPS_PER_LOOP,LOOPS",
                     help="the file's layout without a configuration (bins only, no metres)")
    ins.add_argument("--adc-format", choices=["complex1x", "complex2x", "real"], default="complex1x",
                     help="with --layout: the ADC output format (default: %(default)s)")
    ins.add_argument("--lanes", type=int, choices=[2, 4], help="LVDS lanes: 2 (xWR16/18/68xx, default) or 4 (xWR14xx)")
    ins.add_argument("--iq-swap", action="store_true", help="the file stores Q before I")
    ins.add_argument("--form", choices=["auto", "raw", "packets"], default="auto",
                     help="plain samples or packet-recorded UDP payloads (default: detect)")
    ins.add_argument("--max-frames", type=int, help="analyse only the first frames (all are counted)")
    ins.add_argument("--min-range-bin", type=int, default=0, help="ignore range bins below this (Tx-Rx leakage)")
    ins.add_argument("--json", action="store_true", help="print a machine-readable summary")
    ins.add_argument("--plot", metavar="PNG", help="write the range profile and range-Doppler map")
    ins.set_defaults(func=_inspect)

    imp = verbs.add_parser("import", help="a recorded RIS sweep (raw capture + radar config + sweep schedule) -> "
                                          "a capture file for risloc locate")
    imp.add_argument("raw", help="adc_data_Raw_0.bin (its _Raw_1, _Raw_2 ... siblings are found)")
    imp.add_argument("--config", required=True, help="the radar configuration: mmWave SDK .cfg or mmWave Studio .json")
    imp.add_argument("--sweep", required=True, metavar="SWEEP.toml",
                     help="the sweep schedule: beams, frames per beam, first frame, channel, RIS (docs/formats.md)")
    imp.add_argument("-o", "--output", required=True, help="capture file to write (.npz)")
    imp.add_argument("--lanes", type=int, choices=[2, 4], help="LVDS lanes: 2 (xWR16/18/68xx, default) or 4 (xWR14xx)")
    imp.add_argument("--iq-swap", action="store_true", help="the file stores Q before I")
    imp.add_argument("--form", choices=["auto", "raw", "packets"], default="auto",
                     help="plain samples or packet-recorded UDP payloads (default: detect)")
    imp.set_defaults(func=_import)
