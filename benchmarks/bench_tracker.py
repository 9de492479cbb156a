"""The tracker's cost per update against its error: the closed-form Jacobian and the central differences it replaced.

Synthetic walks (no radar, no DSP): a walker at 1 m/s on straight legs with two instant 90° turns, measured at
every 0.39 s sweep by one of two RISs at its height (a 1-D sweep each: distance 1 mm, azimuth 0.02°, radial
velocity 1 mm/s, Gaussian), the height known. The two-model filter (``dsp.tracking.imm_update``) runs forward and
backward over each walk and ``dsp.smoothing.smooth_track`` joins them, once with the measurement Jacobian in
closed form (``RisMeasurement.linearised``, the default) and once with the central differences of the
residuals (1e-6 steps, 13 residual evaluations per linearisation: the code before 2026-11-28), on the same
measurements. Printed side by side: milliseconds per two-model update (the whole run, both filters and the
smoother, over the updates), the causal and smoothed rms position errors
[mm] and the smoothed track's mean NEES over (x, y, vx, vy) (4 when honest).

    .venv/bin/python benchmarks/bench_tracker.py [--walks 10] [--seed 1]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from dsp import RisPose
from dsp.fusion import RisFix, central_jacobian
from dsp.smoothing import reversed_measurement, smooth_track
from dsp.tracking import HORIZONTAL, Manoeuvres, RisMeasurement, imm_start, imm_update, nees

POSES = (RisPose.facing(np.array([0.0, 5.0, 1.2]), np.array([6.0, 5.0, 1.2])),
         RisPose.facing(np.array([6.0, 14.0, 1.2]), np.array([6.0, 5.0, 1.2])))
SD, SAZ, SV = 1e-3, np.deg2rad(0.02), 1e-3  # [m], [rad], [m/s]
STEP, SPEED, STEPS = 0.3904, 1.0, 40  # [s], [m/s], sweeps per walk
HEIGHT = (1.2, 0.01)  # [m]
MODELS = Manoeuvres(quiet=1e-4, turning=1.0 / STEP, quiet_time=8.0, turning_time=STEP)


def walk(rng: np.random.Generator) -> tuple[np.ndarray, list[RisMeasurement]]:
    """A walk's truth [STEPS, 6] and its measurements (one per sweep, the RISs alternating)."""
    heading = rng.uniform(0, 2 * np.pi) + np.zeros(STEPS)
    for k, sign in zip((rng.integers(8, 18), rng.integers(24, 34)), rng.choice([-1.0, 1.0], 2)):
        heading[k:] += sign * np.pi / 2
    vel = SPEED * np.stack([np.cos(heading), np.sin(heading), np.zeros(STEPS)], axis=1)
    pos = np.array([6.0, 5.0, HEIGHT[0]]) + np.concatenate([np.zeros((1, 3)), np.cumsum(vel[:-1] * STEP, axis=0)])
    meas = []
    for k in range(STEPS):
        pose = POSES[k % 2]
        rel = pos[k] - pose.position
        d = float(np.linalg.norm(rel))
        z = np.array([d, pose.angles_to(pos[k])[0], vel[k] @ rel / d]) + rng.standard_normal(3) * [SD, SAZ, SV]
        fix = RisFix(name=f"ris{k % 2}", pose=pose, distance=z[0], std_distance=SD, aod=np.array([z[1], 0.0]),
                     std_aod=np.array([SAZ, np.nan]))
        meas.append(RisMeasurement(time=k * STEP, fix=fix, velocity=z[2], std_velocity=SV))
    return np.concatenate([pos, vel], axis=1), meas


def filtered(meas: list[RisMeasurement]) -> tuple[list, int]:
    """The two-model filter over ``meas``: the state after each sweep and the number of updates."""
    state = imm_start(meas[0], height=HEIGHT)
    out = [state]
    for m in meas[1:]:
        state = imm_update(state, m, MODELS, height=HEIGHT).state
        out.append(state)
    return out, len(meas) - 1


def run(walks: list, numeric: bool) -> dict[str, float]:
    """Filter and smooth every walk: seconds per update, rms errors [mm], mean NEES."""
    original = RisMeasurement.linearised
    if numeric:
        def by_differences(self: RisMeasurement, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return self.normalised_residuals(state), central_jacobian(self.normalised_residuals, state)
        RisMeasurement.linearised = by_differences
    try:
        updates, err_f, err_s, z = 0, [], [], []
        start = time.perf_counter()
        for truth, meas in walks:
            times = np.arange(STEPS) * STEP
            fwd, n = filtered(meas)
            back, m = filtered([reversed_measurement(x) for x in meas[::-1]])
            updates += n + m
            sm = smooth_track(times, fwd, back[::-1], [True] * STEPS, motion=MODELS, axes=HORIZONTAL)
            for k in range(5, STEPS):
                err_f.append(np.linalg.norm(fwd[k].mean[:3] - truth[k, :3]))
                err_s.append(np.linalg.norm(sm.states[k].mean[:3] - truth[k, :3]))
                z.append(nees(sm.states[k], truth[k], axes=HORIZONTAL))
        seconds = time.perf_counter() - start
    finally:
        RisMeasurement.linearised = original
    rms = lambda e: 1e3 * float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    return {"per_update": seconds / updates, "updates": updates, "causal": rms(err_f), "smoothed": rms(err_s),
            "nees": float(np.mean(z))}


def main() -> None:
    """Time both Jacobians on the same walks, alternating, and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--walks", type=int, default=10, help="synthetic walks of 40 sweeps (default 10)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3, help="alternating repeats; the best time is printed")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    walks = [walk(rng) for _ in range(args.walks)]
    print(f"{platform.machine()}, numpy {np.__version__}; {args.walks} walks x {STEPS} sweeps, forward and backward")
    best: dict[bool, dict[str, float]] = {}
    for _ in range(args.repeat):
        for numeric in (True, False):
            r = run(walks, numeric)
            if numeric not in best or r["per_update"] < best[numeric]["per_update"]:
                best[numeric] = r
    print(f"{'Jacobian':<22}{'ms per update':>14}{'speed-up':>10}{'causal rms mm':>15}{'smoothed rms mm':>17}"
          f"{'NEES (4)':>10}")
    for numeric, label in ((True, "central differences"), (False, "closed form")):
        r = best[numeric]
        print(f"{label:<22}{1e3 * r['per_update']:>14.2f}{best[True]['per_update'] / r['per_update']:>9.1f}x"
              f"{r['causal']:>15.4f}{r['smoothed']:>17.4f}{r['nees']:>10.2f}")


if __name__ == "__main__":
    main()
