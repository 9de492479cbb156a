"""``risloc locate``: run the DSP on a capture file; ``risloc locate --live``: record and localize every sweep."""

from __future__ import annotations

import argparse
import json
import queue
import sys
import threading
import time
from contextlib import nullcontext
from pathlib import Path
from typing import Any, Callable

from .._outputs import output_folder, safe_name
from ..io.capture_file import load_capture
from ..io.fused import check_distinct_ris, common_truth, format_fused, fuse_cases, fused_dict
from ..io.report import format_case, format_environment, report_capture, run_environment, write_result
from .common import (EXIT_NO_DETECTION, CliError, add_device_flag, add_estimator_flags, add_force_flag,
                     add_processing_flags, device_backend, estimator_options, processing_overrides)
from .connection import add_connection_flags, add_sweep_import_flags, record_plan, sweep_import_options

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
    if args.live:
        return _run_live(args, backend)
    if not args.capture:
        raise CliError("give the capture file(s) to localize (.npz), or --live with --config, --serial, --out and "
                       "--sweep to record and localize every sweep")
    for flag, value in _live_only(args):
        raise CliError(f"{flag} {value} is for --live (recording from a radar); leave it out to localize capture files")
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
        results = [_localize(name, capture, args, backend, stage) for name, capture in zip(names, captures)]
        fused = truth = None
        if len(results) > 1:
            fused = fuse_cases(results, height=args.ue_height)
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


def _localize(name: str, capture, args: argparse.Namespace, backend, stage: Path | None):
    """One capture localized: the DSP with the command line's processing and estimator, a measured capture's σ from
    its uncertainty budget; figures under ``stage/name/`` when ``stage`` is given. Files and ``--live`` share it.

    Parameters
    ----------
    name : str
        The case's name (the capture file's stem, or the RIS's name live).
    capture : risloc_rt.model.Capture
        The capture (``--calibration`` applied).
    args : argparse.Namespace
        The parsed command line.
    backend : dsp.ArrayBackend
        The DSP's device (``--device``).
    stage : Path or None
        Where the figures go (None: none).

    Returns
    -------
    risloc_rt.io.report.CaseResult
    """
    budget = None
    if capture.provenance.get("source") == "measurement":
        from ..measured.compare.uncertainty_budget import apply_budget as budget
    return report_capture(name, capture, out_dir=stage, processing=processing_overrides(args, capture.processing),
                          timing={}, budget=budget, backend=backend,
                          **estimator_options(args, traced="scene" in capture.provenance))


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
    return _calibrated(load_capture(path), args)


def _calibrated(capture, args: argparse.Namespace):
    """``capture`` with ``--calibration`` applied (itself without the flag).

    Parameters
    ----------
    capture : risloc_rt.model.Capture
        A loaded or imported capture.
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    risloc_rt.model.Capture
    """
    if args.calibration is not None:
        from ..measured.compare.calibration_file import apply_to_capture, read_calibration

        capture = apply_to_capture(capture, read_calibration(args.calibration))
    return capture


#: ``--live`` options that make no sense for capture files (their default when not given).
_LIVE_ONLY = {"config": None, "serial": None, "sweep": None, "frames": None, "duration": None, "first_frame": None,
              "period_frames": None, "channels": None}
#: The JSON lines file of the fixes, in the recording's folder.
LIVE_FIXES = "live_fixes.jsonl"


def _live_only(args: argparse.Namespace) -> list[tuple[str, Any]]:
    """The ``--live`` options given without ``--live``: ``[(flag, value), ...]``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    list of (str, value)
    """
    return [("--" + k.replace("_", "-"), getattr(args, k)) for k, default in _LIVE_ONLY.items()
            if getattr(args, k, default) != default]


def _record_plan(args: argparse.Namespace):
    """The recording of ``--live``: ``risloc capture record``'s plan from the same options.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`risloc_rt.cli.connection.record_plan`'s options).

    Returns
    -------
    risloc_rt.measured.live.record.RecordPlan

    Raises
    ------
    CliError
        A connection option missing (one line).
    """
    missing = [f for f, v in (("--config", args.config), ("--serial", args.serial), ("--out", args.out),
                              ("--sweep", args.sweep)) if v is None]
    if missing:
        raise CliError(f"--live needs {', '.join(missing)}: the radar's .cfg, its CLI port, a new folder for the "
                       "recording and the sweep schedule (docs/live-locate.md)")
    return record_plan(args)


