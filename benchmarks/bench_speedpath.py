"""The fast paths at Table I sizes: DSP (screened zoom vs the paper's full grid) and synthesis.

DSP: for the paper scenario (both cases) and the default hall (both radar positions), noisy
captures are processed with ``dsp.localize(dsp.scan_beams(...))`` — the paper's method — once with
``doppler_search="full"`` (the N_DFT × K_DFT transform of every beam, the reference) and once with
the screened ``"zoom"`` search, on the same cube. It prints the median time of each, their ratio,
and whether the best beam, every beam's grid peak (delay and Doppler bins) and the estimate are
identical, plus the largest relative difference of the peak and P_ave values. Times are wall
clock and CPU (process) seconds per cube; a closing line gives the paper DSP's speed against the
straight paper method (the full grid) next to its exactness, all from the same run. The "best-only"
columns time the same method with ``scan_beams(best_only=True)`` (only the beams that can be the
best searched: a study's paper run), how many beams it left out and whether its best beam and
position are the whole scan's; a second closing line gives its ratio to the full grid.

``--device cuda`` (or ``strict``, ``numpy``) also runs the paper DSP with the cube on that device: the
grid search where the cube lives (``dsp/devicegrid.py``), timed per cube with the cube already there
(as in a study), and its bins checked against the host's on every cube (and on the random and
adversarial beams). ``numpy`` runs the device search on the host's NumPy, to show what it would cost
there; ``strict`` is CI's array_api_strict, whose cost is not a target.

``--hard-shapes`` times beams the bounds may not prune (a glitch in one ADC sample, a tone in one chirp,
impulses, structured patterns), two of each, on the host (and the device), with the process's peak RSS
so far (``--realizations 0`` runs them alone), and checks their cells against the full search.

``--threads 1`` runs the DSP and BLAS on one thread (one core). ``--baseline FILE`` also times
another version of ``dsp/gridscreen.py`` (e.g. ``git show REV:dsp/gridscreen.py > /tmp/old.py``)
on the same cubes, alternating with the current one, and checks its bins too.

Synthesis: a Table I capture of the default hall's kept paths (``simulate``), with the standard
noise stream and the per-beam ones ("fast": float32 ziggurat, "boxmuller": float32 Box–Muller; per-beam
child streams, threaded), median of ``--repeat``, each beside its noise's law on the last capture:
the power over σ² (sampling std 5e-4) and the Kolmogorov–Smirnov distance of I and Q from N(0, σ²/2)
(0.0004 is the 95 % point for 9.4 M values).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_speedpath.py [--realizations 5] [--full 2] [--low-power 0,10]
        [--threads 1] [--baseline /tmp/old_gridscreen.py] [--device cuda]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import platform
import sys
import time
import warnings
from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

import dsp
import dsp.beamscan
from risloc_rt.hall.pruning import AliasWarning
from risloc_rt.hall.scenario import hall_paths, hall_scenario
from risloc_rt.model.scenario import PAPER_CASES, paper_scenario
from risloc_rt.model.simulate import simulate


def _paper_path(cube, capture, search, screen=None, best_only=False):
    """``dsp.localize(dsp.scan_beams(...))`` with ``search``; ``screen``: another screened_scan to use;
    ``best_only``: only the beams that can be the best searched (what a study's paper run does).

    Returns (localization, wall seconds, CPU seconds).
    """
    original = dsp.beamscan.screened_scan
    if screen is not None:
        dsp.beamscan.screened_scan = screen
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        scan = dsp.scan_beams(cube, capture.sweep, capture.radar, replace(capture.processing, doppler_search=search),
                              **({"best_only": True} if best_only else {}))
        loc = dsp.localize(scan, radar=capture.radar, pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay)
        return loc, time.perf_counter() - t0, time.process_time() - c0
    finally:
        dsp.beamscan.screened_scan = original


def _device_scan(cube, capture_or_radar, processing, backend, sweep=None):
    """``dsp.scan_beams`` of a cube already on ``backend``'s device (NumPy: the device search on the host)."""
    radar = getattr(capture_or_radar, "radar", capture_or_radar)
    sweep = sweep if sweep is not None else capture_or_radar.sweep
    if not backend.is_numpy:
        return dsp.scan_beams(cube, sweep, radar, processing)
    original = dsp.beamscan.is_host_array
    dsp.beamscan.is_host_array = lambda x: False  # route a host cube to dsp.devicegrid (benchmark only)
    try:
        return dsp.scan_beams(cube, sweep, radar, processing)
    finally:
        dsp.beamscan.is_host_array = original


def _device_path(cube, capture, backend):
    """The paper's DSP on a cube already on the device. Returns (localization, wall seconds, CPU seconds)."""
    t0, c0 = time.perf_counter(), time.process_time()
    scan = _device_scan(cube, capture, capture.processing, backend)  # its results come back: synchronised
    loc = dsp.localize(scan, radar=capture.radar, pose=capture.ris.pose, loopback_delay=capture.ris.loopback_delay)
    return loc, time.perf_counter() - t0, time.process_time() - c0


def _load_baseline(path):
    """Another version of ``dsp/gridscreen.py`` loaded as a module of the package (its ``screened_scan``)."""
    spec = importlib.util.spec_from_file_location("dsp._gridscreen_baseline", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module.screened_scan


def _same(a, b):
    """(same best beam, same bins in every beam, same estimate, max rel. diff of peak and P_ave)."""
    bins = bool(np.array_equal(a.scan.delay_bin, b.scan.delay_bin) and np.array_equal(a.scan.doppler_bin, b.scan.doppler_bin))
    diff = max(float(np.max(np.abs(x / y - 1))) for x, y in ((a.scan.peak_power, b.scan.peak_power),
                                                             (a.scan.average_power, b.scan.average_power)))
    return a.beam_index == b.beam_index, bins, bool(np.array_equal(a.position, b.position)), diff


def _cases(low_powers=()):
    for case in PAPER_CASES:
        yield f"paper {case}", paper_scenario(case), None
    for dbm in low_powers:  # weaker RIS returns: most beams hold noise only and go to the dense search
        sc = paper_scenario("off-broadside")
        yield f"paper off-bs {dbm:g} dBm", replace(sc, radar=replace(sc.radar, tx_power_dbm=dbm)), None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        for index in (0, 1):
            try:
                hs = hall_scenario("paper_hall", radar_index=index)
                paths = hall_paths(hs).paths
            except ImportError as exc:  # a machine without the tracer's packages (the GPU machine's image)
                print(f"paper_hall cases skipped: {exc} (install the tracer, or carry its trace cache)")
                return
            yield f"paper_hall radar {index}", hs.base, paths


def bench_dsp(realizations: int, full: int, seed: int, low_powers=(), baseline=None, device=None) -> None:
    """Screened zoom vs the full grid per case; with ``baseline`` (a screened_scan) also the older screen;
    with ``device`` (an ArrayBackend) also the device's grid search on the same cubes."""
    print(f"{'case':<24} {'n':>3} {'zoom [s]':>9} {'cpu [s]':>8} {'full [s]':>9} {'full/zoom':>9} {'same beam':>9} "
          f"{'same bins':>9} {'same estimate':>13} {'max rel. diff':>13} {'best-only [s]':>13} {'cpu [s]':>8} "
          f"{'full/best':>9} {'left out':>8} {'same estimate':>13}"
          + (f" {'baseline [s]':>12} {'cpu [s]':>8} {'base/zoom':>9} {'base bins':>9}" if baseline else "")
          + (f" {'device [s]':>10} {'full/dev':>8} {'dev bins':>8} {'dev diff':>8}" if device else ""))
    cases = list(_cases(low_powers))
    ratios, exact, worst = [], [0, 0], 0.0
    best_ratios, best_exact = [], [0, 0]
    dev_ratios, dev_exact = [], [0, 0]
    for (name, scenario, paths), ss in zip(cases, np.random.SeedSequence(seed).spawn(len(cases))):
        t_zoom, c_zoom, t_full, t_base, c_base, beam, bins, est, diff, base_bins = [], [], [], [], [], 0, 0, 0, 0.0, 0
        t_dev, dev_bins, dev_diff = [], 0, 0.0
        t_best, c_best, left_out, best_same = [], [], [], 0
        for r, child in enumerate(ss.spawn(realizations)):
            cap = simulate(scenario, rng=np.random.default_rng(child), paths=paths)
            if baseline is not None:  # alternating with the current screen, on the same cube
                old, t, c = _paper_path(cap.cube, cap, "zoom", baseline)
                t_base.append(t)
                c_base.append(c)
            zoom, t, c = _paper_path(cap.cube, cap, "zoom")
            t_zoom.append(t)
            c_zoom.append(c)
            reduced, t, c = _paper_path(cap.cube, cap, "zoom", best_only=True)
            t_best.append(t)
            c_best.append(c)
            left_out.append(int(reduced.scan.bounded.sum()))
            best_same += bool(reduced.beam_index == zoom.beam_index and np.array_equal(reduced.position, zoom.position))
            if baseline is not None:
                base_bins += _same(old, zoom)[1]
            if device is not None:  # the cube copied to the device first (a study's cube is there already)
                on_dev, t, _ = _device_path(device.asarray(cap.cube), cap, device)
                t_dev.append(t)
                same = _same(on_dev, zoom)
                dev_bins, dev_diff = dev_bins + (same[0] and same[1]), max(dev_diff, same[3])
            if r >= full:
                continue
            ref, t, _ = _paper_path(cap.cube, cap, "full")
            t_full.append(t)
            same = _same(zoom, ref)
            beam, bins, est, diff = beam + same[0], bins + same[1], est + same[2], max(diff, same[3])
        mz, mf = np.median(t_zoom), np.median(t_full)
        ratios.append((name, mz, np.median(c_zoom), mf / mz))
        exact = [exact[0] + bins, exact[1] + full]
        worst = max(worst, diff)
        line = (f"{name:<24} {len(t_zoom):>3} {mz:>9.3f} {np.median(c_zoom):>8.3f} {mf:>9.2f} {mf / mz:>9.0f} "
                f"{beam:>6}/{full:<2} {bins:>6}/{full:<2} {est:>10}/{full:<2} {diff:>13.1e}")
        mb = float(np.median(t_best))
        best_ratios.append((name, mb, float(np.median(c_best)), mf / mb))
        best_exact = [best_exact[0] + best_same, best_exact[1] + realizations]
        line += (f" {mb:>13.3f} {np.median(c_best):>8.3f} {mf / mb:>9.0f} {int(np.median(left_out)):>5}/{zoom.scan.num_beams:<2}"
                 f" {best_same:>10}/{realizations:<2}")
        if baseline is not None:
            line += (f" {np.median(t_base):>12.3f} {np.median(c_base):>8.3f} {np.median(t_base) / mz:>9.2f} "
                     f"{base_bins:>6}/{realizations:<2}")
        if device is not None:
            md = float(np.median(t_dev))
            dev_ratios.append((name, md, mf / md))
            dev_exact = [dev_exact[0] + dev_bins, dev_exact[1] + realizations]
            line += f" {md:>10.4f} {mf / md:>8.0f} {dev_bins:>5}/{realizations:<2} {dev_diff:>8.1e}"
        print(line)
    slowest = max(ratios, key=lambda r: r[1])
    print(f"paper DSP against the straight paper method (full grid): {min(r[3] for r in ratios):.0f}-"
          f"{max(r[3] for r in ratios):.0f}x faster, slowest case {slowest[0]} {slowest[1]:.3f} s per cube "
          f"(cpu {slowest[2]:.3f} s) [goal >= 170x, <= 0.07 s]; exact: same bins in {exact[0]}/{exact[1]} cubes, "
          f"max rel. diff of peak and P_ave {worst:.1e}")
    slowest = max(best_ratios, key=lambda r: r[1])
    print(f"the same with only the beams that can be the best searched (scan_beams(best_only=True), a study's paper run): "
          f"{min(r[3] for r in best_ratios):.0f}-{max(r[3] for r in best_ratios):.0f}x faster, slowest case {slowest[0]} "
          f"{slowest[1]:.3f} s per cube (cpu {slowest[2]:.3f} s); the same best beam and position as the whole scan in "
          f"{best_exact[0]}/{best_exact[1]} cubes")
    if device is not None:
        slowest = max(dev_ratios, key=lambda r: r[1])
        print(f"paper DSP on {device.summary()}: {min(r[2] for r in dev_ratios):.0f}-{max(r[2] for r in dev_ratios):.0f}x "
              f"the host's full grid, slowest case {slowest[0]} {slowest[1]:.4f} s per cube; the host's bins and beam "
              f"in {dev_exact[0]}/{dev_exact[1]} cubes")


def _device_compare(cube, radar, processing, device, reference):
    """(same cells, exact ties) of the device search against ``reference`` (a BeamScan) on ``cube``."""
    if device is None:
        return 0, 0
    scan = _device_scan(device.asarray(cube), radar, processing, device, sweep=dsp.BeamSweep(np.zeros((cube.shape[0], 2))))
    eq = (scan.delay_bin == reference.delay_bin) & (scan.doppler_bin == reference.doppler_bin)
    return int(eq.sum()), int(np.sum(~eq & np.isclose(scan.peak_power, reference.peak_power, rtol=1e-12, atol=0)))


def bench_random_beams(count: int, seed: int, device=None) -> None:
    """Random Table I beams (1-6 returns, 0-40 dB spread, -20 to +30 dB noise per sample): zoom vs full."""
    scenario = paper_scenario("broadside")
    radar, processing = scenario.radar, scenario.processing
    rng = np.random.default_rng(seed)
    k, n = np.arange(radar.num_chirps)[:, None], np.arange(radar.num_samples)[None, :]
    same, ties, worst, dev_same, dev_ties = 0, 0, 0.0, 0, 0
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
        a, b = _device_compare(cube, radar, processing, device, full)
        dev_same, dev_ties = dev_same + a, dev_ties + b
    print(f"random Table I beams: {same}/{count} same grid cell as the full search, {ties} exact ties, "
          f"largest relative peak difference {worst:.1e}"
          + (f"; on the device {dev_same}/{count} the full search's cell, {dev_ties} exact ties" if device else ""))


def bench_adversarial(batches: int, seed: int, device=None) -> None:
    """Small beams (K = 16, N = 64) with 2-3 near-equal returns within 1.5 cells in delay and Doppler
    (interference between native samples, the screen's hard case), 4 windows: zoom vs full."""
    radar = dsp.RadarConfig(num_samples=64, num_chirps=16)
    res_t = radar.max_delay / radar.num_samples
    res_nu = 1 / (radar.num_chirps * radar.carrier_frequency * radar.chirp_interval)
    k, n = np.arange(16)[:, None], np.arange(64)[None, :]
    rng = np.random.default_rng(seed)
    total = mismatches = ties = dev_same = dev_ties = 0
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
            a, b = _device_compare(cube, radar, proc, device, full)
            dev_same, dev_ties = dev_same + a, dev_ties + b
    print(f"adversarial small beams (2-3 near-equal returns within 1.5 cells, 4 windows): {total} beams, "
          f"{mismatches} other cell than the full search, {ties} exact ties"
          + (f"; on the device {total - dev_same - dev_ties} other cell, {dev_ties} exact ties" if device else ""))


def _hard_shapes(rng):
    """Table I beams the bounds may not prune (name, beam [K, N]): glitches, bursts and structured patterns."""
    k, n = 128, 600

    def put(index, value):
        beam = np.zeros((k, n), complex)
        beam[index] = value
        return beam

    huge = rng.standard_normal((k, n)) + 0j
    huge[0] = 1e6
    return [
        ("one ADC sample (a glitch)", put((5, 100), 1.0)),
        ("a tone in one chirp (a burst)", put(7, np.exp(2j * np.pi * 0.1 * np.arange(n)))),
        ("noise in one chirp", put(3, rng.standard_normal(n) + 1j * rng.standard_normal(n))),
        ("noise in one sample column", put((slice(None), 50), rng.standard_normal(k) + 1j * rng.standard_normal(k))),
        ("5 impulses", put(np.unravel_index(rng.integers(0, k * n, 5), (k, n)), 1.0)),
        ("50 impulses", put(np.unravel_index(rng.integers(0, k * n, 50), (k, n)), rng.standard_normal(50))),
        ("constant", np.ones((k, n), complex)),
        ("one random row in every chirp", np.broadcast_to(np.exp(2j * np.pi * rng.uniform(size=n)), (k, n)).copy()),
        ("random chirp phases", np.broadcast_to(np.exp(2j * np.pi * rng.uniform(size=(k, 1))), (k, n)).copy()),
        ("sign noise", np.sign(rng.standard_normal((k, n))) + 0j),
        ("alternate chirps", put(slice(None, None, 2), 1.0)),
        ("one huge chirp over noise", huge),
    ]


def bench_hard_shapes(seed: int, device=None) -> None:
    """Per shape (two beams of it), seconds per beam and peak RSS of the host's screen, the device's search,
    and whether both give the full search's cells."""
    import resource

    scenario = paper_scenario("broadside")
    radar, processing = scenario.radar, scenario.processing
    print(f"{'beam shape':<32} {'host [s/beam]':>13} {'device [s/beam]':>15} {'full grid cells':>15} "
          f"{'process peak RSS so far [MB]':>28}")
    rng = np.random.default_rng(seed)
    for name, beam in _hard_shapes(rng):
        cube = _with_tiny_noise(np.stack([beam, 0.5 * beam]), rng)
        sweep = dsp.BeamSweep(np.zeros((2, 2)))
        t0 = time.perf_counter()
        host = dsp.scan_beams(cube, sweep, radar, processing)
        t_host = (time.perf_counter() - t0) / 2
        full = dsp.scan_beams(cube, sweep, radar, replace(processing, doppler_search="full"))
        same = np.array_equal(host.delay_bin, full.delay_bin) and np.array_equal(host.doppler_bin, full.doppler_bin)
        t_dev = float("nan")
        if device is not None:
            t0 = time.perf_counter()
            dev = _device_scan(device.asarray(cube), radar, processing, device, sweep=sweep)
            t_dev = (time.perf_counter() - t0) / 2
            same = same and np.array_equal(dev.delay_bin, full.delay_bin) and np.array_equal(dev.doppler_bin, full.doppler_bin)
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024
        print(f"{name:<32} {t_host:>13.3f} {t_dev:>15.3f} {str(same):>15} {rss:>28}")


def _with_tiny_noise(cube, rng):
    """``cube`` plus circular Gaussian noise of power 1e-12 per sample (breaks exact ties of flat spectra)."""
    return cube + np.sqrt(0.5e-12) * (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape))


def bench_synthesis(repeat: int) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        hs = hall_scenario("paper_hall")
        paths = hall_paths(hs).paths
    from scipy import stats

    rng = np.random.default_rng(0)
    clean = simulate(hs.base, rng=rng, paths=paths, noise=False).cube
    sigma2 = hs.base.radar.noise_power
    out = {}
    for stream in ("standard", "fast", "boxmuller"):
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            cap = simulate(hs.base, rng=rng, paths=paths, noise_stream=stream)
            times.append(time.perf_counter() - t0)
        w = (cap.cube - clean).ravel()
        parts = np.concatenate([w.real, w.imag]) / np.sqrt(sigma2 / 2)
        ks = stats.kstest(parts, "norm").statistic
        out[stream] = (np.median(times), min(times), float(np.mean(np.abs(w) ** 2) / sigma2), ks)
    print(f"synthesis of a noisy Table I capture, default hall ({len(paths)} kept paths), median (best) of {repeat}:")
    for stream, (med, best, power, ks) in out.items():
        print(f"  noise stream {stream:<9} {med:.3f} s ({best:.3f} s), {out['standard'][0] / med:.2f}x the standard; "
              f"noise power / sigma^2 {power:.5f}, KS distance of I, Q from N(0, sigma^2/2) {ks:.5f}")


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
    parser.add_argument("--threads", type=int, default=0,
                        help="DSP and BLAS threads (default: all cores); 1 measures one core")
    parser.add_argument("--baseline", default="", metavar="FILE",
                        help="another dsp/gridscreen.py to time on the same cubes (before/after)")
    parser.add_argument("--no-synthesis", action="store_true", help="skip the synthesis benchmark")
    parser.add_argument("--hard-shapes", action="store_true",
                        help="also time beams the bounds may not prune (a glitch, a burst, impulses, patterns)")
    parser.add_argument("--device", default="", choices=("", "cuda", "strict", "numpy"),
                        help="also the paper DSP with the cube on this device (dsp/devicegrid.py)")
    args = parser.parse_args()
    print(f"risloc-rt fast-path benchmark; {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"numpy {np.__version__}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"threads {args.threads or 'all'}, load average {os.getloadavg()[0]:.1f}")
    lows = [float(v) for v in args.low_power.split(",") if v.strip()]
    baseline = _load_baseline(args.baseline) if args.baseline else None
    with contextlib.ExitStack() as stack:
        if args.threads:
            stack.enter_context(dsp.limit_threads(args.threads))
            stack.enter_context(threadpool_limits(args.threads))
        device = None
        if args.device:
            device = {"cuda": lambda: dsp.backend_for("cuda"), "strict": lambda: dsp.strict_backend("CPU_DEVICE"),
                      "numpy": dsp.numpy_backend}[args.device]()
            print(f"device: {device.summary()}")
        if args.realizations > 0:  # 0: only the other parts (e.g. --hard-shapes alone, for its peak RSS)
            bench_dsp(args.realizations, min(args.full, args.realizations), args.seed, lows, baseline, device)
        if args.random_beams:
            bench_random_beams(args.random_beams, args.seed, device)
        if args.adversarial:
            bench_adversarial(args.adversarial, args.seed, device)
        if args.hard_shapes:
            bench_hard_shapes(args.seed, device)
        if not args.no_synthesis:
            bench_synthesis(args.repeat)


if __name__ == "__main__":
    main()
