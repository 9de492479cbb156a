"""Profile-likelihood intervals for a fitted material parameter whose Fisher 1σ is only a local figure.

:func:`~risloc_rt.hall.material_fit.fit_materials` states a 1σ from the Fisher information at its
solution. Its profile check re-traces ±1σ and ±2σ and calls a parameter **weak** when the cost does
not rise like a parabola there. That happens for a concrete wall's conductivity at 60 GHz: the loss
tangent enters a reflection at second order, a decade of σ moves the peaks by ≤ 0.4 dB, and the
likelihood is a long flat valley that climbs only where the wall turns transparent (σ ≲ 0.2 S/m for
0.2 m) or metallic. A local 1σ there held 12 % of the errors at 1σ and 38 % at 3σ over 50 fits of
emulated recordings (``docs/calibration-materials.md``): no statement a paper can carry. Over 40 such
fits the profile intervals below held the truth in 93 / 100 / 100 % (σ) and 78 / 98 / 100 % (ε_r) at
1σ / 2σ / 3σ.

This module states what the data do say, the **profile likelihood**: the parameter is stepped
outward from the fit on both sides; at every step it is held while every other free parameter is
fitted again (a conditional Levenberg–Marquardt fit, started from the previous step's solution), and
the profile Δχ²(c) = χ²_min(c) − χ²_min is recorded. The interval at level n is
{c : Δχ²(c) ≤ n²} (Wilks: for one parameter, Δχ² ≤ 1, 4, 9 hold 68.3, 95.4, 99.7 % in the
large-sample limit, whatever the shape of the likelihood in between). Where the profile stays below
n² up to the scan limit, that side of the interval is **open** (``-inf``/``inf``): an upper or lower
bound only, or no bound. If a conditional fit finds a lower χ² than the fit itself (the fit stopped in
one of two valleys), the free fit is run again from there, χ²_min is its minimum and
:attr:`ProfileInterval.moved` says so. A valley behind a barrier higher than Δχ² = 10 is not searched
(the scan stops there).

Coordinates: ε_r [unitless] as it is, σ in ln σ [ln(S/m)], a scattering coefficient S in the
scattered share S² [unitless], the fit's own parameters. Intervals are returned in both
(:attr:`ProfileInterval.intervals` in the coordinate, :meth:`ProfileInterval.physical` in ε_r, S/m or S).
An S² interval open at the fit's lower bound (S = 1e-3) is an upper bound: "S <= x".

Cost: one conditional fit per grid point, stopped when a step lowers χ² by less than 0.01 or 0.1 %,
whichever is smaller (mostly 1–3 tracer evaluations each: every radar position traced and
differentiated once per evaluation). The step starts at the Fisher 1σ, doubles while the profile
rises by less than 0.5 in χ² per step and halves where it rises by more than 3, so a flat side
reaches its limit in a few steps; then every interval end is bisected (at most 6 times) until the
grid values around it differ by at most 0.5 in Δχ², and the end is interpolated linearly in Δχ²
between them. Measured on 40 fits of emulated recordings: 38–95 evaluations for σ of concrete,
39–268 for its ε_r (at each ε_r the conditional fit moves σ along its flat valley).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .material_fit import DEFAULT_THRESHOLD, DEFAULT_WINDOW, SHARE_RANGE, MaterialFit, Observation, fit_materials
from .raytrace.result import TraceSettings

__all__ = ["ProfileInterval", "profile_interval", "profile_intervals_of", "LEVELS", "SIGMA_SCAN", "EPS_R_SCAN",
           "S_SCAN"]

#: The interval levels n: Δχ² ≤ n² (1σ, 2σ, 3σ equivalents for one parameter).
LEVELS: tuple[int, ...] = (1, 2, 3)
#: Default scan limits of σ [S/m]: below 1 mS/m a 0.2 m concrete wall is a clear Fabry–Pérot slab at
#: 60 GHz, above 1 kS/m a near-perfect mirror; neither is a building material's range.
SIGMA_SCAN: tuple[float, float] = (1e-3, 1e3)
#: Default scan limits of ε_r [unitless]: 1 (what the tracer accepts) to 30 (above any ITU-R P.2040
#: non-metal at 60 GHz).
EPS_R_SCAN: tuple[float, float] = (1.0, 30.0)
#: Default scan limits of a scattering coefficient S [unitless]: the fit's own range
#: (:data:`~risloc_rt.hall.material_fit.SHARE_RANGE`, S from 1e-3 to 0.995).
S_SCAN: tuple[float, float] = (math.sqrt(SHARE_RANGE[0]), math.sqrt(SHARE_RANGE[1]))
#: Step bounds in the coordinate: ln σ [ln(S/m)], ε_r [unitless].
_STEP = {"ln_sigma": (0.05, 1.5), "eps_r": (0.002, 2.0), "scattering": (2e-4, 0.1)}
_MOVED = 0.05  # a conditional fit lower than the fit by more than this in χ² moves the reference
_COST_TOLERANCE = 0.005  # the conditional fits stop when a step lowers ½χ² by less than this (χ² to ~0.01) ...
_TOLERANCE = 1e-3  # ... or by less than this share of it
_BISECTIONS = 6  # most bisections per interval end
_SHARES = {1: "68.3", 2: "95.4", 3: "99.7"}  # the share [%] of each level's interval
_RESOLUTION = 0.5  # Δχ² between the two grid values an interval end is interpolated between, at most


@dataclass(frozen=True)
class ProfileInterval:
    """The profile likelihood of one parameter and its intervals.

    Attributes
    ----------
    parameter : str
        ``"<material>:eps_r"``, ``"<material>:ln_sigma"`` or ``"<material>:scattering"``.
    grid : float array [N]
        The parameter's values where the profile was traced, ascending, in its coordinate
        (ε_r [unitless], ln σ [ln(S/m)] or S² [unitless]); the fit's own value is one of them.
    delta_chi2 : float array [N]
        χ² of the conditional fit at each grid value minus the lowest χ² found [unitless].
    values : tuple of dict
        Per grid value, every fitted material's ``(ε_r, σ [S/m])`` at the conditional fit, S [unitless]
        third for a material whose scattering coefficient was fitted.
    best : float
        The grid value with the lowest χ² [coordinate].
    chi2_min : float
        The lowest χ² found (the fit's, or a conditional fit's or the fit run again from it when lower by more
        than 0.05) [unitless].
    moved : bool
        A conditional fit found a χ² lower than the fit's by more than 0.05: the fit had stopped in a
        local valley, and ``best`` / ``values`` there are the better solution.
    limits : (float, float)
        The scan limits [coordinate].
    intervals : dict
        ``{n: (lo, hi)}`` for n in :data:`LEVELS`: the hull of {c : Δχ²(c) ≤ n²}, its ends linearly
        interpolated in Δχ² between grid values [coordinate]; ``-inf`` / ``inf`` where the profile is
        still below n² at the scan limit (open: no bound on that side).
    evaluations : int
        Tracer evaluations spent (every radar position traced once per evaluation).
    seconds : float
        Wall-clock time [s].
    """

    parameter: str
    grid: np.ndarray
    delta_chi2: np.ndarray
    values: tuple[dict[str, tuple[float, float]], ...]
    best: float
    chi2_min: float
    moved: bool
    limits: tuple[float, float]
    intervals: dict[int, tuple[float, float]]
    evaluations: int
    seconds: float

    @property
    def material(self) -> str:
        """The material's name."""
        return self.parameter.rpartition(":")[0]

    @property
    def kind(self) -> str:
        """``"eps_r"``, ``"ln_sigma"`` or ``"scattering"``."""
        return self.parameter.rpartition(":")[2]

    def physical(self, level: int = 1) -> tuple[float, float]:
        """The level-n interval in physical units: ε_r [unitless], σ [S/m] or S [unitless].

        An open lower end is the physical floor (ε_r 1, σ 0 S/m, S 0), an open upper end ``inf``
        (S: 1).

        Parameters
        ----------
        level : int
            One of :data:`LEVELS`.

        Returns
        -------
        (float, float)
            Lower and upper end.
        """
        lo, hi = self._interval(level)
        if self.kind == "eps_r":
            return max(lo, 1.0), hi
        if self.kind == "scattering":
            return (0.0 if lo == -math.inf else _physical(self.kind, lo)), (1.0 if hi == math.inf else _physical(self.kind, hi))
        return (0.0 if lo == -math.inf else math.exp(lo)), (math.inf if hi == math.inf else math.exp(hi))

    @property
    def grid_physical(self) -> np.ndarray:
        """``grid`` in physical units: ε_r [unitless], σ [S/m] or S [unitless], float [N]."""
        return np.array([_physical(self.kind, c) for c in self.grid])

    @property
    def best_physical(self) -> float:
        """``best`` in physical units: ε_r [unitless], σ [S/m] or S [unitless]."""
        return _physical(self.kind, self.best)

    def covers(self, value: float, level: int = 1) -> bool:
        """Whether a physical value (ε_r, σ [S/m] or S) lies in the level-n interval.

        Parameters
        ----------
        value : float
            ε_r [unitless], σ [S/m] or S [unitless].
        level : int
            One of :data:`LEVELS`.

        Returns
        -------
        bool
            True inside the interval (ends included).
        """
        lo, hi = self.physical(level)
        return lo <= value <= hi

    def span(self, level: int = 1) -> str:
        """The level-n interval in words, open ends said as bounds.

        Parameters
        ----------
        level : int
            One of :data:`LEVELS`.

        Returns
        -------
        str
            E.g. ``"0.121 <= sigma <= 1.27 S/m"``, ``"sigma >= 0.1 S/m (no upper bound up to 1e+03 S/m)"``.
        """
        lo, hi = self._interval(level)
        name, unit = self._name_unit
        lo_p, hi_p = self.physical(level)
        if math.isinf(lo) and math.isinf(hi):
            return f"not bounded within the scan ({_fmt(self._limit_physical(0))}..{_fmt(self._limit_physical(1))}{unit})"
        if math.isinf(hi):
            return f"{name} >= {_fmt(lo_p)}{unit} (no upper bound up to {_fmt(self._limit_physical(1))}{unit})"
        if math.isinf(lo):
            return f"{name} <= {_fmt(hi_p)}{unit} (no lower bound down to {_fmt(self._limit_physical(0))}{unit})"
        return f"{_fmt(lo_p)} <= {name} <= {_fmt(hi_p)}{unit}"

    def describe(self, level: int = 1) -> str:
        """One line: the parameter, its best value and the level-n interval (:meth:`span`).

        Parameters
        ----------
        level : int
            One of :data:`LEVELS`.

        Returns
        -------
        str
            E.g. ``"concrete-200mm:sigma 0.144 S/m, 68.3 % profile interval: 0.121 <= sigma <= 1.27 S/m"``, and
            a note when the profile found a lower χ² than the fit.
        """
        span = self.span(level)  # checks the level
        name, unit = self._name_unit
        return (f"{self.material}:{name} {_fmt(self.best_physical)}{unit}, {_SHARES[level]} % profile interval: {span}"
                + ("; the scan found a lower chi2 than the fit (the fit had stopped in a local valley)" if self.moved else ""))

    @property
    def _name_unit(self) -> tuple[str, str]:
        return {"eps_r": ("eps_r", ""), "scattering": ("S", "")}.get(self.kind, ("sigma", " S/m"))

    def _interval(self, level: int) -> tuple[float, float]:
        if level not in self.intervals:
            raise ValueError(f"level={level!r} must be one of {sorted(self.intervals)}")
        return self.intervals[level]

    def _limit_physical(self, i: int) -> float:
        return _physical(self.kind, self.limits[i])


