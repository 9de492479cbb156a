"""A tracked walk: a radar carried along timed waypoints through a traced hall, the RISs sweeping in turn.

``risloc track`` (issue 22, ``docs/tracking.md``). The walk is a
:class:`risloc_rt.studies.trajectory.Trajectory` (waypoints ``t, x, y, z`` [s, m] joined by straight
segments, read by :func:`risloc_rt.studies.trajectory.read_trajectory`); its figures are drawn by
:mod:`risloc_rt.studies.walk_figures`. The RISs sweep in time division (:class:`risloc_rt.model.time_division.TimeDivision`; default every RIS of the
scene in spec order, back to back), starting at the walk's first waypoint. For every slot whose
sweep ends within the walk:

1. the radar's position and velocity at the slot's reference time (the middle of its sweep,
   :func:`risloc_rt.model.motion.sweep_reference_time`) give the slot's scenario
   (:func:`risloc_rt.hall.scenario.hall_scenario` with ``ris=`` the slot's RIS, the others idle);
2. it is traced at that position (cached per position, :class:`risloc_rt.hall.raytrace.TraceCache`),
   simulated with the radar moving through the sweep (``motion="sweep"``: the traced paths advance
   by their delay rates) with its own noise stream ``default_rng([seed, slot])``, and localized
   (:func:`risloc_rt.io.report.process_capture`, the radar's height known when ``height`` says so);
3. a detection becomes one RIS's measurement at the sweep's reference time: the distance moved
   there by the measured radial velocity (``d + v̂ (t_ref − t_est)``, its variance
   ``σ_d² + (Δt σ_v)²``), the azimuth (the traced paths hold the RIS angles of t_ref) and the
   radial velocity, each with its 1σ; the tracker (:mod:`dsp.tracking`) updates on it as it
   arrives, gates it (NIS), or coasts through a slot with no detection (the radar behind the
   slot's RIS is not simulated: no return can reach it).

A row per slot (:data:`COLUMNS`) holds the truth, the single fix with its σ and flags, the track
with its σ, NEES, NIS and what the update did. The same seed gives the same rows.

Whether a slot's RIS could see the radar (:attr:`WalkSlot.in_view`) is decided from the geometry
alone: the radar in front of the RIS's plane, within its sweep's azimuth span, and no surface of
the scene on the straight line between them (:meth:`risloc_rt.authoring.geometry.HallGeometry.first_hit`).
"""

from __future__ import annotations

import io
import json
import math
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from dsp.budget import check_memory

from .trajectory import Trajectory, TrajectoryError
from .walk_figures import plot_consistency, plot_error, plot_plan
from .walk_summary import walk_summary
from .walk_tracker import SKIP_FLAGS, UPDATE_KINDS, WALK_MANOEUVRES, WalkTracker, smooth_walk

__all__ = ["WalkSlot", "WalkResult", "plan_walk", "run_walk", "write_walk", "COLUMNS", "UPDATE_KINDS",
           "default_schedule", "load_schedule", "MOVING_FLOORS", "NO_POSITION", "SKIP_FLAGS", "SWEEP_BYTES",
           "WALK_MANOEUVRES", "WalkTracker"]