def fix_line(event: Any, latency: float) -> str:
    """One console line of a live fix: time, sweep, RIS, ``x y z ± σ`` [m], flags, latency [ms].

    Parameters
    ----------
    event : LiveFix or FusedLiveFix
        The fix (:mod:`risloc_rt.measured.live.live_sweeps`).
    latency : float
        From the sweep's last frame final to this line [s].

    Returns
    -------
    str
        ``HH:MM:SS.mmm  sweep S  RIS  x +X y +Y z +Z ± σ m  flags CODES  latency L ms``; σ is the PEB
        (``unobservable`` when an axis is); ``NO FIX: why`` or ``NOTHING DETECTED`` instead of the position.
    """
    import numpy as np

    from ..io.report import significant

    now = time.time()
    stamp = time.strftime("%H:%M:%S", time.localtime(now)) + f".{int(now % 1 * 1000):03d}"
    who = getattr(event, "ris", None)
    who = ("fused(" + "+".join(event.used) + ")") if who is None else (who or "ris")
    codes = [c for c, _ in event.flags] + ([f"lost-packets({event.lost_packets})"]
                                           if getattr(event, "lost_packets", 0) else [])
    if getattr(event, "error", None):
        where = f"NO FIX: {event.error}"
    elif not event.detected:
        where = "NOTHING DETECTED: no position"
    else:
        sigma = "unobservable" if not np.isfinite(event.peb) else f"{significant(event.peb)} m"
        where = " ".join(f"{a} {x:+.4f}" for a, x in zip("xyz", event.position)) + f" ± {sigma}"
    return (f"{stamp}  sweep {event.sweep}  {who}  {where}  flags {','.join(codes) or '-'}  "
            f"latency {latency * 1e3:.0f} ms")


class _LiveLoop:
    """Localizes the sweeps on a thread of its own while ``record`` writes: progress in, one line per fix out."""

    def __init__(self, make_watcher: Callable[[], Any], jsonl: Path) -> None:
        self.make_watcher, self.jsonl = make_watcher, jsonl
        self.inbox: queue.Queue = queue.Queue()
        self.error: BaseException | None = None
        self.detected = 0
        self.fixes = 0
        self.thread = threading.Thread(target=self._run, name="risloc-live-sweeps", daemon=True)
        self.thread.start()

    def __call__(self, progress: Any) -> None:
        """``record``'s ``on_progress``: hand the final prefix to the thread (an error there stops the recording).

        Parameters
        ----------
        progress : RecordingProgress
            ``final_bytes`` [bytes] and ``final_time`` [s].
        """
        if self.error is not None:
            raise self.error
        self.inbox.put(("update", progress.final_bytes, progress.final_time))

    def _emit(self, events: list[Any], files: dict[str, Any]) -> None:
        for e in events:
            if "out" not in files:  # made at the first fix: a run that fixes nothing leaves no file behind
                files["out"] = open(self.jsonl, "x", encoding="utf-8")
            out = files["out"]
            print(fix_line(e, time.monotonic() - e.final_time), flush=True)
            line = {**e.to_dict(), "latency_printed": time.monotonic() - e.final_time, "time": time.time()}
            out.write(json.dumps(line, allow_nan=False) + "\n")
            out.flush()
            self.fixes += 1
            self.detected += bool(e.detected)

    def _run(self) -> None:
        watcher = None
        files: dict[str, Any] = {}
        try:
            while True:
                kind, final, when = self.inbox.get()
                while kind == "update" and not self.inbox.empty():     # only the newest prefix matters
                    kind, final, when = self.inbox.get()
                if kind == "stop" or (kind == "finish" and not final):
                    return
                if not final:
                    continue
                watcher = watcher or self.make_watcher()
                self._emit(watcher.finish(final, when) if kind == "finish" else watcher.update(final, when), files)
                if kind == "finish":
                    return
        except BaseException as exc:  # noqa: BLE001 - handed to the recording's thread, which stops and reports it
            self.error = exc
        finally:
            if "out" in files:
                files["out"].close()

    def close(self, final_bytes: int | None, timeout: float = 600.0) -> None:
        """Localize what ``final_bytes`` completes (None: stop at once), then end the thread.

        Parameters
        ----------
        final_bytes : int or None
            The recording's length [bytes]; None after Ctrl-C.
        timeout : float
            Longest wait for the thread [s].
        """
        self.inbox.put(("stop", None, None) if final_bytes is None else ("finish", final_bytes, None))
        self.thread.join(timeout)


