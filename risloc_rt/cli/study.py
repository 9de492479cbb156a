"""``risloc study sweep``: Monte Carlo studies over a parameter grid (docs/studies.md);
``risloc study map``: error, detection and PEB maps over a hall's floor."""

from __future__ import annotations

import argparse
import errno
import sys
from pathlib import Path

from .common import CliError, add_device_flag

__all__ = ["add_parser"]


def _count(what: str):
    """argparse type: an integer >= 1; ``what`` says what it counts in the error."""

    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if n < 1:
            raise argparse.ArgumentTypeError(f"{n} must be >= 1 ({what})")
        return n

    return parse


_workers = _count("worker processes")
_runs = _count("Monte Carlo runs per point")


def _guarded(call, out: Path):
    """Run ``call()``, turning the studies' errors into one-line CLI errors (exit 2; 130 after Ctrl-C)."""
    from dsp.budget import BudgetError

    from ..studies import StudyError, StudyFolderError

    try:
        return call()
    except KeyboardInterrupt:
        print(f"risloc study: interrupted; the finished runs are in {str(out)!r}: rerun the same command to "
              "continue", file=sys.stderr)
        return 130
    except (StudyError, StudyFolderError, BudgetError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise CliError(f"the disk is full writing {exc.filename or str(out)!r}; free some space and rerun the "
                           "same command: it continues where it stopped") from None
        raise


def _sweep(args: argparse.Namespace) -> int:
    from ..studies import load_study_file, run_study, spec_from_options

    try:
        if args.study is not None:
            if args.vary or args.set:
                raise CliError("give the grid either in --study FILE.toml or with --vary/--set, not both")
            spec = load_study_file(args.study, runs=args.runs, seed=args.seed)
        else:
            spec = spec_from_options(vary=args.vary, fixed=args.set, runs=args.runs if args.runs is not None else 100,
                                     seed=args.seed if args.seed is not None else 0,
                                     name=args.out.name or "sweep")
    except ValueError as exc:
        raise CliError(str(exc)) from None
    result = _on_cluster(args, lambda dask: run_study(spec, args.out, workers=args.workers, dask=dask,
                                                      quiet=args.quiet, force=args.force,
                                                      force_long=args.force_long,
                                                      force_workers=args.force_workers, device=args.device))
    if isinstance(result, int):
        return result
    if not args.quiet:
        _print_summary(result)
        _print_devices(result.summary.get("devices"), result.new_runs)
        print(f"noise stream: {result.summary.get('noise_stream')} (study.json; docs/studies.md)")
    return 0


def _print_devices(devices, new_runs: int) -> None:
    """One ``device: ...`` line per distinct DSP device and trace variant that ran the runs (every sitting's),
    after a line saying so when this sitting computed none."""
    from ..io.report import format_environment

    if not new_runs:
        print("device: no runs computed now (every run was already in the log)"
              + ("; they were computed by:" if devices else ""))
    for env in devices or ():
        print(format_environment(env))


def _on_cluster(args: argparse.Namespace, call):
    """``call(dask)`` with a Dask client for ``--dask`` (None without), closed afterwards; guarded."""
    dask = args.dask
    if dask is not None:
        from ..studies.engine import connect_dask

        dask = _guarded(lambda: connect_dask(args.dask, timeout=args.dask_timeout), args.out)
        if isinstance(dask, int):
            return dask
    try:
        return _guarded(lambda: call(dask), args.out)
    finally:
        if dask is not None:
            dask.close()


def _print_summary(result) -> None:
    s = result.summary
    print(f"{s['study']['name']}: {len(s['points'])} point(s) x {s['study']['runs']} runs, "
          f"{result.new_runs} computed now in {result.wall_seconds:.1f} s -> {result.folder}/summary.json, runs.parquet, study.png")
    varied = list(s["study"]["vary"])
    head = "  ".join(f"{n:>14}" for n in varied)
    print(f"  {head}  {'Pd':>5}  {'doubted':>7}  {'MAE d [mm]':>10}  {'MAE ang [deg]':>13}  {'MAE pos [mm]':>12}  "
          f"{'RMSE/CRB pos':>12}  {'s/run':>6}")
    for pt in s["points"]:
        vals = "  ".join(f"{str(pt['params'][n]):>14}" for n in varied)
        mae = pt["mae"]
        print(f"  {vals}  {pt['detection_probability']:5.3f}  {pt['doubted']:7d}  {1e3 * mae['distance']:10.3f}  "
              f"{mae['angle'] * 57.29577951308232:13.4f}  {1e3 * mae['position']:12.3f}  "
              f"{pt['rmse_over_crb']['position']:12.2f}  {pt['seconds_per_run']:6.3f}")
    for msg in s.get("retried", []):
        print(f"  {msg}")


def _map(args: argparse.Namespace) -> int:
    from ..studies.floor_map import MapSettings, run_map

    try:
        settings = MapSettings(scene=args.hall, spacing=args.spacing, height=args.height, runs=args.runs,
                               seed=args.seed, estimator=args.estimator, depth=args.depth, samples=args.samples,
                               tx_power_dbm=args.tx_power_dbm, margin=args.margin, ris=tuple(args.ris or ()),
                               peb_bound=args.peb_bound)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    result = _on_cluster(args, lambda dask: run_map(settings, args.out, workers=args.workers, dask=dask,
                                                    quiet=args.quiet, force=args.force,
                                                    force_long=args.force_long,
                                                    force_workers=args.force_workers, device=args.device))
    if isinstance(result, int):
        return result
    if not args.quiet:
        print(result.describe())
        _print_devices(result.devices, result.new_runs)
    return 0


def _parallel_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--workers", type=_workers,
                        help="local worker processes (default: all cores; more than the cores or the memory limit "
                             "allows are lowered with a note)")
    parser.add_argument("--force-workers", action="store_true",
                        help="keep --workers above the core count (the memory limit still holds)")
    parser.add_argument("--force-long", action="store_true",
                        help="run a study expected to take longer than a day (or a map of more than 1e5 grid points)")
    parser.add_argument("--dask", metavar="ADDRESS", help="run on a Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--dask-timeout", type=float, default=10.0, metavar="S",
                        help="seconds to wait for the Dask scheduler (default 10)")
    add_device_flag(parser)


