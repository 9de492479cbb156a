"""The DSP's whole-cube work on an NVIDIA GPU (CuPy) against NumPy (issue 21: one numeric core, two kinds of hardware).

Skipped, with the reason, where there is no GPU (``dsp.cuda_available()``); run them with
``./setup.sh --gpu && .venv/bin/python -m pytest -m gpu``.

Oracles:

(a) the same noisy cubes (drawn on the host, copied to the GPU): the detector makes the same decisions
    (detected, cell, the candidates in the same order, rejections) and its statistic and noise power
    agree within the precision detect_batch states (complex64 half-bin transform: ~1e-6 relative of
    the float64 value, so 2e-6 between two backends; tests/dsp/test_array_seam.py checks NumPy and
    array_api_strict against float64 itself);
(b) a study on either device: the GPU draws its noise with cuRAND (other numbers, the same law), so
    CPU and GPU are two independent samples of the same estimators — MAE of distance and azimuth,
    RMSE/CRB and the detection probability must agree within their 95 % intervals (written out below);
(c) a run's row on the GPU does not depend on the batch it was evaluated in;
(d) the GPU's receiver noise has the law of the host's: circular complex Gaussian of power σ², real
    and imaginary parts independent with σ²/2 each, copies independent, reproducible from the seed.

Points: Table I (61 beams × 128 chirps × 600 samples, the paper's relay RIS at 13.38 m, broadside).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import scipy.stats

import dsp
from risloc_rt.model.beat import add_noise_batch
from risloc_rt.studies.kernel import prepare_point, run_rng, run_runs
from risloc_rt.studies.params import complete_point

GPU_OK, GPU_WHY = dsp.cuda_available()
pytestmark = [pytest.mark.gpu, pytest.mark.skipif(not GPU_OK, reason=f"no GPU: {GPU_WHY}")]

#: detect_batch's stated precision of its half-bin statistic (~1e-6 relative of float64) on each backend:
#: CPU and GPU differ by at most twice that.
RTOL = 2e-6
REPO = Path(dsp.__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def gpu():
    backend = dsp.backend_for("cuda")
    assert backend.name == "cupy"
    return backend


@pytest.fixture(scope="module")
def table_i():
    """Prepared Table I points by transmit power [dBm] (refined estimator)."""
    cache = {}

    def get(power):
        if power not in cache:
            cache[power] = prepare_point(complete_point({"tx_power_dbm": power, "estimator": "refined"}))
        return cache[power]

    return get


# ------------------------------------------------------------------------------------------ (a)


@pytest.mark.parametrize("case", ["near-threshold", "high-snr", "noise-only"])
def test_detect_batch_on_the_gpu_equals_numpy(table_i, gpu, monkeypatch, case, detect_with_candidates):
    # -8 dBm: the windowed statistic within ~1 dB of η (some runs detect, some not); 10 dBm: ~33 dB above
    power = {"near-threshold": -8.0, "high-snr": 10.0, "noise-only": 10.0}[case]
    prep = table_i(power)
    clean = np.zeros_like(prep.cube) if case == "noise-only" else prep.cube
    cubes = add_noise_batch(clean, prep.radar.noise_power, [run_rng(21, 0, r) for r in range(4)])
    options = dict(pfa=1e-3, min_range=prep.processing.min_range, max_candidates=5, pattern=prep.pattern,
                   sweep=prep.sweep, oversample=2)
    ref, ref_cells, ref_stats = detect_with_candidates(cubes, prep, dsp.numpy_backend(), options, monkeypatch)
    got, cells, stats = detect_with_candidates(cubes, prep, gpu, options, monkeypatch)

    if case == "near-threshold":
        assert any(d.detected for d in ref) and not all(d.detected for d in ref)
    if case == "high-snr":
        assert all(d.detected for d in ref)
    if case == "noise-only":
        assert not any(d.detected for d in ref)
    for i, (a, b) in enumerate(zip(ref, got, strict=True)):
        where = f"{case}, realization {i}"
        assert b.statistic == pytest.approx(a.statistic, rel=RTOL), where
        assert b.noise_power == pytest.approx(a.noise_power, rel=RTOL), where
        assert (b.threshold, b.num_cells, b.integrated_beams) == (a.threshold, a.num_cells, a.integrated_beams), where
        finite = np.isfinite(ref_stats[i])
        np.testing.assert_array_equal(np.isfinite(stats[i]), finite, err_msg=where)
        np.testing.assert_allclose(stats[i][finite], ref_stats[i][finite], rtol=RTOL, err_msg=where)
        if abs(a.statistic - a.threshold) <= RTOL * a.statistic:
            continue  # within the precision of η the decision may fall either way (never seen; stated for safety)
        assert (b.detected, b.cell, b.rejected, b.beam_dependent) == (a.detected, a.cell, a.rejected,
                                                                        a.beam_dependent), where
        s = np.sort(ref_stats[i][finite])
        if s.size < 2 or np.all(np.diff(s) > 2 * RTOL * s[1:]):  # no two candidates tie within the precision
            np.testing.assert_array_equal(cells[i], ref_cells[i], err_msg=f"{where}: candidates and their order")
        np.testing.assert_allclose(b.beam_power, a.beam_power, rtol=RTOL, atol=RTOL, err_msg=where)


# ------------------------------------------------------------------------------------------ (d)


def test_gpu_receiver_noise_has_the_law_of_the_host_noise(table_i, gpu):
    """w = noisy - clean: CN(0, σ²) per sample, independent copies, the same draw again from the same seeds."""
    prep = table_i(10.0)
    sigma2 = prep.radar.noise_power
    rngs = lambda: [run_rng(5, 0, r) for r in range(3)]  # noqa: E731 - fresh generators per draw
    noisy = add_noise_batch(prep.cube, sigma2, rngs(), backend=gpu)
    assert tuple(noisy.shape) == (3,) + prep.cube.shape
    w = gpu.to_host(noisy) - prep.cube
    n = w[0].size
    for i in range(3):
        re, im = w[i].real.ravel() / math.sqrt(sigma2 / 2), w[i].imag.ravel() / math.sqrt(sigma2 / 2)  # N(0, 1) each
        # mean 0 (sd 1/√n), variance 1 (the mean of x² has sd √(2/n)), re ⟂ im (mean of re·im: sd 1/√n)
        assert abs(re.mean()) < 5 / math.sqrt(n) and abs(im.mean()) < 5 / math.sqrt(n)
        assert abs(np.mean(re * re) - 1) < 5 * math.sqrt(2 / n) and abs(np.mean(im * im) - 1) < 5 * math.sqrt(2 / n)
        assert abs(np.mean(re * im)) < 5 / math.sqrt(n)
        # Gaussian: excess kurtosis 0 (sd √(24/n))
        assert abs(scipy.stats.kurtosis(re)) < 5 * math.sqrt(24 / n)
    for i, j in ((0, 1), (0, 2), (1, 2)):  # copies independent: normalized correlation within 5/√n of 0
        c = abs(np.vdot(w[i], w[j])) / math.sqrt(np.vdot(w[i], w[i]).real * np.vdot(w[j], w[j]).real)
        assert c < 5 / math.sqrt(n), (i, j, c)
    again = gpu.to_host(add_noise_batch(prep.cube, sigma2, rngs(), backend=gpu))
    np.testing.assert_array_equal(again - prep.cube, w)


# ------------------------------------------------------------------------------------------ (c)


def test_gpu_rows_do_not_depend_on_the_batch(table_i, gpu):
    prep = table_i(10.0)
    runs = list(range(8))
    one = run_runs(prep, study_seed=9, point=0, runs=runs, backend=gpu, batch=1)
    eight = run_runs(prep, study_seed=9, point=0, runs=runs, backend=gpu, batch=8)
    assert all(r["detected"] for r in one)
    diffs = [(a["run"], k, a[k], b[k]) for a, b in zip(one, eight, strict=True) for k in a
             if k != "seconds" and not (a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k])
                                                          and isinstance(b[k], float) and math.isnan(b[k])))]
    assert diffs == []
    # the GPU's noise is its own (cuRAND): its rows are not the host's, so the comparison above is not vacuous
    host = run_runs(prep, study_seed=9, point=0, runs=runs[:2], batch=2)
    assert [h["distance"] for h in host] != [g["distance"] for g in one[:2]]


# ------------------------------------------------------------------------------------------ (b)

#: One worker process: a chunk of runs of one point on one device, rows to a JSON file. The DSP and
#: BLAS on one thread (as a study's workers), the GPU's batch fixed so that concurrent workers share it.
WORKER = r"""
import json, sys
job = json.loads(sys.argv[1])
import threadpoolctl
import dsp
from risloc_rt.studies.kernel import prepare_point, run_runs
from risloc_rt.studies.params import complete_point
backend = dsp.backend_for(job["device"])
with threadpoolctl.threadpool_limits(1), dsp.limit_threads(1):
    prep = prepare_point(complete_point(job["params"]))
    rows = run_runs(prep, study_seed=job["seed"], point=job["point"], runs=range(job["start"], job["stop"]),
                    backend=backend, batch=job["batch"])