#: The columns of ``walk.parquet`` (one row per slot) and their units.
COLUMNS = {
    "sweep": "slot index from the walk's start", "time": "s, the sweep's reference time (middle)",
    "ris": "the RIS that swept",
    "status": "fix | no-detection | no-position (detected, no distance > 0 at the sweep's middle) | behind (not simulated)",
    "in_view": "the RIS could see the radar (geometry: in front, in its span, line of sight)",
    "truth_x": "m", "truth_y": "m", "truth_z": "m", "truth_vx": "m/s", "truth_vy": "m/s", "truth_vz": "m/s",
    "fix_x": "m", "fix_y": "m", "fix_z": "m", "fix_distance": "m, at the reference time",
    "fix_std_distance": "m, the 1σ the tracker used (the fix's own and the floor)", "fix_az": "rad, RIS frame",
    "fix_std_az": "rad, as fix_std_distance", "fix_velocity": "m/s, radial", "fix_std_velocity": "m/s, as fix_std_distance",
    "fix_error": "m, |fix - truth|", "fix_sigma": "m, the fix's own 1σ of position (norm of the per-axis 1σ)",
    "fix_flags": "the fix's flag codes, comma-separated", "track_x": "m", "track_y": "m", "track_z": "m",
    "track_vx": "m/s", "track_vy": "m/s", "track_vz": "m/s", "track_std_x": "m", "track_std_y": "m",
    "track_std_z": "m", "track_error": "m, |track - truth|", "track_sigma": "m, sqrt(trace of the position covariance)",
    "nees": "normalised estimation error squared of the track", "nees_dof": "its degrees of freedom",
    "nis": "normalised innovation squared of the measurement", "nis_dof": "its degrees of freedom",
    "update": "what the tracker did (UPDATE_KINDS)",
    "smooth_x": "m, the smoothed track (every measurement of the walk, dsp.smoothing)", "smooth_y": "m",
    "smooth_z": "m", "smooth_vx": "m/s", "smooth_vy": "m/s", "smooth_vz": "m/s", "smooth_std_x": "m",
    "smooth_std_y": "m", "smooth_std_z": "m", "smooth_error": "m, |smoothed track - truth|",
    "smooth_sigma": "m, sqrt(trace of its position covariance)", "smooth_nees": "NEES of the smoothed track",
    "smooth": "how the smoothed estimate was made (dsp.smoothing.SMOOTH_KINDS)",
    "seconds_trace": "s", "seconds_simulate": "s",
    "seconds_dsp": "s", "elapsed": "s, wall time from the walk's start to the end of this sweep's work",
}


#: What the single fixes' 1σ (their Cramér–Rao bounds at the measured SNR, the floor's ladder included)
#: leave out for a radar on the move, added in quadrature before the tracker sees them: distance [m],
#: azimuth [rad], radial velocity [m/s] (``docs/tracking.md``, "The fixes' σ on the move"). Calibrated by
#: ``benchmarks/calibrate_walk_floors.py`` on a walk of their own (``benchmarks/l_hall_calibration_walk.csv``:
#: the smallest floors with 68.3 % of the used fixes' errors within their 1σ), not on the benchmark walk
#: that judges them; again after the DSP removed moving hall clutter (2026-11-27: 0.071 mm, 0.0143° and
#: 0.016 mm/s before).
MOVING_FLOORS = (6.9e-5, math.radians(0.0143), 0.0)

#: What a slot's measurement is when the DSP detected a return but gave no distance > 0 at the sweep's
#: middle (a return earlier than the RIS's own loop-back delay, flag ``before-ris-delay``): the row says
#: ``no-position`` and the tracker predicts only.
NO_POSITION = "no-position"
#: Memory a planned sweep holds until the walk is written [bytes]: its slot (~0.5 KiB), its row of
#: :data:`COLUMNS` (~3.3 KiB) and the smoother's forward, backward and smoothed estimates (~5.3 KiB; both
#: measured with ``tracemalloc``), the row doubled for the table and figures made from the rows at the end.
#: A walk's sweeps times this is checked against :func:`dsp.budget.memory_limit` before any is planned.
SWEEP_BYTES = 16384


def default_schedule(spec: Any, radar: Any, num_beams: int) -> Any:
    """Every RIS of ``spec`` in spec order, back to back, idle off.

    Parameters
    ----------
    spec : risloc_rt.authoring.spec.HallSpec
        The scene's spec.
    radar : dsp.RadarConfig
        Its beam interval sets the sweep's duration [s].
    num_beams : int
        Beams per sweep M.

    Returns
    -------
    risloc_rt.model.time_division.TimeDivision
    """
    from ..model.time_division import TimeDivision

    return TimeDivision.consecutive([r.name for r in spec.ris], num_beams * radar.beam_interval)


