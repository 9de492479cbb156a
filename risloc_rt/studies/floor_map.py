"""``risloc study map``: position RMSE, detection probability, PEB and the dominant flag over a hall's floor.

Radar positions on a square grid over the hall's footprint at one height (``margin`` from the
walls, outside objects, within the RIS's sweep fan); each cell is traced (``hall_paths`` with the
trace cache: a rerun traces nothing), its noiseless cube synthesised once, and ``runs`` noise
realizations localized (``kernel.run_once``, the noise of run r of cell c from
``SeedSequence(seed, spawn_key=(c, r))``). The cells run on the sweeps' engine (worker processes or
Dask, retried when a worker dies) and the runs are appended to ``runs.jsonl`` as in a sweep, so a
killed map continues and the numbers do not depend on the number of workers. Outputs: ``map.json`` (one entry per cell), ``map.parquet`` and ``map.png``.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import time
import warnings
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._files import atomic_write_bytes
from .kernel import PreparedPoint, point_bound
from .store import RunLog, StudyFolderError

__all__ = ["MapSettings", "MapResult", "run_map", "grid_cells"]


@dataclass(frozen=True)
class MapSettings:
    """A floor map: hall, grid spacing [m], radar height above the floor [m], runs per cell, ..."""

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
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"--{name} {v!r} must be a positive number of metres")
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise ValueError(f"--margin {self.margin!r} must be >= 0 m")
        if self.runs < 1:
            raise ValueError(f"--runs {self.runs} must be >= 1")
        if self.estimator not in ("paper", "refined"):
            raise ValueError(f"--estimator {self.estimator!r} must be 'paper' or 'refined'")

    @property
    def key(self) -> str:
        d = asdict(self)
        d.pop("runs")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def grid_cells(settings: MapSettings) -> tuple[Any, np.ndarray, np.ndarray]:
    """(spec, cells [C, 3] inside the footprint, away from walls and objects, within the sweep fan, mask)."""
    from ..authoring.geometry import load_geometry
    from ..authoring.polygon import boundary_distance, contains
    from ..authoring.scene_folder import scene_directory
    from ..authoring.spec import load_spec

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
    """Trace one cell (through the trace cache), synthesise its noiseless cube once, and its bound.

    ``params``: ``{"map_cell": index, "ue": [x, y, z], "settings": {...}}`` as :class:`_MapPlan`
    makes them (plain data: a worker process or a Dask worker rebuilds the cell from them).
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
        return [{"map_cell": c, "ue": list(ue), "settings": common} for c, ue in enumerate(self.cells)]


@dataclass(frozen=True)
class MapResult:
    cells: list[dict[str, Any]]
    folder: Path
    figure: Path
    wall_seconds: float

    def describe(self) -> str:
        det = [c for c in self.cells if c["detection_probability"] > 0]
        rmse = [c["rmse_position"] for c in det if c["rmse_position"] is not None]
        return (f"{len(self.cells)} cells, detected in {len(det)}; position RMSE median "
                f"{1e3 * float(np.median(rmse)) if rmse else float('nan'):.1f} mm, worst "
                f"{1e3 * max(rmse) if rmse else float('nan'):.1f} mm; {self.wall_seconds:.0f} s -> "
                f"{self.folder}/map.json, map.parquet, map.png")


def run_map(settings: MapSettings, out: str | Path, *, workers: int | None = None, dask: Any = None,
            quiet: bool = False, force: bool = False) -> MapResult:
    """Run (or continue) a floor map in folder ``out``.

    The cells are the points of a study (:mod:`risloc_rt.studies.engine`): batches of runs on
    ``workers`` processes (default: all cores; each traces its cells through the shared trace cache)
    or on a Dask cluster (``dask``: an address or a ``distributed.Client``), resumable run by run.
    """
    from .engine import default_workers, execute

    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise ValueError(f"--workers {workers} must be >= 1")
    workers = int(workers) if workers is not None else default_workers()
    folder = Path(out)
    manifest = folder / "map-study.json"
    if manifest.exists():
        old = json.loads(manifest.read_text()).get("key")
        if old != settings.key and not force:
            raise StudyFolderError(f"{str(folder)!r} holds another floor map (key {old}); use a new --out or --force")
    elif folder.is_dir() and any(folder.iterdir()) and not force:
        raise StudyFolderError(f"{str(folder)!r} is not empty and holds no floor map; use a new --out folder")
    spec, cells, _ = grid_cells(settings)
    plan = _MapPlan(settings, tuple(tuple(map(float, ue)) for ue in cells))
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(manifest, json.dumps({"key": settings.key, "settings": asdict(settings)}).encode(), sync=True)
    log = RunLog(folder / "runs.jsonl").open()
    start = time.perf_counter()
    try:
        info = execute(plan, log, workers=workers, dask=dask, quiet=quiet)
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
    atomic_write_bytes(folder / "map.json", json.dumps({"settings": asdict(settings), "cells": out_cells},
                                                       indent=1).encode() + b"\n")
    import pyarrow as pa
    import pyarrow.parquet as pq

    buf_pq = io.BytesIO()
    cols = {k: [json.dumps(c[k]) if k in ("flags", "trace_warnings") else c[k] for c in out_cells] for k in out_cells[0]}
    pq.write_table(pa.table(cols), buf_pq)
    atomic_write_bytes(folder / "map.parquet", buf_pq.getvalue())
    fig = plot_map(spec, out_cells, settings, folder / "map.png")
    return MapResult(cells=out_cells, folder=folder, figure=fig, wall_seconds=wall)


