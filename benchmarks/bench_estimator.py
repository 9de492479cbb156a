"""Refined estimator against the CRB and against the paper's method: RMSE, bias and time.

The RIS return of the analytic scenario is synthesised directly (one beam-dependent tone + white
noise, ``docs/estimation.md``): beam m carries ``β |A_m(θ)| e^{jψ_m}`` with a random phase per
beam, A the 16 × 4 relay pattern, true distance, velocity and AoD drawn off every grid. SNR is the
post-integration SNR at the pattern peak, ρ = K N β²/σ². Table I sizes (M = 61, K = 128,
N = 600, N_DFT = 1199, K_DFT = 4793).

For every realization: the detector (windowed half-bin sweep-CFAR, as in ``self_localize``; its strongest beam-dependent cell initialises
the refinement even below the threshold, so that the RMSE is not conditioned on detection), the
refined estimator, and its CRB at the true parameters. The paper's method (zoom grid search,
best beam) runs on the first ``--paper`` realizations of each SNR point.

    .venv/bin/python benchmarks/bench_estimator.py [--realizations 500] [--paper 20] [--seed 0]
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
TAU_RB = 1.78e-9


def synth_cube(radar, sweep, pattern, distance, velocity, aod, peak_snr, rng, noise_power=1.0):
    """RIS tone across the sweep + CN(0, σ²) noise, [M, K, N] (eq. (1), loop-back path only)."""
    m, k, n = sweep.num_beams, radar.num_chirps, radar.num_samples
    tau = 2 * distance / C + TAU_RB
    nu = 2 * velocity / C
    amp = pattern.amplitude(aod, sweep.angles)  # [M]
    beta = np.sqrt(peak_snr * noise_power / (k * n))
    psi = rng.uniform(0, 2 * np.pi, m)
    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
    f2 = radar.carrier_frequency * nu * radar.chirp_interval
    fast = np.exp(-2j * np.pi * ((np.arange(n) * f1) % 1.0))
    slow = np.exp(-2j * np.pi * ((np.arange(k) * f2) % 1.0))
    cube = (beta * np.abs(amp) * np.exp(1j * psi))[:, None, None] * (slow[:, None] * fast[None, :])[None]
    w = rng.standard_normal((2,) + cube.shape)
    cube += (w[0] + 1j * w[1]) * np.sqrt(noise_power / 2)
    return cube, tau, nu


def run(realizations: int, paper: int, seed: int) -> None:
    radar = dsp.RadarConfig()
    processing = dsp.ProcessingConfig()
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    pattern = dsp.BeamPattern().for_wavelength(radar.wavelength)
    pose = dsp.RisPose.facing([0.0, 13.38, 0.0], [0.0, 0.0, 0.0])
    # the detector self_localize runs: pattern-matched beam windows on the half-bin grid
    acquisition = dict(pattern=pattern, sweep=sweep, oversample=2)
    print(f"risloc-rt estimator benchmark: Table I sizes, relay 16x4 RIS, {realizations} realizations per SNR "
          f"(paper method on {paper}), seed {seed}; {platform.processor() or platform.machine()}, numpy {np.__version__}")
    print("SNR = post-integration SNR at the pattern peak, K N beta^2 / sigma^2; CRB of the whole sweep at the truth")
    head = (f"{'SNR':>4} {'est':<7} {'n':>4} {'RMSE d [mm]':>11} {'CRB d [mm]':>10} {'RMSE/CRB':>8} {'bias/sd':>7} "
            f"{'RMSE az [mdeg]':>14} {'CRB az':>8} {'RMSE/CRB':>8} {'bias/sd':>7} {'det':>5} {'ms':>7}")
    print(head)
    print("-" * len(head))
    summary = []
    for snr_db, ss in zip((10, 20, 30, 40), np.random.SeedSequence(seed).spawn(4)):
        rho = 10 ** (snr_db / 10)
        err = {"refined": [], "paper": []}
        crb_d, crb_az, times, det_ok = [], [], {"refined": [], "paper": [], "detect": []}, []
        for i, child in enumerate(ss.spawn(realizations)):
            rng = np.random.default_rng(child)
            distance = rng.uniform(3.0, 18.0)
            velocity = rng.uniform(-1.0, 1.0)
            aod = np.array([np.deg2rad(rng.uniform(-30.0, 30.0)), 0.0])
            cube, tau, nu = synth_cube(radar, sweep, pattern, distance, velocity, aod, rho, rng)
            bound = dsp.sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho)
            crb_d.append(bound.distance)
            crb_az.append(bound.aod[0])
            t0 = time.perf_counter()
            det = dsp.detect(cube, radar, **acquisition)
            t1 = time.perf_counter()
            times["detect"].append(t1 - t0)
            det_ok.append(det.detected)
            init = det if det.detected else dsp.detect(cube, radar, pfa=1 - 1e-12, **acquisition)
            if not np.isfinite(init.delay):  # nothing beam-dependent at all: count as a miss at the grid
                init = dsp.Detection(False, 0, 0, 0, delay=tau, delay_rate=nu)
            t0 = time.perf_counter()
            est = dsp.refine_estimate(cube, sweep=sweep, radar=radar, pattern=pattern,
                                      initial_delay=init.delay, initial_delay_rate=init.delay_rate)
            times["refined"].append(time.perf_counter() - t0)
            err["refined"].append(((est.delay - tau) * C / 2, est.aod.aod[0] - aod[0]))
            if i < paper:
                t0 = time.perf_counter()
                loc = dsp.localize(dsp.scan_beams(cube, sweep, radar, processing), radar=radar, pose=pose,
                                   loopback_delay=TAU_RB)
                times["paper"].append(time.perf_counter() - t0)
                err["paper"].append(((loc.delay - tau) * C / 2, loc.aod[0] - aod[0]))
        rc_d = float(np.sqrt(np.mean(np.square(crb_d))))
        rc_az = float(np.sqrt(np.mean(np.square(crb_az))))
        for name in ("refined", "paper"):
            e = np.array(err[name])
            if not e.size:
                continue
            rmse = np.sqrt(np.mean(e**2, axis=0))
            bias = e.mean(axis=0)
            sd = e.std(axis=0, ddof=1)
            ms = 1e3 * float(np.median(times[name]))
            print(f"{snr_db:>4} {name:<7} {len(e):>4} {rmse[0] * 1e3:>11.4f} {rc_d * 1e3:>10.4f} {rmse[0] / rc_d:>8.3f} "
                  f"{bias[0] / sd[0]:>+7.3f} {np.rad2deg(rmse[1]) * 1e3:>14.2f} {np.rad2deg(rc_az) * 1e3:>8.2f} "
                  f"{rmse[1] / rc_az:>8.3f} {bias[1] / sd[1]:>+7.3f} {np.mean(det_ok):>5.2f} {ms:>7.1f}")
            summary.append((snr_db, name, rmse, rc_d, rc_az, ms))
        e = np.array(err["refined"])[:, 0]
        ok = np.array(det_ok)
        out = np.abs(e) > 0.05
        inl = ok & ~out
        extra = f", over the detected ones without them {np.sqrt(np.mean(e[inl] ** 2)) / rc_d:.3f}" if inl.any() else ""
        print(f"{'':>4} refined outliers (|distance error| > 5 cm): {int(out.sum())}, of them detected "
              f"{int((out & ok).sum())}; distance RMSE/CRB without them {np.sqrt(np.mean(e[~out] ** 2)) / rc_d:.3f}"
              + extra)
        print(f"{'':>4} detect  median {1e3 * np.median(times['detect']):.1f} ms per cube")
    print()
    print("ratios refined / paper (same realizations' SNR point): RMSE distance, RMSE AoD, time")
    by = {(s, n): (r, ms) for s, n, r, _, _, ms in summary}
    for snr_db in (10, 20, 30, 40):
        if (snr_db, "paper") in by:
            (rr, tr), (rp, tp) = by[(snr_db, "refined")], by[(snr_db, "paper")]
            print(f"  {snr_db:>2} dB: distance {rr[0] / rp[0]:.3f}, AoD {rr[1] / rp[1]:.3f}, time {tr / tp:.3f} "
                  f"(refined {tr:.1f} ms on top of the detector, paper grid search {tp:.1f} ms)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=500)
    ap.add_argument("--paper", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    run(args.realizations, args.paper, args.seed)


if __name__ == "__main__":
    main()
