"""The walk's measurement floors (``risloc_rt.studies.walk.MOVING_FLOORS``) and the tracker's quiet model
(``risloc_rt.studies.walk.WALK_MANOEUVRES``) calibrated on a walk of their own.

The floors are what a moving radar's single fixes miss beyond their Cramér–Rao 1σ (docs/tracking.md).
They are set here on ``benchmarks/l_hall_calibration_walk.csv`` (42 m through scenes/l_hall_2ris along
other lines than the benchmark walk: east-west at y = 9, up the short arm at x = 8, down the west side,
east along y = 3), never on the benchmark walk (``benchmarks/l_hall_walk.csv``) that judges them.

Rule, per measured number q (distance at the sweep's middle, azimuth, radial velocity): the smallest
floor f_q with which 68.3 % of the fixes' errors lie within their 1σ, |e_q| ≤ √(σ_q² + f_q²) (a
Gaussian's share; a quantile, so the few gross errors no flag names do not set it), over the sweeps
whose fix the tracker would use (detected, in view, no ``SKIP_FLAGS`` code); 0 when the fixes' own σ
already cover 68.3 %. The truth is the trajectory at the sweep's middle seen from the sweeping RIS.

    .venv/bin/python benchmarks/calibrate_walk_floors.py [--seed 0] [--out DIR]

The tracker's quiet model (the two-model filter of ``dsp.tracking``, docs/tracking.md "Manoeuvres"):
its white acceleration density q₀ is the largest value of the grid ``QUIET_GRID`` whose track RMSE over
the sweeps at least 1.5 s from a turn (where the quiet model is the right one) is within 5 % of the
grid's smallest (below it the straight legs gain nothing, and a larger q₀ leaves room for a real
walker's wander), the calibration walk's fixes (with the floors above) replayed through
``risloc_rt.studies.walk.WalkTracker``; the
turning model's q₁ = v²/T, the mean time between turns and the turn's duration come from the walk's
speed v, its slot T and its legs (``WALK_MANOEUVRES``). The replay also gives the track RMSE and the mean
NEES of the whole calibration walk for each q₀.

It prints the floors, the fixes' coverage (share within 1σ, 2σ, 3σ) before and after, the quiet-model
grid, and the walk's seconds; the figures go in docs/tracking.md and docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


ONE_SIGMA = 0.6827
"""A Gaussian's share within its 1σ."""


def floor_for(errors: np.ndarray, sigmas: np.ndarray, share: float = ONE_SIGMA) -> float:
    """The smallest f with ``share`` of |e| ≤ √(σ² + f²) (0 when the σ alone cover it), in the unit of ``errors``.

    Each fix needs f ≥ √(e² − σ²) to be covered; the answer is that need's ``share`` quantile (the
    order statistic that first covers the share)."""
    e2, s2 = np.asarray(errors, float) ** 2, np.asarray(sigmas, float) ** 2
    need = np.sort(np.sqrt(np.maximum(e2 - s2, 0.0)))
    return float(need[max(int(math.ceil(share * need.size)) - 1, 0)])


def coverage(z: np.ndarray) -> list[float]:
    """Shares of |z| within 1, 2 and 3."""
    return [round(float(np.mean(np.abs(z) <= k)), 3) for k in (1, 2, 3)]


def truths(rows: list[dict], poses: dict) -> dict[str, np.ndarray]:
    """Distance [m], azimuth [rad] and radial velocity [m/s] of each row's truth from its RIS."""
    from dsp.geometry import angles_from_direction

    out = {"distance": [], "az": [], "velocity": []}
    for r in rows:
        pose = poses[r["ris"]]
        p = np.array([r["truth_x"], r["truth_y"], r["truth_z"]]) - pose.position
        v = np.array([r["truth_vx"], r["truth_vy"], r["truth_vz"]])
        d = float(np.linalg.norm(p))
        local = np.stack([pose.to_world(e) for e in np.eye(3)], axis=1).T @ (p / d)
        out["distance"].append(d)
        out["az"].append(float(angles_from_direction(local)[0]))
        out["velocity"].append(float(v @ p / d))
    return {k: np.asarray(v) for k, v in out.items()}


QUIET_GRID = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
"""The quiet model's q₀ tried [m²/s³]."""