def plot_map(spec: Any, cells: list[dict[str, Any]], settings: MapSettings, path: Path) -> Path:
    """Four heat maps over the hall outline: position RMSE, detection probability, PEB, dominant flag."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon, Rectangle

    from dsp import direction_from_angles

    poly = np.array(spec.footprint, dtype=float)
    xs = np.array([c["x"] for c in cells])
    ys = np.array([c["y"] for c in cells])
    s = settings.spacing
    flags = sorted({c["dominant_flag"] for c in cells})
    panels = [("position RMSE [m]", [c["rmse_position"] if c["rmse_position"] is not None else np.nan for c in cells], "log"),
              ("detection probability", [c["detection_probability"] for c in cells], "lin"),
              ("PEB (CRB) [m]", [c["peb"] for c in cells], "log"),
              ("dominant flag", [flags.index(c["dominant_flag"]) for c in cells], "cat")]
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    ris = spec.ris_configs()[0]
    for ax, (title, values, scale) in zip(axes.ravel(), panels):
        v = np.array(values, dtype=float)
        norm = matplotlib.colors.LogNorm() if scale == "log" and np.nanmax(v) > 0 else None
        cmap = "tab10" if scale == "cat" else ("viridis_r" if scale == "log" else "viridis")
        x0, y0 = xs.min(), ys.min()
        ix = np.rint((xs - x0) / s).astype(int)
        iy = np.rint((ys - y0) / s).astype(int)
        img = np.full((iy.max() + 1, ix.max() + 1), np.nan)
        img[iy, ix] = v
        xe = x0 - s / 2 + s * np.arange(ix.max() + 2)
        ye = y0 - s / 2 + s * np.arange(iy.max() + 2)
        sc = ax.pcolormesh(xe, ye, np.ma.masked_invalid(img), cmap=cmap, norm=norm,
                           vmin=None if norm is not None else (0 if scale == "cat" else 0.0),
                           vmax=None if norm is not None else (9 if scale == "cat" else 1.0))
        if scale == "cat":
            handles = [plt.Line2D([], [], marker="s", ls="", color=plt.get_cmap("tab10")(i / 9),
                                  label=f) for i, f in enumerate(flags)]
            ax.legend(handles=handles, fontsize=7, loc="upper left")
        else:
            fig.colorbar(sc, ax=ax)
        ax.add_patch(Polygon(poly, closed=True, fill=False, lw=2, color="k"))
        for ob in spec.objects:
            if hasattr(ob, "radius"):
                ax.add_patch(Circle(ob.center[:2], ob.radius, color="0.4"))
            elif hasattr(ob, "size"):
                ax.add_patch(Rectangle((ob.center[0] - ob.size[0] / 2, ob.center[1] - ob.size[1] / 2), ob.size[0],
                                       ob.size[1], angle=np.rad2deg(getattr(ob, "yaw", 0.0)), rotation_point="center",
                                       color="0.4"))
        p = ris.pose.position
        n = ris.pose.to_world(direction_from_angles(np.zeros(2)))  # boresight
        ax.plot(p[0], p[1], "r^", ms=10)
        ax.annotate("", xy=(p[0] + 2 * n[0], p[1] + 2 * n[1]), xytext=(p[0], p[1]), arrowprops={"color": "r"})
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    fig.suptitle(f"{settings.scene}: {len(cells)} cells, {settings.spacing:g} m grid at {settings.height:g} m, "
                 f"{settings.runs} runs each, {settings.estimator} estimator (RIS: red)")
    b = io.BytesIO()
    fig.savefig(b, format="png", dpi=100)
    plt.close(fig)
    return atomic_write_bytes(path, b.getvalue())