def _physical(kind: str, c: float) -> float:
    """A coordinate value in physical units: ε_r as it is, σ = exp(ln σ) [S/m], S = √(S²)."""
    if kind == "eps_r":
        return c
    if kind == "scattering":
        return math.sqrt(max(c, 0.0))
    return math.exp(c)


def _coordinate(fit: MaterialFit, kind: str, material: str) -> float:
    """The fit's value of one parameter in its coordinate (ε_r, ln σ or S²)."""
    if kind == "scattering":
        return float(fit.scattering_share[fit.scattering.index(material)])
    q = fit.materials.index(material)
    return float(fit.relative_permittivity[q]) if kind == "eps_r" else math.log(float(fit.conductivity[q]))


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def _parameter(fit: MaterialFit, parameter: str) -> tuple[str, str, int]:
    """(material, kind, column) of ``"m:eps_r"`` / ``"m:sigma"`` / ``"m:ln_sigma"`` / ``"m:scattering"`` (``"m:S"``);
    one-line ValueError otherwise."""
    m, _, kind = str(parameter).rpartition(":")
    kind = {"sigma": "ln_sigma", "S": "scattering"}.get(kind, kind)
    name = f"{m}:{kind}"
    params = fit.identifiability.parameters
    if name not in params:
        raise ValueError(f"parameter {parameter!r} must be MATERIAL:eps_r or MATERIAL:sigma with MATERIAL one of the "
                         f"fitted materials ({', '.join(fit.materials)})"
                         + (f", or MATERIAL:scattering for {', '.join(fit.scattering)}" if fit.scattering else ""))
    if name in fit.identifiability.fixed:
        raise ValueError(f"parameter {parameter!r} was held in the fit (--fixed): it has no profile to trace")
    if name in fit.identifiability.not_identifiable:
        raise ValueError(f"parameter {parameter!r} is not identifiable ({fit.identifiability.not_identifiable[name]}): "
                         "its profile is flat by construction; hold it or add radar positions")
    return m, kind, params.index(name)


