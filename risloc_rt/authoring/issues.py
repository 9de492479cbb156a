"""What :func:`~.check.check_scene` reports: :class:`Issue`, :class:`CheckReport` and the :data:`RULES`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .spec import HallSpec

__all__ = ["Issue", "CheckReport", "RULES", "Level", "format_point", "name_list"]

Level = Literal["error", "warning"]

#: Every rule: id -> what it finds (the table with levels is in :mod:`.check`).
RULES: dict[str, str] = {
    "spec": "the spec cannot be read",
    "scene.file": "the scene folder is not built or a file cannot be read",
    "scene.stale": "the built files differ from what the spec builds",
    "material.frequency": "an ITU material is undefined at the carrier frequency",
    "mesh.degenerate": "zero-area or collinear faces",
    "mesh.non_manifold": "edges shared by three or more faces",
    "mesh.flipped": "inward-facing normals on a closed mesh, or inconsistent winding",
    "mesh.units": "an imported mesh in millimetres where metres are expected",
    "mesh.placement": "an imported mesh outside the hall",
    "hall.open": "floor, ceiling and walls leave the hall open",
    "position.outside": "a radar or RIS outside the hall",
    "position.inside": "a radar or RIS inside a closed object",
    "position.clearance": "a radar too close to a surface",
    "ris.clearance": "a RIS too close to a surface",
    "ris.facing_wall": "a RIS facing a wall",
    "ris.radar_behind": "a radar behind the RIS",
    "ris.range": "a RIS loop-back beyond the unambiguous range",
    "ris.sweep": "a radar outside the beam sweep",
    "ris.los": "radar-RIS line of sight blocked",
    "ris.grating_lobe": "grating lobes inside the beam sweep",
    "range.walls": "walls beyond the unambiguous range",
}



@dataclass(frozen=True)
class Issue:
    """One finding of :func:`check_scene`.

    Attributes
    ----------
    level : {"error", "warning"}
    rule : str
        Key of :data:`RULES`.
    object : str
        What it is about: a scene object (``"wall_2"``, ``"rack"``), a RIS name, a radar position
        (``"radar.positions[1]"``) or a spec key path.
    message : str
        What is wrong, with numbers and units.
    fix : str
        How to fix it.
    """

    level: Level
    rule: str
    object: str
    message: str
    fix: str

    def format(self) -> str:
        """``"error [rule] object: message\\n    fix: ..."``."""
        return f"{self.level} [{self.rule}] {self.object}: {self.message}\n    fix: {self.fix}"


@dataclass(frozen=True)
class CheckReport:
    """The result of :func:`check_scene`.

    Attributes
    ----------
    source : str
        What was checked (a path, or the spec's name).
    issues : tuple of Issue
        Errors and warnings, in the order the rules ran.
    spec : HallSpec or None
        The spec, when it could be read.
    """

    source: str
    issues: tuple[Issue, ...] = ()
    spec: HallSpec | None = field(default=None, repr=False)

    @property
    def errors(self) -> tuple[Issue, ...]:
        """The issues of level ``"error"``."""
        return tuple(i for i in self.issues if i.level == "error")

    @property
    def warnings(self) -> tuple[Issue, ...]:
        """The issues of level ``"warning"``."""
        return tuple(i for i in self.issues if i.level == "warning")

    @property
    def ok(self) -> bool:
        """No errors (warnings allowed)."""
        return not self.errors

    @property
    def rules(self) -> set[str]:
        """Rules that produced an issue."""
        return {i.rule for i in self.issues}

    def by_rule(self, rule: str) -> tuple[Issue, ...]:
        """The issues of one rule."""
        return tuple(i for i in self.issues if i.rule == rule)

    def format(self) -> str:
        """Every issue, then a summary line."""
        lines = [i.format() for i in self.issues]
        verdict = "ok" if self.ok else "FAILED"
        lines.append(f"{self.source}: {verdict}: {len(self.errors)} error(s), {len(self.warnings)} warning(s)")
        return "\n".join(lines)


def format_point(p: np.ndarray) -> str:
    """A point or vector for an issue's message: ``"[1.00, -2.50, 0.00]"`` (two decimals, no ``-0.00``).

    Parameters
    ----------
    p : float array-like [n]
        Coordinates, in the unit the message states (positions in m).

    Returns
    -------
    str
    """
    return "[" + ", ".join(f"{v + 0.0:.2f}" for v in np.asarray(p, dtype=float)) + "]"


def name_list(items: list[str], limit: int = 4) -> str:
    """The first ``limit`` names, comma-separated, then ``"and N more"``: ``"a, b, c, d and 2 more"``.

    Parameters
    ----------
    items : list of str
        The names (radar positions, objects), in the order to list them.
    limit : int, default 4
        How many to name before counting the rest.

    Returns
    -------
    str
        ``""`` for no items.
    """
    return ", ".join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")