def _run_live(args: argparse.Namespace, backend: Any) -> int:
    """``risloc locate --live``: record with ``risloc capture record``'s options and print a fix per complete sweep.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    backend : dsp.ArrayBackend
        The DSP's device.

    Returns
    -------
    int
        0 when some sweep gave a position, ``EXIT_NO_DETECTION`` when none did; errors and Ctrl-C as
        ``risloc capture record`` (the recording is complete up to what arrived).
    """
    from ..measured.live.live_sweeps import SweepWatcher
    from ..measured.live.record import record, recording_summary

    if args.capture:
        raise CliError("--live records its own sweeps; leave out the capture files (localize them without --live)")
    plan = _record_plan(args)
    if (plan.out / LIVE_FIXES).exists():
        raise CliError(f"--out {plan.out} already holds {LIVE_FIXES} of an earlier run; risloc does not append to or "
                       "overwrite it: give a new or empty folder")
    options = sweep_import_options(args)
    first = options.pop("first_frame")

    def watcher() -> SweepWatcher:
        return SweepWatcher(plan.out, plan.out / "adc_data.cfg", plan.out / "sweep.toml", first_frame=first,
                            period_frames=args.period_frames, import_options=options, fuse_height=args.ue_height,
                            localize=lambda name, cap: _localize(name, _calibrated(cap, args), args, backend, None))

    holder: dict[str, _LiveLoop] = {}

    def on_progress(progress: Any) -> None:
        if "loop" not in holder:             # record() has made the folder and copied the .cfg and the schedule
            print(f"recording into {plan.out}: one line per complete sweep (docs/live-locate.md)", flush=True)
            holder["loop"] = _LiveLoop(watcher, plan.out / LIVE_FIXES)
        holder["loop"](progress)

    try:
        summary = record(plan, on_progress=on_progress)
    except KeyboardInterrupt:
        if "loop" in holder:
            holder["loop"].close(None, timeout=5.0)
        raise
    except BaseException as exc:
        done = recording_summary(exc)
        if "loop" in holder:
            holder["loop"].close(None if done is None else done.bytes)
        if done is not None and done.bytes > 0:      # nothing arrived: record() removed what it wrote
            print(f"recorded {done.describe()}", file=sys.stderr)
        raise
    loop = holder.get("loop") or _LiveLoop(watcher, plan.out / LIVE_FIXES)
    loop.close(summary.bytes)
    if loop.error is not None:
        raise loop.error
    print(f"recorded {summary.describe()}")
    print(f"wrote {plan.out / LIVE_FIXES}: {loop.fixes} fix(es), {loop.detected} with a position" if loop.fixes else
          f"no complete sweep: no {LIVE_FIXES} written")
    return 0 if loop.detected else EXIT_NO_DETECTION


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
    loc.add_argument("capture", nargs="*", help="capture file(s) (.npz) from 'risloc simulate', 'risloc capture "
                                                "import' or a converter; several: one per RIS, named after it")
    loc.add_argument("--out", help="directory for result.json and plots (default: print only); with --live the "
                                   "recording's folder (new or empty), which also gets live_fixes.jsonl")
    add_force_flag(loc, "a result.json or plot in --out")
    loc.add_argument("--calibration", metavar="FILE",
                     help="a calibration file from 'risloc calibrate': its tau_RB and range offset set the distance")
    add_processing_flags(loc)
    add_estimator_flags(loc)
    add_device_flag(loc)
    _add_live_flags(loc)
    loc.set_defaults(func=_run)


def _add_live_flags(loc: argparse.ArgumentParser) -> None:
    """Add ``--live`` and its options (``risloc capture record``'s connection options, the sweeps' import).

    Parameters
    ----------
    loc : argparse.ArgumentParser
        The ``locate`` verb's parser.
    """
    live = loc.add_argument_group("--live", "record from a TI radar and a DCA1000 (as 'risloc capture record') and "
                                            "print a position for every complete RIS sweep (docs/live-locate.md)")
    live.add_argument("--live", action="store_true",
                      help="record and localize every complete sweep as it arrives (needs --config, --serial, --out, "
                           "--sweep)")
    live.add_argument("--sweep", metavar="SWEEP.toml", help="the sweep schedule (first frame or auto, one RIS or "
                                                             "several [[ris]] slots), copied into --out")
    add_connection_flags(live, required=False, device_flag="--radar-device")
    add_sweep_import_flags(live, first_frame_help="override the schedule's first_frame (one RIS): the first sweep's "
                                                  "first beam frame, or 'auto' (found from the sync code and the "
                                                  "RIS's power)")
    live.add_argument("--period-frames", type=float, metavar="F",
                      help="frames from one sweep's start to the next (default: the time-division cycle, else the "
                           "RIS's program: sync code, gap, beams)")