def add_parser(sub) -> None:
    """Add ``study`` (``sweep``, ``map``) to an ``add_subparsers()`` object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned; the verb's parser is added to it, its
        ``func`` set to the verb (which takes the parsed arguments and returns the exit status).
    """
    study = sub.add_parser("study", help="Monte Carlo studies: parameter sweeps (the paper's Figs 6-8), floor maps",
                           description="Monte Carlo studies (docs/studies.md)")
    verbs = study.add_subparsers(dest="study_command", required=True, metavar="{sweep,map}")

    sw = verbs.add_parser("sweep", help="MAE/RMSE vs CRB, detection and flags over a parameter grid",
                          description="N Monte Carlo runs at every point of a parameter grid; resumable, parallel. "
                                      "Parameters: see docs/studies.md (e.g. tx_power_dbm, sweep_step_deg, ris_size, "
                                      "distance, aod_deg, speed, estimator, scene, depth).")
    sw.add_argument("--study", type=Path, metavar="FILE.toml", help="a study file (studies/*.toml)")
    sw.add_argument("--vary", action="append", metavar="NAME=V1,V2,...",
                    help="a grid axis (repeatable; values or LO:HI:STEP), e.g. tx_power_dbm=0,10,20")
    sw.add_argument("--set", action="append", metavar="NAME=V", help="a fixed parameter (repeatable), e.g. estimator=refined")
    sw.add_argument("--runs", type=_runs, help="Monte Carlo runs per point (default: the study file's, else 100)")
    sw.add_argument("--seed", type=int, help="study seed (default: the study file's, else 0)")
    sw.add_argument("--out", type=Path, required=True, metavar="DIR", help="study folder (created; reopened to continue)")
    _parallel_options(sw)
    sw.add_argument("--force", action="store_true", help="use a folder that holds another study (its log is kept)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    sw.set_defaults(func=_sweep)

    mp = verbs.add_parser("map", help="position RMSE, detection, PEB, serving RIS and coverage over a hall's floor",
                          description="radar positions on a floor grid of a hall, traced once per RIS that sees "
                                      "them, N noise runs each, several RISs' fixes fused; the coverage is printed")
    mp.add_argument("hall", nargs="?", default="paper_hall", help="scene name or folder (default paper_hall)")
    mp.add_argument("--spacing", type=float, default=1.0, help="grid spacing [m] (default 1.0)")
    mp.add_argument("--height", type=float, default=1.2, help="radar height above the floor [m] (default 1.2)")
    mp.add_argument("--margin", type=float, default=0.5, help="keep this far from walls and objects [m] (default 0.5)")
    mp.add_argument("--runs", type=_runs, default=20, help="noise runs per cell (default 20)")
    mp.add_argument("--seed", type=int, default=0)
    mp.add_argument("--estimator", choices=("paper", "refined"), default="refined")
    mp.add_argument("--tx-power-dbm", type=float, default=None, help="transmit power [dBm] (default Table I's 20)")
    mp.add_argument("--ris", action="append", metavar="NAME",
                    help="a RIS that sweeps (repeatable; a name or index of the spec's RISs; default every RIS: "
                         "time division, one slot each)")
    mp.add_argument("--peb-bound", type=float, default=0.05, metavar="M",
                    help="coverage: the share of the floor with Pd >= 0.99 and PEB below M [m] (default 0.05)")
    mp.add_argument("--depth", type=int, default=3, help="ray-tracing depth (default 3)")
    mp.add_argument("--samples", type=int, default=100_000, help="rays per source (default 1e5)")
    mp.add_argument("--out", type=Path, required=True, metavar="DIR")
    _parallel_options(mp)
    mp.add_argument("--force", action="store_true")
    mp.add_argument("--quiet", action="store_true")
    mp.set_defaults(func=_map)
