"""Detector benchmark: false-alarm rate measured against the stated one, Pd against SNR, time per cube.

False alarms: noise-only cubes (and noise plus a strong static return, which the sweep-CFAR
cancels), ``--trials`` of them (>= 10,000), at a reduced size (M = 61 beams, K = 32, N = 64; the
statistic's law does not depend on the size, only the cell count in the threshold does). The
maximum of the statistic is kept per trial, so the rate is read at several stated P_FA at once.
Pd: Table I sizes, the RIS return synthesised as in bench_estimator.py (relay 16 × 4 pattern,
random phase per beam, off-grid delay/Doppler/AoD), against the post-integration SNR at the
pattern peak; time per Table I cube. Both detectors: the whole-sweep test on DFT bins
(``dsp.detect(cube, radar)``) and the pattern-matched windows on the half-bin grid that
``self_localize`` runs (``pattern=, sweep=, oversample=2``).

    .venv/bin/python benchmarks/bench_detection.py [--trials 10000] [--pd-trials 100] [--seed 0]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # threaded BLAS thrashes on a shared 2-core machine

import argparse
import platform
import time

import numpy as np

import dsp

C = dsp.SPEED_OF_LIGHT
SWEEP = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))


def noise(shape, rng):
    w = rng.standard_normal((2,) + shape)
    return (w[0] + 1j * w[1]) * np.sqrt(0.5)


def ris_cube(radar, pattern, rng, peak_snr):
    m, k, n = SWEEP.num_beams, radar.num_chirps, radar.num_samples
    tau = 2 * rng.uniform(3, 18) / C + 1.78e-9
    nu = 2 * rng.uniform(-1, 1) / C
    az = np.deg2rad(rng.uniform(-30, 30))
    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
    f2 = radar.carrier_frequency * nu * radar.chirp_interval
    t = np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))
    amp = np.abs(pattern.amplitude([az, 0.0], SWEEP.angles)) * np.sqrt(peak_snr / (k * n))
    return (amp * np.exp(2j * np.pi * rng.random(m)))[:, None, None] * t[None] + noise((m, k, n), rng)


def run(trials: int, pd_trials: int, seed: int) -> None:
    ss_fa, ss_cl, ss_pd = np.random.SeedSequence(seed).spawn(3)
    print(f"risloc-rt detection benchmark: seed {seed}; {platform.processor() or platform.machine()}, "
          f"numpy {np.__version__}")
    small = dsp.RadarConfig(num_samples=64, num_chirps=32)
    shape = (SWEEP.num_beams, small.num_chirps, small.num_samples)
    levels = (0.1, 0.01, 1e-3)
    for label, ss, n_trials, clutter in (("noise only", ss_fa, trials, False),
                                         ("noise + 60 dB static return", ss_cl, max(trials // 5, 1), True)):
        stats, full, wstats = [], 0, []
        eta = None
        pattern = dsp.BeamPattern().for_wavelength(small.wavelength)
        for child in ss.spawn(n_trials):
            rng = np.random.default_rng(child)
            cube = noise(shape, rng)
            if clutter:
                t = np.exp(-2j * np.pi * ((np.arange(small.num_samples) * rng.uniform(0.1, 0.9)) % 1.0))
                cube += 1e3 * np.exp(2j * np.pi * rng.random()) * t[None, None, :]
            det = dsp.detect(cube, small, pfa=levels[0])
            stats.append(det.statistic)
            full += det.detected
            eta = det.num_cells
            wdet = dsp.detect(cube, small, pfa=levels[-1], pattern=pattern, sweep=SWEEP, oversample=2)
            wstats.append(wdet.statistic)
        stats = np.array(stats)
        print(f"\nfalse alarms, {label}: {n_trials} cubes of [M, K, N] = {list(shape)} ({eta} cells searched)")
        print(f"  {'stated P_FA':>11} {'sweep-CFAR crossings':>21} {'measured':>9} {'95% binomial':>18}")
        for pfa in levels:
            thr = dsp.detection.sweep_cfar_threshold(pfa, SWEEP.num_beams, eta)
            k = int((stats >= thr).sum())
            half = 1.96 * np.sqrt(pfa * (1 - pfa) / n_trials)
            print(f"  {pfa:>11g} {k:>21d} {k / n_trials:>9.4f} [{max(pfa - half, 0):.4f}, {pfa + half:.4f}]")
        print(f"  full detector (sweep-CFAR and sweep-modulation test) at P_FA 0.1: {full / n_trials:.4f}")
        # windowed half-bin search (self_localize's): windows chosen at 1e-3, thresholds per level
        wstats = np.array(wstats)
        cells = 4 * eta
        windows = dsp.sweep_window.sweep_windows(pattern, SWEEP, cell_pfa=-np.expm1(np.log1p(-levels[-1]) / cells))
        print(f"  windowed half-bin search ({windows.size}-beam windows, {windows.count} of them, {cells} cells; "
              "stated P_FA is an upper bound):")
        for pfa in levels:
            thr = windows.threshold(-np.expm1(np.log1p(-pfa) / cells))
            k = int((wstats >= thr).sum())
            print(f"  {pfa:>11g} {k:>21d} {k / n_trials:>9.4f}")

    radar = dsp.RadarConfig()
    pattern = dsp.BeamPattern().for_wavelength(radar.wavelength)
    print(f"\ndetection probability, Table I sizes, P_FA = 1e-3, {pd_trials} cubes per SNR "
          "(post-integration SNR at the pattern peak)")
    print(f"  {'SNR [dB]':>8} {'Pd sweep':>8} {'Pd window':>9} {'ms sweep':>8} {'ms window':>9}")
    for snr_db, child in zip((4, 6, 8, 10, 12, 14, 16, 20), ss_pd.spawn(8)):
        hits, times = [0, 0], ([], [])
        for c in child.spawn(pd_trials):
            rng = np.random.default_rng(c)
            cube = ris_cube(radar, pattern, rng, 10 ** (snr_db / 10))
            for i, kw in enumerate(({}, dict(pattern=pattern, sweep=SWEEP, oversample=2))):
                t0 = time.perf_counter()
                hits[i] += dsp.detect(cube, radar, **kw).detected
                times[i].append(time.perf_counter() - t0)
        print(f"  {snr_db:>8} {hits[0] / pd_trials:>8.2f} {hits[1] / pd_trials:>9.2f} "
              f"{1e3 * np.median(times[0]):>8.1f} {1e3 * np.median(times[1]):>9.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10_000)
    ap.add_argument("--pd-trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    run(args.trials, args.pd_trials, args.seed)


if __name__ == "__main__":
    main()
