"""``risloc capture inspect``: what a raw TI DCA1000 capture holds, before anything is localized;
``risloc capture import``: a recorded RIS sweep (raw + config + sweep schedule) → a capture file;
``risloc capture record``: record from a TI radar and a DCA1000 on Linux (docs/live-capture.md)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from .._outputs import check_output_file, output_file
from .common import CliError, add_force_flag, npz_target
from .connection import add_connection_flags, add_sweep_import_flags, record_plan, sweep_import_options

__all__ = ["add_parser"]


def _layout_or_config(args: argparse.Namespace):
    """What ``capture inspect`` reads the file with: the ``--config`` path, or a ``RawLayout`` from ``--layout``.

    Parameters
    ----------
    args : argparse.Namespace
        ``config``, ``layout`` (``SAMPLES,RX,CHIRPS_PER_LOOP,LOOPS``), ``adc_format``, ``lanes``, ``iq_swap``.

    Returns
    -------
    str or RawLayout
        The configuration file's path (mmWave SDK ``.cfg`` or Studio ``.json``), or the bare layout.
    """
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
                     lanes=args.lanes or 2, iq_swap=bool(args.iq_swap))


def _inspect(args: argparse.Namespace) -> int:
    """``risloc capture inspect``: print the inspection (or ``--json``), write ``--plot``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (RAW, --config or --layout, --json, --plot, ...).

    Returns
    -------
    int
        The exit status: 0 after printing;
        bad input raises ``CliError`` or ``MeasuredFormatError`` (exit 2).
    """
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
            print(f"  flag {flag['code']}: {flag['message']}")
    if args.plot:
        with output_file(args.plot, force=args.force, flag="--plot") as target:
            plot_inspection(result, target)
        print(f"wrote {args.plot}")
    return 0


def _import_options(args: argparse.Namespace) -> dict:
    """The keywords of ``import_capture`` from the command line (``--first-frame``, ``--channels``, ...).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    dict
        ``lanes``, ``iq_swap``, ``form``, ``first_frame`` (int, ``"auto"`` or None), ``leakage``,
        ``gate_range`` [m], ``channels``, ``min_confidence``.
    """
    return {"lanes": args.lanes, "iq_swap": args.iq_swap, "form": args.form, **sweep_import_options(args)}


def _wrote_line(path, capture) -> str:
    """The summary line of one imported capture.

    Parameters
    ----------
    path : Path
        The capture file written.
    capture : Capture
        The imported capture.

    Returns
    -------
    str
    """
    reader = capture.provenance["reader"]
    M, K, N = capture.cube.shape
    az = capture.sweep.angles[:, 0]
    truth = "none" if capture.truth is None else f"distance {capture.truth.distance:.4f} m"
    slot = capture.provenance.get("ris_slot")
    who = "" if not slot else f"RIS {slot['name']}, "
    return (f"wrote {path}: {who}{M} beams (frames {capture.frame_index[0]}..{capture.frame_index[-1]} of "
            f"{reader['frames_recorded']}, az {np.rad2deg(az[0]):+.2f}..{np.rad2deg(az[-1]):+.2f} deg) x {K} chirps x "
            f"{N} samples, channel {reader['channel']}, {len(reader['dropped_packets'])} dropped-packet run(s), "
            f"{len(reader['damaged_beams'])} damaged beam(s); truth: {truth}")


def _import_all(args: argparse.Namespace, schedules) -> int:
    """``risloc capture import`` of a recording of several RISs without ``--ris``: ``-o`` a folder, one file per RIS.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    schedules : SweepSchedules
        The recording's sweep schedule (``[[ris]]`` tables).

    Returns
    -------
    int
        The exit status: 0 when every capture is written (``<RIS name>.npz`` in ``-o``, one line each).
    """
    from pathlib import Path

    from .._outputs import output_folder, safe_name
    from ..io.capture_file import save_capture
    from ..measured import import_captures

    folder = Path(args.output)
    names = [f"{safe_name(n)}.npz" for n in schedules.names]
    if folder.suffix == ".npz" and not folder.is_dir():
        raise CliError(f"-o {args.output}: {args.sweep} describes {len(names)} RISs ({', '.join(schedules.names)}): -o "
                       f"is a folder that gets one capture per RIS ({', '.join(names)}); give a folder, or --ris NAME "
                       "to import one RIS into a file")
    options = _import_options(args)
    with output_folder(folder, force=args.force, flag="-o", expect=tuple(names)) as stage:
        captures = list(import_captures(args.raw, args.config, schedules, **options).values())
        for name, capture in zip(names, captures):
            save_capture(capture, stage / name)
    for name, capture in zip(names, captures):
        print(_wrote_line(folder / name, capture))
        for warning in capture.provenance.get("import_warnings", []):
            print(f"warning: {warning}", file=sys.stderr)
    return 0


def _import(args: argparse.Namespace) -> int:
    """``risloc capture import``: a recorded RIS sweep → a capture file (``-o``), with a summary line.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (RAW, --config, --sweep, -o, --ris, --first-frame, --leakage, --channels, ...).

    Returns
    -------
    int
        The exit status: 0 when the capture file is written (a first frame the recording
        contradicts is a one-line ``warning:`` on stderr and the capture's ``schedule-mismatch``
        flag); bad input raises ``CliError`` or ``MeasuredFormatError`` (exit 2). A schedule of
        ``[[ris]]`` tables without ``--ris``: ``-o`` is a folder that gets ``<RIS name>.npz`` per RIS.
    """
    from pathlib import Path

    from ..io.capture_file import save_capture
    from ..measured import import_capture, read_sweep_schedules

    schedules = read_sweep_schedules(args.sweep)
    if schedules.several and args.ris is None:
        return _import_all(args, schedules)
    schedules.index(args.ris)                                 # a RIS the recording does not have: one line
    target = check_output_file(npz_target(args.output), force=args.force, flag="-o")
    for name, given in (("RAW", args.raw), ("--config", args.config), ("--sweep", args.sweep)):
        if Path(given).exists() and target.exists() and target.resolve() == Path(given).resolve():
            raise CliError(f"-o {args.output} is the {name} input; give another file name for the capture")
    capture = import_capture(args.raw, args.config, schedules, ris=args.ris, **_import_options(args))
    with output_file(target, force=args.force, flag="-o") as staged:
        save_capture(capture, staged)
    print(_wrote_line(target, capture))
    for warning in capture.provenance.get("import_warnings", []):
        print(f"warning: {warning}", file=sys.stderr)
    a = capture.provenance["alignment"]
    conf = "given" if a["confidence"] is None else f"confidence {a['confidence']:.3f}"
    print(f"  alignment {a['method']}: first frame {a['first_frame']}, sweep start {a['start']:.3f} frames, "
          f"{a['dwell']:.4f} frames per beam (RIS clock {a['drift'] * 100:+.3f} %), {conf}, "
          f"{len(a['mixed_beams'])} mixed beam(s), {sum(len(b) > 1 for b in a['beam_chirps'])} across two frames; "
          f"leakage removal: {capture.provenance['leakage']['method']}; "
          f"channels {capture.provenance['channels']['channels']} ({capture.provenance['channels']['combine']})")
    return 0


class _RecordProgress:
    """The ``capture record`` progress line (tqdm on stderr): MB/s, frames, lost packets, socket high-water."""

    def __init__(self, total_bytes: int | None) -> None:
        self.total = total_bytes
        self.bar = None             # drawn at the first report: a refused .cfg or a dead link show no empty bar
        self.shown = 0
        self.warned = False

    def __call__(self, progress) -> None:
        """Show one :class:`~risloc_rt.measured.live.record.RecordingProgress`.

        Parameters
        ----------
        progress : RecordingProgress
            The recording's state.
        """
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, unit="B", unit_scale=True, desc="record", file=sys.stderr,
                            dynamic_ncols=True, leave=True)
        if not self.warned and progress.socket_buffer is not None and progress.socket_buffer.hint():
            self.bar.write(f"warning: {progress.socket_buffer.hint()}", file=sys.stderr)
        self.warned = True
        self.bar.update(progress.final_bytes - self.shown)
        self.shown = progress.final_bytes
        self.bar.set_postfix_str(f"{progress.rate / 1e6:.2f} MB/s, {progress.frames} frames, "
                                 f"{progress.lost_packets} lost packets, socket high-water "
                                 f"{progress.socket_high_water / 1e6:.2f} MB", refresh=False)

    def close(self) -> None:
        """Close the bar (if one was drawn)."""
        if self.bar is not None:
            self.bar.close()


def _print_summary(summary, stream) -> None:
    """The ``recorded …`` line and the first 20 runs of lost packets (the rest: ``lost_packets.csv``)."""
    print(f"recorded {summary.describe()}", file=stream)
    for run in summary.lost[:20]:
        print(f"  lost packets {run.first_sequence}..{run.first_sequence + run.count - 1}: {run.num_bytes} B "
              f"zero-filled at byte {run.stream_offset}", file=stream)
    if len(summary.lost) > 20:
        print(f"  ... {len(summary.lost) - 20} more runs in {summary.folder / 'lost_packets.csv'}", file=stream)


def _record(args: argparse.Namespace) -> int:
    """``risloc capture record``: the radar's ``.cfg`` and a DCA1000 → a DCA1000 folder, with progress.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (--config, --serial, --out, --frames | --duration, --sweep, ...).

    Returns
    -------
    int
        0 when the frames or the duration were recorded (a summary line, with the lost packets);
        a failure raises (one line, exit 2; Ctrl-C: exit 130), after the summary of what was recorded.
    """
    from ..measured.live.record import record, recording_summary

    plan = record_plan(args)
    bar = _RecordProgress(None)
    try:
        summary = record(plan, on_progress=bar)
    except BaseException as exc:
        bar.close()
        done = recording_summary(exc)
        if done is not None and done.bytes > 0:      # nothing arrived: the folder was removed, nothing to report
            _print_summary(done, sys.stderr)
        raise
    bar.close()
    _print_summary(summary, sys.stdout)
    if summary.kernel_drops:
        print(f"warning: the kernel dropped {summary.kernel_drops} datagram(s) for a full socket buffer (listed as "
              "lost packets): raise net.core.rmem_max (docs/live-capture.md)", file=sys.stderr)
    return 0


def _add_record_parser(verbs) -> None:
    """Add ``capture record`` to the ``capture`` sub-parsers.

    Parameters
    ----------
    verbs : argparse._SubParsersAction
        The ``capture`` verb's sub-parsers.
    """
    rec = verbs.add_parser("record", help="record from a TI radar (its CLI port) and a DCA1000 (Ethernet) into a "
                                          "folder that capture import reads (docs/live-capture.md)")
    rec.add_argument("--out", required=True, metavar="DIR", help="the recording's folder (new or empty)")
    rec.add_argument("--sweep", metavar="SWEEP.toml", help="the sweep schedule, copied into --out as sweep.toml")
    add_connection_flags(rec, required=True)
    rec.set_defaults(func=_record)


def add_parser(sub) -> None:
    """Add ``capture`` (with ``inspect``, ``import`` and ``record``) to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    capture = sub.add_parser("capture", help="measured TI DCA1000 captures: inspect raw data, import a RIS sweep, record live",
                             description="Measured captures (docs/measured-captures.md).")
    verbs = capture.add_subparsers(dest="capture_command", required=True, metavar="{inspect,import,record}")
    ins = verbs.add_parser("inspect", help="frames, chirps, channels, the range-Doppler peak, dropped packets, "
                                           "clipping, DC offset and I/Q imbalance of a raw capture")
    ins.add_argument("raw", help="adc_data_Raw_0.bin (its _Raw_1, _Raw_2 ... siblings are found)")
    ins.add_argument("--config", help="the radar configuration: mmWave SDK .cfg or mmWave Studio .json")
    ins.add_argument("--layout", metavar="SAMPLES,RX,CHIRPS_PER_LOOP,LOOPS",
                     help="the file's layout without a configuration (bins only, no metres)")
    ins.add_argument("--adc-format", choices=["complex1x", "complex2x", "real"], default="complex1x",
                     help="with --layout: the ADC output format (default: %(default)s)")
    ins.add_argument("--lanes", type=int, choices=[2, 4], help="LVDS lanes: 2 (xWR16/18/68xx, default) or 4 (xWR14xx)")
    ins.add_argument("--iq-swap", action="store_true", default=None,
                     help="the file stores Q before I (default: a Studio .json's iqSwapSel, else I first)")
    ins.add_argument("--form", choices=["auto", "raw", "packets"], default="auto",
                     help="plain samples or packet-recorded UDP payloads (default: detect)")
    ins.add_argument("--max-frames", type=int, help="analyse only the first frames (all are counted)")
    ins.add_argument("--min-range-bin", type=int, default=0, help="ignore range bins below this (Tx-Rx leakage)")
    ins.add_argument("--json", action="store_true", help="print a machine-readable summary")
    ins.add_argument("--plot", metavar="PNG", help="write the range profile and range-Doppler map")
    add_force_flag(ins, "an existing --plot file")
    ins.set_defaults(func=_inspect)

    imp = verbs.add_parser("import", help="a recorded RIS sweep (raw capture + radar config + sweep schedule) -> "
                                          "a capture file for risloc locate")
    imp.add_argument("raw", help="adc_data_Raw_0.bin (its _Raw_1, _Raw_2 ... siblings are found)")
    imp.add_argument("--config", required=True, help="the radar configuration: mmWave SDK .cfg or mmWave Studio .json")
    imp.add_argument("--sweep", required=True, metavar="SWEEP.toml",
                     help="the sweep schedule: beams, frames per beam, first frame, channel, RIS (docs/formats.md)")
    imp.add_argument("-o", "--output", required=True,
                     help="capture file to write (.npz); for a schedule of several RISs ([[ris]] tables) without "
                          "--ris, a folder that gets <RIS name>.npz per RIS")
    imp.add_argument("--ris", metavar="NAME|INDEX",
                     help="a schedule of several RISs: import this RIS's slot only (its name in the schedule, or index)")
    add_force_flag(imp, "an existing -o file")
    imp.add_argument("--lanes", type=int, choices=[2, 4], help="LVDS lanes: 2 (xWR16/18/68xx, default) or 4 (xWR14xx)")
    imp.add_argument("--iq-swap", action="store_true", default=None,
                     help="the file stores Q before I (default: a Studio .json's iqSwapSel, else I first)")
    imp.add_argument("--form", choices=["auto", "raw", "packets"], default="auto",
                     help="plain samples or packet-recorded UDP payloads (default: detect)")
    add_sweep_import_flags(imp, first_frame_help="override the schedule's first_frame: the recorded frame of the "
                                                 "first beam (checked against the recording: a contradiction is a "
                                                 "one-line warning and the flag schedule-mismatch), or 'auto' to "
                                                 "find the sweep from the RIS's sync code and beam-dependent power")
    imp.set_defaults(func=_import)
    _add_record_parser(verbs)
