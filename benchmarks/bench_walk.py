"""A tracked walk through the L-shaped hall with one RIS per arm (issue 22): speed and error in one run.

Goal (a): scenes/l_hall_2ris, the 40 m walk of ``benchmarks/l_hall_walk.csv`` at 1 m/s (west along
the long arm, north up the short arm, east, back south through the mouth: four turns at the
corner's two arms), Table I radar at 20 dBm, the two RISs in time division (back to back, the
idle one off): the share of the sweeps with the sweeping RIS in view that give a fix, the track's
RMSE against the median single-sweep error, the largest error near the turns, restarts, and the
mean NEES against its 95 % χ² band. Goal (b): the first 60 sweeps of the same walk, from an empty
trace cache (a fresh folder) and again from the warm one.

Order: (1) the 60-sweep walk, cold cache; (2) the same 60 sweeps again, warm; (3) the whole
40 m walk on that cache (its first 60 sweeps warm, the rest traced). Timings are wall seconds on
whatever this machine is doing (say so when it is shared), with the process's CPU seconds (every
thread; the trace's and the DSP's thread pools included) beside them: on a loaded machine the CPU
seconds are the better guide to what an idle 2-core machine would take (at least CPU / 2 of wall).

    .venv/bin/python benchmarks/bench_walk.py [--seed 0] [--out DIR] [--skip-cold]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def same_rows(first: list, second: list) -> bool:
    """Every row equal but the timings (NaN equals NaN)."""
    timing = ("seconds_trace", "seconds_simulate", "seconds_dsp", "elapsed")
    return len(first) == len(second) and all(
        all(a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]) for k in a if k not in timing)
        for a, b in zip(first, second))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="also write the 40 m walk's outputs (walk.parquet, PNGs) into this folder")
    parser.add_argument("--skip-cold", action="store_true", help="skip the cold-cache run (1)")
    parser.add_argument("--workers", type=int, help="processes ahead of the tracker (default: the cores); the warm "
                                                    "60 sweeps also run on one, for the ratio")
    args = parser.parse_args()

    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.studies.engine import choose_workers
    from risloc_rt.studies.trajectory import read_trajectory
    from risloc_rt.studies.walk import run_walk, write_walk

    workers = choose_workers(args.workers)

    walk = read_trajectory(HERE / "l_hall_walk.csv")
    report: dict = {"machine": f"{platform.node()} {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs",
                    "load_average_start": os.getloadavg(), "workers": workers}
    say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    with tempfile.TemporaryDirectory(prefix="bench-walk-cache-") as folder:
        cache = TraceCache(Path(folder))
        if not args.skip_cold:
            start, cpu = time.perf_counter(), time.process_time()
            cold = run_walk("l_hall_2ris", walk, seed=args.seed, cache=cache, max_sweeps=60, progress=say,
                            workers=workers)
            report["sweeps60_cold_s"] = time.perf_counter() - start
            report["sweeps60_cold_cpu_s"] = time.process_time() - cpu
            report["sweeps60_cold_parts_s"] = cold.summary["seconds"]
        start, cpu = time.perf_counter(), time.process_time()
        warm = run_walk("l_hall_2ris", walk, seed=args.seed, cache=cache, max_sweeps=60, progress=say,
                        workers=workers)
        report["sweeps60_warm_s"] = time.perf_counter() - start
        report["sweeps60_warm_cpu_s"] = time.process_time() - cpu  # this process's only: the workers' are not in it
        report["sweeps60_warm_parts_s"] = warm.summary["seconds"]
        if workers > 1:  # the same warm walk in this process alone: the ratio, and the same rows
            start = time.perf_counter()
            alone = run_walk("l_hall_2ris", walk, seed=args.seed, cache=cache, max_sweeps=60, progress=say)
            report["sweeps60_warm_one_worker_s"] = time.perf_counter() - start
            report["speedup_workers"] = report["sweeps60_warm_one_worker_s"] / report["sweeps60_warm_s"]
            report["sweeps60_same_rows_1_vs_n_workers"] = same_rows(alone.rows, warm.rows)
        if not args.skip_cold:  # the same seed gives the same rows, whether the traces were made or read back
            report["sweeps60_same_rows_cold_warm"] = same_rows(cold.rows, warm.rows)
        start, cpu = time.perf_counter(), time.process_time()
        full = run_walk("l_hall_2ris", walk, seed=args.seed, cache=cache, progress=say, workers=workers)
        report["walk40_s"] = time.perf_counter() - start
        report["walk40_cpu_s"] = time.process_time() - cpu
    report["load_average_end"] = os.getloadavg()
    s = full.summary
    keys = ("sweeps", "sweeps_in_view", "fixes", "fixes_in_view", "fix_share_in_view", "fixes_out_of_view",
            "fix_rmse_m", "fix_median_error_m", "track_rmse_m", "track_max_error_m", "corner_max_error_m", "updates",
            "track_rmse_updated_m", "far_from_turns", "near_turns", "tracker",
            "nees_dof", "nees_mean", "nees_band_95", "nees_mean_in_band", "nees_share_in_single_band_95",
            "nis_mean_per_dof", "nis_band_95_per_dof", "smoothed", "seconds")
    report["walk40"] = {k: s[k] for k in keys}
    goals = {
        "fix on >= 95 % of sweeps in view": bool(s["fix_share_in_view"] is not None and s["fix_share_in_view"] >= 0.95),
        "track never restarted (not lost)": s["updates"]["restart"] == 0,
        "track RMSE <= 2 cm": bool(s["track_rmse_m"] is not None and s["track_rmse_m"] <= 0.02),
        "track RMSE < median single-sweep error": bool(s["track_rmse_m"] is not None and
                                                       s["track_rmse_m"] < s["fix_median_error_m"]),
        "mean NEES inside its 95 % band": bool(s["nees_mean_in_band"]),
        "smoothed track RMSE <= 2 cm and < median single-sweep error": bool(
            s["smoothed"]["rmse_m"] is not None and s["smoothed"]["rmse_m"] <= min(0.02, s["fix_median_error_m"])),
        "smoothed track's mean NEES not above its 95 % band": bool(
            s["smoothed"]["nees_mean"] is not None and s["smoothed"]["nees_mean"] <= s["smoothed"]["nees_band_95"][1]),
        "60 sweeps cold <= 300 s": report.get("sweeps60_cold_s", float("inf")) <= 300,
        "60 sweeps warm <= 30 s": report["sweeps60_warm_s"] <= 30,
    }
    report["goals"] = goals
    if args.out:
        from risloc_rt._outputs import output_folder

        with output_folder(args.out, force=False, flag="--out") as stage:
            write_walk(full, stage)
    print(json.dumps(report, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
