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

Per SNR and estimator, RMSE/CRB is printed over all realizations and over the detected ones, each
with a 95 % bootstrap confidence interval (realizations resampled, the ratio of the RMS error to
the RMS bound recomputed), and bias/σ, and the refined RMSE over the random-phase bound
(``dsp.sweep_crb(phases="random")``, the 1σ ``Localization.std`` reports). ``--compare`` also runs
the marginal-likelihood criterion (``likelihood="marginal"``) on the same cubes; ``--start truth`` starts the refinement at the half-bin cell of the true tone instead of
the detector's (a genie: no acquisition error; the detector still runs for the detected flag).
Each SNR point also prints the bound with the phases random instead of unknown constants
(``random_phase_bound_ratio``): the whole-sweep CRB assumes every beam's phase could be learnt,
which beams near the noise floor do not allow; no estimator beats that bound on average.

    .venv/bin/python benchmarks/bench_estimator.py [--realizations 500] [--paper 20] [--seed 0]
        [--compare] [--start detector|truth] [--snr 10 20 30 40]
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


def ratio_ci(err, crb, rng, boot=2000):
    """RMSE/RMS(CRB) and its 95 % bootstrap interval (percentile, realizations resampled)."""
    err, crb = np.asarray(err, dtype=float), np.asarray(crb, dtype=float)
    ratio = float(np.sqrt(np.mean(err**2) / np.mean(crb**2)))
    if err.size < 2:
        return ratio, np.nan, np.nan
    idx = rng.integers(0, err.size, (boot, err.size))
    r = np.sqrt(np.mean(err[idx] ** 2, axis=1) / np.mean(crb[idx] ** 2, axis=1))
    lo, hi = np.percentile(r, [2.5, 97.5])
    return ratio, float(lo), float(hi)


def random_phase_bound_ratio(sweep, pattern, peak_snr, rng, truths=60, draws=4000):
    """RMS bound with the per-beam phases random (uniform) over the whole-sweep CRB's: (distance, AoD).

    ``dsp.sweep_crb`` treats the phases as unknown constants (deterministic). Averaging the
    likelihood over uniform phases instead loses information in the beams near the noise floor:
    per beam, the delay information is the CRB's times E[g(x)²], g = I₁/I₀,
    x = 2√ρ_m·|z|, z ~ √ρ_m + CN(0, 1) (ρ_m = ρ A_m²), and the AoD's comes from the Rician
    magnitudes only (Fisher information of (θ, b) by Monte Carlo over the magnitudes, b removed).
    AoDs drawn as in the benchmark, uniform in ±30°, el = 0.
    """
    import scipy.special

    sq = np.sqrt(peak_snr)
    inv = {"d": [], "d_rp": [], "az": [], "az_rp": []}
    for _ in range(truths):
        aod = np.array([np.deg2rad(rng.uniform(-30.0, 30.0)), 0.0])
        a = np.abs(pattern.amplitude(aod, sweep.angles))
        da = (np.abs(pattern.amplitude(aod + [1e-6, 0.0], sweep.angles))
              - np.abs(pattern.amplitude(aod - [1e-6, 0.0], sweep.angles))) / 2e-6
        z = sq * a + (rng.standard_normal((draws, a.size)) + 1j * rng.standard_normal((draws, a.size))) / np.sqrt(2)
        r = np.abs(z)
        x = 2 * sq * a * r
        g = scipy.special.i1e(x) / scipy.special.i0e(x)
        inv["d"].append(1 / (a @ a))
        inv["d_rp"].append(1 / (a**2 * (g**2).mean(axis=0)).sum())
        s_t = ((g * 2 * sq * r - 2 * peak_snr * a) * da).sum(axis=1)
        s_b = (g * 2 * a * r - 2 * sq * a**2).sum(axis=1)
        j = np.stack([s_t, s_b]) @ np.stack([s_t, s_b]).T / draws
        inv["az_rp"].append(1 / (j[0, 0] - j[0, 1] ** 2 / j[1, 1]))
        inv["az"].append(1 / (2 * peak_snr * (da @ da - (a @ da) ** 2 / (a @ a))))
    return (float(np.sqrt(np.mean(inv["d_rp"]) / np.mean(inv["d"]))),
            float(np.sqrt(np.mean(inv["az_rp"]) / np.mean(inv["az"]))))


def genie_start(radar, tau, nu):
    """(τ, ν) of the half-bin cell (2× zero padding, as the detector's) nearest the true tone."""
    n, k = radar.num_samples, radar.num_chirps
    fct = radar.carrier_frequency * radar.chirp_interval
    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
    f2 = nu * fct
    f1, f2 = np.round(f1 * 2 * n) / (2 * n), np.round(f2 * 2 * k) / (2 * k)
    nu0 = f2 / fct
    return (f1 / radar.sample_period - radar.carrier_frequency * nu0) / radar.slope, nu0