def load_schedule(path: str | Path | None, scene: str | Path, *, idle: str | None = None) -> Any:
    """The time division of a walk: a TOML file's ``[schedule]`` table, or the default.

    Parameters
    ----------
    path : str or Path, optional
        A TOML file with a ``[schedule]`` table (:mod:`risloc_rt.model.time_division`); None: every
        RIS of the scene in spec order, back to back.
    scene : str or Path
        The scene (its RIS names; the hall's radar and sweep set the sweep's duration).
    idle : {"off", "parked"}, optional
        Overrides the table's ``idle``.

    Returns
    -------
    risloc_rt.model.time_division.TimeDivision

    Raises
    ------
    ValueError
        One line naming the file: not TOML, no ``[schedule]`` table, an unknown key or RIS,
        overlapping slots.
    """
    import tomllib

    from dsp import BeamSweep, RadarConfig

    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..model.time_division import TimeDivision, parse_time_division

    spec = load_spec(scene_directory(scene) / "spec.toml")
    names = [r.name for r in spec.ris]
    duration = BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5])).num_beams * RadarConfig().beam_interval
    table: Any = None
    if path is not None:
        path = Path(path)
        try:
            doc = tomllib.loads(path.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: not a TOML file ({exc}); give a file with a [schedule] table, e.g. "
                             f"[schedule] order = {names!r}") from None
        if "schedule" not in doc:
            raise ValueError(f"{path}: no [schedule] table; add one, e.g. [schedule] order = {names!r}")
        table = doc["schedule"]
    schedule = parse_time_division(table, ris_names=names, sweep_duration=duration,
                                   where=f"{path} [schedule]" if path is not None else "[schedule]")
    if idle is not None and idle != schedule.idle:
        schedule = TimeDivision(order=schedule.order, sweep_duration=schedule.sweep_duration, starts=schedule.starts,
                                cycle=schedule.cycle, idle=idle, parked_beam=schedule.parked_beam)
    return schedule


@dataclass(frozen=True)
class WalkSlot:
    """One slot of the walk: which RIS sweeps, when, and where the radar is.

    Attributes
    ----------
    index : int
        Slot index from the walk's start.
    ris : str
        The sweeping RIS.
    start : float
        The sweep's start [s] (the trajectory's clock).
    time : float
        Its reference time, the middle of the sweep [s].
    position, velocity : float array [3]
        The radar's at ``time`` [m], [m/s].
    facing : bool
        The radar is in front of the RIS's plane (else the slot is not simulated).
    in_view : bool
        Facing, within the sweep's azimuth span and in line of sight (no surface in between).
    """

    index: int
    ris: str
    start: float
    time: float
    position: np.ndarray
    velocity: np.ndarray
    facing: bool
    in_view: bool


