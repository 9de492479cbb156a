"""Monte Carlo runs on each device and batch size: time per run beside the error, measured in one run.

    .venv/bin/python benchmarks/bench_device.py --runs 20 --tx-powers 0,10,20 --batches 1,2,4
    .venv/bin/python benchmarks/bench_device.py --device cuda --batches 1,8,32,64   # on a GPU machine

Table I analytic scenario (UE 13.38 m at 10.3°, relay 16x4 RIS, structural reflection), the points of
the paper's Fig. 6, through the study path a worker runs (``risloc_rt.studies.kernel.run_runs``: the
noiseless cube once per point; per group of B runs the seeded noise and the detector on the device,
``dsp.detect_batch``; then each run's estimate on the host). On the host every row is one DSP and one
BLAS thread (a study worker), so a run's seconds are core-seconds. Per row: seconds per run (median
over the groups' per-run time, preparation excluded), its ratio to B = 1 on the same device (the
unbatched path), the goal's ratio (0.25 core-s on a 2-core CPU, 5 ms on one GPU), the expected
Fig. 6 time (6 points x 1000 runs: on 2 workers on the host, on one GPU), and beside them what the
runs measured: Pd, MAE of distance and azimuth, distance RMSE over its CRB (random phase), and the
share of distance errors within the stated 1σ. ``--device strict`` runs the same lines on
array_api_strict (CI's proof of the device-generic code: its cost is not a target).
"""

from __future__ import annotations

import argparse
import platform
import resource
import time

import numpy as np
from threadpoolctl import threadpool_limits

import dsp
from risloc_rt.studies.kernel import prepare_point, run_runs
from risloc_rt.studies.params import complete_point

GOALS = {"cpu": 0.25, "cuda": 0.005, "strict": None}  # seconds per Table I run (issue 21)


def _backend(name: str) -> dsp.ArrayBackend:
    return dsp.strict_backend("CPU_DEVICE") if name == "strict" else dsp.backend_for(name)


def _stats(rows: list[dict], crb: dict) -> dict[str, float]:
    det = [r for r in rows if r["detected"]]
    d = np.array([r["distance_error"] for r in det])
    az = np.array([r["aod_az_error"] for r in det])
    sd = np.array([r["std_distance"] for r in det])
    return {"pd": len(det) / len(rows),
            "mae_d_mm": 1e3 * float(np.mean(np.abs(d))) if det else float("nan"),
            "mae_az_deg": float(np.rad2deg(np.mean(np.abs(az)))) if det else float("nan"),
            "rmse_crb": float(np.sqrt(np.mean(d**2)) / crb["distance_random_phase"]) if det else float("nan"),
            "cover1": float(np.mean(np.abs(d) <= sd)) if det else float("nan")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs per row (default 20)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tx-powers", default="0,10,20", help="dBm, comma-separated (default 0,10,20)")
    ap.add_argument("--estimators", default="paper,refined")
    ap.add_argument("--batches", default="1,2,4", help="realizations per detector call, comma-separated")
    ap.add_argument("--device", default="cpu", choices=("cpu", "cuda", "strict"))
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="after the table, profile the first row's timed runs again (cProfile) and print the N "
                         "functions of largest own time: where a run's time goes on this device")
    args = ap.parse_args()
    try:
        backend = _backend(args.device)
    except dsp.DeviceError as exc:
        raise SystemExit(f"bench_device.py: {exc}") from None
    powers = [float(v) for v in args.tx_powers.split(",")]
    batches = [int(v) for v in args.batches.split(",")]
    goal = GOALS[args.device]
    print(f"risloc-rt device benchmark: Table I, {args.runs} runs per row, {platform.machine()}, "
          f"dsp on {backend.summary()}" + (", one DSP and BLAS thread (a study worker)" if args.device != "cuda" else ""))
    print(f"{'estimator':<9} {'tx dBm':>6} {'B':>3} {'s/run':>7} {'vs B=1':>6} {'vs goal':>7} {'Fig.6':>9} "
          f"{'Pd':>5} {'MAE d mm':>8} {'MAE az °':>8} {'RMSE/CRB':>8} {'1σ cover':>8}")
    with dsp.limit_threads(1), threadpool_limits(limits=1, user_api="blas"):
        for est in args.estimators.split(","):
            for tx in powers:
                prep = prepare_point(complete_point({"aod_deg": 10.3, "estimator": est, "tx_power_dbm": tx}))
                base = None
                for b in batches:
                    run_runs(prep, study_seed=args.seed, point=0, runs=range(args.runs, args.runs + b),
                             backend=backend, batch=b)  # warm caches (plans, tables, kernels)
                    t = time.perf_counter()
                    rows = run_runs(prep, study_seed=args.seed, point=0, runs=range(args.runs), backend=backend,
                                    batch=b)
                    per_run = (time.perf_counter() - t) / args.runs
                    base = per_run if base is None else base
                    s = _stats(rows, prep.crb)
                    workers = 1 if args.device == "cuda" else 2
                    fig = 6000 * per_run / workers
                    fig_txt = f"{fig / 60:6.1f} min" if fig >= 60 else f"{fig:7.1f} s"
                    vs_goal = f"{per_run / goal:6.2f}x" if goal else f"{'-':>7}"
                    print(f"{est:<9} {tx:6.1f} {b:3d} {per_run:7.4f} {per_run / base:6.2f} {vs_goal} {fig_txt:>9} "
                          f"{s['pd']:5.2f} {s['mae_d_mm']:8.3f} {s['mae_az_deg']:8.4f} {s['rmse_crb']:8.2f} "
                          f"{100 * s['cover1']:7.0f}%")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process {rss:.0f} MiB")
    if args.profile:
        _profile(args, backend, powers[0], batches[0])


def _profile(args: argparse.Namespace, backend: dsp.ArrayBackend, tx: float, b: int) -> None:
    """cProfile of ``args.runs`` runs of the first estimator at ``tx`` dBm and batch ``b``: the top functions
    by own time (a GPU's kernels are asynchronous: their time lands where the host waits for them)."""
    import cProfile
    import pstats

    est = args.estimators.split(",")[0]
    prep = prepare_point(complete_point({"aod_deg": 10.3, "estimator": est, "tx_power_dbm": tx}))
    with dsp.limit_threads(1), threadpool_limits(limits=1, user_api="blas"):
        run_runs(prep, study_seed=args.seed, point=0, runs=range(b), backend=backend, batch=b)
        prof = cProfile.Profile()
        prof.enable()
        run_runs(prep, study_seed=args.seed, point=0, runs=range(args.runs), backend=backend, batch=b)
        prof.disable()
    print(f"\nprofile: {est}, {tx:g} dBm, B = {b}, {args.runs} runs (own time, s, all runs)")
    pstats.Stats(prof).sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()
