"""Floor coverage of one RIS against several (issue 22): ``risloc study map`` on each hall, coverage beside time.

For each scene: the map (``risloc_rt.studies.floor_map.run_map``; a folder that holds the map
already is reopened and only its missing runs are computed), then one table row: the floor cells,
the cells some RIS sees, the coverage (Pd >= 0.99 and PEB below the bound), what each RIS
alone would cover (its own Pd and PEB in its slot), the share with Pd >= 0.99 alone, the cells each RIS serves, the position RMSE (median, 90 %, worst), the wall time of the runs
computed now and the mean time of one run (noise + DSP, one core: the run log's ``seconds``). Run it with ``nice`` on a shared machine::

    nice -n 10 .venv/bin/python benchmarks/bench_floor_coverage.py paper_hall paper_hall_2ris \\
        --spacing 1 --runs 5 --workers 2 --out runs

Results: docs/benchmarks.md, "Floor coverage with several RISs".
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np


def main() -> None:
    from risloc_rt.studies.floor_map import COVERED_PD, DEFAULT_PEB_BOUND, MapSettings, run_map

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--spacing", type=float, default=1.0)
    ap.add_argument("--height", type=float, default=1.2)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tx-power-dbm", type=float, default=None)
    ap.add_argument("--peb-bound", type=float, default=DEFAULT_PEB_BOUND)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", type=Path, required=True, help="a folder per scene is made in it (or reopened)")
    args = ap.parse_args()
    rows = []
    for scene in args.scenes:
        settings = MapSettings(scene=scene, spacing=args.spacing, height=args.height, runs=args.runs, seed=args.seed,
                               tx_power_dbm=args.tx_power_dbm, peb_bound=args.peb_bound)
        folder = args.out / f"cov-{scene}-{args.spacing:g}m"
        res = run_map(settings, folder, workers=args.workers, quiet=True)
        cov = res.coverage
        logged = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines() if line.strip()]
        per_run = float(np.mean([x["seconds"] for x in logged if x["run"] < args.runs]))
        pd_ok = sum(c["detection_probability"] >= COVERED_PD for c in res.cells)
        low_pd = sum(c["detection_probability"] < COVERED_PD for c in res.cells)
        high_peb = sum(c["detection_probability"] >= COVERED_PD and not c["peb"] < settings.peb_bound
                       for c in res.cells)
        missed = f"{cov['floor_cells'] - cov['mapped_cells']} / {low_pd} / {high_peb}"
        rmse = np.array([c["rmse_position"] for c in res.cells if c["rmse_position"] is not None])
        served = Counter(c["served_by"] or "none" for c in res.cells)
        alone = Counter(n for c in res.cells for n, v in c["ris"].items()
                        if v["detection_probability"] >= COVERED_PD and v["peb"] < settings.peb_bound)
        rows.append((scene, cov["floor_cells"], cov["mapped_cells"],
                     f"{100 * cov['share']:.1f} % ({100 * cov['share_accurate']:.1f} %)",
                     ", ".join(f"{n} {100 * k / cov['floor_cells']:.1f} %" for n, k in sorted(alone.items())),
                     100 * pd_ok / cov["floor_cells"], ", ".join(f"{k} {v}" for k, v in sorted(served.items())),
                     1e3 * np.median(rmse), 1e3 * np.quantile(rmse, 0.9), 1e3 * rmse.max(), res.wall_seconds, missed, per_run))
    print(f"{args.spacing:g} m grid at {args.height:g} m, {args.runs} runs per cell and RIS, seed {args.seed}, "
          f"PEB bound {1e3 * args.peb_bound:g} mm")
    print("| scene | floor cells | seen | coverage (RMSE under the bound too) | each RIS alone | Pd >= 0.99 | served by | "
          "RMSE median / 90 % / worst [mm] | wall now [s] | s per run | not covered: unseen / Pd < 0.99 / PEB over |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| `{r[0]}` | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[5]:.1f} % | {r[6]} | {r[7]:.1f} / {r[8]:.1f} / "
              f"{r[9]:.0f} | {r[10]:.0f} | {r[12]:.2f} | {r[11]} |")


if __name__ == "__main__":
    main()