with open(job["out"], "w") as fh:
    json.dump({"rows": rows, "crb": prep.crb, "device": backend.summary()}, fh, default=float)
"""


def study_rows(jobs, tmp_path, workers):
    """Run ``jobs`` (dicts: device, params, seed, point, start, stop, batch) in ``workers`` processes at once."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

    def one(k_job):
        k, job = k_job
        job = {**job, "out": str(tmp_path / f"job{k}.json")}
        proc = subprocess.run([sys.executable, "-c", WORKER, json.dumps(job)], env=env, cwd=REPO,
                              capture_output=True, text=True, timeout=1800)
        if proc.returncode:
            raise RuntimeError(f"worker {job['device']} runs {job['start']}-{job['stop']} failed:\n{proc.stderr[-3000:]}")
        return json.loads(Path(job["out"]).read_text())

    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(one, enumerate(jobs)))


def mean_interval(x):
    """Mean of x and its 95 % interval (normal, mean ± 1.96 s/√n)."""
    x = np.asarray(x, float)
    half = 1.96 * x.std(ddof=1) / math.sqrt(x.size)
    return x.mean(), (x.mean() - half, x.mean() + half)


def study_statistics(rows, crb):
    """Per sample: Pd (Wilson 95 %), MAE of distance [m] and azimuth [rad] and RMSE/CRB of both, with 95 % intervals.

    MAE: the mean of |e| with its normal interval. RMSE: √ of the mean of e² and of its normal interval's ends,
    over the point's (fixed-phase) CRB — the ratio the study summary reports.
    """
    n = len(rows)
    k = sum(r["detected"] for r in rows)
    z = 1.96  # Wilson score interval of a binomial proportion
    centre = (k + z * z / 2) / (n + z * z)
    half = z * math.sqrt(k * (n - k) / n + z * z / 4) / (n + z * z)
    out = {"Pd": (k / n, (centre - half, centre + half))}
    det = [r for r in rows if r["detected"]]
    for name, col, bound in (("distance", "distance_error", crb["distance"]), ("azimuth", "aod_az_error", crb["angle"])):
        e = np.array([r[col] for r in det], float)
        out[f"MAE {name}"] = mean_interval(np.abs(e))
        mse, (lo, hi) = mean_interval(e * e)
        out[f"RMSE/CRB {name}"] = (math.sqrt(mse) / bound, (math.sqrt(max(lo, 0.0)) / bound, math.sqrt(hi) / bound))
    return out


