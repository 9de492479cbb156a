"""Ray-traced default hall: trace, synthesis and DSP time, and speed against fidelity.

Part 1 times each stage for the default hall (``scenes/paper_hall``): the trace in a fresh
process with an empty Dr.Jit kernel cache (cold: import + JIT compile + solve), in a fresh process
with a warm kernel cache, in-process after moving the radar (warm), and a trace-cache hit; then
path building, beat-cube synthesis and the DSP.

Part 2 is the speed-versus-fidelity table: for each ray-tracing depth and number of rays per
source it reports the warm trace time, the traced and kept path counts, the model error of the
noiseless beat cube against a reference trace (depth 4, 1e6 rays),
``20 log10(‖Y - Y_ref‖ / ‖Y_ref‖)`` [dB], and the mean distance and position errors over noise
realizations at both radar positions, all measured in this one run.

    .venv/bin/python benchmarks/bench_hall.py [--realizations 5] [--seed 0] [--quick]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

from risloc_rt.hall.scenario import hall_paths, hall_scenario
from risloc_rt.hall.pruning import AliasWarning
from risloc_rt.io.report import process_capture
from risloc_rt.hall.raytrace.backend import backend_info
from risloc_rt.hall.raytrace.tracer import TraceSettings, trace_scene
from risloc_rt.model.simulate import simulate

warnings.simplefilter("ignore", AliasWarning)

_COLD = """
import time, numpy as np
t0 = time.perf_counter()
from risloc_rt.hall.scenario import hall_scenario
from risloc_rt.hall.raytrace.tracer import trace_scene
hs = hall_scenario("paper_hall")
b = hs.base
r = trace_scene(hs.scene_xml, radar_position=b.ue_position, ris_positions=b.ris.pose.position[None],
                frequency=b.radar.carrier_frequency, settings=hs.trace)