def plan_walk(scene: str | Path, trajectory: Trajectory, *, schedule: Any = None, sweep: Any = None,
              radar: Any = None, max_sweeps: int | None = None) -> tuple[WalkSlot, ...]:
    """The slots of a walk: every slot of the schedule whose sweep ends within the walk.

    Parameters
    ----------
    scene : str or Path
        A scene name or folder.
    trajectory : Trajectory
        Checked against the scene's geometry here (:meth:`Trajectory.check_in`).
    schedule : risloc_rt.model.time_division.TimeDivision, optional
        Default :func:`default_schedule`; its RIS names must be the scene's.
    sweep : dsp.BeamSweep, optional
        The sweep (default the hall's: −45° … 45° in 1.5° steps).
    radar : dsp.RadarConfig, optional
        Default Table I.
    max_sweeps : int, optional
        Only the first ``max_sweeps`` slots.

    Returns
    -------
    tuple of WalkSlot
    """
    from dsp import BeamSweep, RadarConfig

    from ..authoring.geometry import load_geometry
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..hall.scenario import facing_radar, ris_index
    from ..model.motion import sweep_reference_time

    folder = scene_directory(scene)
    spec = load_spec(folder / "spec.toml")
    radar = radar or RadarConfig()
    sweep = sweep or BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))
    schedule = schedule or default_schedule(spec, radar, sweep.num_beams)
    for name in schedule.order:
        ris_index(spec, name, where="schedule order")
    if abs(schedule.sweep_duration - sweep.num_beams * radar.beam_interval) > 1e-12:
        raise ValueError(f"the schedule's sweep lasts {schedule.sweep_duration * 1e3:g} ms, the radar's "
                         f"{sweep.num_beams} beams {sweep.num_beams * radar.beam_interval * 1e3:g} ms; give it "
                         "the radar's sweep duration")
    geometry = load_geometry(folder / "scene.xml")
    trajectory.check_in(geometry)
    configs = {r.name: c for r, c in zip(spec.ris, spec.ris_configs())}
    span = (float(sweep.angles[:, 0].min()), float(sweep.angles[:, 0].max()))
    t_mid = sweep_reference_time(radar, sweep.num_beams)
    out = []
    if max_sweeps is not None and not (isinstance(max_sweeps, int) and max_sweeps >= 1):
        raise ValueError(f"max_sweeps={max_sweeps!r} must be a whole number >= 1")
    count = schedule.count_until(trajectory.duration)
    count = count if max_sweeps is None else min(count, max_sweeps)
    check_memory(count * SWEEP_BYTES, f"{trajectory.source}: a walk of {trajectory.duration:g} s ({count} sweeps)",
                 fix="give a shorter walk, or --max-sweeps N for its first N sweeps")
    for k in range(count):
        start = float(trajectory.times[0] + schedule.slot_start(int(k)))
        t = start + t_mid
        name = schedule.ris_of(int(k))
        pos, vel = trajectory.position(t), trajectory.velocity(t)
        cfg = configs[name]
        facing = facing_radar(cfg, pos)
        in_view = False
        if facing:
            az = float(cfg.pose.angles_to(pos)[0])
            gap = pos - cfg.pose.position
            dist = float(np.linalg.norm(gap))
            hit, at = geometry.first_hit(cfg.pose.position, gap)
            in_view = span[0] - 1e-9 <= az <= span[1] + 1e-9 and (hit is None or at >= dist - 1e-6)
        out.append(WalkSlot(index=int(k), ris=name, start=start, time=t, position=pos, velocity=vel, facing=facing,
                            in_view=in_view))
    if not out:
        raise TrajectoryError(f"{trajectory.source}: the walk lasts {trajectory.duration:g} s, less than one sweep "
                              f"({schedule.sweep_duration:g} s); give later timestamps")
    return tuple(out)


@dataclass(frozen=True)
class WalkResult:
    """A tracked walk.

    Attributes
    ----------
    rows : list of dict
        One per slot, :data:`COLUMNS`.
    summary : dict
        What ``summary.json`` holds (fix share, RMSEs, NEES/NIS against their bands, seconds).
    scene : Path
        The scene folder.
    trajectory : Trajectory
    """

    rows: list[dict[str, Any]]
    summary: dict[str, Any]
    scene: Path
    trajectory: Trajectory


def _measurement(name: str, pose: Any, loc: Any, slot: WalkSlot, t_mid: float, floors: tuple[float, float, float]) -> Any:
    """One RIS's :class:`dsp.tracking.RisMeasurement` at the slot's reference time (module notes); ``floors``
    (distance [m], azimuth [rad], velocity [m/s]) are added in quadrature to the fix's 1σ."""
    from dsp.fusion import RisFix
    from dsp.tracking import RisMeasurement

    dt = t_mid - float(loc.reference_time)  # the estimate's time → the sweep's middle (both from the sweep start)
    distance = float(loc.distance) + float(loc.velocity) * dt
    std_d = math.sqrt(float(loc.std.distance) ** 2 + (dt * float(loc.std.velocity)) ** 2 + floors[0] ** 2)
    fix = RisFix(name=name, pose=pose, distance=distance, std_distance=std_d,
                 aod=np.array([float(loc.aod[0]), float(loc.aod[1])]),
                 std_aod=np.array([math.hypot(float(loc.std.aod[0]), floors[1]), np.nan]), flags=tuple(loc.flag_codes))
    return RisMeasurement(time=slot.time, fix=fix, velocity=float(loc.velocity),
                          std_velocity=math.hypot(float(loc.std.velocity), floors[2]))


