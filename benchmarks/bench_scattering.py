"""The scattering coefficient S: recovered from emulated captures, its interval's coverage and its cost (issue 23).

``docs/calibration-materials.md``, "Scattering coefficient". Per seed: DCA1000 recordings (Table I radar on a TI chirp,
the simulator with diffuse paths on) of a 16 m x 10 m x 4 m hall whose walls, a material of their own, scatter with
S = ``--true-s`` (ε_r and σ ITU's concrete at 60 GHz), at the hall's two radar positions; the model is the same hall
with smooth walls. Capture 0 is calibrated (``risloc calibrate -o``) against the true hall (``--calibrate-against
true``, the default: the radar's power offset known independently of the walls, as from a corner reflector) or
against the model (``model``: its power offset then absorbs part of the walls' scattering loss, which biases S low), and
``risloc calibrate --materials wall-concrete --scattering wall-concrete --fixed ...:eps_r --fixed ...:sigma`` states S
by its profile over the full simulator. Printed per seed: S best, its 68.3 / 95.4 % intervals, whether they hold the
truth, the points and seconds of the profile; over the seeds the coverage (share of truths inside each interval;
expected 68.3 / 95.4 %) and the median seconds. The receiver noise differs between seeds (``numpy`` seed 11 + 100·seed
+ position), the hall does not. ``--coarse`` uses the test's grid (S 0 to 0.6 in steps of 0.1).

    .venv/bin/python benchmarks/bench_scattering.py [--seeds N] [--first-seed S] [--true-s S] [--coarse]
        [--calibrate-against true|model] [--log F.jsonl]

Run with one worker on the shared 2-core machine.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dsp import RadarConfig  # noqa: E402

#: The hall: 16 m x 10 m x 4 m, every wall within the radar's unambiguous range, the walls a material of their own (the
#: spec the command's end-to-end test uses).
SPEC = (REPO / "tests" / "measured" / "rough_box.toml").read_text(encoding="utf-8")
WALL = "wall-concrete"
SIGMA_ITU = 0.0462 * 60 ** 0.7822  # ITU-R P.2040 concrete at 60 GHz [S/m]
TRACE = ["--depth", "2", "--samples", "20000"]


def _captures(root: Path, model: Path, true_s: float, seed: int) -> tuple[list[Path], Path, Path]:
    """Recordings of the hall with scattering walls at both positions, imported; the cache folder; the true hall."""
    from risloc_rt.authoring.fitted_scene import write_fitted_scene
    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.hall.scenario import hall_paths, hall_scenario
    from risloc_rt.io.capture_file import save_capture
    from risloc_rt.measured import RecordingPlan, dca1000_radar, emulate_recording, import_capture

    true_scene = write_fitted_scene(model, root / "true_hall", {WALL: (5.24, SIGMA_ITU, true_s)}, {"truth": True})
    settings = TraceSettings(max_depth=2, samples_per_src=20000)
    cache = TraceCache(root / "cache")
    paths = []
    for index in (0, 1):
        hs = hall_scenario(str(true_scene), radar_index=index, radar=dca1000_radar(RadarConfig()), trace=settings)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            traced = hall_paths(hs, cache=cache)
        plan = RecordingPlan(lead_frames=3.0, sync_on=2, sync_off=2, sync_cycles=2, sync_gap=1, tail_frames=2)
        rec = emulate_recording(hs.base, root / f"rec{index}", plan=plan, paths=traced.paths,
                                rng=np.random.default_rng(11 + 100 * seed + index))
        exp = rec.experiment
        first = round(rec.start)
        capture = import_capture(exp.raw_path, exp.config_path, exp.schedule_path, first_frame=first)
        paths.append(save_capture(capture, root / f"capture{index}.npz"))
    return paths, cache.directory, true_scene


def run_seed(seed: int, true_s: float, coarse: bool, against: str) -> dict:
    """One seed: captures, calibration, the S profile; its figures."""
    from risloc_rt.authoring import build_scene, loads_spec
    from risloc_rt.cli import main
    import risloc_rt.cli.calibrate_scattering as command

    if coarse:
        command.SCATTERING_GRID = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    root = Path(tempfile.mkdtemp(prefix="bench-scattering-"))
    try:
        model = root / "model"
        model.mkdir()
        (model / "spec.toml").write_text(SPEC)
        build_scene(loads_spec(SPEC, base_dir=model), model)
        paths, cache, true_scene = _captures(root, model, true_s, seed)
        os.environ["RISLOC_CACHE_DIR"] = str(cache)
        cal, out = root / "cal.toml", root / "fitted"
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            reference = true_scene if against == "true" else model
            assert main(["calibrate", str(paths[0]), "--scene", str(reference), "-o", str(cal), *TRACE]) == 0
            t0 = time.perf_counter()
            rc = main(["calibrate", str(paths[0]), "--scene", str(model), "--materials", WALL, "--scattering", WALL,
                       "--fixed", f"{WALL}:eps_r", "--fixed", f"{WALL}:sigma", "--calibration", str(cal),
                       "--out", str(out), *TRACE])
            seconds = time.perf_counter() - t0
        if rc != 0:
            return {"seed": seed, "rc": rc, "seconds": seconds}
        doc = json.loads((out / "material-fit.json").read_text())
        prof = doc["profile_intervals"][f"{WALL}:S"]
        computed = doc["scattering_profiles"][f"{WALL}:S"]["computed_S"]
        inside = {}
        for n in (1, 2):
            lo, hi = prof[f"interval_{n}sigma"]
            inside[n] = (lo or 0.0) <= true_s <= (1.0 if hi is None else hi)
        return {"seed": seed, "rc": rc, "best": prof["best"], "interval_1sigma": prof["interval_1sigma"],
                "interval_2sigma": prof["interval_2sigma"], "inside_1sigma": inside[1], "inside_2sigma": inside[2],
                "points": len(computed), "profile_seconds": prof["seconds"], "seconds": seconds}
    finally:
        shutil.rmtree(root, ignore_errors=True)


def main() -> None:
    """Parse the options, run the seeds, print each and the coverage."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--true-s", type=float, default=0.4)
    ap.add_argument("--coarse", action="store_true", help="the test's coarser grid")
    ap.add_argument("--calibrate-against", choices=["true", "model"], default="true",
                    help="the hall the radar's power offset is calibrated against (default: true)")
    ap.add_argument("--log", help="append one JSON line per seed")
    args = ap.parse_args()
    rows = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        row = run_seed(seed, args.true_s, args.coarse, args.calibrate_against)
        row["calibrated_against"] = args.calibrate_against
        rows.append(row)
        if args.log:
            with open(args.log, "a", encoding="utf-8") as f:
                f.write(json.dumps(row) + "\n")
        if row["rc"] != 0:
            print(f"seed {seed}: refused (exit {row['rc']}), {row['seconds']:.0f} s", flush=True)
            continue
        print(f"seed {seed}: S {row['best']:.3f} (true {args.true_s:g}), 68.3 % {row['interval_1sigma']}, "
              f"95.4 % {row['interval_2sigma']}; {row['points']} S computed, profile {row['profile_seconds']:.0f} s, "
              f"command {row['seconds']:.0f} s", flush=True)
    done = [r for r in rows if r["rc"] == 0]
    if done:
        cover = {n: sum(r[f"inside_{n}sigma"] for r in done) / len(done) for n in (1, 2)}
        err = [abs(r["best"] - args.true_s) for r in done]
        print(f"{len(done)} of {len(rows)} seeds stated S: truth inside the 68.3 % interval {100 * cover[1]:.0f} %, "
              f"the 95.4 % {100 * cover[2]:.0f} %; |S - truth| median {statistics.median(err):.3f}; profile "
              f"{statistics.median(r['profile_seconds'] for r in done):.0f} s median "
              f"({statistics.median(r['points'] for r in done):.0f} S computed)")


if __name__ == "__main__":
    main()
