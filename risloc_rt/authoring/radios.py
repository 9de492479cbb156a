"""RIS panels and radar positions of a hall spec (``[[ris]]`` and ``[radar]``; schema in :mod:`.spec`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from dsp import SPEED_OF_LIGHT, RisPose

from . import polygon
from ._parse import SpecError, Table, check_vector
from .materials import MaterialSpec, check_name, parse_material

if TYPE_CHECKING:
    from ..model.ris import RisConfig

__all__ = ["RisPanel", "RisSpec", "RadarSpec", "check_grid_memory", "inside_hall", "parse_ris", "parse_radar"]

#: Bytes per radar position a spec keeps: a tuple of three floats in ``RadarSpec.positions`` (about
#: 120 B), its row of ``HallSpec.radar_positions()`` (24 B) and the list ``tuple()`` builds it from.
POSITION_BYTES = 160


@dataclass(frozen=True)
class RisPanel:
    """The RIS's physical plate (not written into the scene; modelled analytically).

    Attributes
    ----------
    width : float
        Extent along the RIS row axis **u** [m].
    height : float
        Extent along the column axis **w** [m].
    material : MaterialSpec
    """

    width: float = 0.10
    height: float = 0.05
    material: MaterialSpec = field(default_factory=lambda: MaterialSpec(name="metal-2mm", thickness=0.002, itu="metal"))


@dataclass(frozen=True)
class RisSpec:
    """One ``[[ris]]`` table in SI units.

    Attributes
    ----------
    name : str
    position : (float, float, float)
        Centre of the element grid [m].
    normal : (float, float, float)
        Unit broadside, after ``facing``/``normal`` and ``yaw_deg`` are applied.
    up : (float, float, float)
        Unit "up" giving the column axis (``dsp.RisPose``).
    rows, columns : int
        Elements along u and w.
    spacing : float
        Element pitch [m].
    amplification_db : float
        ζ [dB].
    loopback_delay : float
        τ_RB [s].
    mode : {"relay", "reflective"}
    relay_rx_toward : (float, float, float) or None
        Point the relay Rx beam is steered at [m]; ``None``: toward whichever radar position is
        simulated, as in the paper's experiment (the simulator applies it per radar).
    panel : RisPanel
    """

    name: str
    position: tuple[float, float, float]
    normal: tuple[float, float, float]
    up: tuple[float, float, float]
    rows: int
    columns: int
    spacing: float
    amplification_db: float
    loopback_delay: float
    mode: Literal["relay", "reflective"]
    relay_rx_toward: tuple[float, float, float] | None
    panel: RisPanel

    @property
    def pose(self) -> RisPose:
        """The panel's pose (``docs/conventions.md``)."""
        return RisPose(position=np.array(self.position), normal=np.array(self.normal), up=np.array(self.up))

    def to_config(self) -> "RisConfig":
        """The simulator's :class:`risloc_rt.model.ris.RisConfig`, relay Rx beam toward ``relay_rx_toward``
        (broadside when ``None``; :func:`risloc_rt.hall.hall_scenario` then points it at the radar)."""
        from ..model.ris import RisConfig

        cfg = RisConfig(pose=self.pose, num_rows=self.rows, num_columns=self.columns, element_spacing=self.spacing,
                        amplification_db=self.amplification_db, loopback_delay=self.loopback_delay, mode=self.mode)
        return cfg if self.relay_rx_toward is None else cfg.with_rx_toward(np.array(self.relay_rx_toward))


@dataclass(frozen=True)
class RadarSpec:
    """The ``[radar]`` table.

    Attributes
    ----------
    positions : tuple of (x, y, z)
        Radar (UE) positions [m], explicit or generated from ``grid``.
    facing : str or (float, float, float) or None
        A RIS name or a point the radar's boresight faces; ``None`` when there is no RIS.
    velocity : (float, float, float)
        [m/s].
    grid : dict or None
        ``{"spacing", "height", "margin"}`` [m] when the positions came from a grid.
    """

    positions: tuple[tuple[float, float, float], ...] = ()
    facing: str | tuple[float, float, float] | None = None
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    grid: tuple[tuple[str, float], ...] | None = None



def inside_hall(point: tuple[float, ...], key: str, footprint: np.ndarray, height: float, what: str) -> None:
    p = np.array(point[:2])[None, :]
    if not (polygon.contains(footprint, p)[0] and polygon.boundary_distance(footprint, p)[0] > 0):
        raise SpecError(key, f"the {what} at [{', '.join(f'{v:g}' for v in point)}] m is outside the hall footprint",
                        "move it inside the hall", code="position.outside")
    if not 0 < point[2] < height:
        raise SpecError(key, f"the {what}'s height z = {point[2]:g} m is not between the floor (0) and the "
                        f"ceiling ({height:g} m)", "give a height inside the hall", code="position.outside")