@pytest.mark.slow
def test_study_statistics_on_the_gpu_agree_with_the_cpu(table_i, gpu, tmp_path):
    """200 runs of Table I at 0 and 10 dBm on each device (independent seeds): the statistics overlap.

    Two 95 % intervals of equal width overlap unless the estimates differ by more than 2 · 1.96 s.e.
    — a two-sided test at 0.56 % each; the 8 comparisons of MAE and RMSE (those of Pd at Pd ≈ 1 cannot
    fail by chance) hold together at least 95.5 % of the time when the law is the same (Bonferroni). They
    catch what a wrong GPU path would do: noise of another power (RMSE ∝ σ; with 200 runs the relative
    s.e. of an RMSE is ~√(1/2n) = 5 %, so RMSEs 20 % apart — noise power off by 45 % — separate) or a
    detector that misplaces the cell (errors of whole bins: MAE × 10 and more).
    test_gpu_receiver_noise_has_the_law_of_the_host_noise checks the noise power itself to 0.3 %.
    """
    runs, powers = 200, (0.0, 10.0)
    import cupy

    cupy.get_default_memory_pool().free_all_blocks()  # the worker processes share the GPU's memory
    workers = max(2, min(16, len(os.sched_getaffinity(0))))
    chunk = math.ceil(runs / max(1, workers // (2 * len(powers))))
    jobs = []
    for device, seed in (("cpu", 101), ("cuda", 202)):  # other seeds: the two samples are independent
        for point, power in enumerate(powers):
            for start in range(0, runs, chunk):
                jobs.append({"device": device, "params": {"tx_power_dbm": power, "estimator": "refined"}, "seed": seed,
                             "point": point, "start": start, "stop": min(runs, start + chunk),
                             "batch": 4 if device == "cuda" else None})
    results = study_rows(jobs, tmp_path, workers)
    assert any("cuda" in r["device"] for r in results) and any(r["device"].startswith("cpu") for r in results)

    lines, failures = [], []
    for point, power in enumerate(powers):
        crb = table_i(power).crb
        sample = {}
        for device in ("cpu", "cuda"):
            rows = [row for job, res in zip(jobs, results) if job["device"] == device and job["point"] == point
                    for row in res["rows"]]
            assert sorted(r["run"] for r in rows) == list(range(runs))
            sample[device] = study_statistics(rows, crb)
        for stat in sample["cpu"]:
            (c, (clo, chi)), (g, (glo, ghi)) = sample["cpu"][stat], sample["cuda"][stat]
            line = f"{power:+5.1f} dBm  {stat:20s} cpu {c:.4g} [{clo:.4g}, {chi:.4g}]  gpu {g:.4g} [{glo:.4g}, {ghi:.4g}]"
            lines.append(line)
            if not (clo <= ghi and glo <= chi):
                failures.append(line)
    print("\n".join(lines))
    assert failures == [], "95 % intervals that do not overlap:\n" + "\n".join(failures) + "\nall:\n" + "\n".join(lines)
