"""Benchmark: self-interference removal on import — localization error with each method (gate, background, none).

Emulates recordings of the paper's off-broadside case (Table I radar on a TI chirp, RIS 13.38 m
away, UE at 21°) with a Tx→Rx leakage tone (``--leakage-dbm`` at 8 cm, ``--jitter`` rad rms
phase noise per chirp), a DC offset and RIS on/off sync frames (one frame per beam, RIS in step with the
radar, so that only the leakage differs between methods); imports each
with ``first_frame = "auto"`` and every ``--leakage`` method, localizes with both estimators and
prints the errors (mean absolute distance error, AoD error, position error, detections) side by
side. The figures in docs/measured-captures.md come from:

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_leakage.py --trials 5
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from risloc_rt.io.report import process_capture
from risloc_rt.measured import LEAKAGE_METHODS, RecordingPlan, emulate_recording, import_capture
from risloc_rt.model.scenario import paper_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--leakage-dbm", type=float, default=-10.0)
    ap.add_argument("--jitter", type=float, default=0.02)
    ap.add_argument("--dc", type=float, default=40.0, help="DC offset [LSB] on I and Q")
    args = ap.parse_args()
    scenario = paper_scenario("off-broadside")
    truth = scenario.truth
    plan = RecordingPlan(lead_frames=3.0, frames_per_beam=1, sync_on=2, sync_off=2, sync_cycles=3, sync_gap=1,
                         clock_drift=0.0, tail_frames=2, leakage_dbm=args.leakage_dbm,
                         leakage_jitter=args.jitter)
    rows: dict[tuple[str, str], list[tuple[float, float, float, bool]]] = {}
    t0 = time.perf_counter()
    for trial in range(args.trials):
        with tempfile.TemporaryDirectory() as tmp:
            rec = emulate_recording(scenario, Path(tmp) / "rec", plan=plan, rng=np.random.default_rng(100 + trial),
                                    dc_offset=complex(args.dc, -args.dc))
            exp = rec.experiment
            for method in LEAKAGE_METHODS:
                cap = import_capture(exp.raw_path, exp.config_path, exp.schedule_path, leakage=method)
                for est in ("refined", "paper"):
                    loc, _ = process_capture(cap, estimator=est)
                    if not loc.detected or loc.position is None:
                        rows.setdefault((method, est), []).append((np.nan, np.nan, np.nan, False))
                        continue
                    d = loc.distance - truth.distance
                    az = np.rad2deg(loc.aod[0] - truth.aod[0])
                    p = float(np.linalg.norm(np.asarray(loc.position) - scenario.ue_position))
                    rows.setdefault((method, est), []).append((d, az, p, True))
        print(f"trial {trial + 1}/{args.trials} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"\nleakage {args.leakage_dbm:g} dBm at 0.08 m, jitter {args.jitter:g} rad, DC {args.dc:g} LSB; "
          f"{args.trials} recordings; paper off-broadside case (13.38 m, 21 deg)")
    print("| method | estimator | detected | distance MAE [mm] | AoD MAE [deg] | position MAE [m] | worst position [m] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for (method, est), vals in rows.items():
        a = np.array([v[:3] for v in vals], float)
        det = sum(v[3] for v in vals)
        ok = ~np.isnan(a[:, 0])
        if ok.any():
            print(f"| {method} | {est} | {det}/{len(vals)} | {np.mean(np.abs(a[ok, 0])) * 1e3:.2f} | "
                  f"{np.mean(np.abs(a[ok, 1])):.3f} | {np.mean(a[ok, 2]):.4f} | {np.max(a[ok, 2]):.4f} |")
        else:
            print(f"| {method} | {est} | 0/{len(vals)} | – | – | – | – |")


if __name__ == "__main__":
    main()
