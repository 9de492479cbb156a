"""A walk's path: timed waypoints ``t, x, y, z`` [s, m] joined by straight segments (``risloc track``).

:class:`Trajectory` gives the radar's position and velocity at any time of the walk and checks the
path against a hall's geometry (every waypoint inside, no segment through a surface);
:func:`read_trajectory` reads the CSV (``docs/tracking.md``), every bad line one
:class:`TrajectoryError` naming the file and line.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Trajectory", "TrajectoryError", "read_trajectory"]


class TrajectoryError(ValueError):
    """A trajectory file or path that cannot be walked: one line naming the file, the line and the fix."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Timed waypoints joined by straight segments, walked at constant velocity between them.

    Attributes
    ----------
    times : float array [W]
        Strictly increasing [s], W ≥ 2.
    points : float array [W, 3]
        World positions [m].
    lines : int array [W]
        The file line of each waypoint (for messages; 0 when not read from a file).
    source : str
        Where it came from (the file), for messages.
    """

    times: np.ndarray
    points: np.ndarray
    lines: np.ndarray = field(default=None)  # type: ignore[assignment]
    source: str = "trajectory"

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float).reshape(-1)
        p = np.asarray(self.points, dtype=float)
        if p.shape != (len(t), 3):
            raise TrajectoryError(f"{self.source}: points has shape {list(p.shape)}; give one [x, y, z] [m] per time")
        if len(t) < 2:
            raise TrajectoryError(f"{self.source}: {len(t)} waypoint(s); a walk needs at least two (t,x,y,z lines)")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise TrajectoryError(f"{self.source}: times and points must be finite numbers")
        lines = np.zeros(len(t), dtype=int) if self.lines is None else np.asarray(self.lines, dtype=int)
        for k in range(1, len(t)):
            if not t[k] > t[k - 1]:
                where = f"line {lines[k]}" if lines[k] else f"waypoint {k}"
                prev = f"line {lines[k - 1]}" if lines[k - 1] else f"waypoint {k - 1}"
                verb = "repeats" if t[k] == t[k - 1] else "goes back from"
                raise TrajectoryError(f"{self.source}: {where}: t = {t[k]:g} s {verb} t = {t[k - 1]:g} s of {prev}; "
                                      "timestamps must increase from line to line")
        for name, arr in (("times", t), ("points", p), ("lines", lines)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def duration(self) -> float:
        """Last time minus first [s]."""
        return float(self.times[-1] - self.times[0])

    @property
    def length(self) -> float:
        """Path length [m]."""
        return float(np.sum(np.linalg.norm(np.diff(self.points, axis=0), axis=1)))

    def _segment(self, t: float) -> int:
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        return min(max(k, 0), len(self.times) - 2)

    def position(self, t: float) -> np.ndarray:
        """The radar's position at a time of the walk.

        Parameters
        ----------
        t : float
            Time [s], within ``times[0]`` … ``times[-1]``.

        Returns
        -------
        float array [3]
            World position [m].
        """
        k = self._segment(t)
        a = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        return self.points[k] + a * (self.points[k + 1] - self.points[k])

    def velocity(self, t: float) -> np.ndarray:
        """The velocity of the segment walked at a time of the walk (at a waypoint: the next segment's).

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        float array [3]
            World velocity [m/s].
        """
        k = self._segment(t)
        return (self.points[k + 1] - self.points[k]) / (self.times[k + 1] - self.times[k])

    def check_in(self, geometry: Any) -> None:
        """Refuse waypoints outside the hall (or in an object, or in a wall) and segments through a surface.

        Parameters
        ----------
        geometry : risloc_rt.authoring.geometry.HallGeometry
            The scene's triangles.

        Raises
        ------
        TrajectoryError
            One line naming the waypoint's line (or the segment's two lines) and the surface.
        """
        for k, p in enumerate(self.points):
            try:
                geometry.check_point(p, what="radar")
            except ValueError as exc:
                raise TrajectoryError(f"{self.source}: {self._where(k)}: {exc}") from None
        for k in range(len(self.points) - 1):
            a, b = self.points[k], self.points[k + 1]
            length = float(np.linalg.norm(b - a))
            if length == 0:
                continue
            name, dist = geometry.first_hit(a, b - a)
            if name is not None and dist < length:
                hit = a + (b - a) * dist / length
                raise TrajectoryError(
                    f"{self.source}: the segment from {self._where(k)} {_fmt(a)} to {self._where(k + 1)} {_fmt(b)} m "
                    f"passes through '{name}' at {_fmt(hit)} m; add a waypoint that walks around it")

    def _where(self, k: int) -> str:
        return f"line {self.lines[k]}" if self.lines[k] else f"waypoint {k}"


def _fmt(p: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.3f}" for x in np.asarray(p, dtype=float)) + "]"


def read_trajectory(path: str | Path) -> Trajectory:
    """A trajectory CSV: a header ``t,x,y,z`` then one waypoint per line [s, m, m, m].

    Blank lines and lines starting with ``#`` are skipped. Every error names the file and line.

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    Trajectory

    Raises
    ------
    TrajectoryError
        A missing header, a line without four numbers, timestamps that repeat or go back, fewer
        than two waypoints.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise TrajectoryError(f"{path}: not a text file; give a CSV with a header t,x,y,z and one waypoint "
                              "per line [s, m]") from None
    rows, lines, header = [], [], False
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        cells = [c.strip() for c in next(csv.reader([line]))]
        if not header:
            if [c.lower() for c in cells] != ["t", "x", "y", "z"]:
                raise TrajectoryError(f"{path}: line {number}: the header must be 't,x,y,z' (time [s], position [m]), "
                                      f"got {line[:60]!r}")
            header = True
            continue
        if len(cells) != 4:
            raise TrajectoryError(f"{path}: line {number}: {len(cells)} value(s) {line[:60]!r}; give four numbers "
                                  "t,x,y,z [s, m]")
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise TrajectoryError(f"{path}: line {number}: {line[:60]!r} is not four numbers t,x,y,z [s, m]") from None
        if not all(math.isfinite(v) for v in values):
            raise TrajectoryError(f"{path}: line {number}: {line[:60]!r} must hold finite numbers")
        rows.append(values)
        lines.append(number)
    if not header:
        raise TrajectoryError(f"{path}: empty; give a header t,x,y,z and at least two waypoints [s, m]")
    arr = np.array(rows, dtype=float).reshape(-1, 4)
    return Trajectory(times=arr[:, 0], points=arr[:, 1:], lines=np.array(lines, dtype=int), source=str(path))
