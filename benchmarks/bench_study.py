"""Cost of one Monte Carlo run of a study against the naive way, with the error side by side.

    .venv/bin/python benchmarks/bench_study.py --runs 5

Table I analytic scenario (UE 13.38 m at 10.3°, 20 dBm, relay 16x4 RIS, structure reflection).
"naive": per run ``simulate(scenario, rng)`` (synthesis + noise) then ``process_capture``;
"study": the noiseless cube once per point, per run the seeded noise + ``dsp.self_localize``
(``risloc_rt.studies.kernel.run_once``). Both see the same noise streams, so their errors agree.
The breakdown times the study path's stages on the same cubes: noise, detector
(``dsp.detect``), the per-beam 2-D DFT search (``dsp.scan_beams``) and the rest (estimate, bound,
flags). The goal line is the issue's: 6 points x 1000 runs on 2 cores in 5 min = 0.1 core-s per run.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import dsp  # noqa: E402
from risloc_rt.io.report import process_capture  # noqa: E402
from risloc_rt.model import simulate  # noqa: E402
from risloc_rt.model.beat import add_noise  # noqa: E402
from risloc_rt.studies.kernel import _analytic, prepare_point, run_once, run_rng  # noqa: E402
from risloc_rt.studies.params import complete_point  # noqa: E402

GOAL = 0.1  # core-seconds per run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"risloc-rt study benchmark: Table I, {args.runs} runs per estimator, {platform.machine()}, "
          f"numpy {np.__version__}, single-threaded BLAS")
    print(f"{'estimator':<9} {'path':<6} {'s/run':>7} {'MAE pos [mm]':>12} {'MAE d [mm]':>10} "
          f"{'vs naive':>8} {'figure on 2 cores':>18} {'vs goal':>8}")
    for est in ("paper", "refined"):
        params = complete_point({"aod_deg": 10.3, "estimator": est})
        scenario = _analytic(params, structure=True)
        naive_t, naive_e, naive_d = [], [], []
        for r in range(args.runs):
            t = time.perf_counter()
            cap = simulate(scenario, rng=run_rng(args.seed, 0, r))
            loc, _ = process_capture(cap, estimator=est)
            naive_t.append(time.perf_counter() - t)
            naive_e.append(np.linalg.norm(loc.position - cap.truth.ue_position))
            naive_d.append(abs(loc.distance - cap.truth.distance))
        t = time.perf_counter()
        prep = prepare_point(params)
        prep_s = time.perf_counter() - t
        buf = np.empty_like(prep.cube)
        rows = [run_once(prep, study_seed=args.seed, point=0, run=r, buffer=buf) for r in range(args.runs)]
        study_t = [r["seconds"] for r in rows]
        per_run = float(np.mean(study_t)) + prep_s / 1000  # the cube is shared by a point's 1000 runs
        for name, s, e, d in (("naive", float(np.mean(naive_t)), naive_e, naive_d),
                              ("study", per_run, [r["position_error"] for r in rows],
                               [abs(r["distance_error"]) for r in rows])):
            fig = 6000 * s / 2
            print(f"{est:<9} {name:<6} {s:7.3f} {1e3 * np.nanmean(e):12.3f} {1e3 * np.nanmean(d):10.3f} "
                  f"{np.mean(naive_t) / s:7.2f}x {fig / 60:15.1f} min {s / GOAL:7.1f}x")
        # breakdown of the study path
        stages = {"noise": [], "detect": [], "scan_beams": []}
        for r in range(min(args.runs, 3)):
            t = time.perf_counter()
            cube = add_noise(prep.cube, prep.radar.noise_power, run_rng(args.seed, 0, r), out=buf)
            stages["noise"].append(time.perf_counter() - t)
            t = time.perf_counter()
            dsp.detect(cube, prep.radar, pfa=params["pfa"], min_range=prep.processing.min_range)
            stages["detect"].append(time.perf_counter() - t)
            t = time.perf_counter()
            dsp.scan_beams(cube, prep.sweep, prep.radar, prep.processing)
            stages["scan_beams"].append(time.perf_counter() - t)
        parts = {k: float(np.mean(v)) for k, v in stages.items()}
        rest = float(np.mean(study_t)) - sum(parts.values())
        print(f"          breakdown: " + ", ".join(f"{k} {v:.3f} s" for k, v in parts.items()) +
              f", estimate+rest {rest:.3f} s; cube synthesis once per point {prep_s:.3f} s")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process {rss:.0f} MiB (one worker)")


if __name__ == "__main__":
    main()
