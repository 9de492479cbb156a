"""One position from several RIS landmarks: fused fixes with their covariance and a consistency test.

Each detected RIS i gives the radar's distance dᵢ and angle of departure (azimuth, and elevation
where its sweep sees it) in its own frame, each with a 1σ (:class:`RisFix`, e.g. from a
:class:`dsp.Localization` by :meth:`RisFix.from_localization`). The fused position x̂ minimises

    T(x) = Σᵢ Σⱼ (zᵢⱼ − hᵢⱼ(x))² / σᵢⱼ²,   hᵢ(x) = (‖x − pᵢ‖, az(Rᵢᵀ(x − pᵢ)), el(Rᵢᵀ(x − pᵢ))),

by trust-region Gauss–Newton (:func:`scipy.optimize.least_squares`) from the best single fix
(azimuth residuals wrapped to (−π, π]). Its covariance
is the inverse of the summed Fisher information ``Σᵢ Jᵢᵀ Wᵢ Jᵢ`` (Jᵢ = ∂hᵢ/∂x at x̂ in closed form,
:meth:`RisFix.linearised`; Wᵢ = diag(1/σ²)):
with each fix's σ its Cramér–Rao bound this is the multi-RIS position bound, and ``peb`` its trace's
square root.

**Consistency.** At x̂, T is χ² with n − r degrees of freedom (n measurements, r the directions
they see: 3, or 2 when the height is unobservable) when every fix is right. Above its level of probability ``pfa`` (:func:`scipy.stats.chi2.isf`) the fixes disagree:
each fix is left out in turn, and the one whose removal lowers T most is excluded — named, with its
own residual, in :attr:`FusedFix.excluded` and the flag ``inconsistent-ris`` — when the others then
pass; so on until they agree, never below what still over-determines the position (n − r ≥ 1).
When the test cannot say which fix is wrong (two fixes that each determine the position alone:
either may be the wrong one), the fixes that carry a doubt of their own (:data:`DOUBT_CODES`:
``aliased``, ``grating-lobe``, ...) are left out, named; fixes that still cannot be told apart are
kept, and the flag says their position is a compromise. A grating-lobe twin, a blocked RIS whose peak is
another path, or a path taken for a return shows up this way; an average would hide it.

**The compromise's covariance.** The inverse information describes fixes that agree; for fixes that
do not, it is the σ of an answer nobody gave (two fixes 0.1 m apart, each of 1 mm, fused to ±1 mm).
The compromise x̂ therefore states the covariance of "one of the kept fixes is right, which one is not
known": the second moment about x̂ of the equal mixture of the fixes' own positions (each fix alone,
with the known height when given: x̂ᵢ with covariance Pᵢ),

    P = (1/m) Σᵢ [Pᵢ + (x̂ᵢ − x̂)(x̂ᵢ − x̂)ᵀ],

so whichever fix is right, its position lies within NEES ≤ m of x̂ (m fixes), and ``peb`` grows with
the disagreement. Where a fix alone cannot see every direction (no known height, a 1-D sweep) its own
position is not defined; the covariance is then the inverse information scaled by T/(n − r) (the
Birge ratio squared), which spans the disagreement only in proportion to the fixes' weights. Either
way the flag's message gives the widened ``peb``.

**Observability.** Directions along which the information is below 1e-12 of its largest
eigenvalue cannot be seen: two RISs at one height whose sweeps
cannot see elevation leave the height unobservable (the mirror image below the sweep plane gives
the same distances and azimuths). The covariance is then infinite along them, the flag
``unobservable`` names the world direction, and the position lies where the best single fix put it
along that direction (its elevation as given). RISs at different heights, or a sweep that sees
elevation, make it observable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats

from .flags import Flag
from .geometry import RisPose, angles_from_direction, direction_from_angles
from .validation import as_finite_array, finite, positive

__all__ = ["DOUBT_CODES", "KNOWN_HEIGHT_STD", "RisFix", "FusedFix", "fuse_fixes", "central_jacobian"]

#: Gauss–Newton steps at most, and the step [m] below which it has converged.
_MAX_STEPS, _TOLERANCE = 50, 1e-10
#: A fix's own flags that say its position may be grossly wrong (not merely biased by millimetres, as
#: ``unresolved-peaks`` and ``pattern-mismatch`` say of most fixes in a traced hall): when the fixes
#: disagree and the χ² test cannot say which one is wrong, the fixes that carry one of these are left
#: out (named) before any compromise.
#: The 1σ of a known radar height in a fusion (``fuse_fixes(height=(z, KNOWN_HEIGHT_STD))``) [m]: the height
#: is taken as exact, as a single fix solved for it is (``ue_height``); 0.1 mm keeps the information
#: well conditioned.
KNOWN_HEIGHT_STD = 1e-4
DOUBT_CODES = frozenset({"aliased", "grating-lobe", "floor-leg", "before-ris-delay", "beam-edge",
                         "no-beam-dependence", "off-detection", "schedule-mismatch", "damaged-beams",
                         "ris-facing-away"})
#: Information eigenvalues below this fraction of the largest are directions the fixes cannot see.
_RANK_TOLERANCE = 1e-12


@dataclass(frozen=True, eq=False)
class RisFix:
    """One RIS's answer: the radar's distance and AoD from it, with their 1σ.

    Attributes
    ----------
    name : str
        The RIS (its name in the scene).
    pose : RisPose
        Its position and orientation.
    distance : float
        d [m] from the RIS.
    std_distance : float
        Its 1σ [m], > 0.
    aod : float array [2]
        [az, el] in the RIS frame [rad].
    std_aod : float array [2]
        Their 1σ [rad], > 0; NaN or inf for an angle the sweep cannot see (not used; a 1-D sweep's
        elevation).
    flags : tuple of str
        The fix's own flag codes (kept with it).
    """

    name: str
    pose: RisPose
    distance: float
    std_distance: float
    aod: np.ndarray
    std_aod: np.ndarray
    flags: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"RisFix name {self.name!r} must be a non-empty string (the RIS's name)")
        if not isinstance(self.pose, RisPose):
            raise TypeError(f"RisFix {self.name}: pose must be a dsp.RisPose, got {type(self.pose).__name__}")
        object.__setattr__(self, "distance", positive(self.distance, f"RisFix {self.name}: distance", "m"))
        object.__setattr__(self, "std_distance", positive(self.std_distance, f"RisFix {self.name}: std_distance", "m"))
        aod = as_finite_array(self.aod, f"RisFix {self.name}: aod", shape=(2,))
        std = np.asarray(self.std_aod, dtype=float)
        if std.shape != (2,):
            raise ValueError(f"RisFix {self.name}: std_aod has shape {list(std.shape)}; it must be [σ_az, σ_el] [rad]")
        seen = np.isfinite(std)
        if np.any(seen & ~(std > 0)):
            raise ValueError(f"RisFix {self.name}: std_aod={std.tolist()} must be > 0 where finite "
                             "(NaN or inf for an angle the sweep cannot see)")
        object.__setattr__(self, "aod", aod)
        object.__setattr__(self, "std_aod", np.where(seen, std, np.nan))
        object.__setattr__(self, "flags", tuple(str(f) for f in self.flags))

    @classmethod
    def from_localization(cls, name: str, pose: RisPose, loc: Any) -> "RisFix":
        """The fix of a detected :class:`dsp.Localization` (its distance, AoD, 1σ and flag codes).

        Parameters
        ----------
        name : str
            The RIS.
        pose : RisPose
            Its pose (the one ``loc`` was computed with).
        loc : dsp.Localization
            Detected, with ``std``.

        Returns
        -------
        RisFix
        """
        if not getattr(loc, "detected", False) or loc.std is None:
            raise ValueError(f"RIS {name}: nothing was detected, so it gives no fix; leave it out of the fusion")
        return cls(name=name, pose=pose, distance=float(loc.distance), std_distance=float(loc.std.distance),
                   aod=np.asarray(loc.aod, dtype=float), std_aod=np.asarray(loc.std.aod, dtype=float),
                   flags=tuple(loc.flag_codes))

    @property
    def measurements(self) -> int:
        """How many numbers the fix gives: the distance and each angle it sees."""
        return 1 + int(np.sum(np.isfinite(self.std_aod)))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """(z − h(x)) / σ for the measurements it has [unitless]; the azimuth residual wrapped to (−π, π]."""
        rel = np.asarray(x, dtype=float) - self.pose.position
        dist = float(np.linalg.norm(rel))
        out = [(self.distance - dist) / self.std_distance]
        if dist > 0:
            az, el = angles_from_direction(self.pose.to_local(rel / dist))
        else:
            az = el = 0.0
        if np.isfinite(self.std_aod[0]):
            out.append(math.remainder(self.aod[0] - az, 2 * math.pi) / self.std_aod[0])
        if np.isfinite(self.std_aod[1]):
            out.append((self.aod[1] - el) / self.std_aod[1])
        return np.asarray(out)

    def linearised(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residuals at x and their Jacobian ∂r/∂x [n], [n, 3] [1/m].

        Analytic: with q = Rᵀ(x − p) the RIS-frame offset, d = ‖q‖ and ρ = √(q_u² + q_n²),
        ∂d/∂q = q/d, ∂az/∂q = (q_n, 0, −q_u)/ρ², ∂el/∂q = (−q_w q_u/ρ, ρ, −q_w q_n/ρ)/d², and ∂/∂x = (∂/∂q) Rᵀ.
        Where they do not exist (x at the RIS, or on its column axis where the azimuth is undefined) it is the
        central difference of :meth:`residuals`, as before.
        """
        x = np.asarray(x, dtype=float)
        r = self.residuals(x)
        rot = self.pose.rotation
        q = (x - self.pose.position) @ rot
        dist, rho = float(np.linalg.norm(q)), math.hypot(float(q[0]), float(q[2]))
        if not (dist > 0 and rho > 0):
            return r, central_jacobian(self.residuals, x)
        rows = [-(q / dist) / self.std_distance]
        if np.isfinite(self.std_aod[0]):
            rows.append(-np.array([q[2], 0.0, -q[0]]) / (rho**2 * self.std_aod[0]))
        if np.isfinite(self.std_aod[1]):
            rows.append(-np.array([-q[1] * q[0] / rho, rho, -q[1] * q[2] / rho]) / (dist**2 * self.std_aod[1]))
        return r, np.stack(rows) @ rot.T

    def position(self, elevation: float | None = None) -> np.ndarray:
        """The fix's own position [3] [m] (its elevation, or ``elevation`` [rad] where it cannot see it)."""
        el = self.aod[1] if elevation is None else elevation
        return self.pose.position + self.distance * self.pose.to_world(direction_from_angles([self.aod[0], el]))