@dataclass(frozen=True)
class _SlotJob:
    """What one slot's measurement needs, picklable for a worker process."""

    folder: Path
    slot: WalkSlot
    idle: str
    parked_beam: Any
    trace: Any
    sweep: Any
    radar: Any
    seed: int
    estimator: str
    height: float | None
    t_mid: float
    pose: Any
    floors: tuple[float, float, float]
    cache: Any
    backend: Any


def _measure_slot(job: _SlotJob) -> tuple[Any, float, dict[str, float]]:
    """One slot traced, simulated and localized: (its measurement or None, the fix's position 1σ [m], seconds).

    On one DSP and one BLAS thread (:func:`risloc_rt.studies.engine.one_thread`), here or in a worker
    process alike: a multi-threaded BLAS sums in another order (last-digit differences), so this is
    what makes the rows the same for any number of workers.
    """
    from .engine import one_thread

    with one_thread():
        return _measured(job)


def _measured(job: _SlotJob) -> tuple[Any, float, dict[str, float]]:
    from ..hall.pruning import AliasWarning
    from ..hall.scenario import FLOOR_HEIGHT, hall_paths, hall_scenario
    from ..io.report import process_capture
    from ..model.simulate import simulate

    slot = job.slot
    secs = {"seconds_trace": 0.0, "seconds_simulate": 0.0, "seconds_dsp": 0.0}
    if not slot.facing:
        return None, math.nan, secs
    hs = hall_scenario(job.folder, ris=slot.ris, ue_position=slot.position, ue_velocity=slot.velocity,
                       idle=job.idle, parked_beam=job.parked_beam, trace=job.trace, sweep=job.sweep, radar=job.radar)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        t0 = time.perf_counter()
        traced = hall_paths(hs, cache=job.cache)
    t1 = time.perf_counter()
    capture = simulate(hs.base, rng=np.random.default_rng([job.seed, slot.index]), paths=traced.paths,
                       motion="sweep", seed=job.seed, backend=job.backend)
    t2 = time.perf_counter()
    loc, _ = process_capture(capture, estimator=job.estimator, ue_height=job.height, backend=job.backend,
                             floor_height=FLOOR_HEIGHT)
    secs = {"seconds_trace": t1 - t0, "seconds_simulate": t2 - t1, "seconds_dsp": time.perf_counter() - t2}
    if loc.detected and loc.std is not None and math.isfinite(float(loc.std.velocity)):
        if not float(loc.distance) + float(loc.velocity) * (job.t_mid - float(loc.reference_time)) > 0:
            return NO_POSITION, math.nan, secs  # e.g. before-ris-delay: a return earlier than the RIS's own
        return (_measurement(slot.ris, job.pose, loc, slot, job.t_mid, job.floors),
                float(np.linalg.norm(loc.std.position)), secs)
    return None, math.nan, secs


@contextmanager
def _slot_results(jobs: list[_SlotJob], workers: int) -> Iterator[Iterator[tuple[Any, float, dict[str, float]]]]:
    """The slots' measurements in slot order: here, or on ``workers`` processes (results do not depend on it)."""
    if workers <= 1 or len(jobs) <= 1:
        yield map(_measure_slot, jobs)
        return
    from concurrent.futures.process import BrokenProcessPool

    from .engine import worker_pool

    def in_order(pool: Any) -> Iterator[tuple[Any, float, dict[str, float]]]:
        try:
            yield from pool.map(_measure_slot, jobs)
        except BrokenProcessPool:
            raise RuntimeError(f"a worker process died (killed, or out of memory: each of the {workers} loads the "
                               "ray tracer); rerun with fewer --workers") from None

    with worker_pool(min(workers, len(jobs))) as pool:
        yield in_order(pool)