def replay(rows: list[dict], poses: dict, floors: tuple[float, float, float], manoeuvres: object) -> list[dict]:
    """The walk's fixes (their own σ, ``floors`` added in quadrature) through ``WalkTracker(manoeuvres)``: per
    row the time [s], the track's position error [m] and its NEES over (x, y, vx, vy)."""
    from dsp import tracking
    from dsp.fusion import RisFix
    from risloc_rt.studies.walk import WalkTracker

    tracker, out = WalkTracker(manoeuvres=manoeuvres), []
    for r in rows:
        meas = None
        if r["status"] == "fix":
            sd, saz, sv = (math.hypot(r[k], f) for k, f in zip(("fix_std_distance", "fix_std_az", "fix_std_velocity"),
                                                                  floors))
            fix = RisFix(name=r["ris"], pose=poses[r["ris"]], distance=r["fix_distance"], std_distance=sd,
                         aod=np.array([r["fix_az"], 0.0]), std_aod=np.array([saz, np.nan]),
                         flags=tuple(filter(None, (r["fix_flags"] or "").split(","))))
            meas = tracking.RisMeasurement(time=r["time"], fix=fix, velocity=r["fix_velocity"], std_velocity=sv)
        tracker.step(r["time"], meas, height=(r["truth_z"], 0.01))
        truth = np.array([r[k] for k in ("truth_x", "truth_y", "truth_z", "truth_vx", "truth_vy", "truth_vz")])
        out.append({"time": r["time"], "error": float(np.linalg.norm(tracker.state.mean[:3] - truth[:3])),
                    "nees": tracking.nees(tracker.state, truth, axes=tracking.HORIZONTAL)})
    return out


def quiet_grid(rows: list[dict], poses: dict, floors: tuple[float, float, float], turns: np.ndarray) -> dict:
    """For each q₀ of :data:`QUIET_GRID`: the track RMSE [m] ≥ 1.5 s from a turn and over the walk, the mean NEES."""
    from dsp.tracking import Manoeuvres
    from risloc_rt.studies.walk import WALK_MANOEUVRES

    out = {}
    for q0 in QUIET_GRID:
        m = Manoeuvres(quiet=q0, turning=WALK_MANOEUVRES.turning, quiet_time=WALK_MANOEUVRES.quiet_time,
                       turning_time=WALK_MANOEUVRES.turning_time)
        res = replay(rows, poses, floors, m)
        t = np.array([x["time"] for x in res])
        err = np.array([x["error"] for x in res])
        far = np.min(np.abs(t[:, None] - turns[None, :]), axis=1) >= 1.5
        out[q0] = {"rmse_far_from_turns_m": float(np.sqrt(np.mean(err[far] ** 2))),
                   "rmse_m": float(np.sqrt(np.mean(err**2))), "nees_mean": float(np.mean([x["nees"] for x in res]))}
    return out


def main() -> None:
    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.hall.scenario import hall_scenario
    from risloc_rt.studies.trajectory import read_trajectory
    from risloc_rt.studies.walk import SKIP_FLAGS, run_walk

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="write the walk's rows and summary here")
    parser.add_argument("--cache", type=Path, default=None, help="trace cache folder (default: the user's)")
    args = parser.parse_args()
    walk = read_trajectory(HERE / "l_hall_calibration_walk.csv")
    start = time.perf_counter()
    result = run_walk("l_hall_2ris", walk, seed=args.seed, floors=(0.0, 0.0, 0.0),
                      cache=TraceCache(args.cache) if args.cache else TraceCache())
    seconds = time.perf_counter() - start
    rows = [r for r in result.rows if r["status"] == "fix" and r["in_view"]
            and not set(filter(None, (r["fix_flags"] or "").split(","))) & set(SKIP_FLAGS)]
    poses = {name: hall_scenario("l_hall_2ris", ris=name).base.ris.pose for name in {r["ris"] for r in rows}}
    truth = truths(rows, poses)
    report = {"walk": str(HERE / "l_hall_calibration_walk.csv"), "seed": args.seed, "fixes_used": len(rows),
              "seconds": round(seconds, 1), "floors": {}, "coverage_before": {}, "coverage_after": {}}
    for key, column, unit in (("distance", "fix_distance", "m"), ("az", "fix_az", "rad"),
                              ("velocity", "fix_velocity", "m/s")):
        est = np.array([r[column] for r in rows])
        sig = np.array([r[f"fix_std_{key}"] for r in rows])
        err = est - truth[key]
        if key == "az":
            err = (err + math.pi) % (2 * math.pi) - math.pi
        f = floor_for(err, sig)
        report["floors"][key] = f
        report["coverage_before"][key] = coverage(err / sig)
        report["coverage_after"][key] = coverage(err / np.sqrt(sig**2 + f * f))
    report["floors_display"] = {"distance_mm": round(1e3 * report["floors"]["distance"], 3),
                                "az_deg": round(math.degrees(report["floors"]["az"]), 4),
                                "velocity_mm_s": round(1e3 * report["floors"]["velocity"], 3)}
    floors = tuple(report["floors"][k] for k in ("distance", "az", "velocity"))
    poses.update({name: hall_scenario("l_hall_2ris", ris=name).base.ris.pose for name in {r["ris"] for r in result.rows}})
    grid = quiet_grid(result.rows, poses, floors, walk.times[1:-1])
    report["quiet_grid"] = {f"{q:g}": v for q, v in grid.items()}
    best = min(v["rmse_far_from_turns_m"] for v in grid.values())
    report["quiet_q_m2_s3"] = max(q for q, v in grid.items() if v["rmse_far_from_turns_m"] <= 1.05 * best)
    if args.out:
        from risloc_rt.studies.walk import write_walk

        args.out.mkdir(parents=True, exist_ok=True)
        write_walk(result, args.out)
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
