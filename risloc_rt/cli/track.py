"""``risloc track``: a radar walked along timed waypoints through a traced hall, every sweep localized and tracked."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .._outputs import output_folder
from .common import (CliError, add_device_flag, add_force_flag, add_trace_flags, device_backend, trace_cache,
                     trace_settings)

__all__ = ["add_parser", "OUTPUTS"]

#: The files ``--out`` receives.
OUTPUTS = ("walk.parquet", "summary.json", "plan.png", "error.png", "consistency.png")


def _height(text: str) -> object:
    """``--ue-height``: ``path``, ``unknown`` or a number [m] -> "path", None or a float."""
    if text == "path":
        return "path"
    if text == "unknown":
        return None
    try:
        value = float(text)
    except ValueError:
        raise CliError(f"--ue-height {text!r} must be 'path' (the trajectory's z), 'unknown', or a height in "
                       "metres, e.g. 1.2") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise CliError(f"--ue-height {text!r} must be a finite height in metres, e.g. 1.2")
    return value


def _run(args: argparse.Namespace) -> int:
    """``risloc track``: read and check the trajectory and schedule, walk, write ``--out``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        0 (bad input raises: one line, exit status 2).
    """
    from ..studies.engine import choose_workers
    from ..studies.trajectory import read_trajectory
    from ..studies.walk import load_schedule, plan_walk, run_walk, write_walk

    backend = device_backend(args)  # a missing GPU or a bad --device: one line before anything is read or written
    if args.progress_every < 1:
        raise CliError(f"--progress-every {args.progress_every} must be >= 1 (sweeps between progress lines)")
    if args.max_sweeps is not None and args.max_sweeps < 1:
        raise CliError(f"--max-sweeps {args.max_sweeps} must be >= 1 (the walk's first N sweeps)")
    if args.accel_density is not None and not args.accel_density > 0:
        raise CliError(f"--accel-density {args.accel_density:g} must be > 0 [m²/s³], e.g. 0.05 for a steady walk")
    height = _height(args.ue_height)
    trajectory = read_trajectory(args.trajectory)
    schedule = load_schedule(args.schedule, args.scene, idle=args.idle)
    slots = plan_walk(args.scene, trajectory, schedule=schedule,  # every bad input before anything is traced
                      max_sweeps=args.max_sweeps)
    settings = trace_settings(args)
    cache = trace_cache(args)
    workers = 1 if not backend.is_numpy else choose_workers(args.workers)
    out = Path(args.out)
    print(f"walking {trajectory.length:.1f} m in {trajectory.duration:g} s: {len(slots)} sweeps "
          f"({', '.join(schedule.order)} in turn), {sum(s.in_view for s in slots)} with the sweeping RIS in view",
          file=sys.stderr)
    extra = {} if args.accel_density is None else {"accel_density": args.accel_density}
    with output_folder(out, force=args.force, flag="--out", expect=OUTPUTS) as stage:
        result = run_walk(args.scene, trajectory, schedule=schedule, seed=args.seed, tx_power_dbm=args.tx_power_dbm,
                          trace=settings, cache=cache, height=height, estimator=args.estimator,
                          progress=lambda line: print(line, file=sys.stderr, flush=True),
                          progress_every=args.progress_every, max_sweeps=args.max_sweeps, backend=backend,
                          workers=workers, **extra)
        write_walk(result, stage)
    s = result.summary
    share = "n/a" if s["fix_share_in_view"] is None else f"{100 * s['fix_share_in_view']:.1f} %"
    rmse = "n/a" if s["track_rmse_m"] is None else f"{100 * s['track_rmse_m']:.2f} cm"
    median = "n/a" if s["fix_median_error_m"] is None else f"{100 * s['fix_median_error_m']:.2f} cm"
    nees = "n/a" if s["nees_mean"] is None else (f"{s['nees_mean']:.2f} (95 % band {s['nees_band_95'][0]:.2f} … "
                                                 f"{s['nees_band_95'][1]:.2f}, {s['nees_dof']} states)")
    print(f"{s['sweeps']} sweeps: fixes on {s['fixes_in_view']}/{s['sweeps_in_view']} in view ({share}); track RMSE "
          f"{rmse}, median single-sweep error {median}; mean NEES {nees}; updates {s['updates']}")
    sm = s["smoothed"]
    if sm["rmse_m"] is not None:
        print(f"smoothed track (every measurement of the walk): RMSE {100 * sm['rmse_m']:.2f} cm, mean NEES "
              f"{sm['nees_mean']:.2f} (95 % band {sm['nees_band_95'][0]:.2f} … {sm['nees_band_95'][1]:.2f}); "
              f"{len(sm['turns'])} turn(s) placed between measurements")
    print(f"wrote {out}: " + ", ".join(OUTPUTS))
    return 0


def add_parser(sub) -> None:
    """Add ``track`` to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    p = sub.add_parser("track", help="walk the radar along timed waypoints through a traced hall: every RIS sweep "
                                     "localized, the walk tracked (docs/tracking.md)")
    p.add_argument("scene", help="scene name in scenes/ or folder with scene.xml and spec.toml")
    p.add_argument("--trajectory", required=True, metavar="CSV",
                   help="timed waypoints: a header t,x,y,z then one line per waypoint [s, m], joined by straight "
                        "segments")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for walk.parquet, summary.json, plan.png, error.png, consistency.png")
    add_force_flag(p, "an existing output in --out")
    p.add_argument("--tx-power-dbm", type=float, help="transmit power [dBm] (default: Table I, 20)")
    p.add_argument("--seed", type=int, default=0, help="noise seed; the same seed gives the same rows (default: 0)")
    p.add_argument("--schedule", metavar="TOML",
                   help="a TOML file with a [schedule] table: RIS order, gap_ms, idle, parked_deg, start_ms, cycle_ms "
                        "(default: every RIS in spec order, back to back)")
    p.add_argument("--idle", choices=["off", "parked"],
                   help="what the other RISs do during a slot (default: the schedule's, else off)")
    p.add_argument("--ue-height", default="path", metavar="{path,unknown,Z}",
                   help="the radar's known height: 'path' (default: the trajectory's z, a radar carried at a known "
                        "height), a number [m], or 'unknown' (the tracker estimates z too)")
    p.add_argument("--accel-density", type=float, metavar="Q",
                   help="track with one nearly-constant-velocity model of this white acceleration density [m²/s³] "
                        "per axis (default: the two-model filter, quiet and turning, of docs/tracking.md)")
    p.add_argument("--estimator", choices=["refined", "paper"], default="refined",
                   help="single-sweep estimator (default: refined)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="processes that trace, simulate and localize the sweeps ahead of the tracker (default: the "
                        "cores the memory limit allows; the rows are the same for any number)")
    p.add_argument("--max-sweeps", type=int, metavar="N",
                   help="walk only the first N sweeps (default: every sweep that ends within the walk; a walk whose "
                        "sweeps would not fit the memory limit is refused with this remedy)")
    p.add_argument("--progress-every", type=int, default=10, metavar="N",
                   help="a progress line on stderr every N sweeps (default: 10)")
    add_trace_flags(p)
    add_device_flag(p)
    p.set_defaults(func=_run)