def _track_row(slot: WalkSlot, job: _SlotJob, meas: Any, fix_sigma: float, secs: dict[str, float]) -> dict[str, Any]:
    """A row's truth, status, seconds and fix columns (the track's are added by the caller)."""
    row: dict[str, Any] = {"sweep": slot.index, "time": slot.time, "ris": slot.ris, "in_view": slot.in_view}
    row.update(zip(("truth_x", "truth_y", "truth_z"), map(float, slot.position)))
    row.update(zip(("truth_vx", "truth_vy", "truth_vz"), map(float, slot.velocity)))
    row["status"] = "behind" if not slot.facing else ("fix" if meas is not None else "no-detection")
    row.update(secs)
    if meas is not None:
        fix = meas.fix
        p_fix = fix.pose.point_at(fix.aod, fix.distance)
        row.update(zip(("fix_x", "fix_y", "fix_z"), map(float, p_fix)))
        row.update(fix_distance=fix.distance, fix_std_distance=fix.std_distance, fix_az=float(fix.aod[0]),
                   fix_std_az=float(fix.std_aod[0]), fix_velocity=meas.velocity,
                   fix_std_velocity=meas.std_velocity, fix_error=float(np.linalg.norm(p_fix - slot.position)),
                   fix_sigma=fix_sigma, fix_flags=",".join(fix.flags))
    else:
        row.update({k: math.nan for k in ("fix_x", "fix_y", "fix_z", "fix_distance", "fix_std_distance", "fix_az",
                                           "fix_std_az", "fix_velocity", "fix_std_velocity", "fix_error",
                                           "fix_sigma")})
        row["fix_flags"] = ""
    return row