def _profile(points: dict[float, tuple[float, dict]], chi2_fit: float,
             theta_fit: float) -> tuple[np.ndarray, np.ndarray, int, float, bool]:
    """(grid, Δχ², index of the best point, χ²_min, moved) of the points traced so far."""
    grid = np.array(sorted(points))
    chi2 = np.array([points[c][0] for c in grid])
    i_best = int(np.argmin(chi2))
    chi2_min = float(chi2[i_best])
    moved = chi2_fit - chi2_min > _MOVED
    if not moved:  # the fit's own point is the reference (conditional fits within 0.05 of it count as equal)
        chi2_min, i_best = chi2_fit, int(np.flatnonzero(grid == theta_fit)[0])
    delta = np.maximum(chi2 - chi2_min, 0.0)
    delta[i_best] = 0.0
    return grid, delta, i_best, chi2_min, moved


def _outermost_inside(d: np.ndarray, level: float, best: int, side: int) -> int:
    """Index of the outermost grid point on one side of ``best`` with Δχ² ≤ level (``best`` itself at least)."""
    idx = range(best, -1, -1) if side < 0 else range(best, d.size)
    return [i for i in idx if d[i] <= level][-1]


def _crossing(grid: np.ndarray, d: np.ndarray, level: float, best: int, side: int) -> float:
    """Outer end on one side of ``best`` of the hull of {Δχ² ≤ level}, linear in Δχ² between grid values; ±inf
    when the scan's last point on that side is still inside."""
    last = _outermost_inside(d, level, best, side)
    nxt = last + side
    if not 0 <= nxt < grid.size:
        return -math.inf if side < 0 else math.inf
    f = (level - d[last]) / (d[nxt] - d[last])
    return float(grid[last] + f * (grid[nxt] - grid[last]))