def _check_ris_size(rows: int, columns: int, t: Table) -> None:
    """Refuse a RIS whose response to a single beam would not fit in the memory limit (the least any
    simulation of it needs; the simulator checks again with its sweep's beams)."""
    from dsp.budget import check_memory

    from ..model.ris import ris_response_memory

    check_memory(ris_response_memory(rows * columns, 1), f"{t.key('rows')} = {rows:,} x {t.key('columns')} = "
                 f"{columns:,} ({rows * columns:,} elements)",
                 fix="give the RIS fewer elements (the paper's panel has 16 x 4)")


def parse_ris(t: Table, index: int, frequency: float, footprint: np.ndarray, height: float) -> RisSpec:
    name = check_name(t.string("name", default=f"ris{index}"), t.key("name"), what="RIS")
    position = t.vector("position", 3, unit="m")
    inside_hall(position, t.key("position"), footprint, height, "RIS")
    if t.has("facing") == t.has("normal"):
        raise SpecError(t.key("facing"), "a RIS needs exactly one of 'facing' (a point) and 'normal' (a direction)",
                        "write facing = [x, y, z] (e.g. the radar) or normal = [-1, 0, 0]")
    yaw = math.radians(t.number("yaw_deg", unit="deg", default=0.0))
    up = t.vector("up", 3, unit="direction", default=(0.0, 0.0, 1.0))
    if t.has("facing"):
        target, tkey = np.array(t.vector("facing", 3, unit="m")), t.key("facing")
    else:
        target, tkey = np.array(position) + np.array(t.vector("normal", 3, unit="direction")), t.key("normal")
    try:
        pose = RisPose.facing(np.array(position), target, yaw=yaw, up=np.array(up))
    except ValueError as exc:
        raise SpecError(tkey, str(exc), "give a direction that is non-zero and not parallel to 'up'") from None
    rows = t.integer("rows", default=16, minimum=1)
    columns = t.integer("columns", default=4, minimum=1)
    _check_ris_size(rows, columns, t)
    spacing_raw = t.raw("spacing", "half-wavelength")
    if spacing_raw == "half-wavelength":
        spacing = SPEED_OF_LIGHT / frequency / 2
    elif isinstance(spacing_raw, str):
        raise SpecError(t.key("spacing"), f"{spacing_raw!r} is not a spacing",
                        'use "half-wavelength" or a pitch in metres, e.g. 0.0025')
    else:
        spacing = t.number("spacing", unit="m", minimum=0.0, strict=True)
    amplification_db = t.number("amplification_db", unit="dB", default=45.532)
    loopback_delay = t.number("loopback_delay", unit="s", default=1.78e-9, minimum=0.0)
    mode = t.string("mode", default="relay", choices=("relay", "reflective"))
    rx = t.vector("relay_rx_toward", 3, unit="m", default=None)
    panel_t = t.table("panel")
    if panel_t is None:
        panel = RisPanel()
    else:
        width = panel_t.number("width", unit="m", default=0.10, minimum=0.0, strict=True)
        pheight = panel_t.number("height", unit="m", default=0.05, minimum=0.0, strict=True)
        mat = parse_material(panel_t.raw("material", "metal"), panel_t.key("material"), default_thickness=0.002,
                             frequency=frequency)
        if mat.scattering_coefficient > 0:
            raise SpecError(panel_t.key("material") + ".scattering_coefficient",
                            "is not used: the RIS panel is not ray traced but modelled as a flat physical-optics "
                            "plate (docs/ray-tracing.md)", "leave scattering_coefficient out of the panel's material")
        panel_t.finish()
        panel = RisPanel(width=width, height=pheight, material=mat)
    t.finish()
    for extent, n, axis, key in ((panel.width, rows, "rows", "width"), (panel.height, columns, "columns", "height")):
        if extent < n * spacing - 1e-12:
            raise SpecError(f"{t.key('panel')}.{key}", f"{extent:g} m is smaller than the element grid "
                            f"({n} {axis} × {spacing * 1e3:.4g} mm = {n * spacing:.4g} m)",
                            "make the panel at least as large as its element grid")
    return RisSpec(name=name, position=position,  # type: ignore[arg-type]
                   normal=tuple(pose.normal.tolist()), up=tuple(pose.up.tolist()),  # type: ignore[arg-type]
                   rows=rows, columns=columns, spacing=spacing, amplification_db=amplification_db,
                   loopback_delay=loopback_delay, mode=mode, relay_rx_toward=rx, panel=panel)


