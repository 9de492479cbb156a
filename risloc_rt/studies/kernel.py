"""One study point: its noiseless cube (made once), its Cramér–Rao bound, and one seeded run.

Every run of a point shares the same paths and therefore the same noiseless beat cube, so
:func:`prepare_point` synthesises it once; :func:`run_once` adds the run's receiver noise
(``SeedSequence(study_seed, spawn_key=(point, run))``) and runs the public DSP,
``dsp.self_localize``, exactly as ``risloc locate`` does on a simulated capture: the numbers equal
``simulate(..., rng, noise_stream="boxmuller") -> process_capture``'s for the noise of that stream,
because ``risloc_rt.model.add_noise`` is what ``simulate`` calls — bit for bit when both run on one
BLAS thread, as every study run does (``engine.run_batch``); a multi-threaded BLAS changes last
digits. The "boxmuller" stream (float32 Box–Muller, one child stream per beam) has the distribution
of the standard one and costs a third as much, which a run of a study feels (docs/studies.md); a
study folder started on the older "fast" stream (NumPy's float32 ziggurat) continues on it
(``noise_stream``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

import dsp
from dsp import SPEED_OF_LIGHT, BeamSweep, ProcessingConfig, RadarConfig

from ..model import analytic_scenario, simulate
from .params import ris_size

__all__ = ["PreparedPoint", "prepare_point", "point_scenario", "run_once", "run_runs", "run_rng", "point_bound",
           "ROW_FLOATS", "detector_workspace"]


@dataclass(frozen=True, eq=False)
class PreparedPoint:
    """What every run of one point shares.

    Attributes
    ----------
    params : dict
        The point (every parameter, :func:`risloc_rt.studies.params.complete_point`).
    cube : complex128 array [M, K, N]
        The noiseless beat cube [√W].
    radar, sweep, processing, pose, loopback_delay, pattern
        What ``dsp.self_localize`` needs.
    truth : risloc_rt.model.Truth
    crb : dict
        1σ bounds at the true parameters: ``distance`` [m], ``angle`` (azimuth) [rad],
        ``position`` (PEB) [m], ``velocity`` [m/s], the same with ``_random_phase`` (the bound
        with the per-beam phases random), and the post-integration ``peak_snr_db`` [dB].
    seconds : float
        Time to prepare it (synthesis, tracing, bound) [s].
    floor_height : float or None
        World z of the floor under the radar and the RIS [m] (a traced hall's,
        ``risloc_rt.hall.scenario.FLOOR_HEIGHT``): ``dsp.self_localize`` reads the floor's ladder
        (``docs/estimation.md``); None for the analytic scenario (no floor).
    """

    params: dict[str, Any]
    cube: np.ndarray
    radar: RadarConfig
    sweep: BeamSweep
    processing: ProcessingConfig
    pose: dsp.RisPose
    loopback_delay: float
    pattern: dsp.BeamPattern
    truth: Any
    crb: dict[str, float]
    seconds: float
    floor_height: float | None = None


def _radar_sweep_processing(p: dict[str, Any]) -> tuple[RadarConfig, BeamSweep, ProcessingConfig]:
    radar = RadarConfig(tx_power_dbm=p["tx_power_dbm"], num_chirps=p["num_chirps"], num_samples=p["num_samples"])
    span, step = np.deg2rad(p["sweep_span_deg"]), np.deg2rad(p["sweep_step_deg"])
    sweep = BeamSweep.azimuth_grid(-span, span + 1e-9, step)
    processing = ProcessingConfig(n_dft=p["n_dft"], k_dft=p["k_dft"])
    return radar, sweep, processing


def point_scenario(p: dict[str, Any], *, structure: bool) -> Any:
    """The analytic scenario of a study point (not a hall's: ``scene`` is ignored).

    Parameters
    ----------
    p : dict
        A complete point (:func:`risloc_rt.studies.params.complete_point`): distance [m], AoD [deg],
        speed [m/s], RIS size, mode, radar and DFT sizes, transmit power [dBm], sweep [deg].
    structure : bool
        Include the RIS panel's structural reflection (the bound is computed without it).

    Returns
    -------
    risloc_rt.model.Scenario
        What ``simulate`` synthesises for every run of the point (SI units inside).
    """
    radar, sweep, processing = _radar_sweep_processing(p)
    sc = analytic_scenario(distance=p["distance"], aod=np.deg2rad([p["aod_deg"], 0.0]), mode=p["mode"],
                           radar=radar, sweep=sweep, processing=processing, structure=structure,
                           name="study")
    if p["speed"]:
        direction = sc.ue_position - sc.ris.pose.position
        direction /= np.linalg.norm(direction)
        sc = replace(sc, ue_velocity=p["speed"] * direction)
    rows, cols = ris_size(p["ris_size"])
    if (rows, cols) != (sc.ris.num_rows, sc.ris.num_columns):
        sc = replace(sc, ris=replace(sc.ris, num_rows=rows, num_columns=cols))
    return sc


def point_bound(cube_without_clutter: np.ndarray, *, radar: RadarConfig, sweep: BeamSweep, pattern: dsp.BeamPattern,
                pose: dsp.RisPose, truth: Any, loopback_delay: float) -> dict[str, float]:
    """The whole-sweep CRB (``dsp.sweep_crb``) at the true parameters and the true SNR.

    The true post-integration SNR ρ = K N β²/σ² comes from the noiseless cube of the RIS return
    alone: β = Σ|A_m| |Z_m| / (K N Σ A_m²) with Z_m the beams' DTFTs at the true (τ, ν), the
    estimate ``dsp.self_localize`` uses on noisy data. Position: ``dsp.position_std`` of
    x = x_RIS + d·R·d(az, el) with the elevation known (a 1-D sweep).

    Parameters
    ----------
    cube_without_clutter : complex ndarray, shape (M, K, N)
        The noiseless beat cube of the RIS return alone [√W].
    radar : dsp.RadarConfig
    sweep : dsp.BeamSweep
    pattern : dsp.BeamPattern
        The RIS's beam pattern (rescaled to the radar's wavelength here).
    pose : dsp.RisPose
    truth : risloc_rt.model.Truth
        True distance [m], AoD [rad] and radial velocity [m/s].
    loopback_delay : float
        The RIS's loop-back delay [s].

    Returns
    -------
    dict of str to float
        ``distance`` [m], ``angle`` (azimuth) [rad], ``position`` (PEB) [m], ``velocity`` [m/s]:
        the fixed-phase CRB (the figures' dashed line); the same with ``_random_phase`` (the bound
        with the per-beam phases random, what ``Localization.std`` reports and a phase-blind
        estimator can reach); ``peak_snr_db``, the post-integration SNR ρ [dB].
    """
    pat = pattern.for_wavelength(radar.wavelength)
    tau = 2.0 * truth.distance / SPEED_OF_LIGHT + loopback_delay
    nu = 2.0 * truth.velocity / SPEED_OF_LIGHT
    mags, _, _ = dsp.beam_dtft(cube_without_clutter, radar, tau, nu)
    amp = np.abs(pat.amplitude(truth.aod, sweep.angles))
    k, n = radar.num_chirps, radar.num_samples
    beta = float(amp @ mags / (amp @ amp)) / (k * n)
    rho = k * n * beta**2 / radar.noise_power
    def locate(x: np.ndarray) -> np.ndarray:
        return pose.position + x[0] * pose.to_world(dsp.direction_from_angles(x[1:3]))

    out: dict[str, float] = {}
    for phases, suffix in (("fixed", ""), ("random", "_random_phase")):
        bound = dsp.sweep_crb(radar=radar, sweep=sweep, pattern=pat, aod=truth.aod, peak_snr=max(rho, 1e-300),
                              phases=phases)
        pos = dsp.position_std(locate, [truth.distance, *truth.aod], [bound.distance, *bound.aod])
        out.update({f"distance{suffix}": bound.distance, f"angle{suffix}": float(bound.aod[0]),
                    f"position{suffix}": float(np.linalg.norm(pos)), f"velocity{suffix}": bound.velocity})
    out["peak_snr_db"] = float(10 * np.log10(max(rho, 1e-300)))
    return out


def prepare_point(params: dict[str, Any]) -> PreparedPoint:
    """A sweep's point preparer: the noiseless cube of one point and its bound (analytic scenario or a traced hall).

    Parameters
    ----------
    params : dict
        A complete point (:func:`risloc_rt.studies.params.complete_point`); with ``scene`` set, the
        hall is traced (``depth``, ``samples``) through the trace cache.

    Returns
    -------
    PreparedPoint
        What every run of the point shares; ``seconds`` is the time this took [s].
    """
    start = time.perf_counter()
    rng = np.random.default_rng(0)  # unused: noise=False
    if params["scene"]:
        from ..hall import hall_paths, hall_scenario
        from ..hall.raytrace import TraceCache, TraceSettings
        from ..hall.scenario import FLOOR_HEIGHT

        radar, sweep, processing = _radar_sweep_processing(params)
        hs = hall_scenario(params["scene"], radar_index=params["radar_index"], mode=params["mode"], radar=radar,
                           sweep=sweep, processing=processing,
                           trace=TraceSettings(max_depth=params["depth"], samples_per_src=params["samples"]))
        traced = hall_paths(hs, cache=TraceCache())
        cap = simulate(hs.base, rng=rng, paths=traced.paths, noise=False)
        clean_ris = cap.cube  # the hall's echoes are far from the RIS return (docs/studies.md)
    else:
        sc = point_scenario(params, structure=params["structure"])
        cap = simulate(sc, rng=rng, noise=False)
        clean_ris = simulate(point_scenario(params, structure=False), rng=rng, noise=False).cube \
            if params["structure"] else cap.cube
    pattern = cap.ris.beam_pattern()
    crb = point_bound(clean_ris, radar=cap.radar, sweep=cap.sweep, pattern=pattern, pose=cap.ris.pose,
                      truth=cap.truth, loopback_delay=cap.ris.loopback_delay)
    return PreparedPoint(params=dict(params), cube=cap.cube, radar=cap.radar, sweep=cap.sweep,
                         processing=cap.processing, pose=cap.ris.pose, loopback_delay=cap.ris.loopback_delay,
                         pattern=pattern, truth=cap.truth, crb=crb, seconds=time.perf_counter() - start,
                         floor_height=FLOOR_HEIGHT if params["scene"] else None)


def run_rng(study_seed: int, point: int, run: int) -> np.random.Generator:
    """The noise stream of run ``run`` of point ``point``: independent of workers and order.

    Parameters
    ----------
    study_seed, point, run : int
        The study seed and the run's indices.

    Returns
    -------
    numpy.random.Generator
        ``default_rng(SeedSequence(study_seed, spawn_key=(point, run)))``.
    """
    return np.random.default_rng(np.random.SeedSequence(study_seed, spawn_key=(point, run)))


def detector_workspace(shape: Any, batch: int = 1) -> np.ndarray:
    """Host scratch space for the detector's half-bin transform of ``batch`` cubes.

    Parameters
    ----------
    shape : (int, int, int)
        A cube's (M, K, N): beams, chirps, samples.
    batch : int
        Cubes per detector call (0: no memory, only the shape).

    Returns
    -------
    complex64 ndarray [batch, M, 2K, 2N] (uninitialised; :func:`run_runs` overwrites it whole)
    """
    m, k, n = (int(v) for v in shape)
    return np.empty((int(batch), m, 2 * k, 2 * n), np.complex64)


def run_once(prep: PreparedPoint, *, study_seed: int, point: int, run: int,
             buffer: np.ndarray | None = None, backend: dsp.ArrayBackend | None = None,
             noise_stream: str = "boxmuller", workspace: np.ndarray | None = None) -> dict[str, Any]:
    """One Monte Carlo run: the seeded noise on the point's cube, then ``dsp.self_localize``.

    :func:`run_runs` with one run: the same row as that run has in any batch.

    Parameters
    ----------
    prep : PreparedPoint
        The point (from a point preparer).
    study_seed, point, run : int
        Select the noise stream (:func:`run_rng`).
    buffer : complex ndarray, optional
        Host scratch space shaped like ``prep.cube`` or ``[B, *prep.cube.shape]``, reused between runs.
    backend : dsp.ArrayBackend, optional
        Where the noise and the detector run (default NumPy).
    noise_stream : {"boxmuller", "fast"}, default "boxmuller"
        The host's per-beam noise stream (:func:`risloc_rt.model.beat.add_noise`); a GPU draws its own.
    workspace : complex64 ndarray, optional
        Host scratch space for the detector's half-bin transform (:func:`run_runs`), reused between runs.

    Returns
    -------
    dict
        One row of the run table: ``point``, ``run``, ``detected``, ``true_aod_az`` [rad],
        ``snr_db`` [dB], ``flags`` (comma-separated codes), ``seconds`` (noise + DSP, one core) [s],
        and :data:`ROW_FLOATS`: the estimate (``distance`` [m], ``aod_az`` [rad], ``x``, ``y``, ``z``
        [m]), signed errors [m, rad, m/s], ``angle_error`` [rad], ``position_error`` [m] and the
        stated 1σ (``std_distance`` [m], ``std_aod_az`` [rad], ``peb`` [m]); NaN without a detection.
    """
    if buffer is not None and buffer.ndim == 3:
        buffer = buffer[None]
    if workspace is not None and workspace.ndim == 3:
        workspace = workspace[None]
    return run_runs(prep, study_seed=study_seed, point=point, runs=[run], buffer=buffer, backend=backend,
                    noise_stream=noise_stream, workspace=workspace)[0]


def run_runs(prep: PreparedPoint, *, study_seed: int, point: int, runs: Any, buffer: np.ndarray | None = None,
             backend: dsp.ArrayBackend | None = None, batch: int | None = None,
             share: int = 1, noise_stream: str = "boxmuller",
             workspace: np.ndarray | None = None) -> list[dict[str, Any]]:
    """Monte Carlo runs of one point, B realizations per call of the whole-cube steps.

    For each group of B runs: their receiver noise (:func:`risloc_rt.model.beat.add_noise_batch`,
    run r's from :func:`run_rng`) and the detector (:func:`dsp.detect_batch`) run on ``backend`` for
    the whole group; then each realization's cube goes through ``dsp.self_localize`` with its
    detection, where it lives: its whole-cube reads (the refined estimator's projections, the flags'
    DTFTs) and the paper's grid search (:mod:`dsp.devicegrid`) run on the backend and only small
    results come to the host. A run's row depends on the study seed, the point and its run index
    only: not on B, the order or the worker.

    Parameters
    ----------
    prep : PreparedPoint
    study_seed, point : int
    runs : sequence of int
        The run indices.
    buffer : complex128 ndarray [B', M, K, N], optional
        Host scratch space for the noisy cubes (B' >= B), reused between calls.
    backend : dsp.ArrayBackend, optional
        Default NumPy.
    batch : int, optional
        B; default from the memory estimate (:func:`dsp.budget.detect_batch_size`: the memory limit
        on the host, the GPU's free memory on a GPU).
    share : int
        Processes sharing the GPU (a study's local workers): each sizes B from its share of the free
        memory.
    noise_stream : {"boxmuller", "fast"}, default "boxmuller"
        The host's per-beam noise stream (:func:`risloc_rt.model.beat.add_noise`; NumPy and
        array_api_strict); a GPU draws its own (cuRAND).
    workspace : complex64 ndarray [B', M, 2K, 2N], B' >= B, optional
        Host scratch space (NumPy, :func:`detector_workspace`) for the detector's half-bin transform,
        reused between calls (a fresh one per call costs its page faults, ≈ 15 ms per Table I run);
        default: one for this call.

    Returns
    -------
    list of dict
        The rows (:func:`run_once`), in the order of ``runs``.
    """
    from dsp.budget import detect_batch_size

    from ..model.beat import add_noise_batch

    backend = dsp.numpy_backend() if backend is None else backend
    runs = [int(r) for r in runs]
    p = prep.params
    if batch is None:
        free = backend.free_memory()
        batch = detect_batch_size(prep.cube.shape, free_bytes=None if free is None else free // max(1, int(share)),
                                  runs=len(runs))
    if buffer is not None and buffer.shape[0] < min(batch, len(runs)):
        buffer = None
    spread = p.get("aod_spread_deg", 0.0) > 0
    # the point's cube on the GPU once per call (the host backends draw the noise on the host)
    device_cube = backend.asarray(prep.cube) if backend.name == "cupy" and not spread else None
    rows: list[dict[str, Any]] = []
    # the detector's half-bin transform, reused by every group (NumPy: 150 MB per Table I cube)
    need = min(batch, len(runs))
    if not backend.is_numpy or not runs:
        workspace = None
    else:
        one_cube = detector_workspace(prep.cube.shape, 0).shape[1:]  # [M, 2K, 2N], no memory
        if workspace is None or workspace.shape[0] < need or workspace.shape[1:] != one_cube:
            workspace = detector_workspace(prep.cube.shape, need)
    for g in range(0, len(runs), batch):
        group = runs[g:g + batch]
        start = time.perf_counter()
        rngs = [run_rng(study_seed, point, r) for r in group]
        truths = [prep.truth] * len(group)
        if spread:  # each run's UE azimuth: its own cube (no sharing)
            noisy = []
            for i, rng in enumerate(rngs):
                az = p["aod_deg"] + (rng.random() - 0.5) * p["aod_spread_deg"]
                cap = simulate(point_scenario({**p, "aod_deg": az}, structure=p["structure"]), rng=rng, noise=False)
                truths[i] = cap.truth
                noisy.append(add_noise_batch(cap.cube, prep.radar.noise_power, [rng], backend=backend,
                                             stream=noise_stream))
            cubes = backend.xp.concat(noisy, axis=0)
        else:
            cubes = add_noise_batch(prep.cube, prep.radar.noise_power, rngs, backend=backend, out=buffer,
                                    device_cube=device_cube, stream=noise_stream)
        dets = dsp.detect_batch(cubes, prep.radar, backend=backend, pfa=p["pfa"],
                                min_range=prep.processing.min_range, max_candidates=5, pattern=prep.pattern,
                                sweep=prep.sweep, oversample=2,
                                workspace=None if workspace is None else workspace[:len(group)])
        shared_seconds = (time.perf_counter() - start) / len(group)
        for i, r in enumerate(group):
            t = time.perf_counter()
            # the realization stays where it is: the estimator's whole-cube reads run there too (dsp.xp)
            loc = dsp.self_localize(cubes[i, ...], sweep=prep.sweep, radar=prep.radar, processing=prep.processing,
                                    pose=prep.pose, loopback_delay=prep.loopback_delay, estimator=p["estimator"],
                                    pattern=prep.pattern, pfa=p["pfa"], detection=dets[i], floor_height=prep.floor_height,
                                    scan=False)  # no per-beam profile: the paper estimator searches only its best beams
            rows.append(_row(prep, truths[i], loc, point=point, run=r,
                             seconds=shared_seconds + time.perf_counter() - t))
    return rows


def _row(prep: PreparedPoint, truth: Any, loc: dsp.Localization, *, point: int, run: int,
         seconds: float) -> dict[str, Any]:
    """The run table's row of one localization (:func:`run_once`)."""
    detected = bool(loc.detected)
    nan = float("nan")
    row: dict[str, Any] = {"point": point, "run": run, "detected": detected, "true_aod_az": float(truth.aod[0]),
                           "snr_db": float(loc.detection.snr_db) if loc.detection is not None else nan,
                           "flags": ",".join(c for c in loc.flag_codes), "seconds": seconds}
    if detected:
        true_dir = prep.pose.to_world(dsp.direction_from_angles(truth.aod))
        # the truth at the estimate's own reference time (a moving UE: docs/estimation.md)
        true_pos = truth.position_at(loc.reference_time) if np.isfinite(loc.reference_time) else truth.ue_position
        true_dist = float(np.linalg.norm(true_pos - prep.pose.position))
        row.update({
            "distance": loc.distance, "distance_error": loc.distance - true_dist,
            "aod_az": float(loc.aod[0]), "aod_az_error": float(loc.aod[0] - truth.aod[0]),
            "angle_error": float(np.arccos(np.clip(loc.direction @ true_dir, -1.0, 1.0))),
            "velocity_error": loc.velocity - truth.velocity,
            "x": float(loc.position[0]), "y": float(loc.position[1]), "z": float(loc.position[2]),
            "position_error": float(np.linalg.norm(loc.position - true_pos)),
            "std_distance": loc.std.distance if loc.std is not None else nan,
            "std_aod_az": float(loc.std.aod[0]) if loc.std is not None else nan,
            "peb": float(loc.std.peb) if loc.std is not None else nan,
        })
    for key in ROW_FLOATS:
        row.setdefault(key, nan)
    return row


#: The float columns of a run row (NaN without a detection).
ROW_FLOATS = ("distance", "distance_error", "aod_az", "aod_az_error", "angle_error", "velocity_error",
              "x", "y", "z", "position_error", "std_distance", "std_aod_az", "peb")