def run(realizations: int, paper: int, seed: int, compare: bool = False, start: str = "detector",
        snrs=(10, 20, 30, 40)) -> None:
    radar = dsp.RadarConfig()
    processing = dsp.ProcessingConfig()
    sweep = dsp.BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    pattern = dsp.BeamPattern().for_wavelength(radar.wavelength)
    pose = dsp.RisPose.facing([0.0, 13.38, 0.0], [0.0, 0.0, 0.0])
    # the detector self_localize runs: pattern-matched beam windows on the half-bin grid
    acquisition = dict(pattern=pattern, sweep=sweep, oversample=2)
    boot_rng = np.random.default_rng(12345)
    print(f"risloc-rt estimator benchmark: Table I sizes, relay 16x4 RIS, {realizations} realizations per SNR "
          f"(paper method on {paper}), seed {seed}, start {start}; "
          f"{platform.processor() or platform.machine()}, numpy {np.__version__}")
    print("SNR = post-integration SNR at the pattern peak, K N beta^2 / sigma^2; CRB of the whole sweep at the truth;")
    print("RMSE/CRB = RMS error / RMS bound [95 % bootstrap CI]; 'refined' = refine_estimate (default: profiled phases), "
          "'marginal' = the same with likelihood='marginal'")
    head = (f"{'SNR':>4} {'est':<8} {'set':<4} {'n':>4} {'RMSE d [mm]':>11} {'CRB d [mm]':>10} {'RMSE/CRB d [95% CI]':>22} "
            f"{'bias/sd':>7} {'RMSE az [mdeg]':>14} {'CRB az':>8} {'RMSE/CRB az [95% CI]':>22} {'bias/sd':>7} "
            f"{'det':>5} {'ms':>7}")
    print(head)
    print("-" * len(head))
    names = ["refined"] + (["marginal"] if compare else []) + ["paper"]
    summary = []
    seqs = dict(zip((10, 20, 30, 40), np.random.SeedSequence(seed).spawn(4)))
    for snr_db in snrs:
        ss = seqs[snr_db]
        rho = 10 ** (snr_db / 10)
        err = {name: [] for name in names}
        crb_d, crb_az, det_ok, rp_bound = [], [], [], []
        times = {name: [] for name in names + ["detect"]}
        for i, child in enumerate(ss.spawn(realizations)):
            rng = np.random.default_rng(child)
            distance = rng.uniform(3.0, 18.0)
            velocity = rng.uniform(-1.0, 1.0)
            aod = np.array([np.deg2rad(rng.uniform(-30.0, 30.0)), 0.0])
            cube, tau, nu = synth_cube(radar, sweep, pattern, distance, velocity, aod, rho, rng)
            bound = dsp.sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho)
            crb_d.append(bound.distance)
            crb_az.append(bound.aod[0])
            rb = dsp.sweep_crb(radar=radar, sweep=sweep, pattern=pattern, aod=aod, peak_snr=rho, phases="random")
            rp_bound.append((rb.distance, rb.aod[0]))  # what Localization.std reports (at the truth)
            t0 = time.perf_counter()
            det = dsp.detect(cube, radar, **acquisition)
            t1 = time.perf_counter()
            times["detect"].append(t1 - t0)
            det_ok.append(det.detected)
            if start == "truth":
                tau0, nu0 = genie_start(radar, tau, nu)
            else:
                init = det if det.detected else dsp.detect(cube, radar, pfa=1 - 1e-12, **acquisition)
                if not np.isfinite(init.delay):  # nothing beam-dependent at all: count as a miss at the grid
                    init = dsp.Detection(False, 0, 0, 0, delay=tau, delay_rate=nu)
                tau0, nu0 = init.delay, init.delay_rate
            for name, likelihood in (("refined", "profile"), ("marginal", "marginal")):
                if name not in err:
                    continue
                t0 = time.perf_counter()
                est = dsp.refine_estimate(cube, sweep=sweep, radar=radar, pattern=pattern,
                                          initial_delay=tau0, initial_delay_rate=nu0, likelihood=likelihood)
                times[name].append(time.perf_counter() - t0)
                err[name].append(((est.delay - tau) * C / 2, est.aod.aod[0] - aod[0]))
            if i < paper:
                t0 = time.perf_counter()
                loc = dsp.localize(dsp.scan_beams(cube, sweep, radar, processing), radar=radar, pose=pose,
                                   loopback_delay=TAU_RB)
                times["paper"].append(time.perf_counter() - t0)
                err["paper"].append(((loc.delay - tau) * C / 2, loc.aod[0] - aod[0]))
        crb = np.array([crb_d, crb_az]).T
        ok = np.array(det_ok)
        for name in names:
            e = np.array(err[name])
            if not e.size:
                continue
            ms = 1e3 * float(np.median(times[name]))
            for subset in ("all", "det"):
                mask = np.ones(len(e), bool) if subset == "all" else ok[:len(e)]
                if not mask.any():
                    continue
                es, cs = e[mask], crb[:len(e)][mask]
                rc = np.sqrt(np.mean(cs**2, axis=0))
                rmse = np.sqrt(np.mean(es**2, axis=0))
                bias = es.mean(axis=0)
                sd = es.std(axis=0, ddof=1) if len(es) > 1 else np.full(2, np.nan)
                cells = []
                for j in (0, 1):
                    r, lo, hi = ratio_ci(es[:, j], cs[:, j], boot_rng)
                    cells.append(f"{r:.3f} [{lo:.3f}, {hi:.3f}]")
                print(f"{snr_db:>4} {name:<8} {subset:<4} {len(es):>4} {rmse[0] * 1e3:>11.4f} {rc[0] * 1e3:>10.4f} "
                      f"{cells[0]:>22} {bias[0] / sd[0]:>+7.3f} {np.rad2deg(rmse[1]) * 1e3:>14.2f} "
                      f"{np.rad2deg(rc[1]) * 1e3:>8.2f} {cells[1]:>22} {bias[1] / sd[1]:>+7.3f} "
                      f"{np.mean(ok[:len(e)]):>5.2f} {ms:>7.1f}")
                if subset == "all":
                    summary.append((snr_db, name, rmse, rc[0], rc[1], ms))
        for name in [n for n in names if n != "paper"]:
            e = np.array(err[name])[:, 0]
            out = np.abs(e) > 0.05
            inl = ok & ~out
            extra = (f", over the detected ones without them {np.sqrt(np.mean(e[inl] ** 2)) / np.sqrt(np.mean(crb[inl, 0] ** 2)):.3f}"
                     if inl.any() else "")
            rest = (f"{np.sqrt(np.mean(e[~out] ** 2)) / np.sqrt(np.mean(crb[~out, 0] ** 2)):.3f}"
                    if (~out).any() else "-")
            print(f"{'':>4} {name} outliers (|distance error| > 5 cm): {int(out.sum())}, of them detected "
                  f"{int((out & ok).sum())}; distance RMSE/CRB without them {rest}" + extra)
        if "marginal" in err:
            e_r, e_p = np.square(err["marginal"]), np.square(err["refined"])  # [n, 2], same cubes
            for subset, mask in (("all", np.ones(len(e_r), bool)), ("detected", ok)):
                if mask.sum() < 2:
                    continue
                d = e_r[mask] - e_p[mask]
                rel = d.mean(axis=0) / e_p[mask].mean(axis=0)
                half = 1.96 * d.std(axis=0, ddof=1) / np.sqrt(mask.sum()) / e_p[mask].mean(axis=0)
                print(f"{'':>4} marginal vs profiled (refined), paired MSE change over {subset}: distance {rel[0]:+.3f} +- "
                      f"{half[0]:.3f}, AoD {rel[1]:+.3f} +- {half[1]:.3f} (95 %)")
        rb_arr = np.array(rp_bound)
        for subset, mask in (("all", np.ones(len(rb_arr), bool)), ("detected", ok)):
            e = np.array(err["refined"])[mask]
            if len(e) < 2:
                continue
            cells = [ratio_ci(e[:, j], rb_arr[mask, j], boot_rng) for j in (0, 1)]
            print(f"{'':>4} refined RMSE / random-phase bound (dsp.sweep_crb(phases='random'), the reported 1 sigma), "
                  f"{subset} ({len(e)}): distance {cells[0][0]:.3f} [{cells[0][1]:.3f}, {cells[0][2]:.3f}], "
                  f"AoD {cells[1][0]:.3f} [{cells[1][1]:.3f}, {cells[1][2]:.3f}]")
        print(f"{'':>4} detect  median {1e3 * np.median(times['detect']):.1f} ms per cube")
        rp = random_phase_bound_ratio(sweep, pattern, rho, np.random.default_rng(seed + snr_db))
        print(f"{'':>4} bound with random phases / CRB (RMS over AoDs in +-30 deg): distance {rp[0]:.3f}, "
              f"AoD {rp[1]:.3f}")
    print()
    print("ratios refined / paper (same realizations' SNR point): RMSE distance, RMSE AoD, time")
    by = {(s, n): (r, ms) for s, n, r, _, _, ms in summary}
    for snr_db in snrs:
        if (snr_db, "paper") in by:
            (rr, tr), (rp, tp) = by[(snr_db, "refined")], by[(snr_db, "paper")]
            print(f"  {snr_db:>2} dB: distance {rr[0] / rp[0]:.3f}, AoD {rr[1] / rp[1]:.3f}, time {tr / tp:.3f} "
                  f"(refined {tr:.1f} ms on top of the detector, paper grid search {tp:.1f} ms)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=500)
    ap.add_argument("--paper", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--compare", action="store_true",
                    help="also run likelihood='marginal' (the phases averaged out instead of profiled) on the same cubes")
    ap.add_argument("--start", choices=("detector", "truth"), default="detector",
                    help="start the refinement at the detector's cell or (genie) at the true tone's half-bin cell")
    ap.add_argument("--snr", type=int, nargs="+", choices=(10, 20, 30, 40), default=(10, 20, 30, 40),
                    help="SNR points [dB] (each keeps its own seed stream)")
    args = ap.parse_args()
    run(args.realizations, args.paper, args.seed, compare=args.compare, start=args.start, snrs=tuple(args.snr))


if __name__ == "__main__":
    main()