@dataclass(frozen=True, eq=False)
class FusedFix:
    """The fused position of several RIS fixes.

    Attributes
    ----------
    position : float array [3]
        x̂, world frame [m].
    covariance : float array [3, 3]
        Its covariance [m²]: the inverse of the summed Fisher information; ``inf`` on the diagonal
        along a direction the fixes cannot see; widened to span the fixes when they disagree and none
        can be left out (module notes, "The compromise's covariance").
    peb : float
        sqrt(trace(covariance)) [m] (inf when a direction is unobservable).
    used : tuple of str
        The fixes in the fusion.
    excluded : tuple of (str, str)
        The fixes left out, each with why.
    statistic, threshold : float
        T at x̂ over the used fixes and its χ² level at ``pfa`` [unitless] (NaN when the used fixes
        do not over-determine the position).
    dof : int
        n − 3 of the used fixes (≤ 0: nothing to test).
    unobservable : tuple of float arrays [3]
        World directions the fixes cannot see (unit vectors).
    flags : tuple of dsp.Flag
        ``inconsistent-ris`` (fixes left out, or a disagreement that cannot be pinned on one),
        ``unobservable`` (a direction the geometry cannot see).
    """

    position: np.ndarray
    covariance: np.ndarray
    peb: float
    used: tuple[str, ...]
    excluded: tuple[tuple[str, str], ...]
    statistic: float
    threshold: float
    dof: int
    unobservable: tuple[np.ndarray, ...] = field(default_factory=tuple)
    flags: tuple[Flag, ...] = ()

    @property
    def std(self) -> np.ndarray:
        """1σ along the world axes [3] [m]."""
        return np.sqrt(np.diag(self.covariance))


