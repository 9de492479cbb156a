"""A study: fixed parameters, a grid of varied ones, N Monte Carlo runs per point, one seed.

Study file (TOML, ``studies/*.toml``)::

    [study]
    name = "fig6_tx_power"
    runs = 1000            # Monte Carlo runs per point
    seed = 6               # the study seed: run r of point p draws its noise from
                           # SeedSequence(seed, spawn_key=(p, r))
    description = "..."

    [fixed]                # parameters held at one value (others: the paper's defaults)
    aod_deg = 10.3

    [vary]                 # the grid: the cartesian product, the first parameter on the x axis
    tx_power_dbm = [-10, -5, 0, 5, 10, 20]

The command line makes the same object: ``--vary NAME=V1,V2`` (repeatable), ``--set NAME=V``,
``--runs``, ``--seed``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .params import PARAMETERS, check_value, complete_point, parse_values

__all__ = ["StudySpec", "load_study_file", "spec_from_options"]

#: Above this many points a grid is refused (a typo such as 0:1000:0.01 would make 100k points).
MAX_POINTS = 10_000


@dataclass(frozen=True)
class StudySpec:
    """What a study computes.

    Attributes
    ----------
    name : str
    runs : int
        Monte Carlo runs per point (>= 1).
    seed : int
        Study seed (>= 0); the noise of run r at point p comes from
        ``numpy.random.SeedSequence(seed, spawn_key=(p, r))``.
    fixed : dict
        Parameters held fixed (unit-suffixed names, values as written).
    vary : tuple of (name, tuple of values)
        The grid axes, in order; points are their cartesian product (last axis fastest).
    description : str
    """

    name: str
    runs: int
    seed: int = 0
    fixed: dict[str, Any] = field(default_factory=dict)
    vary: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        if isinstance(self.runs, bool) or not isinstance(self.runs, int) or self.runs < 1:
            raise ValueError(f"runs={self.runs!r} must be an integer >= 1 (Monte Carlo runs per point)")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed={self.seed!r} must be an integer >= 0")
        fixed = {k: check_value(k, v) for k, v in dict(self.fixed).items()}
        vary = []
        seen = set()
        for name, values in self.vary:
            if name in seen:
                raise ValueError(f"{name} is varied twice; give all its values in one --vary {name}=V1,V2,...")
            if name in fixed:
                raise ValueError(f"{name} is both fixed and varied; drop one of them")
            seen.add(name)
            vals = tuple(check_value(name, v) for v in values)
            if not vals:
                raise ValueError(f"the grid of {name} is empty: give at least one value")
            if len(set(vals)) != len(vals):
                raise ValueError(f"{name} lists a value twice: {list(vals)}")
            vary.append((name, vals))
        set_("fixed", fixed)
        set_("vary", tuple(vary))
        n = 1
        for _, vals in self.vary:
            n *= len(vals)
        if n > MAX_POINTS:
            raise ValueError(f"the grid has {n} points (more than {MAX_POINTS}); use fewer values")
        self.points()  # every point must be buildable (e.g. no analytic-only parameter for a hall)

    @property
    def x_name(self) -> str | None:
        """The parameter on the figures' x axis: the first varied one (None without a grid)."""
        return self.vary[0][0] if self.vary else None

    def points(self) -> list[dict[str, Any]]:
        """Every grid point with every parameter filled in (defaults from :data:`PARAMETERS`).

        Returns
        -------
        list of dict
            The cartesian product of the grid axes, last axis fastest; each point holds every
            parameter (:func:`risloc_rt.studies.params.complete_point`), units as in its name.
        """
        names = [n for n, _ in self.vary]
        grids = [v for _, v in self.vary]
        return [complete_point({**self.fixed, **dict(zip(names, combo))}) for combo in itertools.product(*grids)]

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain data (``study.json``, ``summary.json``).

        Returns
        -------
        dict
            ``name``, ``runs``, ``seed``, ``description``, ``fixed`` and ``vary`` (name -> list of values).
        """
        return {"name": self.name, "runs": self.runs, "seed": self.seed, "description": self.description,
                "fixed": dict(self.fixed), "vary": {n: list(v) for n, v in self.vary}}

    @property
    def key(self) -> str:
        """sha256 of the study's settings (name, seed, fixed, grid; not ``runs``: more runs extend a study).

        Parameters left at their defaults do not enter it, so a new parameter added to a later
        version does not orphan an existing study folder."""
        d = self.to_dict()
        d.pop("runs")
        d.pop("description")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def load_study_file(path: str | Path, *, runs: int | None = None, seed: int | None = None) -> StudySpec:
    """Read a study file (module docstring).

    Parameters
    ----------
    path : path-like
        The TOML file.
    runs, seed : int, optional
        Override the file's ``runs`` (default 100) and ``seed`` (default 0).

    Returns
    -------
    StudySpec

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not TOML, unknown tables, keys or parameters, or a bad value (one line naming it).
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"study file {str(p)!r} does not exist; see studies/*.toml for examples") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"study file {str(p)!r} is not valid TOML: {exc}") from None
    unknown = set(data) - {"study", "fixed", "vary"}
    if unknown:
        raise ValueError(f"study file {str(p)!r}: unknown table(s) {sorted(unknown)}; use [study], [fixed], [vary]")
    head = data.get("study", {})
    extra = set(head) - {"name", "runs", "seed", "description"}
    if extra:
        raise ValueError(f"study file {str(p)!r}: unknown [study] key(s) {sorted(extra)}; known: name, runs, seed, description")
    vary = []
    for name, values in data.get("vary", {}).items():
        if name not in PARAMETERS:
            raise ValueError(f"study file {str(p)!r}: unknown parameter {name!r} in [vary]; known: {', '.join(PARAMETERS)}")
        vary.append((name, tuple(values if isinstance(values, list) else [values])))
    for name in data.get("fixed", {}):
        if name not in PARAMETERS:
            raise ValueError(f"study file {str(p)!r}: unknown parameter {name!r} in [fixed]; known: {', '.join(PARAMETERS)}")
    return StudySpec(name=str(head.get("name", p.stem)),
                     runs=runs if runs is not None else head.get("runs", 100),
                     seed=seed if seed is not None else head.get("seed", 0),
                     fixed=data.get("fixed", {}), vary=tuple(vary),
                     description=str(head.get("description", "")))