def run_walk(scene: str | Path, trajectory: Trajectory, *, schedule: Any = None, seed: int = 0,
             tx_power_dbm: float | None = None, trace: Any = None, cache: Any = None, height: Any = "path",
             height_std: float = 0.01, accel_density: float | None = None, manoeuvres: Any = None,
             gate_pfa: float = 1e-3, restart_after: int = 3,
             estimator: str = "refined", progress: Callable[[str], None] | None = None,
             progress_every: int = 10, max_sweeps: int | None = None, floors: Any = MOVING_FLOORS,
             sweep: Any = None, backend: Any = None, workers: int = 1) -> WalkResult:
    """Walk the radar along ``trajectory`` through the traced hall, localize every sweep and track it.

    Parameters
    ----------
    scene : str or Path
        A scene name or folder (built, up to date).
    trajectory : Trajectory
        The walk [s, m].
    schedule : risloc_rt.model.time_division.TimeDivision, optional
        When each RIS sweeps (default :func:`default_schedule`); its ``idle`` and ``parked_beam`` say
        what the others do meanwhile.
    seed : int
        Slot k's receiver noise is ``default_rng([seed, k])``: the same seed, the same rows.
    tx_power_dbm : float, optional
        Transmit power [dBm] (default Table I's 20).
    trace : risloc_rt.hall.raytrace.tracer.TraceSettings, optional
        Ray-tracer settings (default the hall's).
    cache : risloc_rt.hall.raytrace.TraceCache, optional
        Traces reused per position (None: every slot traced).
    height : "path", float or None
        The radar's known height [m]: ``"path"`` (default) the trajectory's z at each sweep (a radar
        carried at a known height), a number, or None (unknown: the filter tracks all six states).
        Known, it resolves the elevation in the localization (``ue_height``) and holds the track's z
        (:mod:`dsp.tracking`, "A known height").
    height_std : float
        1σ of the known height [m].
    accel_density : float, optional
        Track with one nearly-constant-velocity model of this white acceleration density q [m²/s³] per
        axis instead of the two-model filter (:class:`WalkTracker`).
    manoeuvres : dsp.tracking.Manoeuvres, optional
        The two-model filter's models (default :data:`WALK_MANOEUVRES`); not with ``accel_density``.
    gate_pfa : float
        Probability that a consistent measurement is gated out (χ² on the NIS).
    restart_after : int
        Consecutive gated measurements after which the track restarts from the next one.
    estimator : {"refined", "paper"}
        The single-sweep estimator.
    progress : callable, optional
        Receives one line every ``progress_every`` slots and at the end.
    progress_every : int
        Slots between progress lines.
    max_sweeps : int, optional
        Only the first ``max_sweeps`` slots (:func:`plan_walk`).
    floors : (float, float, float)
        1σ added in quadrature to every fix's distance [m], azimuth [rad] and radial velocity [m/s]
        before the tracker sees it (default :data:`MOVING_FLOORS`; ``(0, 0, 0)``: the fixes' own 1σ).
    sweep : dsp.BeamSweep, optional
        The RISs' sweep (default the hall's, −45° … 45° in 1.5° steps); its beams set the slot's length.
    backend : dsp.ArrayBackend, optional
        Where the receiver noise and the DSP's whole-cube work run (``--device``); default NumPy.
    workers : int
        Processes that trace, simulate and localize the slots ahead of the tracker (each slot's
        numbers depend on its seed and index only, so the rows are the same for any number; one
        DSP and BLAS thread each). The tracker takes the slots in order in this process. A GPU
        backend takes one.

    Returns
    -------
    WalkResult
    """
    from dsp import BeamSweep, RadarConfig, tracking

    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..model.motion import sweep_reference_time

    begin = time.perf_counter()
    folder = scene_directory(scene)
    spec = load_spec(folder / "spec.toml")
    poses = {r.name: c.pose for r, c in zip(spec.ris, spec.ris_configs())}
    floors = tuple(float(f) for f in floors)
    if len(floors) != 3 or not all(math.isfinite(f) and f >= 0 for f in floors):
        raise ValueError(f"floors={floors!r} must be three numbers >= 0: distance [m], azimuth [rad], velocity [m/s]")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r} must be an integer >= 1 (processes)")
    if backend is not None and backend.is_numpy:
        backend = None  # NumPy is the default, and a worker process is handed no modules
    if backend is not None:
        workers = 1  # one GPU: its work is already parallel
    if isinstance(height, str) and height != "path":
        raise ValueError(f"height={height!r} must be 'path', a number [m] or None")
    sweep = sweep or BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))  # the hall's (hall_scenario)
    radar = RadarConfig() if tx_power_dbm is None else replace(RadarConfig(), tx_power_dbm=float(tx_power_dbm))
    slots = plan_walk(folder, trajectory, schedule=schedule, max_sweeps=max_sweeps, sweep=sweep, radar=radar)
    schedule = schedule or default_schedule(spec, radar, sweep.num_beams)
    t_mid = sweep_reference_time(radar, sweep.num_beams)
    axes = tracking.HORIZONTAL if height is not None else tracking.ALL_AXES
    tracker = WalkTracker(manoeuvres=manoeuvres, accel_density=accel_density, gate_pfa=gate_pfa,
                          restart_after=restart_after)
    state, rows, seen = None, [], []
    jobs = [_SlotJob(folder=folder, slot=slot, idle=schedule.idle, parked_beam=schedule.parked_beam, trace=trace,
                     sweep=sweep, radar=radar, seed=int(seed), estimator=estimator,
                     height=None if height is None else (float(slot.position[2]) if height == "path" else float(height)),
                     t_mid=t_mid, pose=poses[slot.ris], floors=floors, cache=cache, backend=backend)
            for slot in slots]
    with _slot_results(jobs, workers) as results:
        for n, (slot, job, (meas, fix_sigma, secs)) in enumerate(zip(slots, jobs, results)):
            no_position = isinstance(meas, str) and meas == NO_POSITION  # a worker sends a copy, not the object
            meas = None if no_position else meas
            row = _track_row(slot, job, meas, fix_sigma, secs)
            if no_position:
                row["status"] = "no-position"
            known = None if job.height is None else (job.height, height_std)
            kind, nis, nis_dof = tracker.step(slot.time, meas, height=known)
            state = tracker.state
            seen.append((meas, known, state, kind in ("start", "used", "restart")))
            row.update(update=kind, nis=nis, nis_dof=nis_dof)
            if state is not None:
                truth = np.concatenate([slot.position, slot.velocity])
                row.update(zip(("track_x", "track_y", "track_z", "track_vx", "track_vy", "track_vz"),
                               map(float, state.mean)))
                row.update(zip(("track_std_x", "track_std_y", "track_std_z"), map(float, state.position_std)))
                row.update(track_error=float(np.linalg.norm(state.mean[:3] - slot.position)),
                           track_sigma=float(np.sqrt(np.trace(state.covariance[:3, :3]))),
                           nees=tracking.nees(state, truth, axes=axes), nees_dof=len(axes))
            else:
                row.update({k: math.nan for k in ("track_x", "track_y", "track_z", "track_vx", "track_vy", "track_vz",
                                                   "track_std_x", "track_std_y", "track_std_z", "track_error",
                                                   "track_sigma", "nees")})
                row["nees_dof"] = 0
            row["elapsed"] = time.perf_counter() - begin
            rows.append(row)
            if progress is not None and ((n + 1) % max(int(progress_every), 1) == 0 or n + 1 == len(slots)):
                fixes = sum(r["status"] == "fix" for r in rows)
                progress(f"sweep {n + 1}/{len(slots)} (t = {slot.time:.2f} s): {fixes} fix(es), "
                         f"{time.perf_counter() - begin:.0f} s")
    smoothed = smooth_walk([slot.time for slot in slots], seen, tracker, axes)
    for row, slot, est, kind in zip(rows, slots, smoothed.states, smoothed.kinds):
        row.update(_smoothed_columns(slot, est, kind, axes))
    rows = [{k: row[k] for k in COLUMNS} for row in rows]
    summary = walk_summary(rows, scene=folder, trajectory=trajectory, schedule=schedule, seed=seed, radar=radar,
                           height=height, height_std=height_std, tracker=tracker, gate_pfa=gate_pfa,
                           wall=time.perf_counter() - begin, turns=smoothed.turns)
    return WalkResult(rows=rows, summary=summary, scene=folder, trajectory=trajectory)


