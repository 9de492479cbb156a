"""A moving radar: position error against speed, radial and tangential, for each estimator.

The paper scenario (Table I, relay RIS, UE 13.38 m from the RIS) with the UE moving at 0, 0.5, 1
and 2 m/s, radially (away from the RIS) or tangentially (across the RIS broadside), synthesised
with the UE where it is at each frame (``simulate(motion="sweep")``, ``docs/moving-radar.md``;
Table I's back-to-back frames: 61 × 6.4 ms = 0.39 s of sweep). For each estimator of
``dsp.self_localize`` it reports, over a few noise seeds, the DSP time and the mean position
error (a) against the truth at the time the estimate says it refers to
(``Localization.reference_time``), and (b) with the estimate moved to the middle of the sweep by
the measured radial velocity (``reference_time=truth.reference_time``) against the truth there.

    .venv/bin/python benchmarks/bench_motion.py [--seeds 3] [--case broadside|off-broadside]
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import time

import numpy as np

import dsp
from risloc_rt.model.scenario import paper_scenario
from risloc_rt.model.simulate import simulate

SPEEDS = (0.0, 0.5, 1.0, 2.0)


def estimators() -> list[str]:
    """The estimators this dsp offers: the paper's, and "refined" where it exists."""
    import inspect
    import sys

    src = inspect.getsource(sys.modules["dsp.localize"])  # the module (dsp.localize is the function)
    return ["paper", "refined"] if '"refined"' in src else ["paper"]


def localize(capture, estimator: str, reference_time: float | None):
    kw = {}
    if hasattr(capture.ris, "beam_pattern"):
        kw["pattern"] = capture.ris.beam_pattern()
    if reference_time is not None:
        kw["reference_time"] = reference_time
    return dsp.self_localize(capture.cube, sweep=capture.sweep, radar=capture.radar, processing=capture.processing,
                             pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay, estimator=estimator, **kw)


def run(seeds: int, case: str, seed: int) -> None:
    base = paper_scenario(case)
    toward_ris = base.ris.pose.position - base.ue_position
    toward_ris /= np.linalg.norm(toward_ris)
    across = np.cross(toward_ris, [0.0, 0.0, 1.0])
    directions = {"radial": -toward_ris, "tangential": across}
    names = estimators()
    print(f"risloc-rt moving-radar benchmark: paper scenario '{case}', {seeds} noise seeds per point, estimators "
          f"{names}; sweep {base.sweep.num_beams} frames × {base.radar.frame_interval * 1e3:.1f} ms; "
          f"{platform.processor() or platform.machine()}, numpy {np.__version__}")
    header = (f"{'motion':<11} {'v [m/s]':>7} {'estimator':<9} {'DSP [s]':>7} {'t_est [ms]':>10} "
              f"{'err@t_est [mm]':>14} {'err@mid [mm]':>12} {'travel [mm]':>11}")
    print(header)
    print("-" * len(header))
    for direction, unit in directions.items():
        for speed in SPEEDS:
            if speed == 0 and direction != "radial":
                continue
            scenario = dataclasses.replace(base, ue_velocity=speed * unit)
            truth = scenario.truth
            rows = {n: [] for n in names}
            for child in np.random.SeedSequence([seed, int(speed * 10)]).spawn(seeds):
                capture = simulate(scenario, rng=np.random.default_rng(child))
                for name in names:
                    t0 = time.perf_counter()
                    loc = localize(capture, name, None)
                    elapsed = time.perf_counter() - t0
                    err_own = np.linalg.norm(loc.position - truth.position_at(loc.reference_time))
                    mid = localize(capture, name, truth.reference_time)
                    err_mid = np.linalg.norm(mid.position - truth.ue_position)
                    rows[name].append((elapsed, loc.reference_time, err_own, err_mid))
            travel = speed * (base.radar.beam_times(base.sweep.num_beams)[-1] - base.radar.beam_times(1)[0])
            for name, data in rows.items():
                a = np.array(data)
                print(f"{direction:<11} {speed:>7.1f} {name:<9} {a[:, 0].mean():>7.3f} {1e3 * a[:, 1].mean():>10.1f} "
                      f"{1e3 * a[:, 2].mean():>14.2f} {1e3 * a[:, 3].mean():>12.2f} {1e3 * travel:>11.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--case", choices=["broadside", "off-broadside"], default="off-broadside")
    args = parser.parse_args()
    run(args.seeds, args.case, args.seed)


if __name__ == "__main__":
    main()
