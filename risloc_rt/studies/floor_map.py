"""``risloc study map``: position RMSE, detection probability, PEB and the dominant flag over a hall's floor.

Radar positions on a square grid over the hall's footprint at one height (``margin`` from the
walls, outside objects, within the RIS's sweep fan); each cell is traced (``hall_paths`` with the
trace cache: a rerun traces nothing), its noiseless cube synthesised once, and ``runs`` noise
realizations localized (``kernel.run_once``, the noise of run r of cell c from
``SeedSequence(seed, spawn_key=(c, r))``). The cells are the points of a study on the sweeps'
engine (:func:`risloc_rt.studies.engine.execute` with :func:`prepare_cell` as the point preparer:
worker processes or Dask, retried when a worker dies) and the runs are appended to ``runs.jsonl``
as in a sweep, so a killed map continues and the numbers do not depend on the number of workers.
Outputs: ``map.json`` (one entry per cell), ``map.parquet`` and ``map.png``
(:func:`risloc_rt.studies.figures.plot_map`).
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
import time
import warnings
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dsp.validation import integer, non_negative, one_of, positive

from .._files import atomic_write_bytes
from .._outputs import output_folder
from .engine import choose_workers, default_workers, execute
from .figures import plot_map
from .kernel import PreparedPoint, point_bound
from .store import RunLog, StudyFolderError, check_stream, keep_log, study_device

__all__ = ["MapSettings", "MapResult", "run_map", "grid_cells", "grid_budget", "prepare_cell", "MAX_GRID_POINTS"]

#: More grid points than this (before the cells are chosen) are refused unless ``force_long``: each
#: cell is a trace and ``runs`` runs (≈ 14 s of one core at 20 runs), so 10⁵ cells are weeks.
MAX_GRID_POINTS = 100_000


@dataclass(frozen=True)
class MapSettings:
    """A floor map: which hall, which grid, how many runs.

    Attributes
    ----------
    scene : str
        A hall in ``scenes/`` or a built scene folder.
    spacing : float
        Grid spacing [m].
    height : float
        Radar height above the floor [m].
    runs : int
        Noise runs per cell (>= 1).
    seed : int
        Study seed: run r of cell c draws its noise from ``SeedSequence(seed, spawn_key=(c, r))``.
    estimator : {"paper", "refined"}
    depth : int
        Ray-tracing depth.
    samples : int
        Rays per source.
    tx_power_dbm : float or None
        Transmit power [dBm] (None: Table I's 20 dBm).
    margin : float
        Least distance of a cell from walls and objects [m].
    """

    scene: str = "paper_hall"
    spacing: float = 1.0
    height: float = 1.2
    runs: int = 20
    seed: int = 0
    estimator: str = "refined"
    depth: int = 3
    samples: int = 100_000
    tx_power_dbm: float | None = None
    margin: float = 0.5

    def __post_init__(self) -> None:
        for name in ("spacing", "height"):
            positive(getattr(self, name), f"--{name}", "m", error=ValueError)
        non_negative(self.margin, "--margin", "m", error=ValueError)
        integer(self.runs, "--runs", minimum=1, error=ValueError)
        one_of(self.estimator, "--estimator", ("paper", "refined"), error=ValueError)

    @property
    def key(self) -> str:
        """sha256 of every setting but ``runs`` (more runs extend a map), 16 hex digits."""
        d = asdict(self)
        d.pop("runs")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def grid_budget(settings: MapSettings, *, long_ok: bool = False) -> tuple[int, int]:
    """Count the grid points of ``settings`` from the hall's footprint and check their memory, before any grid is made.

    Parameters
    ----------
    settings : MapSettings
        The hall and ``spacing`` [m].
    long_ok : bool
        Allow more than :data:`MAX_GRID_POINTS` grid points (``--force-long``).

    Returns
    -------
    points : int
        Grid points over the footprint's bounding box (the cells are those that qualify).
    estimate : int
        Peak memory of :func:`grid_cells` [bytes]: ``P × 8 × (8 + 6 V)`` for ``P`` grid points and
        ``V`` footprint vertices (the grid, its positions and mask, and the point-in-polygon and
        edge-distance temporaries of ``P × V`` elements); 256 B per point for a rectangular hall,
        the 255 B per point measured (7.4 GB for 2.9·10⁷ positions).

    Raises
    ------
    dsp.budget.BudgetError
        ``estimate`` exceeds the memory limit.
    StudyError
        More than :data:`MAX_GRID_POINTS` grid points without ``long_ok``.
    """
    import math

    from dsp.budget import check_memory, format_bytes

    from ..authoring.polygon import grid_test_memory
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from .engine import StudyError

    spec = load_spec(scene_directory(settings.scene) / "spec.toml")
    poly = np.array(spec.footprint, dtype=float)
    size = poly.max(axis=0) - poly.min(axis=0)
    nx, ny = (max(0, math.ceil(float(s) / settings.spacing - 0.5)) for s in size)
    points = nx * ny
    estimate = grid_test_memory(points, len(poly))
    what = (f"a floor grid of {points:,} points (--spacing {settings.spacing:g} m over the {size[0]:.3g} m x "
            f"{size[1]:.3g} m footprint of {settings.scene!r}: {nx:,} x {ny:,})")
    check_memory(estimate, what, fix="use a larger --spacing")
    if points > MAX_GRID_POINTS and not long_ok:
        raise StudyError(f"{what} (about {format_bytes(estimate)} of memory), more than the {MAX_GRID_POINTS:,} a map "
                         "may have without --force-long (each cell is a trace and --runs runs); use a larger --spacing")
    return points, estimate


def grid_cells(settings: MapSettings, *, long_ok: bool = False) -> tuple[Any, np.ndarray, np.ndarray]:
    """The cells of a floor map: inside the footprint, away from walls and objects, within the sweep fan.

    Parameters
    ----------
    settings : MapSettings
        The hall, ``spacing``, ``height`` and ``margin`` [m].
    long_ok : bool
        Allow more than :data:`MAX_GRID_POINTS` grid points (:func:`grid_budget`, checked first).

    Returns
    -------
    spec : risloc_rt.authoring.spec.HallSpec
        The hall's spec.
    cells : ndarray, shape (C, 3)
        Radar positions [m], world frame, at ``height``.
    keep : ndarray of bool
        Which grid points (x-major over the footprint's bounding box) are cells.

    Raises
    ------
    ValueError
        No grid point qualifies.
    dsp.budget.BudgetError, StudyError
        The grid is too large (:func:`grid_budget`).
    """
    from ..authoring.geometry import load_geometry
    from ..authoring.polygon import boundary_distance, contains
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec

    grid_budget(settings, long_ok=long_ok)
    folder = scene_directory(settings.scene)
    spec = load_spec(folder / "spec.toml")
    poly = np.array(spec.footprint, dtype=float)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    xs = np.arange(lo[0] + settings.spacing / 2, hi[0], settings.spacing)
    ys = np.arange(lo[1] + settings.spacing / 2, hi[1], settings.spacing)
    xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    keep = contains(poly, xy) & (boundary_distance(poly, xy) >= settings.margin)
    pts = np.column_stack([xy, np.full(len(xy), settings.height)])
    geometry = load_geometry(folder / "scene.xml")
    ris = spec.ris_configs()[0]
    for i in np.flatnonzero(keep):
        try:
            geometry.check_point(pts[i], clearance=settings.margin)
        except ValueError:
            keep[i] = False
            continue
        if np.linalg.norm(pts[i] - ris.pose.position) < 1.0:  # too near the panel (and its own cell)
            keep[i] = False
            continue
        az, _ = ris.pose.angles_to(pts[i])
        front = ris.pose.to_local(pts[i] - ris.pose.position)[2] > 0
        if not (front and abs(az) <= np.deg2rad(45.0)):
            keep[i] = False
    if not keep.any():
        raise ValueError(f"no grid cell of {settings.scene!r} lies inside the hall, {settings.margin:g} m from its walls "
                         "and objects and within the RIS's ±45° sweep; use a smaller --spacing or --margin")
    return spec, pts[keep], keep


def _cell_settings(settings: MapSettings) -> dict[str, Any]:
    """What a cell's cube depends on (not ``runs``, ``seed`` or ``estimator``: those are per run)."""
    d = asdict(settings)
    for name in ("runs", "seed"):
        d.pop(name)
    return d


def prepare_cell(params: dict[str, Any]) -> PreparedPoint:
    """The floor map's point preparer: trace one cell (through the trace cache), synthesise its noiseless
    cube once, and its bound.

    Parameters
    ----------
    params : dict
        ``{"cell": index, "ue": [x, y, z] (radar position [m]), "settings": {...}}`` as
        :class:`_MapPlan` makes them (plain data: a worker process or a Dask worker rebuilds the
        cell from them).

    Returns
    -------
    PreparedPoint
        The cell's noiseless cube [√W], its bounds (``crb``: m, rad, m/s; ``peak_snr_db`` [dB]) and,
        in ``params["warnings"]``, the tracer's warnings (e.g. range aliasing) instead of printing them.
    """
    from dsp import RadarConfig

    from ..hall import hall_paths, hall_scenario
    from ..hall.raytrace import TraceCache, TraceSettings
    from ..model import simulate

    start = time.perf_counter()
    settings = MapSettings(**params["settings"])
    ue = np.asarray(params["ue"], dtype=float)
    radar = RadarConfig() if settings.tx_power_dbm is None else RadarConfig(tx_power_dbm=settings.tx_power_dbm)
    hs = hall_scenario(settings.scene, ue_position=ue, radar=radar,
                       trace=TraceSettings(max_depth=settings.depth, samples_per_src=settings.samples))
    with warnings.catch_warnings(record=True) as caught:  # e.g. range aliasing: kept per cell, not printed
        warnings.simplefilter("always")
        traced = hall_paths(hs, cache=TraceCache())
    cap = simulate(hs.base, rng=np.random.default_rng(0), paths=traced.paths, noise=False)
    pattern = cap.ris.beam_pattern()
    crb = point_bound(cap.cube, radar=cap.radar, sweep=cap.sweep, pattern=pattern, pose=cap.ris.pose,
                      truth=cap.truth, loopback_delay=cap.ris.loopback_delay)
    run_params = {"estimator": settings.estimator, "pfa": 1e-3,
                  "warnings": sorted({str(w.message).split(":")[0] for w in caught})}
    return PreparedPoint(params=run_params, cube=cap.cube, radar=cap.radar, sweep=cap.sweep,
                         processing=cap.processing, pose=cap.ris.pose, loopback_delay=cap.ris.loopback_delay,
                         pattern=pattern, truth=cap.truth, crb=crb, seconds=time.perf_counter() - start)


@dataclass(frozen=True)
class _MapPlan:
    """A floor map as the study engine sees it: one point per cell, ``runs`` runs each."""

    settings: MapSettings
    cells: tuple[tuple[float, float, float], ...]

    @property
    def name(self) -> str:
        return f"map {self.settings.scene}"

    @property
    def runs(self) -> int:
        return self.settings.runs

    @property
    def seed(self) -> int:
        return self.settings.seed

    @property
    def key(self) -> str:
        return self.settings.key

    def points(self) -> list[dict[str, Any]]:
        common = _cell_settings(self.settings)
        return [{"cell": c, "ue": list(ue), "settings": common} for c, ue in enumerate(self.cells)]


@dataclass(frozen=True)
class MapResult:
    """What a finished floor map wrote.

    Attributes
    ----------
    cells : list of dict
        One entry per cell (``map.json``): position ``x``, ``y``, ``z`` [m], ``runs``,
        ``detection_probability``, ``rmse_position`` [m] (None without a detection), ``peb`` [m],
        ``peak_snr_db`` [dB], ``dominant_flag``, ``flags`` (counts), ``trace_warnings``.
    folder : Path
    figure : Path
        ``map.png``.
    wall_seconds : float
        Wall-clock time of the runs [s].
    devices : list of dict
        What ran this sitting's runs (``map.json``'s ``devices``: :func:`risloc_rt.io.report.run_environment`
        of each distinct device); empty when every run was already in the log.
    """

    cells: list[dict[str, Any]]
    folder: Path
    figure: Path
    wall_seconds: float
    devices: list[dict[str, Any]] = field(default_factory=list)

    def describe(self) -> str:
        """One line for the terminal.

        Returns
        -------
        str
            Cells, detections, median and worst position RMSE [mm], wall time [s], the files.
        """
        det = [c for c in self.cells if c["detection_probability"] > 0]
        rmse = [c["rmse_position"] for c in det if c["rmse_position"] is not None]
        return (f"{len(self.cells)} cells, detected in {len(det)}; position RMSE median "
                f"{1e3 * float(np.median(rmse)) if rmse else float('nan'):.1f} mm, worst "
                f"{1e3 * max(rmse) if rmse else float('nan'):.1f} mm; {self.wall_seconds:.0f} s -> "
                f"{self.folder}/map.json, map.parquet, map.png")


def run_map(settings: MapSettings, out: str | Path, *, workers: int | None = None, dask: Any = None,
            quiet: bool = False, force: bool = False, force_long: bool = False,
            force_workers: bool = False, device: str | None = None) -> MapResult:
    """Run (or continue) a floor map in folder ``out``.

    The cells are the points of a study (:mod:`risloc_rt.studies.engine`, point preparer
    :func:`prepare_cell`): batches of runs on ``workers`` processes (each traces its cells through
    the shared trace cache) or on a Dask cluster, resumable run by run.

    Parameters
    ----------
    settings : MapSettings
    out : path
        The map's folder: created, or reopened to continue the same map.
    workers : int, optional
        Local worker processes (default: all cores); 1 runs in this process.
    dask : str or distributed.Client, optional
        A Dask scheduler address or client: run the batches there instead.
    quiet : bool
        No progress bar.
    force : bool
        Use a folder that holds another floor map (or other files).
    force_long : bool
        Run a map of more than :data:`MAX_GRID_POINTS` grid points, or one expected to take longer
        than a day (``--force-long``).
    force_workers : bool
        Keep ``workers`` above the core count (``--force-workers``).
    device : {"cpu", "cuda", "auto"}, optional
        Where the runs' noise and detector go (``--device``; default ``$RISLOC_DEVICE``, else ``cpu``):
        :func:`risloc_rt.studies.engine.run_batch`. On a given device the rows do not depend on it
        otherwise (batch size, workers, Dask); on another device the noise is another stream with
        the same law (``docs/studies.md``).

    Returns
    -------
    MapResult

    Raises
    ------
    StudyFolderError
        ``out`` holds something else and ``force`` is not given.
    ValueError
        ``workers`` < 1, or no cell qualifies (:func:`grid_cells`).
    dsp.budget.BudgetError
        The grid (:func:`grid_budget`), the runs or ``force_workers``'s workers exceed the memory limit.
    StudyError
        More than :data:`MAX_GRID_POINTS` grid points, or more than a day expected, without ``force_long``.
    """
    if dask is None:
        workers = choose_workers(workers, insist=force_workers)
    else:  # batch sizes only: the cluster's threads are the parallelism
        workers = choose_workers(workers, insist=True) if workers is not None else default_workers()
    grid_budget(settings, long_ok=force_long)
    folder = Path(out)
    device, stream = study_device(device, local=dask is None)  # one line before any folder is made
    manifest = folder / "map-study.json"
    if manifest.exists():
        old_manifest = json.loads(manifest.read_text())
        old = old_manifest.get("key")
        if old == settings.key:
            check_stream(folder, old_manifest, stream, folder / "runs.jsonl")
        else:
            if not force:
                raise StudyFolderError(f"{str(folder)!r} holds another floor map (key {old}); use a new --out or "
                                       f"--force (the old log is kept as runs-{old}.jsonl, or runs-{old}-N.jsonl)")
            if (folder / "runs.jsonl").exists():  # its rows are another map's cells: keep them, never reuse them
                kept = keep_log(folder / "runs.jsonl", str(old))
                print(f"note: {str(folder)!r} held another floor map (key {old}); its run log is kept as "
                      f"{str(kept)!r}", file=sys.stderr)
    elif folder.is_dir() and any(folder.iterdir()) and not force:
        raise StudyFolderError(f"{str(folder)!r} is not empty and holds no floor map; use a new --out folder")
    spec, cells, _ = grid_cells(settings, long_ok=force_long)
    plan = _MapPlan(settings, tuple(tuple(map(float, ue)) for ue in cells))
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(manifest, json.dumps({"key": settings.key, "settings": asdict(settings),
                                             "noise_stream": stream}).encode(), sync=True)
    log = RunLog(folder / "runs.jsonl").open()
    start = time.perf_counter()
    try:
        info = execute(plan, log, prepare=prepare_cell, workers=workers, dask=dask, quiet=quiet, long_ok=force_long,
                       device=device)
        out_cells = []
        for c, ue in enumerate(cells):
            rows = [log.rows[(c, r)] for r in range(settings.runs)]
            err = np.array([x["position_error"] for x in rows if x["detected"] and x["position_error"] is not None],
                           float)
            flags = Counter(f for x in rows for f in (x.get("flags") or "").split(",")
                            if f and f != "elevation-assumed")
            crb = info["crb"][c]
            out_cells.append({
                "x": float(ue[0]), "y": float(ue[1]), "z": float(ue[2]), "runs": len(rows),
                "detection_probability": sum(bool(x["detected"]) for x in rows) / len(rows),
                "rmse_position": float(np.sqrt(np.mean(err**2))) if err.size else None,
                "peb": crb["position"], "peak_snr_db": crb["peak_snr_db"],
                "dominant_flag": flags.most_common(1)[0][0] if flags else "none", "flags": dict(flags),
                "trace_warnings": info["warnings"].get(c, []),
            })
    finally:
        log.close()
    wall = time.perf_counter() - start
    import pyarrow as pa
    import pyarrow.parquet as pq

    buf_pq = io.BytesIO()
    cols = {k: [json.dumps(c[k]) if k in ("flags", "trace_warnings") else c[k] for c in out_cells] for k in out_cells[0]}
    pq.write_table(pa.table(cols), buf_pq)
    # moved in together (risloc_rt._outputs); the folder is the map's (its manifest was checked)
    with output_folder(folder, force=True, flag="--out") as stage:
        atomic_write_bytes(stage / "map.json", json.dumps({"settings": asdict(settings), "devices": info["devices"],
                                                           "cells": out_cells},
                                                          indent=1).encode() + b"\n")
        atomic_write_bytes(stage / "map.parquet", buf_pq.getvalue())
        plot_map(spec, out_cells, settings, stage / "map.png")
    return MapResult(cells=out_cells, folder=folder, figure=folder / "map.png", wall_seconds=wall,
                     devices=info["devices"])

