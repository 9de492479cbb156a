"""The fast paths at Table I sizes: DSP (screened zoom vs the paper's full grid) and synthesis.

DSP: for the paper scenario (both cases) and the default hall (both radar positions), noisy
captures are processed with ``dsp.localize(dsp.scan_beams(...))`` — the paper's method — once with
``doppler_search="full"`` (the N_DFT × K_DFT transform of every beam, the reference) and once with
the screened ``"zoom"`` search, on the same cube. It prints the median time of each, their ratio,
and whether the best beam, every beam's grid peak (delay and Doppler bins) and the estimate are
identical, plus the largest relative difference of the peak and P_ave values.

Synthesis: a Table I capture of the default hall's kept paths (``simulate``), with the standard
noise stream and with the fast one (float32 per-beam streams, threaded), median of ``--repeat``.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_speedpath.py [--realizations 5] [--full 2] [--low-power 0,10]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
import warnings
from dataclasses import replace

import numpy as np

import dsp
from risloc_rt.hall.pruning import AliasWarning
from risloc_rt.hall.scenario import hall_paths, hall_scenario
from risloc_rt.model.scenario import PAPER_CASES, paper_scenario
from risloc_rt.model.simulate import simulate


def _paper_path(cube, capture, search):
    t0 = time.perf_counter()
    scan = dsp.scan_beams(cube, capture.sweep, capture.radar, replace(capture.processing, doppler_search=search))
    loc = dsp.localize(scan, radar=capture.radar, pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay)
    return loc, time.perf_counter() - t0


def _cases(low_powers=()):
    for case in PAPER_CASES:
        yield f"paper {case}", paper_scenario(case), None
    for dbm in low_powers:  # weaker RIS returns: most beams hold noise only and go to the dense search
        sc = paper_scenario("off-broadside")
        yield f"paper off-bs {dbm:g} dBm", replace(sc, radar=replace(sc.radar, tx_power_dbm=dbm)), None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        for index in (0, 1):
            hs = hall_scenario("paper_hall", radar_index=index)
            yield f"paper_hall radar {index}", hs.base, hall_paths(hs).paths


def bench_dsp(realizations: int, full: int, seed: int, low_powers=()) -> None:
    print(f"{'case':<24} {'n':>3} {'zoom [s]':>9} {'full [s]':>9} {'full/zoom':>9} {'same beam':>9} "
          f"{'same bins':>9} {'same estimate':>13} {'max rel. diff':>13}")
    cases = list(_cases(low_powers))
    for (name, scenario, paths), ss in zip(cases, np.random.SeedSequence(seed).spawn(len(cases))):
        t_zoom, t_full, beam, bins, est, diff = [], [], 0, 0, 0, 0.0
        for r, child in enumerate(ss.spawn(realizations)):
            cap = simulate(scenario, rng=np.random.default_rng(child), paths=paths)
            zoom, t = _paper_path(cap.cube, cap, "zoom")
            t_zoom.append(t)
            if r >= full:
                continue
            ref, t = _paper_path(cap.cube, cap, "full")
            t_full.append(t)
            beam += zoom.beam_index == ref.beam_index
            bins += bool(np.array_equal(zoom.scan.delay_bin, ref.scan.delay_bin)
                         and np.array_equal(zoom.scan.doppler_bin, ref.scan.doppler_bin))
            est += bool(np.array_equal(zoom.position, ref.position))
            for a, b in ((zoom.scan.peak_power, ref.scan.peak_power), (zoom.scan.average_power, ref.scan.average_power)):
                diff = max(diff, float(np.max(np.abs(a / b - 1))))
        mz, mf = np.median(t_zoom), np.median(t_full)
        print(f"{name:<24} {len(t_zoom):>3} {mz:>9.3f} {mf:>9.2f} {mf / mz:>9.0f} {beam:>6}/{full:<2} "
              f"{bins:>6}/{full:<2} {est:>10}/{full:<2} {diff:>13.1e}")


def bench_random_beams(count: int, seed: int) -> None:
    """Random Table I beams (1-6 returns, 0-40 dB spread, -20 to +30 dB noise per sample): zoom vs full."""
    scenario = paper_scenario("broadside")
    radar, processing = scenario.radar, scenario.processing
    rng = np.random.default_rng(seed)
    k, n = np.arange(radar.num_chirps)[:, None], np.arange(radar.num_samples)[None, :]
    same, ties, worst = 0, 0, 0.0
    for start in range(0, count, 8):
        cube = np.zeros((min(8, count - start), radar.num_chirps, radar.num_samples), complex)
        for m in range(cube.shape[0]):
            for _ in range(rng.integers(1, 7)):
                tau, nu = rng.uniform(0, 0.95) * radar.max_delay, rng.uniform(-1, 1) / (2 * radar.carrier_frequency * radar.chirp_interval)
                f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
                f2 = radar.carrier_frequency * nu * radar.chirp_interval
                cube[m] += 10 ** (-rng.uniform(0, 40) / 20) * np.exp(2j * np.pi * (rng.uniform() - ((k * f2 + n * f1) % 1.0)))
            cube[m] += np.sqrt(10 ** (rng.uniform(-20, 30) / 10) / 2) * (rng.standard_normal(cube[m].shape)
                                                                         + 1j * rng.standard_normal(cube[m].shape))
        sweep = dsp.BeamSweep(np.zeros((cube.shape[0], 2)))
        zoom = dsp.scan_beams(cube, sweep, radar, processing)
        full = dsp.scan_beams(cube, sweep, radar, replace(processing, doppler_search="full"))
        eq = (zoom.delay_bin == full.delay_bin) & (zoom.doppler_bin == full.doppler_bin)
        same += int(eq.sum())
        ties += int(np.sum(~eq & np.isclose(zoom.peak_power, full.peak_power, rtol=1e-12, atol=0)))
        worst = max(worst, float(np.max(np.abs(zoom.peak_power / full.peak_power - 1))))
    print(f"random Table I beams: {same}/{count} same grid cell as the full search, {ties} exact ties, "
          f"largest relative peak difference {worst:.1e}")


def bench_adversarial(batches: int, seed: int) -> None:
    """Small beams (K = 16, N = 64) with 2-3 near-equal returns within 1.5 cells in delay and Doppler
    (interference between native samples, the screen's hard case), 4 windows: zoom vs full."""
    radar = dsp.RadarConfig(num_samples=64, num_chirps=16)
    res_t = radar.max_delay / radar.num_samples
    res_nu = 1 / (radar.num_chirps * radar.carrier_frequency * radar.chirp_interval)
    k, n = np.arange(16)[:, None], np.arange(64)[None, :]
    rng = np.random.default_rng(seed)
    total = mismatches = ties = 0
    for window in ("hann", "hamming", "boxcar", "blackman"):
        proc = dsp.ProcessingConfig(n_dft=127, k_dft=67, window=window)
        for _ in range(batches):
            cube = np.zeros((40, 16, 64), complex)
            for m in range(40):
                t0, n0 = rng.uniform(5, 55) * res_t, rng.uniform(-5, 5) * res_nu
                for _ in range(rng.integers(2, 4)):
                    tau, nu = t0 + rng.uniform(-1.5, 1.5) * res_t, n0 + rng.uniform(-1.5, 1.5) * res_nu
                    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
                    f2 = radar.carrier_frequency * nu * radar.chirp_interval
                    cube[m] += (1 + 0.1 * rng.standard_normal()) * np.exp(2j * np.pi * (rng.uniform() - (k * f2 + n * f1) % 1.0))
                cube[m] += np.sqrt(10 ** (rng.uniform(-25, 10) / 10) / 2) * (rng.standard_normal((16, 64))
                                                                              + 1j * rng.standard_normal((16, 64)))
            sweep = dsp.BeamSweep(np.zeros((40, 2)))
            zoom = dsp.scan_beams(cube, sweep, radar, proc)
            full = dsp.scan_beams(cube, sweep, radar, replace(proc, doppler_search="full"))
            eq = (zoom.delay_bin == full.delay_bin) & (zoom.doppler_bin == full.doppler_bin)
            tie = ~eq & np.isclose(zoom.peak_power, full.peak_power, rtol=1e-12, atol=0)
            total, mismatches, ties = total + 40, mismatches + int((~eq & ~tie).sum()), ties + int(tie.sum())
    print(f"adversarial small beams (2-3 near-equal returns within 1.5 cells, 4 windows): {total} beams, "
          f"{mismatches} other cell than the full search, {ties} exact ties")


def bench_synthesis(repeat: int) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        hs = hall_scenario("paper_hall")
        paths = hall_paths(hs).paths
    rng = np.random.default_rng(0)
    out = {}
    for stream in ("standard", "fast"):
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            simulate(hs.base, rng=rng, paths=paths, noise_stream=stream)
            times.append(time.perf_counter() - t0)
        out[stream] = (np.median(times), min(times))
    print(f"synthesis of a noisy Table I capture, default hall ({len(paths)} kept paths), median (best) of {repeat}:")
    for stream, (med, best) in out.items():
        print(f"  noise stream {stream:<9} {med:.3f} s ({best:.3f} s), {out['standard'][0] / med:.2f}x the standard")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realizations", type=int, default=5)
    parser.add_argument("--full", type=int, default=2, help="realizations also run with the full 2-D DFT")
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--random-beams", type=int, default=0, help="also compare zoom and full on N random beams")
    parser.add_argument("--adversarial", type=int, default=0, help="also run N batches of 40 adversarial small beams per window")
    parser.add_argument("--low-power", default="", metavar="DBM,...",
                        help="also the off-broadside paper case at these transmit powers, e.g. 0,10")
    args = parser.parse_args()
    print(f"risloc-rt fast-path benchmark; {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"numpy {np.__version__}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    lows = [float(v) for v in args.low_power.split(",") if v.strip()]
    bench_dsp(args.realizations, min(args.full, args.realizations), args.seed, lows)
    if args.random_beams:
        bench_random_beams(args.random_beams, args.seed)
    if args.adversarial:
        bench_adversarial(args.adversarial, args.seed)
    bench_synthesis(args.repeat)


if __name__ == "__main__":
    main()
