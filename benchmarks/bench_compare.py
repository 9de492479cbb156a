"""The comparison of a capture with its traced hall: time beside what it computes, the map path against the row path.

    .venv/bin/python benchmarks/bench_compare.py --repeats 3

A lab-like recording of the default hall at radar position 1 (DCA1000 radar, 61 beams, the same emulated
recording as the compare tests: true τ_RB 1.93 ns and ζ 42 dB, +7 dB receiver gain, Tx→Rx leakage; imported),
compared with the hall traced at depth 2 with 2·10⁴ rays (``compare_capture``), then its sweep-mean profiles
(``sweep_mean_profiles``, what ``calibrate materials --profile sweep-mean`` reads). Each is timed twice in one run:

- **row**: the code as it is: every zero-Doppler range profile is one row of eq. (2DDFT), ``dsp.delay_profile``
  (a K-term slow-time sum and one N_DFT-point transform per beam);
- **map**: the same call with ``delay_profile`` replaced by the whole delay-Doppler map's row,
  ``dsp.delay_doppler_map(frame).profile(ν)`` per frame (what every profile cost before): the reference.

Beside the times it prints how far apart the two paths' outputs are (the largest difference of the profiles
relative to their peak, and the largest relative difference of the summary's and the peak table's numbers), so
the speed-up is of the same answer. One process, the DSP on this machine's threads; medians over ``--repeats``.
"""

from __future__ import annotations

import argparse
import platform
import time
import warnings
from dataclasses import replace
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

import dsp
from risloc_rt.measured.compare import comparison, sweep_mean_peaks


def _map_rows(frames, radar, processing, delay_rate=0.0):
    """The reference: each frame's whole delay-Doppler map, then its row (the code before ``delay_profile``)."""
    arr = np.asarray(frames)
    maps = [dsp.delay_doppler_map(f, radar, processing) for f in (arr if arr.ndim == 3 else arr[None])]
    power = np.array([m.profile(delay_rate) for m in maps])
    nu = maps[0].delay_rate[int(np.argmin(np.abs(maps[0].delay_rate - delay_rate)))]
    return dsp.DelayProfile(power=power if arr.ndim == 3 else power[0], delay=maps[0].delay, delay_rate=float(nu))


def _recording(root: Path):
    """The compare tests' emulated hall recording (tests/measured/conftest.py, ``injected_hall``), imported."""
    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.hall.scenario import hall_paths, hall_scenario
    from risloc_rt.measured import RecordingPlan, dca1000_radar, emulate_recording, import_capture

    cache = TraceCache(root / "cache")
    hs = hall_scenario("paper_hall", radar_index=1, radar=dca1000_radar(dsp.RadarConfig()),
                       trace=TraceSettings(max_depth=3, samples_per_src=100_000, diffuse_reflection=True,
                                           scattering_coefficient=0.3))
    nominal = hs.base.ris
    true = replace(hs, base=replace(hs.base, ris=replace(nominal, loopback_delay=1.93e-9, amplification_db=42.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traced = hall_paths(true, cache=cache)
    plan = dict(lead_frames=3.0, sync_on=2, sync_off=2, sync_cycles=2, sync_gap=1, tail_frames=2,
                range_offset=0.0123, power_offset_db=7.0, leakage_dbm=-10.0)
    rec = emulate_recording(true.base, root / "rec", plan=RecordingPlan(**plan), paths=traced.paths,
                            nominal_ris=nominal, rng=np.random.default_rng(3))
    exp = rec.experiment
    return import_capture(exp.raw_path, exp.config_path, exp.schedule_path, first_frame=round(rec.start)), cache


def _timed(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed calls per path (median; default 3)")
    ap.add_argument("--k-dft", type=int, default=None,
                    help="the slow-time DFT length of the processing (default: the imported capture's, 512; Table I's "
                         "is 4793)")
    args = ap.parse_args()
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.measured.compare.traced_hall import hall_model

    with TemporaryDirectory() as tmp:
        capture, cache = _recording(Path(tmp))
        if args.k_dft is not None:
            capture = replace(capture, processing=replace(capture.processing, k_dft=args.k_dft))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = hall_model(capture, "paper_hall", capture.truth.ue_position,
                               trace=TraceSettings(max_depth=2, samples_per_src=20000), cache=cache)
        m, k, n = np.shape(capture.cube)
        print(f"risloc-rt compare benchmark: default hall, radar 1, {m} beams x {k} chirps x {n} samples, "
              f"N_DFT {capture.processing.n_dft}, K_DFT {capture.processing.k_dft}, {platform.machine()}, "
              f"numpy {np.__version__}, {dsp.thread_count()} DSP threads, median of {args.repeats}")
        rows: dict[str, dict] = {}
        for name in ("row", "map"):
            profile = dsp.delay_profile if name == "row" else _map_rows
            comparison.delay_profile = sweep_mean_peaks.delay_profile = profile
            try:
                t_cmp, cmp = _timed(lambda: comparison.compare_capture(capture, model), args.repeats)
                t_mean, mean = _timed(lambda: sweep_mean_peaks.sweep_mean_profiles(capture, model, cmp), args.repeats)
            finally:
                comparison.delay_profile = sweep_mean_peaks.delay_profile = dsp.delay_profile
            rows[name] = {"compare": t_cmp, "sweep_mean": t_mean, "cmp": cmp, "mean": mean}
        row, ref = rows["row"], rows["map"]
        diff = max(np.max(np.abs(row["cmp"].mean_profile_measured - ref["cmp"].mean_profile_measured))
                   / ref["cmp"].mean_profile_measured.max(),
                   np.max(np.abs(row["cmp"].mean_profile_simulated - ref["cmp"].mean_profile_simulated))
                   / ref["cmp"].mean_profile_simulated.max(),
                   np.max(np.abs(row["mean"].measured - ref["mean"].measured)) / ref["mean"].measured.max(),
                   np.max(np.abs(row["mean"].expected - ref["mean"].expected)) / ref["mean"].expected.max())
        print(f"{'call':<22} {'map [s]':>8} {'row [s]':>8} {'map/row':>8}")
        for key, label in (("compare", "compare_capture"), ("sweep_mean", "sweep_mean_profiles")):
            print(f"{label:<22} {ref[key]:8.3f} {row[key]:8.3f} {ref[key] / row[key]:7.1f}x")
        print(f"largest profile difference (of its peak): {diff:.1e}; largest relative difference of the summary's "
              f"numbers and the peak table's: {_largest_difference(row['cmp'], ref['cmp']):.1e}; "
              f"{len(row['cmp'].peaks)} peaks, {row['cmp'].summary['explained']} explained")


def _largest_difference(a, b) -> float:
    """Largest relative difference of the numbers of two comparisons' summaries and peak tables (inf: other keys)."""
    pairs = [(a.summary, b.summary)] + list(zip(a.peaks, b.peaks))
    if len(a.peaks) != len(b.peaks) or any(x.keys() != y.keys() for x, y in pairs):
        return float("inf")
    worst = 0.0
    for x, y in pairs:
        for key in x:
            u, v = x[key], y[key]
            if isinstance(u, (int, float)) and not isinstance(u, bool) and v is not None:
                worst = max(worst, abs(u - v) / max(abs(v), 1e-300))
            elif u != v and not isinstance(u, list):
                return float("inf")
    return worst


if __name__ == "__main__":
    main()