def _smoothed_columns(slot: WalkSlot, est: Any, kind: str, axes: tuple[int, ...]) -> dict[str, Any]:
    """A row's ``smooth_*`` columns from the slot's smoothed estimate (None: NaN)."""
    from dsp.tracking import nees

    names = ("smooth_x", "smooth_y", "smooth_z", "smooth_vx", "smooth_vy", "smooth_vz")
    if est is None:
        out = {k: math.nan for k in names + ("smooth_std_x", "smooth_std_y", "smooth_std_z", "smooth_error",
                                             "smooth_sigma", "smooth_nees")}
    else:
        truth = np.concatenate([slot.position, slot.velocity])
        out = dict(zip(names, map(float, est.mean)))
        out.update(zip(("smooth_std_x", "smooth_std_y", "smooth_std_z"), map(float, est.position_std)))
        out.update(smooth_error=float(np.linalg.norm(est.mean[:3] - slot.position)),
                   smooth_sigma=float(np.sqrt(np.trace(est.covariance[:3, :3]))),
                   smooth_nees=nees(est, truth, axes=axes))
    out["smooth"] = kind
    return out


def write_walk(result: WalkResult, folder: str | Path) -> list[Path]:
    """Write ``walk.parquet``, ``summary.json``, ``plan.png``, ``error.png`` and ``consistency.png`` into ``folder``.

    Parameters
    ----------
    result : WalkResult
        The walk.
    folder : str or Path
        An existing folder (the CLI's staging folder of ``risloc_rt._outputs.output_folder``).

    Returns
    -------
    list of Path
        The files written (atomically, :mod:`risloc_rt._files`).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from .._files import atomic_write_bytes

    folder = Path(folder)
    buf = io.BytesIO()
    pq.write_table(pa.table({k: [r[k] for r in result.rows] for k in COLUMNS}), buf)
    out = [folder / "walk.parquet", folder / "summary.json"]
    atomic_write_bytes(out[0], buf.getvalue())
    atomic_write_bytes(out[1], json.dumps(result.summary, indent=1).encode() + b"\n")
    out += [plot_plan(result, folder / "plan.png"), plot_error(result, folder / "error.png"),
            plot_consistency(result, folder / "consistency.png")]
    return out