def check_grid_memory(nx: int, ny: int, num_vertices: int, *, key: str, spacing: float, span: Any) -> int:
    """Refuse a ``[radar] grid`` whose points would not fit in the memory limit, before any is made.

    Parameters
    ----------
    nx, ny : int
        Grid points along x and y over the footprint's bounding box less the margin.
    num_vertices : int
        V, the footprint's vertices.
    key : str
        The spacing's key path, for the message (``radar.grid.spacing``).
    spacing : float
        [m].
    span : float array [2]
        Extent of the grid along x and y [m].

    Returns
    -------
    int
        The estimate [bytes]: ``P · (8 · (8 + 6 V) + 160)`` for ``P = nx · ny`` points, the grid and its
        point-in-polygon test (:func:`.polygon.grid_test_memory`) plus :data:`POSITION_BYTES` per position.

    Raises
    ------
    dsp.budget.BudgetError
        The estimate exceeds :func:`dsp.budget.memory_limit`.
    """
    from dsp.budget import check_memory

    points = int(nx) * int(ny)
    estimate = polygon.grid_test_memory(points, num_vertices) + POSITION_BYTES * points
    sx, sy = (max(float(v), 0.0) for v in span)
    check_memory(estimate, f"{key} = {spacing:g} m over {sx:.3g} m x {sy:.3g} m makes {nx:,} x {ny:,} = {points:,} "
                           "radar positions, which", fix=f"raise {key} (1 m gives {_count(sx, 1.0) * _count(sy, 1.0):,} "
                                                         "positions here) or list radar.positions")
    return estimate


def _count(span: float, spacing: float) -> int:
    """Grid points ``floor(span / spacing) + 1`` along one axis (0 for a negative span), capped near 10¹⁸ so
    that a spacing of 1e-300 m gives a count instead of an overflow."""
    n = float(span) / float(spacing) + 1e-9
    return max(0, math.floor(min(n, 1e18)) + 1)


def parse_radar(t: Table | None, ris: tuple[RisSpec, ...], footprint: np.ndarray, height: float) -> RadarSpec:
    if t is None:
        return RadarSpec(facing=ris[0].name if ris else None)
    if t.has("positions") == t.has("grid"):
        raise SpecError(t.key("positions"), "[radar] needs exactly one of 'positions' and 'grid'",
                        "write positions = [[6.0, 9.0, 1.2]] or grid = {spacing = 1.0, height = 1.2}")
    grid = None
    if t.has("positions"):
        raw = t.raw("positions")
        if not isinstance(raw, list) or not raw:
            raise SpecError(t.key("positions"), "must be a non-empty array of [x, y, z] points",
                            "write positions = [[6.0, 9.0, 1.2]]")
        positions = tuple(check_vector(p, f"{t.key('positions')}[{i}]", 3, unit="m") for i, p in enumerate(raw))
        for i, p in enumerate(positions):
            inside_hall(p, f"{t.key('positions')}[{i}]", footprint, height, "radar")
    else:
        g = t.required_table("grid")
        spacing = g.number("spacing", unit="m", minimum=0.0, strict=True)
        z = g.number("height", unit="m")
        margin = g.number("margin", unit="m", default=0.5, minimum=0.0)
        g.finish()
        if not 0 < z < height:
            raise SpecError(g.key("height"), f"{z:g} m is not between the floor and the ceiling ({height:g} m)",
                            "give a height inside the hall")
        lo, hi = footprint.min(axis=0) + margin, footprint.max(axis=0) - margin
        nx, ny = (_count(hi[i] - lo[i], spacing) for i in range(2))
        check_grid_memory(nx, ny, len(footprint), key=g.key("spacing"), spacing=spacing, span=hi - lo)
        xs = lo[0] + spacing * np.arange(nx)
        ys = lo[1] + spacing * np.arange(ny)
        xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)  # x-major order
        keep = polygon.contains(footprint, xy) & (polygon.boundary_distance(footprint, xy) >= margin - 1e-9)
        xy = xy[keep]
        if not len(xy):
            raise SpecError(g.path, f"no grid point lies inside the footprint at least {margin:g} m from the walls",
                            "reduce spacing or margin")
        positions = tuple((float(x), float(y), z) for x, y in xy)
        grid = (("spacing", spacing), ("height", z), ("margin", margin))
    facing_raw = t.raw("facing", None)
    if facing_raw is None:
        facing: Any = ris[0].name if ris else None
        if facing is None:
            raise SpecError(t.key("facing"), "no RIS to face", "add facing = [x, y, z] or a [[ris]] table")
    elif isinstance(facing_raw, str):
        names = [r.name for r in ris]
        if facing_raw not in names:
            raise SpecError(t.key("facing"), f"{facing_raw!r} is not a RIS of this spec",
                            f"use one of {names} or a point [x, y, z]")
        facing = facing_raw
    else:
        facing = check_vector(facing_raw, t.key("facing"), 3, unit="m")
    velocity = t.vector("velocity", 3, unit="m/s", default=(0.0, 0.0, 0.0))
    t.finish()
    target = np.array(facing if isinstance(facing, tuple) else next(r.position for r in ris if r.name == facing))
    for i, p in enumerate(positions):
        if np.linalg.norm(np.array(p) - target) < 1e-3:
            raise SpecError(f"{t.key('positions')}[{i}]", f"the radar stands on the point it faces ({facing})",
                            "move the radar or change radar.facing")
    return RadarSpec(positions=positions, facing=facing, velocity=velocity, grid=grid)
