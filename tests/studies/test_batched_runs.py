"""Monte Carlo runs in batches (risloc_rt.studies.kernel.run_runs): a run's row depends on the study seed,
the point and its run index only — not on the batch size B, the order of the runs, a reused buffer or
the array backend (issue 21).

Oracles: NumPy's rows for B = 1 are the reference; any other B gives them bit for bit (every whole-cube
step is elementwise or reduces along one realization's own axes, and the host draws each run's noise
from its own stream). On array_api_strict ('device1': no implicit host copy) the noise is the same host
draw and the estimators run on the same host cube; only the detector's statistic and noise power differ,
within the precision dsp.detect_batch states (complex64 half-bin transform: ~1e-6 relative of the
float64 value, so 2e-6 between two backends) — the tolerances below follow from it field by field.

The point: Table I's RF parameters and geometry on a smaller radar and sweep (K = 16, N = 128, 31
beams) at 10 dBm, where the post-integration SNR (~12 dB) puts runs on both sides of the threshold,
so rows with and without a detection (NaN estimates) are compared.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsp import strict_backend
from risloc_rt.studies.kernel import ROW_FLOATS, prepare_point, run_once, run_runs
from risloc_rt.studies.params import complete_point

SMALL = {"num_chirps": 16, "num_samples": 128, "n_dft": 255, "k_dft": 64, "sweep_step_deg": 3.0,
         "tx_power_dbm": 10.0}
#: The precision of the detector's half-bin statistic and noise power on one backend (dsp.detect_batch's
#: Notes): ~1e-6 relative of the float64 value; two backends differ by at most twice that.
BACKENDS_RTOL = 2e-6
SEED, POINT = 11, 2
#: Seven runs out of order: B = 3 and 4 leave a partial last batch.
RUNS = [6, 0, 3, 5, 1, 4, 2]

VARIANTS = {
    "refined": {"estimator": "refined"},
    "paper": {"estimator": "paper"},
    # each run draws its own UE azimuth: its own noiseless cube, the other branch of run_runs
    # (at 8 dBm: 5° off broadside the windowed detector gains ~2 dB, runs again fall on both sides of η)
    "refined-aod-spread": {"estimator": "refined", "aod_deg": 5.0, "aod_spread_deg": 4.0, "tx_power_dbm": 8.0},
}


@pytest.fixture(scope="module")
def prepared():
    cache = {}

    def get(variant):
        if variant not in cache:
            cache[variant] = prepare_point(complete_point({**SMALL, **VARIANTS[variant]}))
        return cache[variant]

    return get


def same(a, b):
    """Equal, NaN equal to NaN."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def differences(reference, rows):
    """Fields (all but 'seconds') where two lists of rows differ: [(run, field, reference, other)]."""
    out = []
    for a, b in zip(reference, rows, strict=True):
        assert set(a) == set(b)
        out += [(a["run"], k, a[k], b[k]) for k in a if k != "seconds" and not same(a[k], b[k])]
    return out


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_rows_do_not_depend_on_the_batch(prepared, variant):
    prep = prepared(variant)
    one = run_runs(prep, study_seed=SEED, point=POINT, runs=RUNS, batch=1)
    assert [r["run"] for r in one] == RUNS and all(r["point"] == POINT for r in one)
    detected = [r["detected"] for r in one]
    assert any(detected) and not all(detected), "the point must give rows with and without a detection"
    assert all(math.isnan(r["distance"]) != r["detected"] for r in one)

    for batch in (3, 4):
        assert differences(one, run_runs(prep, study_seed=SEED, point=POINT, runs=RUNS, batch=batch)) == [], batch
    # reused scratch buffers (left full of NaN: the noisy cubes and the detector's transform) and the default
    # batch from the memory estimate
    buffer = np.full((4,) + prep.cube.shape, np.nan, dtype=complex)
    m, k, n = prep.cube.shape
    workspace = np.full((4, m, 2 * k, 2 * n), np.nan, dtype=np.complex64)
    assert differences(one, run_runs(prep, study_seed=SEED, point=POINT, runs=RUNS, batch=4, buffer=buffer,
                                     workspace=workspace)) == []
    assert np.isfinite(workspace[0]).all()  # the transform went there
    assert differences([one[1]], [run_once(prep, study_seed=SEED, point=POINT, run=RUNS[1],
                                           workspace=workspace[0])]) == []
    assert differences(one, run_runs(prep, study_seed=SEED, point=POINT, runs=RUNS)) == []
    # the same run alone, by run_once, and in another order
    assert differences([one[0]], [run_once(prep, study_seed=SEED, point=POINT, run=RUNS[0])]) == []
    by_run = {r["run"]: r for r in one}
    ordered = run_runs(prep, study_seed=SEED, point=POINT, runs=sorted(RUNS), batch=4)
    assert differences([by_run[r] for r in sorted(RUNS)], ordered) == []
    # another seed is other noise: the rows do change (the comparison above can fail)
    other = run_runs(prep, study_seed=SEED + 1, point=POINT, runs=RUNS, batch=4)
    assert differences(one, other) != []


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_strict_rows_equal_numpy_rows(prepared, variant):
    """run_runs on array_api_strict ('device1'): the same rows as on NumPy to the detector's precision.

    Why these tolerances: the strict backend's noise is the host's draw, bit for bit (one explicit copy to
    the device), so the estimators see the same samples in float64, wherever they read them. The detection
    reaches them through its cell (identical: the estimators' starting delay and rate) and its noise power
    σ̂² (within 2e-6 relative). σ̂² sets the stated 1σ — the CRB at the measured SNR, ∝ σ̂, so within 1e-6
    relative (2e-6 allowed) — and the flag tests' levels, not where a fit peaks: the estimates and their
    errors agree to float64 rounding (1e-15 of 13 m). 1e-9 m / rad / m/s leaves a factor 1e6 for the
    fits' conditioning and is still 1e-6 of the 1σ (~1 mm, ~1 mrad here), so any difference of physical
    meaning fails. snr_db = 10 log10(D - L) moves by 10/ln10 · ΔD/(D - L), ΔD/D <= 2e-6, L <= M.
    """
    prep = prepared(variant)
    runs = list(range(8))
    reference = run_runs(prep, study_seed=SEED, point=POINT, runs=runs, batch=1)
    # B = 3: groups of 3, 3 and 2, none of whose host cell blocks divides the cube's cells
    rows = run_runs(prep, study_seed=SEED, point=POINT, runs=runs, batch=3, backend=strict_backend("device1"))
    assert any(r["detected"] for r in reference) and not all(r["detected"] for r in reference)
    m = prep.sweep.num_beams
    for a, b in zip(reference, rows, strict=True):
        where = f"run {a['run']}"
        for key in ("point", "run", "detected", "flags", "true_aod_az"):
            assert b[key] == a[key], (where, key)
        for key in ROW_FLOATS:
            if not a["detected"]:
                assert math.isnan(b[key]), (where, key)
            elif key in ("std_distance", "std_aod_az", "peb"):
                assert b[key] == pytest.approx(a[key], rel=BACKENDS_RTOL, abs=0), (where, key)
            else:  # m, rad, m/s
                assert abs(b[key] - a[key]) <= 1e-9, (where, key, a[key], b[key])
        if a["snr_db"] == b["snr_db"] == -99.0:
            continue
        excess = 10 ** (a["snr_db"] / 10)  # D - L
        tol = 10 / math.log(10) * BACKENDS_RTOL * (1 + m / excess)
        assert abs(b["snr_db"] - a["snr_db"]) <= tol, (where, a["snr_db"], b["snr_db"])
