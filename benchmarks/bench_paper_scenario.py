"""Baseline benchmark: the paper scenario, time per realization against estimation error.

For each paper case it draws independent noise realizations (``SeedSequence(seed).spawn``),
times the synthesis of the beat cube (eq. (1)) and the DSP (peak search, P_ave, localization),
and reports the mean absolute errors of distance, angle and position, measured in the same run.
The DSP runs with the fast ``zoom`` Doppler search on every realization and with the paper's
``full`` 2-D DFT on the first few, and the two are compared bin for bin.

    .venv/bin/python benchmarks/bench_paper_scenario.py [--realizations 20] [--full 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import platform
import time
from dataclasses import replace

import numpy as np

from risloc_rt.io.report import estimation_errors, process_capture
from risloc_rt.model.scenario import PAPER_CASES, paper_scenario
from risloc_rt.model.simulate import simulate


def run(realizations: int, full: int, seed: int, mode: str) -> None:
    print(f"risloc-rt paper-scenario benchmark: {realizations} realizations per case ({full} also with the full "
          f"2-D DFT), RIS mode {mode}, seed {seed}; {platform.processor() or platform.machine()}, "
          f"numpy {np.__version__}")
    header = (f"{'case':<20} {'DSP':<5} {'n':>3} {'synth [s]':>9} {'DSP [s]':>8} "
              f"{'MAE dist [mm]':>13} {'MAE angle [deg]':>15} {'MAE pos [mm]':>12} {'same bins':>9}")
    print(header)
    print("-" * len(header))
    for case, ss in zip(PAPER_CASES, np.random.SeedSequence(seed).spawn(len(PAPER_CASES))):
        scenario = paper_scenario(case, mode=mode)
        rows = {"zoom": [], "full": []}
        synth_times = []
        same = []
        for i, child in enumerate(ss.spawn(realizations)):
            t0 = time.perf_counter()
            capture = simulate(scenario, rng=np.random.default_rng(child))
            synth_times.append(time.perf_counter() - t0)
            scans = {}
            for method in (("zoom", "full") if i < full else ("zoom",)):
                proc = replace(scenario.processing, doppler_search=method)
                loc, elapsed = process_capture(capture, processing=proc)
                err = estimation_errors(loc, capture.truth, capture)
                rows[method].append((elapsed, abs(err["distance"]), abs(err["angle"]), err["position"]))
                scans[method] = loc.scan
            if "full" in scans:
                same.append(bool(np.array_equal(scans["zoom"].delay_bin, scans["full"].delay_bin)
                                 and np.array_equal(scans["zoom"].doppler_bin, scans["full"].doppler_bin)))
        for method, data in rows.items():
            if not data:
                continue
            a = np.array(data)
            agree = f"{sum(same)}/{len(same)}" if same else "-"
            print(f"{scenario.name:<20} {method:<5} {len(a):>3} {np.mean(synth_times):>9.3f} {a[:, 0].mean():>8.3f} "
                  f"{1e3 * a[:, 1].mean():>13.2f} {np.rad2deg(a[:, 2].mean()):>15.3f} {1e3 * a[:, 3].mean():>12.2f} "
                  f"{agree:>9}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realizations", type=int, default=20)
    parser.add_argument("--full", type=int, default=2, help="realizations also processed with the full 2-D DFT")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--mode", choices=["relay", "reflective"], default="relay")
    args = parser.parse_args()
    run(args.realizations, min(args.full, args.realizations), args.seed, args.mode)


if __name__ == "__main__":
    main()