def central_jacobian(fun: Any, x: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """∂fun/∂x at x by central differences [len(fun(x)), len(x)].

    Parameters
    ----------
    fun : callable
        ``x [P] -> float array [Q]``.
    x : float array [P]
        Where [x's units].
    step : float
        The difference step in x's units (1e-6: 1 µm for positions in m, 1 µm/s for velocities).

    Returns
    -------
    float array [Q, P]
    """
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = step
        cols.append((np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * step))
    return np.column_stack(cols)


def _solve(fixes: list[RisFix], start: np.ndarray,
           height: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares from ``start``: (x̂, information [3, 3] at x̂ [1/m²], T at x̂).

    A trust-region Gauss–Newton (:func:`scipy.optimize.least_squares`, ``"trf"``): plain
    Gauss–Newton steps can run away when the fixes disagree (two range circles that do not meet);
    a trust region only takes steps that lower T. Steps along a direction no fix sees are zero.
    A known ``height`` (z, σ_z) [m] is one more measurement, (z − x₃)/σ_z.
    """
    def residuals(x: np.ndarray) -> np.ndarray:
        known = [] if height is None else [np.array([(height[0] - x[2]) / height[1]])]
        return np.concatenate([f.residuals(x) for f in fixes] + known)

    def jacobian(x: np.ndarray) -> np.ndarray:
        known = [] if height is None else [np.array([[0.0, 0.0, -1.0 / height[1]]])]
        return np.vstack([f.linearised(x)[1] for f in fixes] + known)  # ∂r/∂x = −∂h/∂x / σ

    # Along a direction no fix sees the analytic Jacobian has an exactly zero singular value; at the converged
    # point scipy's trust-region subproblem then divides 0 by 0 for that step, which it rejects (T does not fall).
    with np.errstate(divide="ignore", invalid="ignore"):
        fit = scipy.optimize.least_squares(residuals, np.array(start, dtype=float), jac=jacobian, method="trf",
                                           xtol=_TOLERANCE, ftol=1e-15, gtol=1e-15, max_nfev=20 * _MAX_STEPS)
    x = fit.x
    jac, r = jacobian(x), residuals(x)
    return x, jac.T @ jac, float(r @ r)


def _rank(info: np.ndarray) -> int:
    """How many directions the information sees (eigenvalues above ``_RANK_TOLERANCE`` of the largest)."""
    vals = np.linalg.eigvalsh(info)
    return int(np.sum(vals > _RANK_TOLERANCE * max(float(vals.max()), 1e-300)))


def _covariance(info: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The inverse of the information on what it sees, ``inf`` along what it does not; the unseen directions."""
    vals, vecs = np.linalg.eigh(info)
    seen = vals > _RANK_TOLERANCE * max(float(vals.max()), 1e-300)
    cov = (vecs[:, seen] / vals[seen]) @ vecs[:, seen].T
    unseen = tuple(vecs[:, i] * np.sign(vecs[np.argmax(np.abs(vecs[:, i])), i]) for i in np.flatnonzero(~seen))
    if unseen:
        cov = cov.copy()
        for v in unseen:
            cov[np.abs(v) > 1e-6, :] = np.inf  # the axes that direction moves
            cov[:, np.abs(v) > 1e-6] = np.inf
    return cov, unseen


def _compromise_covariance(fixes: list[RisFix], x: np.ndarray, cov: np.ndarray, birge: float,
                           height: tuple[float, float] | None) -> np.ndarray:
    """The covariance [m²] of the compromise ``x`` of fixes that disagree (module notes): the equal mixture
    of each fix's own position about ``x``; ``cov`` (the inverse information, every direction seen) times
    ``birge`` (T/dof) where a fix alone cannot see every direction."""
    parts = []
    for f in fixes:
        start = f.position(None if np.isfinite(f.std_aod[1]) else 0.0)
        xi, info_i, _ = _solve([f], start, height)
        if _rank(info_i) < 3:
            return cov * max(float(birge), 1.0)
        d = xi - x
        parts.append(np.linalg.inv(info_i) + np.outer(d, d))
    return np.mean(parts, axis=0)


def _mm(cov: np.ndarray) -> str:
    """sqrt(trace(cov)) as text with its unit [m or mm]."""
    peb = float(np.sqrt(np.trace(cov)))
    return f"{1e3 * peb:.3g} mm" if peb < 1.0 else f"{peb:.3g} m"


def _describe(direction: np.ndarray) -> str:
    """'the height (z)' for a vertical direction, else the world vector."""
    if abs(direction[2]) > 0.999:
        return "the height (z)"
    return f"the world direction [{direction[0]:+.2f}, {direction[1]:+.2f}, {direction[2]:+.2f}]"


def fuse_fixes(fixes: Any, *, pfa: float = 1e-3, height: Any = None) -> FusedFix:
    """Fuse the fixes of several RISs into one position with its covariance (module notes).

    Parameters
    ----------
    fixes : sequence of RisFix
        One per detected RIS (distinct names).
    pfa : float, default 1e-3
        Probability that consistent fixes fail the χ² test (and one is left out wrongly).
    height : (float, float), optional
        The radar's known height z and its 1σ [m], world frame: one more measurement in the fusion
        and its χ² test (RISs at one height whose 1-D sweeps cannot see elevation then fix z too).

    Returns
    -------
    FusedFix

    Raises
    ------
    ValueError
        No fix, two with one name, or ``pfa`` outside (0, 1): one line naming it.
    """
    fixes = list(fixes)
    if not fixes:
        raise ValueError("fuse_fixes needs at least one RisFix (a detected RIS); none was given")
    for f in fixes:
        if not isinstance(f, RisFix):
            raise TypeError(f"fuse_fixes takes dsp.fusion.RisFix items, got {type(f).__name__}")
    names = [f.name for f in fixes]
    if len(set(names)) != len(names):
        raise ValueError(f"RIS names must be distinct, got {names}")
    pfa = finite(pfa, "pfa", "")
    if not 0 < pfa < 1:
        raise ValueError(f"pfa={pfa!r} must lie in (0, 1), e.g. 1e-3")
    if height is not None:
        h = as_finite_array(height, "height", shape=(2,))
        height = (float(h[0]), positive(float(h[1]), "height's 1σ", "m"))
    known = 0 if height is None else 1  # measurements the height adds

    def begin(f: RisFix) -> np.ndarray:
        x = f.position(None if np.isfinite(f.std_aod[1]) else 0.0)
        if height is not None and not np.isfinite(f.std_aod[1]):
            x = f.position(f.pose.angles_to(np.array([*x[:2], height[0]]))[1])  # its fix at the known height
        return x

    # the start: the single fix whose own position is best determined (smallest σ·d lever), elevation 0 if unseen
    def lever(f: RisFix) -> float:
        s_az = f.std_aod[0] if np.isfinite(f.std_aod[0]) else np.inf
        return float(np.hypot(f.std_distance, f.distance * s_az))

    used = sorted(fixes, key=lever)
    start = begin(used[0])
    excluded: list[tuple[str, str]] = []
    flags: list[Flag] = []
    disagree = False  # fixes that disagree and none can be left out: their compromise
    while True:
        x, info, stat = _solve(used, start, height)
        dof = sum(f.measurements for f in used) + known - _rank(info)
        threshold = float(scipy.stats.chi2.isf(pfa, dof)) if dof > 0 else float("nan")
        if dof <= 0 or stat <= threshold:
            break
        trials = []  # leave each fix out; the remaining fixes must still over-determine what they see
        for i, f in enumerate(used):
            rest = used[:i] + used[i + 1:]
            xr, info_r, tr = _solve(rest, x, height)
            rest_dof = sum(g.measurements for g in rest) + known - _rank(info_r)
            if rest_dof >= 1 and tr <= float(scipy.stats.chi2.isf(pfa, rest_dof)):
                trials.append((tr, i, xr))
        doubtful = [f for f in used if set(f.flags) & DOUBT_CODES]
        if not trials and doubtful and len(doubtful) < len(used):
            # the test cannot say which fix is wrong, but some carry a doubt of their own: they go
            for f in doubtful:
                excluded.append((f.name, f"its own flags ({', '.join(sorted(set(f.flags) & DOUBT_CODES))}) and the "
                                         "others disagree with it"))
            used = [f for f in used if f not in doubtful]
            start = begin(used[0])
            continue
        if not trials:
            disagree = True
            break
        _, i, xr = min(trials)
        bad = used[i]
        own = float(np.sum(bad.residuals(xr) ** 2))
        excluded.append((bad.name, f"inconsistent with the others: its residual χ² {own:.1f} over "
                                   f"{bad.measurements} measurement(s) at their fused position"))
        used = used[:i] + used[i + 1:]
        start = xr
    if excluded:
        flags.insert(0, Flag("inconsistent-ris", "left out: " + "; ".join(f"{n} ({why})" for n, why in excluded)))
    cov, unseen = _covariance(info)
    if disagree:
        if not unseen:
            cov = _compromise_covariance(used, x, cov, stat / dof, height)
        flags.append(Flag("inconsistent-ris", (
            f"the fixes of {', '.join(f.name for f in used)} disagree (χ² {stat:.1f} against {threshold:.1f} at "
            f"{dof} degrees of freedom) and no one of them explains it: the position is their compromise, its "
            f"covariance widened to span them (PEB {_mm(cov)}); check each RIS's flags (grating-lobe, "
            "unresolved-peaks) and add a RIS to tell them apart")))
    for v in unseen:
        flags.append(Flag("unobservable", (
            f"{_describe(v)} cannot be seen by the fixes of {', '.join(f.name for f in used)} (e.g. RISs at one "
            "height whose sweeps cannot see elevation): the position takes the first fix's value along it; "
            "a RIS at another height, a 2-D sweep or a known height resolves it")))
    peb = float(np.sqrt(np.trace(cov))) if not unseen else float("inf")
    return FusedFix(position=x, covariance=cov, peb=peb, used=tuple(f.name for f in used), excluded=tuple(excluded),
                    statistic=stat if dof > 0 else float("nan"), threshold=threshold, dof=int(dof),
                    unobservable=unseen, flags=tuple(flags))
