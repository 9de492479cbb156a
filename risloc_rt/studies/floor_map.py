"""``risloc study map``: position RMSE, detection probability, PEB, the serving RIS and the coverage over a hall's floor.

Radar positions on a square grid over the hall's footprint at one height (``margin`` from the
walls, outside objects, at least 1 m from every RIS): the *floor cells*. A RIS *sees* a floor cell
that lies in front of its panel within its ±45° sweep; the cells seen by at least one RIS are
mapped, the others (``coverage["unseen"]`` of ``map.json``) count as floor that is not covered.

**Several RISs: time division.** Each RIS sweeps in its own slot while the others are off
(:func:`risloc_rt.hall.hall_scenario` with ``ris=k``, ``idle="off"``: the slot
:func:`risloc_rt.hall.scenario.hall_slots` makes; their panels are echoes of the hall). A study *point* is a
(cell, RIS) pair, in cell order and then the spec's RIS order, for each RIS that sees the cell: each
is traced (``hall_paths`` with the trace cache: a rerun traces nothing), its noiseless cube
synthesised once and ``runs`` noise realizations localized (``kernel.run_once``; the noise of run r
of point p from ``SeedSequence(seed, spawn_key=(p, r))``). In a one-RIS scene the points are the
cells, as before issue 22: the same rows for the same seed. The points run on the sweeps' engine
(:func:`risloc_rt.studies.engine.execute` with :func:`prepare_cell` as the point preparer: worker
processes or Dask, retried when a worker dies) and go to ``runs.jsonl`` as in a sweep, so a killed map
continues and the numbers do not depend on the number of workers.

**Per cell and run** (:func:`cell_run_position`): each detected RIS gives a ``dsp.RisFix`` (its
distance and azimuth with their stated 1σ; the 1-D sweep sees no elevation); one fix is the
position as ``dsp.self_localize`` gave it; two or more are fused by ``dsp.fuse_fixes`` with the radar's height
known (the map's height, one more measurement: :func:`fuse_at_height`; RISs at one height leave the
height unobservable, and a known height is what the single-RIS fix uses): its χ² test leaves out an
inconsistent one (flag ``inconsistent-ris``).
**Folded returns**: a radar beyond a RIS's unambiguous range sees its return folded to d - R_max,
a wrong fix the DSP does not flag; the map applies ``risloc locate``'s link-budget check to every
detected run (:func:`folded_return`) and a fix it flags ``aliased`` gives no position (the run counts
the flag); nor does a fix at or below zero distance (a return folded to just before the loop-back
delay). **Per cell**: ``detection_probability`` (runs with a position: at least one RIS detected and
not folded), ``rmse_position`` (over those runs), ``peb`` (the bound of the geometry:
:func:`multi_ris_peb`, the summed Fisher information of the RISs that see the cell), ``served_by``
(the RIS with the smallest single-RIS PEB among those detected in at least half the runs; None when
none is) and ``ris`` (each seeing RIS's own Pd, PEB, peak SNR and RMSE). **Coverage**: the share of
the floor cells with ``detection_probability >= 0.99`` and ``peb < peb_bound`` (:func:`coverage`;
also the share whose RMSE is under the bound too). ``points.json`` keeps every point's bounds, so a
finished map reopened (e.g. with another ``peb_bound``) prepares nothing again.
Outputs: ``map.json`` (one entry per mapped cell, and ``coverage``), ``map.parquet`` and ``map.png``
(:func:`risloc_rt.studies.figures.plot_map`). The per-cell and per-run functions live in
:mod:`risloc_rt.studies.floor_cells` (re-exported here).
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
from .engine import check_rows_memory, choose_workers, default_workers, execute
from .figures import plot_map
from .floor_cells import (COVERED_PD, HEIGHT_STD, cell_run_position, coverage, folded_return, fuse_at_height,
                          multi_ris_peb, usable_run)
from .kernel import PreparedPoint, point_bound
from .store import RunLog, StudyFolderError, check_stream, devices_path, keep_log, study_device

__all__ = ["MapSettings", "MapResult", "run_map", "grid_cells", "floor_grid", "grid_budget", "prepare_cell",
           "multi_ris_peb", "fuse_at_height", "HEIGHT_STD", "cell_run_position", "folded_return", "coverage", "MAX_GRID_POINTS",
           "COVERED_PD", "DEFAULT_PEB_BOUND"]

#: More grid points than this (before the cells are chosen) are refused unless ``force_long``: each
#: cell is a trace and ``runs`` runs (≈ 14 s of one core at 20 runs), so 10⁵ cells are weeks.
MAX_GRID_POINTS = 100_000
#: The default PEB bound of the coverage [m] (``--peb-bound``; docs/studies.md, "Coverage").
DEFAULT_PEB_BOUND = 0.05


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
    ris : tuple of str
        The RISs that sweep (names in the spec; empty: every RIS of the scene).
    peb_bound : float
        The coverage's PEB bound [m] (a cell is covered with Pd >= :data:`COVERED_PD` and PEB below it).
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
    ris: tuple[str, ...] = ()
    peb_bound: float = DEFAULT_PEB_BOUND

    def __post_init__(self) -> None:
        for name in ("spacing", "height"):
            positive(getattr(self, name), f"--{name}", "m", error=ValueError)
        positive(self.peb_bound, "--peb-bound", "m", error=ValueError)
        names = (self.ris,) if isinstance(self.ris, str) else tuple(self.ris)
        if len(set(names)) != len(names):
            raise ValueError(f"--ris names a RIS twice ({', '.join(names)}); give each RIS once")
        object.__setattr__(self, "ris", tuple(str(n) for n in names))
        non_negative(self.margin, "--margin", "m", error=ValueError)
        integer(self.runs, "--runs", minimum=1, error=ValueError)
        one_of(self.estimator, "--estimator", ("paper", "refined"), error=ValueError)

    @property
    def key(self) -> str:
        """sha256 of every setting but ``runs`` (more runs extend a map) and ``peb_bound`` (read after the
        runs), 16 hex digits; ``ris`` only when given (a map of every RIS keeps its key from before issue 22)."""
        d = asdict(self)
        d.pop("runs")
        d.pop("peb_bound")
        if not d["ris"]:
            d.pop("ris")
        else:
            d["ris"] = list(d["ris"])
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


@dataclass(frozen=True)
class FloorGrid:
    """The floor cells of a map and which RIS sees which (:func:`floor_grid`).

    Attributes
    ----------
    spec : risloc_rt.authoring.spec.HallSpec
        The hall's spec.
    positions : ndarray, shape (P, 3)
        Every grid point (x-major over the footprint's bounding box) at the map's height [m].
    floor : ndarray of bool, shape (P,)
        Floor cells: inside the footprint, ``margin`` from walls and objects, at least 1 m from every RIS.
    sees : ndarray of bool, shape (P, R)
        RIS k (of ``names``) sees point p: a floor cell in front of its panel within its ±45° sweep.
    names : tuple of str
        The RISs that sweep (``settings.ris``, or every RIS), in the spec's order.
    indices : tuple of int
        Their indices in the spec.
    """

    spec: Any
    positions: np.ndarray
    floor: np.ndarray
    sees: np.ndarray
    names: tuple[str, ...]
    indices: tuple[int, ...]


def floor_grid(settings: MapSettings, *, long_ok: bool = False) -> FloorGrid:
    """The floor cells of a map and, for each RIS that sweeps, the cells it sees.

    Parameters
    ----------
    settings : MapSettings
        The hall, ``spacing``, ``height`` and ``margin`` [m], ``ris`` (names; empty: every RIS).
    long_ok : bool
        Allow more than :data:`MAX_GRID_POINTS` grid points (:func:`grid_budget`, checked first).

    Returns
    -------
    FloorGrid

    Raises
    ------
    ValueError
        A name of ``settings.ris`` the spec does not have (one line naming the RISs it has), or the
        scene has no RIS.
    dsp.budget.BudgetError, StudyError
        The grid is too large (:func:`grid_budget`).
    """
    from ..authoring.geometry import load_geometry
    from ..authoring.polygon import boundary_distance, contains
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec
    from ..hall.scenario import ris_index

    grid_budget(settings, long_ok=long_ok)
    folder = scene_directory(settings.scene)
    spec = load_spec(folder / "spec.toml")
    configs = spec.ris_configs()
    if not configs:
        raise ValueError(f"scene {settings.scene!r} has no RIS; add a [[ris]] table to its spec")
    indices = sorted({ris_index(spec, name, where="--ris") for name in settings.ris}) if settings.ris \
        else list(range(len(configs)))
    poly = np.array(spec.footprint, dtype=float)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    xs = np.arange(lo[0] + settings.spacing / 2, hi[0], settings.spacing)
    ys = np.arange(lo[1] + settings.spacing / 2, hi[1], settings.spacing)
    xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    floor = contains(poly, xy) & (boundary_distance(poly, xy) >= settings.margin)
    pts = np.column_stack([xy, np.full(len(xy), settings.height)])
    geometry = load_geometry(folder / "scene.xml")
    sees = np.zeros((len(xy), len(indices)), dtype=bool)
    for i in np.flatnonzero(floor):
        try:
            geometry.check_point(pts[i], clearance=settings.margin)
        except ValueError:
            floor[i] = False
            continue
        if any(np.linalg.norm(pts[i] - ris.pose.position) < 1.0 for ris in configs):  # too near a panel
            floor[i] = False
            continue
        for j, k in enumerate(indices):
            ris = configs[k]
            az, _ = ris.pose.angles_to(pts[i])
            front = ris.pose.to_local(pts[i] - ris.pose.position)[2] > 0
            sees[i, j] = bool(front and abs(az) <= np.deg2rad(45.0))
    return FloorGrid(spec=spec, positions=pts, floor=floor, sees=sees,
                     names=tuple(spec.ris[k].name for k in indices), indices=tuple(indices))


def grid_cells(settings: MapSettings, *, long_ok: bool = False) -> tuple[Any, np.ndarray, np.ndarray]:
    """The mapped cells: floor cells (inside the footprint, away from walls, objects and RISs) that some RIS sees.

    Parameters
    ----------
    settings : MapSettings
        The hall, ``spacing``, ``height`` and ``margin`` [m], ``ris``.
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
        No grid point qualifies, or a RIS of ``settings.ris`` the spec does not have.
    dsp.budget.BudgetError, StudyError
        The grid is too large (:func:`grid_budget`).
    """
    grid = floor_grid(settings, long_ok=long_ok)
    keep = grid.floor & grid.sees.any(axis=1)
    if not keep.any():
        raise ValueError(f"no grid cell of {settings.scene!r} lies inside the hall, {settings.margin:g} m from its walls "
                         "and objects and within a RIS's ±45° sweep; use a smaller --spacing or --margin")
    return grid.spec, grid.positions[keep], keep


def _cell_settings(settings: MapSettings) -> dict[str, Any]:
    """What a cell's cube depends on (not ``runs``, ``seed`` or ``estimator``: those are per run; not
    ``ris`` or ``peb_bound``: a point names its RIS, the bound is read after the runs)."""
    d = asdict(settings)
    for name in ("runs", "seed", "ris", "peb_bound"):
        d.pop(name)
    return d


def prepare_cell(params: dict[str, Any]) -> PreparedPoint:
    """The floor map's point preparer: trace one cell in one RIS's slot (through the trace cache), synthesise
    its noiseless cube once, and its bound.

    Parameters
    ----------
    params : dict
        ``{"cell": index, "ue": [x, y, z] (radar position [m]), "ris": k (the spec's index of the RIS that
        sweeps; default 0), "settings": {...}}`` as :class:`_MapPlan` makes them (plain data: a worker
        process or a Dask worker rebuilds the cell from them). The other RISs of the scene are off in
        this slot (time division), their panels echoes of the hall.

    Returns
    -------
    PreparedPoint
        The cell's noiseless cube [√W], its bounds (``crb``: m, rad, m/s; ``peak_snr_db`` [dB]) and,
        in ``params["warnings"]``, the tracer's warnings (e.g. range aliasing) instead of printing them.
    """
    from dsp import RadarConfig

    from ..hall import hall_paths, hall_scenario
    from ..hall.raytrace import TraceCache, TraceSettings
    from ..hall.scenario import FLOOR_HEIGHT
    from ..model import simulate

    start = time.perf_counter()
    settings = MapSettings(**params["settings"])
    ue = np.asarray(params["ue"], dtype=float)
    radar = RadarConfig() if settings.tx_power_dbm is None else RadarConfig(tx_power_dbm=settings.tx_power_dbm)
    hs = hall_scenario(settings.scene, ue_position=ue, radar=radar, ris=int(params.get("ris", 0)), idle="off",
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
                         pattern=pattern, truth=cap.truth, crb=crb, seconds=time.perf_counter() - start,
                         floor_height=FLOOR_HEIGHT)


@dataclass(frozen=True)
class _MapPlan:
    """A floor map as the study engine sees it: one point per (cell, RIS that sees it), ``runs`` runs each."""

    settings: MapSettings
    cells: tuple[tuple[float, float, float], ...]
    pairs: tuple[tuple[int, int], ...]  # (cell, spec index of the RIS), point order

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
        return [{"cell": c, "ue": list(self.cells[c]), "ris": k, "settings": common} for c, k in self.pairs]


@dataclass(frozen=True)
class MapResult:
    """What a finished floor map wrote.

    Attributes
    ----------
    cells : list of dict
        One entry per cell (``map.json``): position ``x``, ``y``, ``z`` [m], ``runs``,
        ``detection_probability``, ``rmse_position`` [m] (None without a detection), ``peb`` [m],
        ``peak_snr_db`` [dB], ``dominant_flag``, ``flags`` (counts), ``trace_warnings``, ``served_by``
        (a RIS name or None) and ``ris`` (per RIS that sees the cell: its own ``detection_probability``,
        ``peb`` [m], ``peak_snr_db`` [dB], ``rmse_position`` [m]); the module notes say how several
        RISs are combined.
    folder : Path
    figure : Path
        ``map.png``.
    wall_seconds : float
        Wall-clock time of the runs [s].
    devices : list of dict
        What ran the map's runs, every sitting's (``map.json``'s ``devices``: :func:`risloc_rt.io.report.run_environment`
        of each distinct device, as the folder's ``devices-<key>.json`` records them); empty only for a
        log written before they were recorded.
    coverage : dict
        The floor's coverage (:func:`coverage`).
    new_runs : int
        Runs computed in this sitting (0: every run was already in the log).
    """

    cells: list[dict[str, Any]]
    folder: Path
    figure: Path
    wall_seconds: float
    devices: list[dict[str, Any]] = field(default_factory=list)
    coverage: dict[str, Any] = field(default_factory=dict)
    new_runs: int = 0

    def describe(self) -> str:
        """One line for the terminal.

        Returns
        -------
        str
            Cells, detections, median and worst position RMSE [mm], the coverage, wall time [s], the files.
        """
        det = [c for c in self.cells if c["detection_probability"] > 0]
        rmse = [c["rmse_position"] for c in det if c["rmse_position"] is not None]
        cov = self.coverage
        covered = (f"; coverage {100 * cov['share']:.1f} % of the floor ({cov['covered']} of {cov['floor_cells']} "
                   f"cells with Pd >= {cov['detection_probability']:g} and PEB < {1e3 * cov['peb_bound']:g} mm; "
                   f"{100 * cov['share_accurate']:.1f} % with the RMSE below it too)" if cov else "")
        return (f"{len(self.cells)} cells, detected in {len(det)}; position RMSE median "
                f"{1e3 * float(np.median(rmse)) if rmse else float('nan'):.1f} mm, worst "
                f"{1e3 * max(rmse) if rmse else float('nan'):.1f} mm{covered}; {self.wall_seconds:.0f} s -> "
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
            stream = check_stream(folder, old_manifest, stream, folder / "runs.jsonl")
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
    grid = floor_grid(settings, long_ok=force_long)
    spec = grid.spec
    mapped = np.flatnonzero(grid.floor & grid.sees.any(axis=1))
    if not mapped.size:
        raise ValueError(f"no grid cell of {settings.scene!r} lies inside the hall, {settings.margin:g} m from its walls "
                         "and objects and within a RIS's ±45° sweep; use a smaller --spacing or --margin")
    cells = grid.positions[mapped]
    sees = grid.sees[mapped]
    pairs = tuple((c, grid.indices[j]) for c in range(len(cells)) for j in range(len(grid.indices)) if sees[c, j])
    unseen = grid.positions[grid.floor & ~grid.sees.any(axis=1)]
    plan = _MapPlan(settings, tuple(tuple(map(float, ue)) for ue in cells), pairs)
    check_rows_memory(plan.name, len(pairs), settings.runs)  # a --runs beyond memory: nothing made yet
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(manifest, json.dumps({"key": settings.key, "settings": asdict(settings),
                                             "noise_stream": stream}).encode(), sync=True)
    log = RunLog(folder / "runs.jsonl", devices_file=devices_path(folder, settings.key)).open()
    log.noise_stream = stream
    start = time.perf_counter()
    try:
        saved = _saved_points(folder / "points.json", settings, spec, pairs)
        if saved is not None and all((p, r) in log.rows for p in range(len(pairs)) for r in range(settings.runs)):
            # every run is in the log and every point's bounds in points.json: nothing to prepare again
            info = {"crb": {p: x["crb"] for p, x in enumerate(saved)},
                    "warnings": {p: x["warnings"] for p, x in enumerate(saved)}, "devices": []}
        else:
            info = execute(plan, log, prepare=prepare_cell, workers=workers, dask=dask, quiet=quiet,
                           long_ok=force_long, device=device)
        # every point's bounds beside its runs: map.json can be remade from the folder alone
        atomic_write_bytes(folder / "points.json", json.dumps({
            "key": settings.key, "points": [{"cell": c, "ris": spec.ris[k].name, "crb": info["crb"][p],
                                             "warnings": info["warnings"].get(p, [])}
                                            for p, (c, k) in enumerate(pairs)]}).encode())
        out_cells = _cells(settings, spec, cells, pairs, log, info)
    finally:
        log.close()
    wall = time.perf_counter() - start
    import pyarrow as pa
    import pyarrow.parquet as pq

    buf_pq = io.BytesIO()
    cols = {k: [json.dumps(c[k]) if k in ("flags", "trace_warnings", "ris") else c[k] for c in out_cells]
            for k in out_cells[0]}
    cover = coverage(out_cells, int(grid.floor.sum()), settings.peb_bound)
    pq.write_table(pa.table(cols), buf_pq)
    # moved in together (risloc_rt._outputs); the folder is the map's (its manifest was checked)
    with output_folder(folder, force=True, flag="--out") as stage:
        atomic_write_bytes(stage / "map.json", json.dumps({
            "settings": asdict(settings), "devices": log.devices, "noise_stream": log.noise_stream,
            "ris": list(grid.names),
            "coverage": {**cover, "unseen": [[float(v) for v in ue] for ue in unseen]},
            "cells": out_cells}, indent=1).encode() + b"\n")
        atomic_write_bytes(stage / "map.parquet", buf_pq.getvalue())
        plot_map(spec, out_cells, settings, stage / "map.png", unseen=unseen, coverage=cover)
    return MapResult(cells=out_cells, folder=folder, figure=folder / "map.png", wall_seconds=wall,
                     devices=log.devices, coverage=cover, new_runs=int(info.get("new_runs", 0)))


def _saved_points(path: Path, settings: MapSettings, spec: Any, pairs: tuple[tuple[int, int], ...]) -> list | None:
    """The points' bounds a finished sitting left in ``points.json``, when they are this map's (same key, same
    (cell, RIS) points); None otherwise."""
    try:
        saved = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(saved, dict) or saved.get("key") != settings.key:
        return None
    points = saved.get("points")
    if not isinstance(points, list) or len(points) != len(pairs) or not all(
            isinstance(x, dict) and x.get("cell") == c and x.get("ris") == spec.ris[k].name
            and isinstance(x.get("crb"), dict) for x, (c, k) in zip(points, pairs)):
        return None
    return points


def _cells(settings: MapSettings, spec: Any, cells: np.ndarray, pairs: tuple[tuple[int, int], ...], log: RunLog,
           info: dict[str, Any]) -> list[dict[str, Any]]:
    """The per-cell entries of ``map.json`` from the run log and the points' bounds (module notes)."""
    from dsp import RadarConfig

    from ..hall import hall_scenario

    configs = spec.ris_configs()
    radar = RadarConfig() if settings.tx_power_dbm is None else RadarConfig(tx_power_dbm=settings.tx_power_dbm)
    by_cell: dict[int, list[tuple[int, int]]] = {}
    for p, (c, k) in enumerate(pairs):
        by_cell.setdefault(c, []).append((p, k))
    out_cells = []
    for c, ue in enumerate(cells):
        points = by_cell[c]
        runs = {p: [log.rows[(p, r)] for r in range(settings.runs)] for p, _ in points}
        for p, k in points:  # the link-budget alias check of risloc locate (folded_return)
            if not any(x["detected"] for x in runs[p]):
                continue
            base = hall_scenario(settings.scene, ris=k, ue_position=ue, radar=radar).base
            marked = []
            for x in runs[p]:
                flag = folded_return(x, base, configs[k].pose, info["crb"][p]["peak_snr_db"])
                if flag is not None:
                    codes = [f for f in (x.get("flags") or "").split(",") if f]
                    x = {**x, "folded": True, "flags": ",".join(codes + ["aliased"] * ("aliased" not in codes))}
                marked.append(x)
            runs[p] = marked
        flags = Counter(f for rows in runs.values() for x in rows for f in (x.get("flags") or "").split(",")
                        if f and f != "elevation-assumed")
        own: dict[str, dict[str, Any]] = {}
        for p, k in points:
            err = np.array([x["position_error"] for x in runs[p] if usable_run(x) and x["position_error"] is not None],
                           float)
            crb = info["crb"][p]
            own[spec.ris[k].name] = {
                "detection_probability": sum(usable_run(x) for x in runs[p]) / len(runs[p]),
                "rmse_position": float(np.sqrt(np.mean(err**2))) if err.size else None,
                "peb": crb["position"], "peak_snr_db": crb["peak_snr_db"]}
        if len(points) == 1:  # one RIS sees the cell: its own numbers (as before issue 22)
            (p, k), = points
            crb = info["crb"][p]
            pd, rmse = own[spec.ris[k].name]["detection_probability"], own[spec.ris[k].name]["rmse_position"]
            peb, snr = crb["position"], crb["peak_snr_db"]
        else:
            errors = []
            for r in range(settings.runs):
                entries = [(spec.ris[k].name, configs[k].pose, runs[p][r]) for p, k in points]
                got = cell_run_position(entries, ue, settings.height)
                if got is None:
                    continue
                errors.append(got[0])
                if "inconsistent-ris" in got[3]:  # a RIS left out, or a compromise the test could not resolve
                    flags["inconsistent-ris"] += 1
            err = np.array([e for e in errors if np.isfinite(e)], float)
            pd = len(errors) / settings.runs
            rmse = float(np.sqrt(np.mean(err**2))) if err.size else None
            peb = multi_ris_peb([(configs[k].pose, info["crb"][p]) for p, k in points], ue)
            snr = max(info["crb"][p]["peak_snr_db"] for p, _ in points)
        served = sorted((v["peb"], name) for name, v in own.items() if v["detection_probability"] >= 0.5)
        warned = sorted({w for p, _ in points for w in info["warnings"].get(p, [])})
        out_cells.append({
            "x": float(ue[0]), "y": float(ue[1]), "z": float(ue[2]), "runs": settings.runs,
            "detection_probability": pd, "rmse_position": rmse, "peb": peb, "peak_snr_db": snr,
            "dominant_flag": flags.most_common(1)[0][0] if flags else "none", "flags": dict(flags),
            "trace_warnings": warned, "served_by": served[0][1] if served else None, "ris": own,
        })
    return out_cells

