"""Emulated lab recordings (issue 20): distance bias, velocity error and the coverage of the stated 1σ.

Each recording is made the way a lab makes one: a random IWR6843-like profile written with round
numbers in its ``.cfg`` (start 60-61.5 GHz, slope 30-100 MHz/µs with two decimals, N, f_s, K), the
device running TI's truncated registers, the ADC window's centre as the carrier; a relay RIS at a
random distance (3 m to 80 % of the unambiguous range, ≤ 15 m), azimuth (±40°) and transmit power
(0-25 dBm). Two kinds alternate:

* ``moving``: one frame per beam (``emulate_capture``), the radar moving at up to 0.5 m/s in the
  sweep plane; the schedule's ``first_frame = 0``;
* ``clock``: a static radar, a whole recording (``emulate_recording``) with the RIS on its own
  clock: lead frames, a clock drift of ±1 %, 1-2 frames per beam or a dwell in milliseconds, and an
  on/off or chip-code sync; ``first_frame = "auto"``.

Each is imported (``import_capture``), localized with the refined estimator and its uncertainty
budget (``apply_budget``), and, for the "before" column, with the old mapping (slope rounded to the
nearest step, carrier at the start frequency). Printed side by side: time per recording, distance
bias with a 95 % interval, velocity error [%], and the share of errors within 1σ/2σ/3σ (Wilson 95 %).

    .venv/bin/python benchmarks/bench_recordings.py --recordings 200 [--seed 0] [--workers 2] [--json out.json]

Recording i draws from ``SeedSequence(seed, spawn_key=(i,))``: the rows do not depend on the workers.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.stats

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dsp import ProcessingConfig, RadarConfig  # noqa: E402
from risloc_rt.io.report import process_capture  # noqa: E402
from risloc_rt.measured import (dca1000_radar, device_steps, emulate_capture, import_capture,  # noqa: E402
                                slope_step)
from risloc_rt.measured import MeasuredFormatError  # noqa: E402
from risloc_rt.measured.compare.uncertainty_budget import apply_budget  # noqa: E402
from risloc_rt.measured.emulate.recording import RecordingPlan, emulate_recording  # noqa: E402
from risloc_rt.model.builder import analytic_scenario  # noqa: E402
from risloc_rt.model.simulate import simulate  # noqa: E402

C = 299_792_458.0
ADC_START = 6e-6                     # the emulator's ADC start time [s]


def lab_profile(rng: np.random.Generator) -> dict:
    """A profile as a lab writes it: round start frequency and slope, common N, f_s, K."""
    n = int(rng.choice([128, 256]))
    fs = float(rng.choice([5e6, 10e6, 12.5e6]))
    k = int(rng.choice([16, 32, 64]))
    ramp = ADC_START + n / fs + 1e-6
    s_max = min(100.0, 3.5e9 / ramp / 1e12)                       # ≤ 3.5 GHz swept [MHz/µs]
    slope = round(float(rng.uniform(30.0, s_max)), 2)
    start = float(rng.choice([60.0, 60.25, 60.5, 61.0, 61.5]))
    return {"n": n, "fs": fs, "k": k, "slope_mhz_us": slope, "start_ghz": start}


def device_radar(p: dict, tx_power_dbm: float) -> RadarConfig:
    """The radar the device runs for profile ``p`` (truncated slope, carrier at the window's centre)."""
    s_file = p["slope_mhz_us"] * 1e12
    step = slope_step(p["start_ghz"] * 1e9)
    s_dev = device_steps(s_file, step) * step
    offset = ADC_START + p["n"] / p["fs"] / 2
    nominal = RadarConfig(carrier_frequency=p["start_ghz"] * 1e9 + s_dev * offset, bandwidth=s_file * 50e-6,
                          chirp_duration=50e-6, num_samples=p["n"], sample_rate=p["fs"], num_chirps=p["k"],
                          tx_power_dbm=tx_power_dbm, frame_period=20e-3)
    return dca1000_radar(nominal)


def lab_cfg(path: Path, p: dict) -> None:
    """Rewrite the emulator's ``profileCfg`` with the lab's round numbers (the device runs the same registers)."""
    text = path.read_text()
    line = next(x for x in text.splitlines() if x.startswith("profileCfg"))
    f = line.split()
    f[2], f[8] = f"{p['start_ghz']:g}", f"{p['slope_mhz_us']:.2f}"
    path.write_text(text.replace(line, " ".join(f)))


def old_mapping(cap, p: dict):
    """The capture with the mapping before issue 20: slope rounded to the nearest step, carrier = f_0."""
    s_file = p["slope_mhz_us"] * 1e12
    step = slope_step(p["start_ghz"] * 1e9)
    s_round = round(s_file / step) * step
    radar = replace(cap.radar, carrier_frequency=p["start_ghz"] * 1e9, bandwidth=s_round * cap.radar.chirp_duration)
    return replace(cap, radar=radar)


def clock_plan(rng: np.random.Generator) -> RecordingPlan:
    """A RIS on its own clock: lead, drift, dwell (frames or ms) and a sync (on/off or chip code)."""
    fields: dict = {"lead_frames": float(rng.uniform(2.0, 8.0)), "clock_drift": float(rng.uniform(-0.01, 0.01)),
                    "tail_frames": 3}
    if rng.random() < 0.5:
        fields["frames_per_beam"] = int(rng.choice([1, 2]))
    else:
        fields["beam_dwell_ms"] = float(rng.choice([20.0, 25.0, 30.0]))
    if rng.random() < 0.5:
        fields.update(sync_on=5, sync_off=5, sync_cycles=2, sync_gap=2)
    else:
        fields.update(sync_pattern="1111100110101", chip_ms=20.0, repeat_after=bool(rng.random() < 0.5))
    return RecordingPlan(**fields)


def one(i: int, seed: int, folder: Path) -> dict:
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
    p = lab_profile(rng)
    kind = "moving" if i % 2 == 0 else "clock"
    power = float(rng.uniform(0.0, 25.0))
    radar = device_radar(p, power)
    r_max = C * p["fs"] / (2 * radar.slope)
    distance = float(rng.uniform(3.0, min(15.0, 0.8 * r_max)))
    az = float(rng.uniform(-40.0, 40.0))
    speed = float(rng.uniform(0.0, 0.5)) if kind == "moving" else 0.0
    heading = float(rng.uniform(0, 2 * np.pi))
    velocity = (speed * math.cos(heading), speed * math.sin(heading), 0.0)
    scenario = analytic_scenario(distance=distance, aod=np.deg2rad([az, 0.0]), radar=radar, ue_velocity=velocity,
                                 processing=ProcessingConfig(n_dft=2 * p["n"] - 1, k_dft=4 * p["k"]))
    start = time.perf_counter()
    if kind == "moving":
        sim = simulate(scenario, rng=rng)
        exp = emulate_capture(sim, folder / f"r{i}")
        truth = sim.truth
    else:
        rec = emulate_recording(scenario, folder / f"r{i}", plan=clock_plan(rng), rng=rng)
        exp = rec.experiment
        truth = None
    lab_cfg(exp.config_path, p)
    made = time.perf_counter() - start
    start = time.perf_counter()
    row = {"i": i, "kind": kind, **p, "tx_power_dbm": power, "distance": distance, "az_deg": az, "speed": speed,
           "make_s": made, "detected": False, "refused": None}
    try:
        imported = import_capture(exp.raw_path, exp.config_path, exp.schedule_path)
    except MeasuredFormatError as exc:                       # a clear refusal (alignment not found): counted
        row["refused"] = str(exc).split(": ", 1)[-1]
        return row
    cap = getattr(imported, "capture", imported)
    loc, _ = process_capture(cap)
    loc, _ = apply_budget(cap, loc)
    spent = time.perf_counter() - start
    old, _ = process_capture(old_mapping(cap, p))
    row.update(locate_s=spent, detected=bool(loc.detected), flags=[f.code for f in loc.flags])
    if not loc.detected:
        return row
    truth = cap.truth if truth is None else truth               # static radar: the capture's own truth
    pose = cap.ris.pose

    def at(t: float) -> tuple[float, float]:                     # true distance [m] and azimuth [rad] at time t
        q = truth.position_at(t)
        return float(np.linalg.norm(q - pose.position)), float(np.asarray(pose.angles_to(q)).reshape(-1)[0])

    t_dist, t_az = at(loc.reference_time)
    q_ref = truth.position_at(loc.reference_time) - pose.position
    t_vel = float(np.asarray(truth.ue_velocity, float) @ q_ref / np.linalg.norm(q_ref))   # radial, then
    old_dist = at(old.reference_time)[0] if old.detected else None
    row.update(
        err_distance=loc.distance - t_dist,
        err_distance_old=old.distance - old_dist if old.detected else None,
        err_velocity=loc.velocity - t_vel, err_velocity_old=(old.velocity - t_vel) if old.detected else None,
        true_velocity=t_vel, err_az=float(loc.aod[0]) - t_az,
        std_distance=float(loc.std.distance), std_velocity=float(loc.std.velocity), std_az=float(loc.std.aod[0]),
        snr_db=float(loc.detection.snr_db))
    return row


def _one(job: tuple[int, int, Path]) -> dict:
    return one(*job)


def wilson(k: int, n: int) -> tuple[float, float]:
    if n == 0:
        return (math.nan, math.nan)
    ci = scipy.stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def coverage(err: np.ndarray, std: np.ndarray) -> dict:
    z = np.abs(err) / std
    n = int(z.size)
    out = {"n": n}
    for m in (1, 2, 3):
        k = int(np.sum(z <= m))
        out[f"{m}sigma"] = k / n if n else math.nan
        out[f"{m}sigma_ci"] = wilson(k, n)
    return out


def mean_ci(x: np.ndarray) -> tuple[float, float, float]:
    m = float(np.mean(x))
    h = 1.96 * float(np.std(x, ddof=1)) / math.sqrt(x.size) if x.size > 1 else math.nan
    return m, m - h, m + h


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recordings", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1, help="processes (each recording is independent)")
    ap.add_argument("--json", type=Path, help="write every row and the summary here")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(i, args.seed, Path(tmp)) for i in range(args.recordings)]
        with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
            for row in pool.imap_unordered(_one, jobs):
                rows.append(row)
                if len(rows) % 20 == 0:
                    print(f"  {len(rows)}/{args.recordings} recordings", file=sys.stderr, flush=True)
    rows.sort(key=lambda r: r["i"])
    det = [r for r in rows if r["detected"]]
    refused = [r for r in rows if r["refused"]]
    summary: dict = {"recordings": len(rows), "detected": len(det), "refused": len(refused)}
    for kind in ("all", "moving", "clock"):
        rs = [r for r in det if kind == "all" or r["kind"] == kind]
        if not rs:
            continue
        e_d = np.array([r["err_distance"] for r in rs])
        e_d_old = np.array([r["err_distance_old"] for r in rs if r["err_distance_old"] is not None])
        s = {"n": len(rs), "locate_s_mean": float(np.mean([r["locate_s"] for r in rs])),
             "distance_bias_mm": [1e3 * v for v in mean_ci(e_d)],
             "distance_bias_old_mm": [1e3 * v for v in mean_ci(e_d_old)],
             "coverage_distance": coverage(e_d, np.array([r["std_distance"] for r in rs])),
             "coverage_az": coverage(np.array([r["err_az"] for r in rs]), np.array([r["std_az"] for r in rs]))}
        mv = [r for r in rs if abs(r["true_velocity"]) > 0.1]
        if mv:
            rel = np.array([r["err_velocity"] / r["true_velocity"] for r in mv])
            rel_old = np.array([r["err_velocity_old"] / r["true_velocity"] for r in mv if r["err_velocity_old"] is not None])
            s["velocity_error_pct"] = [100 * v for v in mean_ci(rel)]
            s["velocity_error_old_pct"] = [100 * v for v in mean_ci(rel_old)]
            s["coverage_velocity"] = coverage(np.array([r["err_velocity"] for r in mv]),
                                              np.array([r["std_velocity"] for r in mv]))
        summary[kind] = s
    print(f"{len(rows)} emulated recordings, {len(det)} detected, {len(refused)} refused on import (seed {args.seed})")
    for r in refused[:5]:
        print(f"  refused #{r['i']} ({r['kind']}): {r['refused'][:150]}")
    fmt_ci = lambda v: f"{v[0]:+.3f} [{v[1]:+.3f}, {v[2]:+.3f}]"  # noqa: E731
    for kind in ("all", "moving", "clock"):
        s = summary.get(kind)
        if not s:
            continue
        print(f"== {kind}: n = {s['n']}, locate {s['locate_s_mean']:.2f} s per recording")
        print(f"  distance bias [mm]  after {fmt_ci(s['distance_bias_mm'])}   before {fmt_ci(s['distance_bias_old_mm'])}")
        if "velocity_error_pct" in s:
            print(f"  velocity error [%]  after {fmt_ci(s['velocity_error_pct'])}   "
                  f"before {fmt_ci(s['velocity_error_old_pct'])}")
        for q in ("distance", "az", "velocity"):
            c = s.get(f"coverage_{q}")
            if c:
                print(f"  coverage {q:9s} n={c['n']:4d}  " + "  ".join(
                    f"{m}σ {100 * c[f'{m}sigma']:5.1f} % [{100 * c[f'{m}sigma_ci'][0]:.1f}, "
                    f"{100 * c[f'{m}sigma_ci'][1]:.1f}]" for m in (1, 2, 3)))
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