print(time.perf_counter() - t0, r.timing.get("solve", float("nan")))
"""


def _fresh_process(kernel_cache: str) -> tuple[float, float]:
    env = dict(os.environ, DRJIT_CACHE_DIR=kernel_cache)
    out = subprocess.run([sys.executable, "-c", _COLD], env=env, capture_output=True, text=True, check=True)
    total, solve = out.stdout.split()[-2:]
    return float(total), float(solve)


def stage_times(realizations: int, seed: int) -> None:
    print("Part 1: stage times, default hall (paper_hall, depth 3, 1e5 rays per source)")
    with tempfile.TemporaryDirectory() as kc:
        cold_total, cold_solve = _fresh_process(kc)
        warm_total, warm_solve = _fresh_process(kc)
    print(f"  trace, new process, empty kernel cache (import + load + JIT + solve): {cold_total:.2f} s (solve {cold_solve:.2f} s)")
    print(f"  trace, new process, warm kernel cache:                                {warm_total:.2f} s (solve {warm_solve:.2f} s)")
    hs = hall_scenario("paper_hall")
    b = hs.base
    trace_scene(hs.scene_xml, radar_position=b.ue_position, ris_positions=b.ris.pose.position[None],
                frequency=b.radar.carrier_frequency, settings=hs.trace)
    t0 = time.perf_counter()
    trace_scene(hs.scene_xml, radar_position=b.ue_position + [0.3, 0.0, 0.0], ris_positions=b.ris.pose.position[None],
                frequency=b.radar.carrier_frequency, settings=hs.trace)
    print(f"  trace, same process, radar moved (warm):                              {time.perf_counter() - t0:.2f} s")
    from risloc_rt.hall.raytrace.cache import TraceCache

    with tempfile.TemporaryDirectory() as cd:
        cache = TraceCache(cd)
        hall_paths(hs, cache=cache)
        t0 = time.perf_counter()
        hp = hall_paths(hs, cache=cache)
        hit = time.perf_counter() - t0
    print(f"  trace-cache hit + path building + pruning:                            {hit:.3f} s "
          f"(paths {hp.timing['paths']:.3f} s; {hp.report.summary()})")
    synth, dsp, errs = [], [], []
    for ss in np.random.SeedSequence(seed).spawn(realizations):
        t0 = time.perf_counter()
        cap = simulate(b, rng=np.random.default_rng(ss), paths=hp.paths)
        synth.append(time.perf_counter() - t0)
        loc, elapsed = process_capture(cap)
        dsp.append(elapsed)
        errs.append(np.linalg.norm(loc.position - b.truth.ue_position))
    print(f"  synthesis ({len(hp.paths)} paths, 61x128x600 cube + noise): {np.mean(synth):.2f} s;  DSP (zoom): "
          f"{np.mean(dsp):.2f} s;  position error {1e3 * np.mean(errs):.1f} mm (mean of {realizations})")


def fidelity_table(realizations: int, seed: int, quick: bool) -> None:
    depths = (1, 2, 3) if quick else (1, 2, 3, 4)
    samples = (10_000, 100_000) if quick else (10_000, 100_000, 1_000_000)
    reference = TraceSettings(max_depth=max(depths), samples_per_src=max(samples))
    positions = (0, 1)
    ref_cubes = {}
    for i in positions:
        hs = hall_scenario("paper_hall", radar_index=i, trace=reference)
        ref_cubes[i] = simulate(hs.base, rng=np.random.default_rng(0), paths=hall_paths(hs).paths, noise=False).cube
    print(f"\nPart 2: speed against fidelity, both radar positions, {realizations} noise realizations each; "
          f"model error against depth {reference.max_depth}, {reference.samples_per_src:g} rays")
    header = (f"{'depth':>5} {'rays/src':>9} {'trace [s]':>9} {'traced':>7} {'kept':>5} {'model err [dB]':>14} "
              f"{'MAE dist [mm]':>13} {'MAE pos [mm]':>12} {'AoD hits':>8}")
    print(header)
    print("-" * len(header))
    for depth in depths:
        for n in samples:
            settings = TraceSettings(max_depth=depth, samples_per_src=n)
            times, traced, kept, model, dist, pos, hits = [], [], [], [], [], [], 0
            for i in positions:
                hs = hall_scenario("paper_hall", radar_index=i, trace=settings)
                b = hs.base
                trace_scene(hs.scene_xml, radar_position=b.ue_position, ris_positions=b.ris.pose.position[None],
                            frequency=b.radar.carrier_frequency, settings=settings)  # compile outside the timing
                hp = hall_paths(hs)
                times.append(hp.trace.timing.get("solve", hp.timing["trace"]))
                traced.append(len(hp.trace.monostatic) + len(hp.trace.legs[0]))
                kept.append(len(hp.paths))
                clean = simulate(b, rng=np.random.default_rng(0), paths=hp.paths, noise=False).cube
                model.append(np.linalg.norm(clean - ref_cubes[i]) / np.linalg.norm(ref_cubes[i]))
                for ss in np.random.SeedSequence([seed, depth, n, i]).spawn(realizations):
                    cap = simulate(b, rng=np.random.default_rng(ss), paths=hp.paths)
                    loc, _ = process_capture(cap)
                    dist.append(abs(loc.distance - b.truth.distance))
                    pos.append(np.linalg.norm(loc.position - b.truth.ue_position))
                    hits += bool(np.allclose(loc.aod, b.truth.aod, atol=1e-9))
            err = np.mean(model)
            err_text = "identical" if err == 0 else f"{20 * np.log10(err):.1f}"
            print(f"{depth:>5} {n:>9.0e} {np.mean(times):>9.3f} {np.mean(traced):>7.0f} {np.mean(kept):>5.0f} "
                  f"{err_text:>14} {1e3 * np.mean(dist):>13.2f} {1e3 * np.mean(pos):>12.2f} "
                  f"{hits:>4}/{len(dist)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realizations", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="depths 1-3 and 1e4/1e5 rays only")
    args = parser.parse_args()
    info = backend_info()
    print(f"risloc-rt hall benchmark on {info.get('variant')} (LLVM {info.get('llvm_version')}), {os.cpu_count()} cores")
    stage_times(args.realizations, args.seed)
    fidelity_table(args.realizations, args.seed, args.quick)


if __name__ == "__main__":
    main()