def profile_intervals_of(grid: np.ndarray, delta_chi2: np.ndarray, best: int) -> dict[int, tuple[float, float]]:
    """The intervals ``{n: (lo, hi)}`` at :data:`LEVELS` of a traced profile (as :attr:`ProfileInterval.intervals`).

    Parameters
    ----------
    grid : float array [N]
        The parameter's values, ascending [its coordinate].
    delta_chi2 : float array [N]
        The profile Δχ² at each, 0 at ``best`` [unitless].
    best : int
        Index of the lowest point.

    Returns
    -------
    dict
        The hull of {Δχ² ≤ n²} around ``best``, its ends linear in Δχ² between grid values; ``-inf`` / ``inf``
        where the last point on that side is still inside.
    """
    grid = np.asarray(grid, dtype=float)
    delta = np.asarray(delta_chi2, dtype=float)
    return {n: (_crossing(grid, delta, n ** 2, best, -1), _crossing(grid, delta, n ** 2, best, 1)) for n in LEVELS}


def profile_interval(
    scene: str | os.PathLike[str],
    observations: Sequence[Observation],
    fit: MaterialFit,
    parameter: str,
    *,
    settings: TraceSettings | None = None,
    window: float = DEFAULT_WINDOW,
    threshold: float = DEFAULT_THRESHOLD,
    limits: tuple[float, float] | None = None,
    max_iter: int = 15,
    progress: Callable[[float, float], None] | None = None,
) -> ProfileInterval:
    """Trace the profile likelihood of one fitted parameter outward from the fit and state its intervals.

    Parameters
    ----------
    scene : path-like
        The scene folder (or its ``scene.xml``) the fit used.
    observations : sequence of Observation
        The fit's observations.
    fit : MaterialFit
        The fit (:func:`~risloc_rt.hall.material_fit.fit_materials` with the same scene, observations,
        settings and window); its held parameters stay held.
    parameter : str
        ``"<material>:eps_r"``, ``"<material>:sigma"`` (``ln_sigma`` accepted) or
        ``"<material>:scattering"`` (``S`` accepted; profiled in S², stated in S): a fitted, free,
        identifiable parameter.
    settings : TraceSettings, optional
        The fit's solver options.
    window : float
        The fit's delay window [s].
    threshold : float
        The fit's identifiability threshold.
    limits : (float, float), optional
        Scan limits in physical units, ε_r [unitless], σ [S/m] or S [unitless]; default
        :data:`EPS_R_SCAN` / :data:`SIGMA_SCAN` / :data:`S_SCAN`, widened to include the fit's value.
    max_iter : int
        Most Levenberg–Marquardt iterations per conditional fit (default 15).
    progress : callable, optional
        ``progress(value, delta_chi2)`` after every grid point, the value in physical units.

    Returns
    -------
    ProfileInterval
        The grid, the profile Δχ², the intervals at 1, 2, 3 σ-equivalents (open where unbounded).

    Raises
    ------
    ValueError
        An unknown, held or not-identifiable parameter; bad limits (not finite, lo >= hi, ε_r < 1,
        σ <= 0, S outside [``S_SCAN``]). Errors of the conditional fits pass through.
    """
    t0 = time.perf_counter()
    material, kind, col = _parameter(fit, parameter)
    name = f"{material}:{kind}"
    q = fit.materials.index(material)
    theta_fit = _coordinate(fit, kind, material)
    default = {"eps_r": EPS_R_SCAN, "scattering": S_SCAN}.get(kind, SIGMA_SCAN)
    lo_p, hi_p = default if limits is None else limits
    if not (isinstance(lo_p, (int, float)) and isinstance(hi_p, (int, float)) and math.isfinite(lo_p)
            and math.isfinite(hi_p) and lo_p < hi_p):
        raise ValueError(f"limits={limits!r} must be two finite numbers, lo < hi")
    if kind == "eps_r" and lo_p < 1.0:
        raise ValueError(f"limits={limits!r}: eps_r below 1 is not accepted by the ray tracer")
    if kind == "ln_sigma" and lo_p <= 0:
        raise ValueError(f"limits={limits!r}: sigma must be > 0 S/m (the fit works in ln sigma)")
    if kind == "scattering" and not (S_SCAN[0] * (1 - 1e-9) <= lo_p and hi_p <= S_SCAN[1] * (1 + 1e-9)):
        raise ValueError(f"limits={limits!r}: S must lie within {S_SCAN[0]:.3g}..{S_SCAN[1]:.3g}, the fit's range")
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter={max_iter!r} must be an int >= 1")
    lim = {"eps_r": (lo_p, hi_p), "scattering": (lo_p ** 2, hi_p ** 2)}.get(kind, (math.log(lo_p), math.log(hi_p)))
    lim = (min(lim[0], theta_fit), max(lim[1], theta_fit))
    held = [p.replace("ln_sigma", "sigma") for p in fit.identifiability.fixed]
    others = len(fit.identifiability.parameters) - len(held) > 1
    fit_values = fit.values()
    h_min, h_max = _STEP[kind]
    sd = float({"eps_r": fit.relative_permittivity_sigma, "ln_sigma": fit.log_conductivity_sigma}[kind][q]
               if kind != "scattering" else fit.scattering_share_sigma[fit.scattering.index(material)])
    h0 = min(max(sd if math.isfinite(sd) and sd > 0 else h_max, h_min), h_max)
    stop = max(LEVELS) ** 2 + 1.0
    tolerance = min(_TOLERANCE, _COST_TOLERANCE / max(0.5 * fit.chi2, 1e-9))
    points: dict[float, tuple[float, dict[str, tuple[float, ...]]]] = {theta_fit: (fit.chi2, fit_values)}
    evaluations = 0
    slot = {"eps_r": 0, "ln_sigma": 1, "scattering": 2}[kind]

    def set_value(values: dict[str, tuple[float, ...]], c: float) -> dict[str, tuple[float, ...]]:
        out = dict(values)
        new = list(values[material])
        new[slot] = c if kind == "eps_r" else math.exp(c) if kind == "ln_sigma" else math.sqrt(c)
        out[material] = tuple(new)
        return out

    def conditional(c: float, values: dict[str, tuple[float, ...]]) -> dict[str, tuple[float, ...]]:
        """χ² of the fit with the parameter held at c, started from ``values``; stored in ``points``."""
        nonlocal evaluations
        # Nothing else free (one material, its other parameter held): the profile is the cost itself.
        cond = fit_materials(scene, observations, fit.materials, start=set_value(values, c), settings=settings,
                             window=window, threshold=threshold, max_iter=max_iter if others else 0,
                             tolerance=tolerance, profile_check=False, scattering=fit.scattering, search=False,
                             fixed=[*held, name.replace("ln_sigma", "sigma")] if others else held)
        evaluations += cond.evaluations
        out = cond.values()
        points[c] = (cond.chi2, out)
        if progress is not None:
            progress(_physical(kind, c), cond.chi2 - fit.chi2)
        return out

    # 1. Outward from the fit on both sides, the step adapted to the profile's slope, until Δχ² passes 3² + 1.
    for side in (-1, 1):
        c, values, h = theta_fit, fit_values, h0
        while (c > lim[0]) if side < 0 else (c < lim[1]):
            before = points[c][0]
            c = max(c - h, lim[0]) if side < 0 else min(c + h, lim[1])
            values = conditional(c, values)
            if points[c][0] - min(v[0] for v in points.values()) > stop:
                break
            rise = abs(points[c][0] - before)
            h = min(2.0 * h, h_max) if rise < 0.5 else max(0.5 * h, h_min) if rise > 3.0 else h
    # 2. Every interval end bisected until the grid values around it differ by at most 0.5 in Δχ² (or lie h_min
    # apart). 3. If the scan or the bisections found a lower valley than the fit's: the free fit again from its best
    # grid value, so that Δχ² is measured from that valley's minimum, and the ends bisected again.
    refitted = False
    while True:
        for side in (-1, 1):
            for n in LEVELS:
                for _ in range(_BISECTIONS):
                    grid, delta, i_best, _, _ = _profile(points, fit.chi2, theta_fit)
                    inner = _outermost_inside(delta, n ** 2, i_best, side)
                    outer = inner + side
                    if (not 0 <= outer < grid.size or delta[outer] - delta[inner] <= _RESOLUTION
                            or abs(grid[outer] - grid[inner]) <= h_min):
                        break
                    conditional(0.5 * (grid[inner] + grid[outer]), points[grid[inner]][1])
        grid, _, i_best, _, moved = _profile(points, fit.chi2, theta_fit)
        if not moved or refitted:
            break
        refitted = True
        refit = fit_materials(scene, observations, fit.materials, start=points[grid[i_best]][1], settings=settings,
                              window=window, threshold=threshold, max_iter=max_iter, tolerance=tolerance,
                              profile_check=False, fixed=held, scattering=fit.scattering, search=False)
        evaluations += refit.evaluations + refit.search_evaluations
        c = _coordinate(refit, kind, material)
        if refit.chi2 < points.get(c, (math.inf,))[0]:
            points[c] = (refit.chi2, refit.values())
    grid, delta, i_best, chi2_min, moved = _profile(points, fit.chi2, theta_fit)
    intervals = profile_intervals_of(grid, delta, i_best)
    for arr in (grid, delta):
        arr.setflags(write=False)
    return ProfileInterval(parameter=name, grid=grid, delta_chi2=delta, values=tuple(points[c][1] for c in grid),
                           best=float(grid[i_best]), chi2_min=chi2_min, moved=moved, limits=(float(lim[0]), float(lim[1])),
                           intervals=intervals, evaluations=evaluations, seconds=time.perf_counter() - t0)