def _assignment(text: str, flag: str) -> tuple[str, str]:
    name, sep, value = str(text).partition("=")
    name = name.strip()
    if not sep or not name:
        raise ValueError(f"{flag} {text!r} must be NAME=VALUE(S), e.g. {flag} tx_power_dbm=0,10,20")
    if name not in PARAMETERS:
        raise ValueError(f"{flag} {text!r}: unknown parameter {name!r}; known: {', '.join(PARAMETERS)}")
    return name, value


def spec_from_options(*, vary: list[str] | None, fixed: list[str] | None, runs: int, seed: int,
                      name: str = "sweep") -> StudySpec:
    """The spec of ``--vary NAME=V1,V2 ... --set NAME=V``.

    Parameters
    ----------
    vary : list of str, optional
        ``NAME=V1,V2,...`` or ``NAME=LO:HI:STEP`` (units as in the name), one per grid axis.
    fixed : list of str, optional
        ``NAME=V``, one per fixed parameter.
    runs : int
        Monte Carlo runs per point.
    seed : int
        The study seed.
    name : str
        The study's name.

    Returns
    -------
    StudySpec

    Raises
    ------
    ValueError
        Nothing to vary, a malformed assignment, an unknown parameter or a bad value.
    """
    grid = []
    for text in vary or []:
        n, v = _assignment(text, "--vary")
        grid.append((n, tuple(parse_values(n, v))))
    fix = {}
    for text in fixed or []:
        n, v = _assignment(text, "--set")
        fix[n] = check_value(n, v)
    if not grid:
        raise ValueError("nothing to vary: give --vary NAME=V1,V2,... (e.g. --vary tx_power_dbm=0,10,20) or --study FILE.toml")
    return StudySpec(name=name, runs=runs, seed=seed, fixed=fix, vary=tuple(grid))
