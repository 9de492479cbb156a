"""Fit the hall's materials (ε_r, σ at the carrier) to observed peak powers, by gradients through the tracer.

The engine of ``risloc calibrate --materials`` (issue 23); there is no CLI and no scene writing
here. The observations, the paths each peak explains and its model power are
:mod:`risloc_rt.hall.material_observations`; the result types :mod:`risloc_rt.hall.material_fit_result`
(both re-exported here). Every gain and derivative comes from
:func:`risloc_rt.hall.raytrace.material_gradients.material_jacobian` (no sionna import here).

Model
-----
An :class:`Observation` is one radar position [m] and its observed peaks, each a round-trip delay
[s] (as the tracer reports delays), a power [dB] and its 1σ [dB]. A peak is *explained* by the
traced monostatic paths whose delay lies within ``window`` of it (default: half the radar's
Rayleigh delay resolution, ``RadarConfig().delay_resolution / 2`` = 0.121 ns for Table I, i.e.
the paths one beat peak merges); a path within the window of two peaks goes to the nearer one.
The model power of peak k is

    P_k [dB] = 10 log10( Σ_{p ∈ k} w_p |a_p|² ) + offset_db

with ``a_p`` sionna-rt's gain (``Paths.a``, V-V, without the propagation phase),
``offset_db`` the observation's known radar/RIS constant (0 for powers in units of |a|²) and
``w_p`` the observation's optional per-path weight (the antenna pattern toward the path; 1 if none).
**Incoherent** sum: the paths that share one beat peak are distinct legs (A→B and B→A, or
different bounce sequences of nearly the same length) whose relative phase is 2π f_c Δτ; at
60 GHz a 1 mm difference in path length is 72° of phase, far below what the hall's geometry is
known to, so their phases are effectively random and the expected power is the sum of powers.
(A→B and B→A of the same bounce pair are exactly equal in length and would add coherently, a
constant +3 dB that a measured radar/RIS constant absorbs; the incoherent model is kept so a
fitted material does not depend on sub-mm geometry.)

Parameters are (ε_r, s = ln σ) per material (σ in S/m): σ > 0 by construction, ε_r ≥ 1 by
projection of every step (what sionna-rt accepts). For the materials named in ``scattering``, a
third parameter follows the 2Q: the **scattered share** u = S² of the material's reflected power
(sionna-rt's scattering coefficient S; the specular reflection keeps √(1 − u) of its amplitude per
bounce), projected onto [``SHARE_RANGE``] (S from 1e-3 to 0.995). u rather than S because the
specular loss is smooth in u at 0 (∂ ln|a|²/∂u = −1/(1 − u) per bounce) while ∂/∂S vanishes there.
The model power is that of the specular (and, where asked, diffracted/refracted) paths; the diffuse
paths are left out unless the settings ask for them (``diffuse_reflection``): sionna-rt samples each
bounce's interaction type with probabilities set by S, so their set changes with S, and inside a
peak's window they add a few hundredths of a dB (measured: −19 dB of a 0.2 m concrete wall's echo at
S = 0.3, ``docs/calibration-materials.md``). The fit is Levenberg–Marquardt on the
residuals (observed − model) [dB] weighted by 1/σ_dB, with the Jacobian of each peak's dB power

    ∂P_k[dB]/∂θ = 10/ln 10 · Σ_{p∈k} 2 Re(a_p* ∂a_p/∂θ) / Σ_{p∈k} |a_p|²,   ∂/∂s = σ ∂/∂σ,

from one ``material_jacobian`` per radar position and evaluation. The 1σ and correlations are
those of the Fisher information at the solution, (JᵀWJ)⁻¹, W = diag(1/σ_dB²).

Identifiability (reported, not guessed)
---------------------------------------
- A material that no *explained* peak touches (no path within the windows interacts with its
  objects) is refused before fitting: one-line ``ValueError`` naming it and why.
- The weighted Jacobian's columns are scaled to unit norm and decomposed (SVD); the report holds
  its singular values and condition number. A direction whose singular value is below
  ``threshold`` (default 1e-3) times the largest is **not identifiable**: every parameter whose
  component in it is ≥ 0.1 is flagged with its reason — "only a combination of ε_r and σ of M is
  seen" (e.g. powers at normal incidence: |Γ|² is one number for two parameters), "collinear
  with X" (two materials that only appear together) or "does not change any peak".
- **Choice**: the fit then does not refuse; its steps are taken in the identifiable subspace only
  (truncated SVD), so it still fits what is seen (e.g. the combination of ε_r and σ that sets
  |Γ|² at normal incidence). A flagged parameter's value is wherever those steps left it and
  means nothing on its own: it carries an **infinite σ** and NaN correlations, and
  :meth:`MaterialFit.value` refuses it with its reason. It is never returned as a bare number.
- **Profile check** (``profile_check=True``, 8Q more evaluations): every identifiable parameter
  is re-traced at ±1σ and ±2σ along its linear profile direction; the cost ½χ² should rise by 0.5
  and 2 on both sides. A rise outside [0.25, 1.0] at ±1σ or [1, 4] at ±2σ (``PROFILE_RATIO`` = 2)
  marks the parameter **weak**: its 1σ is a local figure (measured: a 0.2 m concrete wall's σ at
  60 GHz, whose |Γ|² moves by < 0.05 dB rms between 0.2 and 1.1 S/m and climbs steeply below
  0.2 S/m where the wall turns transparent). The ±2σ step was added (2026-11-27) after fits of
  emulated recordings with 16 repeats per position placed concrete's σ at 3.5 ± 1.2 S/m (true 0.6)
  with a quadratic-looking ±1σ: the likelihood was flat further out, toward the truth.

Tests (``tests/hall/test_material_fit.py``) are the engine's self-consistency check: the
"measured" peaks are made by :func:`synthetic_observations` from the same traced paths the model
uses, at changed material values, with Gaussian dB noise; the physics oracle is the tracer at the
true values.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .material_fit_result import IdentifiabilityReport, MaterialFit
from .material_observations import DEFAULT_WINDOW, Observation, assign_paths, peak_model, synthetic_observations
from .raytrace.material_gradients import MaterialJacobian, material_jacobian
from .raytrace.result import TraceSettings

__all__ = ["Observation", "MaterialFit", "IdentifiabilityReport", "fit_materials", "synthetic_observations",
           "assign_paths", "DEFAULT_WINDOW", "DEFAULT_THRESHOLD",
           "PROFILE_RATIO", "SHARE_RANGE", "SEARCH_EPS_R", "SEARCH_S", "SEARCH_DESCENTS"]

#: Default identifiability threshold: smallest singular value of the column-scaled weighted
#: Jacobian, relative to its largest, below which a direction is not identifiable (condition 1e3).
DEFAULT_THRESHOLD: float = 1e-3
#: A parameter takes part in a flagged direction when its component there is at least this.
_COMPONENT = 0.1
#: Profile check: a rise of the cost at ±1σ outside [0.5/PROFILE_RATIO, 0.5·PROFILE_RATIO] marks the 1σ as weak.
PROFILE_RATIO: float = 2.0
_LOG_SIGMA_BOUNDS = (-40.0, 20.0)  # ln σ [ln(S/m)]: 4e-18 to 5e8 S/m; at e^40 S/m sionna-rt's float32 slab model loses every path
#: The scattered share u = S² the fit moves within [unitless]: S from 1e-3 (a specular loss of 4e-6 dB per bounce,
#: nothing a peak shows) to 0.995 (the specular reflection 20 dB down per bounce). A fit at the lower end means
#: "no scattering seen"; its profile interval gives the upper bound.
SHARE_RANGE: tuple[float, float] = (1e-6, 0.995 ** 2)
#: Start search of a fit with S free: per scattering material, the cost on the grid ε_r = these factors × its start
#: ε_r [unitless] by S = :data:`SEARCH_S`, from traces without derivatives; the descent is repeated from the grid's
#: lowest local minima (at most :data:`SEARCH_DESCENTS`) and the lowest χ² kept. The (ε_r, S²) valley of the specular
#: powers has more than one minimum (measured: a concrete wall's fit from the ITU start stopped at χ² 140 beside
#: the truth's 38, 50 peaks); its basins are ≈ ±0.25 wide in ε_r, hence the step of 0.05 × ε_r.
SEARCH_EPS_R: tuple[float, ...] = tuple(float(x) for x in np.round(np.linspace(0.6, 1.6, 21), 3))
#: The scattering coefficients of the start search's grid [unitless].
SEARCH_S: tuple[float, ...] = (0.0, 0.15, 0.3, 0.45, 0.6, 0.75, 0.9)
#: Most descents started from the search grid's local minima, per scattering material.
SEARCH_DESCENTS: int = 3


def _values_of(materials: Sequence[str], theta: np.ndarray,
               scattering: Sequence[str] = ()) -> dict[str, tuple[float, ...]]:
    """``{material: (ε_r, σ)}`` of a parameter vector, with S = √(S²) third for the ``scattering`` materials."""
    out: dict[str, tuple[float, ...]] = {m: (float(theta[2 * q]), float(math.exp(theta[2 * q + 1])))
                                         for q, m in enumerate(materials)}
    for j, m in enumerate(scattering):
        out[m] = (*out[m], float(math.sqrt(theta[2 * len(materials) + j])))
    return out


def _project(theta: np.ndarray, q: int) -> np.ndarray:
    """``theta`` moved into what the tracer accepts: ε_r ≥ 1, ln σ and S² within their bounds (a copy)."""
    out = np.array(theta, dtype=float)
    out[0:2 * q:2] = np.maximum(out[0:2 * q:2], 1.0)
    out[1:2 * q:2] = np.clip(out[1:2 * q:2], *_LOG_SIGMA_BOUNDS)
    out[2 * q:] = np.clip(out[2 * q:], *SHARE_RANGE)
    return out


def _check_start(materials: tuple[str, ...], start: Any, own: MaterialJacobian | None,
                 scattering: tuple[str, ...] = ()) -> np.ndarray:
    """The start vector: given values, else the scene's own (``own``); S² raised to ``SHARE_RANGE``'s lower end."""
    q_count = len(materials)
    theta = np.empty(2 * q_count + len(scattering))
    start = {} if start is None else start
    if not isinstance(start, Mapping):
        raise TypeError(f"start must be a mapping {{material: (eps_r, sigma [S/m][, S])}}, got {type(start).__name__}")
    for name in start:
        if name not in materials:
            raise ValueError(f"start names {name!r}, which is not among the fitted materials {', '.join(materials)}")
    for q, m in enumerate(materials):
        given = start[m] if own is None else start.get(m, (own.relative_permittivity[q], own.conductivity[q],
                                                             own.scattering_coefficient[q]))
        try:
            eps, sigma, *rest = (float(x) for x in given)
        except (TypeError, ValueError):
            raise ValueError(f"start[{m!r}]={given!r} must be (eps_r, sigma [S/m]) or (eps_r, sigma, S)") from None
        if len(rest) > 1:
            raise ValueError(f"start[{m!r}]={given!r} must be (eps_r, sigma [S/m]) or (eps_r, sigma, S)")
        if not (math.isfinite(eps) and eps >= 1.0):
            raise ValueError(f"start[{m!r}] eps_r={eps!r} must be finite and >= 1")
        if not (math.isfinite(sigma) and sigma > 0.0):
            raise ValueError(f"start[{m!r}] sigma={sigma!r} must be finite and > 0 S/m (the fit works in ln sigma)")
        if rest and not (math.isfinite(rest[0]) and 0.0 <= rest[0] <= 1.0):
            raise ValueError(f"start[{m!r}] S={rest[0]!r} must be a scattering coefficient in [0, 1]")
        theta[2 * q], theta[2 * q + 1] = float(eps), math.log(float(sigma))
        if m in scattering:
            share = rest[0] ** 2 if rest else 0.0
            theta[2 * q_count + scattering.index(m)] = min(max(share, SHARE_RANGE[0]), SHARE_RANGE[1])
    return theta


def _fixed_parameters(fixed: Any, names: tuple[str, ...], scattering: tuple[str, ...] = ()) -> set[str]:
    """The held parameters as column names (``"m:eps_r"``, ``"m:ln_sigma"``, ``"m:scattering"``); one-line
    ValueError for a bad one."""
    items = [fixed] if isinstance(fixed, str) else list(fixed)
    out = set()
    for item in items:
        m, _, kind = str(item).rpartition(":")
        if m not in names or kind not in ("eps_r", "sigma", "scattering") or (kind == "scattering"
                                                                              and m not in scattering):
            raise ValueError(f"fixed parameter {item!r} must be MATERIAL:eps_r or MATERIAL:sigma with MATERIAL one of "
                             f"the fitted materials ({', '.join(names)})"
                             + (f", or MATERIAL:scattering for {', '.join(scattering)}" if scattering else ""))
        out.add(f"{m}:{'ln_sigma' if kind == 'sigma' else kind}")
    return out


def _flags(vt: np.ndarray, s: np.ndarray, threshold: float, names: tuple[str, ...]) -> dict[str, str]:
    """Reasons for every parameter taking part in a direction below the threshold."""
    out: dict[str, str] = {}
    top = s[0] if s.size and s[0] > 0 else 0.0
    for i in range(s.size):
        if top > 0 and s[i] >= threshold * top:
            continue
        v = vt[i]
        part = [j for j in range(v.size) if abs(v[j]) >= _COMPONENT]
        mats = sorted({names[j].split(":")[0] for j in part})
        combo = " ".join(f"{v[j]:+.2f}*{names[j]}" for j in part)
        rel = s[i] / top if top > 0 else 0.0
        for j in part:
            m, kind = names[j].split(":")
            if len(part) == 1:
                reason = f"{kind} of {m} does not change any explained peak's power (relative singular value {rel:.1e})"
            elif len(mats) == 1:
                kinds = " and ".join(dict.fromkeys(names[i].split(":")[1].replace("ln_sigma", "sigma") for i in part))
                reason = (f"only a combination of {kinds} of {m} is seen ({combo} unresolved, relative "
                          f"singular value {rel:.1e}): e.g. powers at one incidence angle give one |Gamma|^2 for two "
                          f"parameters")
            else:
                others = ", ".join(x for x in mats if x != m)
                reason = f"collinear with {others} ({combo} unresolved, relative singular value {rel:.1e})"
            out.setdefault(names[j], reason)
    return out


def fit_materials(
    scene: str | os.PathLike[str],
    observations: Sequence[Observation],
    materials: str | Sequence[str],
    *,
    start: Mapping[str, tuple[float, float]] | None = None,
    settings: TraceSettings | None = None,
    window: float = DEFAULT_WINDOW,
    threshold: float = DEFAULT_THRESHOLD,
    max_iter: int = 30,
    tolerance: float = 1e-6,
    progress: Callable[[int, float], None] | None = None,
    profile_check: bool = True,
    fixed: Sequence[str] = (),
    scattering: str | Sequence[str] = (),
    search: bool = True,
) -> MaterialFit:
    """Fit the named materials' ε_r and σ (and S) to the observed peak powers (Levenberg–Marquardt, dB residuals).

    Parameters
    ----------
    scene : path-like
        Scene folder (``scenes/<name>/``) or its ``scene.xml``.
    observations : sequence of Observation
        Radar positions [m] with their peaks (delay [s], power [dB], 1σ [dB]).
    materials : str or sequence of str
        Radio materials to fit (sionna-rt names, e.g. ``"concrete-200mm"``): a list or ``"a,b"``.
    start : mapping, optional
        ``{material: (ε_r [unitless], σ [S/m])}`` or ``(ε_r, σ, S)``; materials not given start
        from the scene's own values (ITU-R P.2040 at 60 GHz, the spec's S). Other materials keep
        the scene's values throughout. A fitted S starts at least at √``SHARE_RANGE[0]`` = 1e-3.
    settings : TraceSettings, optional
        Solver options (default ``TraceSettings()``); depth ≥ 3 is what makes ε_r and σ
        separable (``docs/calibration-materials.md``).
    window : float
        Delay window explaining a peak [s] (default half Table I's delay resolution, 0.121 ns).
    threshold : float
        Identifiability threshold on the relative singular values (default 1e-3), in (0, 1).
    max_iter : int
        Most Levenberg–Marquardt iterations (default 30).
    tolerance : float
        Convergence: an accepted step lowering the cost by less than ``tolerance`` × cost (+1e-9).
    progress : callable, optional
        ``progress(iteration, cost)`` after every iteration (cost = ½χ² [unitless]).
    profile_check : bool
        Re-trace at ±1σ and ±2σ of every identifiable parameter along its profile direction (8Q more
        evaluations) and report the cost's rise (``IdentifiabilityReport.profile_cost``,
        ``profile_cost_2sigma``, ``weak``).
    fixed : sequence of str
        Parameters held at their start value, ``"<material>:eps_r"``, ``"<material>:sigma"`` or
        ``"<material>:scattering"`` (e.g. ε_r known from elsewhere when the peaks see only one
        combination of ε_r and σ): their Jacobian columns are set to 0, their 1σ is 0 and the
        others' 1σ are conditional on them. Every parameter may be held: the result is then the
        χ² at the start values (e.g. a profile point over a parameter this engine does not fit).
    scattering : str or sequence of str
        Materials among ``materials`` whose scattering coefficient S is fitted too, as the
        scattered share S² (a list or ``"a,b"``; default none: S stays the scene's).
    search : bool
        With ``scattering``: search each scattering material's (ε_r, S) grid for other valleys and
        descend from its lowest local minima too (:data:`SEARCH_EPS_R`; ``False`` for a fit that
        continues from a known solution, e.g. the profile's conditional fits).

    Returns
    -------
    MaterialFit
        Values, 1σ, correlations, residuals before/after [dB], identifiability report, timing.

    Raises
    ------
    ValueError
        No observations; a material that no explained peak touches (named, with why); no peak
        explained at all; a bad start, window, threshold or max_iter. Errors of
        ``material_jacobian`` (unknown material, bad settings) pass through.
    """
    t0 = time.perf_counter()
    obs = list(observations) if isinstance(observations, Sequence) else None
    if not obs:
        raise ValueError("observations is empty: give at least one Observation")
    for i, o in enumerate(obs):
        if not isinstance(o, Observation):
            raise TypeError(f"observations[{i}] must be an Observation, got {type(o).__name__}")
    if not (isinstance(window, (int, float)) and math.isfinite(window) and window > 0):
        raise ValueError(f"window={window!r} must be finite and > 0 [s]")
    if not (isinstance(threshold, (int, float)) and 0 < threshold < 1):
        raise ValueError(f"threshold={threshold!r} must lie in (0, 1)")
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 0:
        raise ValueError(f"max_iter={max_iter!r} must be an int >= 0")
    settings = TraceSettings() if settings is None else settings

    if isinstance(materials, str):
        names = tuple(m.strip() for m in materials.split(","))
    else:
        names = tuple(materials)
    if isinstance(scattering, str):
        scattering = [m.strip() for m in scattering.split(",") if m.strip()]
    if not isinstance(scattering, Sequence):
        raise TypeError(f"scattering must be material names, got {type(scattering).__name__}")
    rough = tuple(m for m in names if m in scattering)
    if len(rough) != len(set(scattering)):
        unknown = sorted({str(m) for m in scattering} - set(names))
        raise ValueError(f"scattering names {', '.join(map(repr, unknown))}, not among the fitted materials "
                         f"({', '.join(map(str, names))})")

    evaluations = 0
    searched = 0

    def evaluate(theta: np.ndarray | None, derivatives: bool = True) -> dict[str, Any]:
        nonlocal evaluations, searched
        if derivatives:
            evaluations += 1
        else:
            searched += 1
        values = None if theta is None else _values_of(names, theta, rough)
        rows, jrows, wrows, touch, peaks, unexplained, model = [], [], [], [], [], [], []
        jacs = []
        for i, o in enumerate(obs):
            jac = material_jacobian(scene, o.radar_position, names, values=values, settings=settings,
                                    scattering=rough, derivatives=derivatives)
            jacs.append(jac)
            db, jdb, t, explained = peak_model(jac, assign_paths(jac.delay, o.delay, window), len(o), o.path_weight)
            offsets = o.offsets()
            for k in range(len(o)):
                if explained[k]:
                    peaks.append((i, k))
                    model.append(db[k] + offsets[k])
                    rows.append(o.power_db[k] - db[k] - offsets[k])
                    jrows.append(jdb[k])
                    wrows.append(1.0 / o.sigma_db[k])
                    touch.append(t[k])
                else:
                    unexplained.append((i, k))
        q2 = 2 * len(names) + len(rough)
        return dict(residual=np.array(rows), jdb=np.array(jrows).reshape(-1, q2), w=np.array(wrows),
                    theta_given=theta is not None,
                    touches=np.array(touch, dtype=bool).reshape(-1, len(names)), peaks=tuple(peaks),
                    unexplained=tuple(unexplained), jacs=jacs)

    if isinstance(start, Mapping) and names and all(isinstance(m, str) and m in start for m in names):
        # Every material starts from a given value (e.g. the profile scan's conditional fits): no trace at the
        # scene's own values is needed.
        theta = _check_start(names, start, None, rough)
        first = evaluate(theta)
        names = first["jacs"][0].materials
    else:
        first = evaluate(None)
        names = first["jacs"][0].materials
        theta = _check_start(names, start, first["jacs"][0], rough)
    q_count = len(names)
    params = tuple(f"{m}:{k}" for m in names for k in ("eps_r", "ln_sigma")) + tuple(f"{m}:scattering" for m in rough)
    held = _fixed_parameters(fixed, names, rough)
    mask = np.array([p in held for p in params], dtype=bool)
    if not first["peaks"]:
        raise ValueError(f"no observed peak is explained: no traced path lies within {window * 1e9:.3g} ns of any of "
                         f"the {sum(len(o) for o in obs)} peaks")
    for q, m in enumerate(names):
        if not first["touches"][:, q].any():
            seen = any(j.touches[:, q].any() for j in first["jacs"])
            why = ("its traced paths fall in no observed peak's window" if seen
                   else "no traced path from these radar positions interacts with its objects")
            raise ValueError(f"material {m!r} cannot be fitted: no explained peak touches it ({why})")
    # The scene's own values are the start unless some were given (or a fitted S was raised to SHARE_RANGE's end).
    cur = first if first["theta_given"] or (start is None and not rough) else evaluate(theta)
    start_values = _values_of(names, theta, rough)
    theta_start = theta.copy()
    residual_start = cur["residual"].copy()

    def cost_of(ev: dict[str, Any]) -> float:
        r = ev["residual"] * ev["w"]
        return 0.5 * float(r @ r)

    def descend(theta: np.ndarray, cur: dict[str, Any], iteration0: int) -> tuple[np.ndarray, dict[str, Any], float,
                                                                                 int, list[float], bool]:
        """Levenberg–Marquardt from ``theta``: (θ, its evaluation, cost, iterations, costs, converged)."""
        cost = cost_of(cur)
        lam = 1e-3
        history: list[float] = []
        converged = False
        iterations = 0
        for it in range(1, max_iter + 1):
            iterations = it
            jw = cur["jdb"] * cur["w"][:, None]
            jw[:, mask] = 0.0
            rw = cur["residual"] * cur["w"]
            norm = np.linalg.norm(jw, axis=0)
            norm[norm == 0] = 1.0
            u, s, vt = np.linalg.svd(jw / norm, full_matrices=False)
            keep = s >= threshold * s[0] if s.size and s[0] > 0 else np.zeros(s.size, bool)
            accepted = False
            while not accepted and lam < 1e12:
                damp = s[keep] / (s[keep] ** 2 + lam * s[0] ** 2)
                step = (vt[keep].T @ (damp * (u[:, keep].T @ rw))) / norm
                # The linear model's decrease of the cost for this step: below the tolerance no trial can pass it,
                # so the fit has converged (saves the ~20 rejected trials that would raise the damping to its limit).
                resid = rw - jw @ step
                if cost - 0.5 * float(resid @ resid) <= tolerance * cost + 1e-9:
                    break
                trial = _project(theta + step, q_count)
                if np.allclose(trial, theta, rtol=0, atol=1e-12):
                    break
                ev = evaluate(trial)
                new = cost_of(ev)
                if new < cost:
                    accepted = True
                    converged = cost - new <= tolerance * cost + 1e-9
                    theta, cur, cost = trial, ev, new
                    lam = max(lam / 3.0, 1e-9)
                else:
                    lam *= 4.0
            history.append(cost)
            if progress is not None:
                progress(iteration0 + it, cost)
            if not accepted or converged:
                converged = True if not accepted else converged
                break
        return theta, cur, cost, iterations, history, converged

    theta, cur, cost, iterations, history, converged = descend(theta, cur, 0)
    # A fitted S: search the (ε_r, S) grid of each scattering material for other valleys (SEARCH_EPS_R).
    for j, m in enumerate(rough if max_iter > 0 and search else ()):
        q = names.index(m)
        e_col, s_col = 2 * q, 2 * q_count + j
        e_free, s_free = f"{m}:eps_r" not in held, f"{m}:scattering" not in held
        if not s_free:
            continue
        eps_grid = [theta_start[e_col] * f for f in SEARCH_EPS_R] if e_free else [theta[e_col]]
        eps_grid = sorted({max(e, 1.0) for e in eps_grid})
        grid = np.full((len(eps_grid), len(SEARCH_S)), np.inf)
        for a, e in enumerate(eps_grid):
            for b, sc_ in enumerate(SEARCH_S):
                trial = theta.copy()
                trial[e_col], trial[s_col] = e, sc_ ** 2
                grid[a, b] = cost_of(evaluate(_project(trial, q_count), derivatives=False))
        padded = np.pad(grid, 1, constant_values=np.inf)
        centre = padded[1:-1, 1:-1]
        minima = ((centre <= padded[:-2, 1:-1]) & (centre <= padded[2:, 1:-1]) & (centre <= padded[1:-1, :-2])
                  & (centre <= padded[1:-1, 2:]))
        for flat in sorted(np.flatnonzero(minima), key=lambda i: grid.flat[i])[:SEARCH_DESCENTS]:
            a, b = np.unravel_index(flat, grid.shape)
            other = theta.copy()
            other[e_col], other[s_col] = eps_grid[a], SEARCH_S[b] ** 2
            other = _project(other, q_count)
            found = descend(other, evaluate(other), iterations)
            iterations += found[3]
            history += found[4]
            if found[2] < cost - 1e-9:
                theta, cur, cost, _, _, converged = found

    # Fisher information at the solution, in column-scaled coordinates.
    jw = cur["jdb"] * cur["w"][:, None]
    jw[:, mask] = 0.0
    norm = np.linalg.norm(jw, axis=0)
    safe = np.where(norm == 0, 1.0, norm)
    free = jw[:, ~mask] / safe[~mask]
    # Fewer peaks than free parameters: pad with zero rows, so that the directions no peak sees get their
    # singular value 0 (and are flagged) instead of being left out of the decomposition.
    free = np.vstack([free, np.zeros((max(0, free.shape[1] - free.shape[0]), free.shape[1]))])
    if free.shape[1]:
        _, s, vt = np.linalg.svd(free, full_matrices=False)
    else:  # every parameter held: nothing to decompose
        s, vt = np.zeros(0), np.zeros((0, 0))
    vt_full = np.zeros((vt.shape[0], len(params)))
    vt_full[:, ~mask] = vt
    vt = vt_full
    flags = _flags(vt, s, threshold, params)
    keep = s >= threshold * s[0] if s.size and s[0] > 0 else np.zeros(s.size, bool)
    cov_scaled = (vt[keep].T / s[keep] ** 2) @ vt[keep]
    cov = cov_scaled / np.outer(safe, safe)
    bad = np.array([p in flags for p in params])
    cov[mask, :] = 0.0
    cov[:, mask] = 0.0
    cov[bad, :] = np.nan
    cov[:, bad] = np.nan
    cov[bad, bad] = np.inf
    sd = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr[bad | mask, :] = np.nan
    corr[:, bad | mask] = np.nan
    condition = (float(s[0] / s[-1]) if s[-1] > 0 else math.inf) if s.size else 1.0
    profile: dict[str, tuple[float, float]] = {}
    profile2: dict[str, tuple[float, float]] = {}
    weak: dict[str, str] = {}
    if profile_check:
        for i, p in enumerate(params):
            if p in flags or p in held:
                continue
            direction = np.where(np.isfinite(cov[:, i]), cov[:, i], 0.0) / sd[i]
            rise = {}
            for step in (-2.0, -1.0, 1.0, 2.0):
                trial = _project(theta + step * direction, q_count)
                rise[step] = cost_of(evaluate(trial)) - cost
            profile[p] = (float(rise[-1.0]), float(rise[1.0]))
            profile2[p] = (float(rise[-2.0]), float(rise[2.0]))
            if not all(0.5 / PROFILE_RATIO <= rise[k] <= 0.5 * PROFILE_RATIO for k in (-1.0, 1.0)):
                weak[p] = (f"the cost rises by {rise[-1.0]:.3g} at -1 sigma and {rise[1.0]:.3g} at +1 sigma instead of "
                           f"0.5: the likelihood is not quadratic over its stated 1 sigma, which is a local figure only")
            elif not all(2.0 / PROFILE_RATIO <= rise[k] <= 2.0 * PROFILE_RATIO for k in (-2.0, 2.0)):
                weak[p] = (f"the cost rises by {rise[-2.0]:.3g} at -2 sigma and {rise[2.0]:.3g} at +2 sigma instead of "
                           f"2: the likelihood is not quadratic beyond its stated 1 sigma, which is a local figure only")
    report = IdentifiabilityReport(
        parameters=params, peaks=cur["peaks"], unexplained=cur["unexplained"], constrains=cur["touches"],
        jacobian_db=cur["jdb"], singular_values=s, condition=condition, threshold=float(threshold),
        not_identifiable=flags, profile_cost=profile, weak=weak, fixed=tuple(p for p in params if p in held),
        profile_cost_2sigma=profile2)
    for arr in (cov, corr, sd, s, cur["jdb"], cur["touches"]):
        arr.setflags(write=False)
    eps = theta[0:2 * q_count:2].copy()
    sigma = np.exp(theta[1:2 * q_count:2])
    share = theta[2 * q_count:].copy()
    residual = cur["residual"].copy()
    eps_sd, log_sd, share_sd = sd[0:2 * q_count:2].copy(), sd[1:2 * q_count:2].copy(), sd[2 * q_count:].copy()
    for arr in (eps, sigma, share, residual, residual_start, eps_sd, log_sd, share_sd):
        arr.setflags(write=False)
    r = residual * cur["w"]
    return MaterialFit(
        materials=names, relative_permittivity=eps, conductivity=sigma, relative_permittivity_sigma=eps_sd,
        log_conductivity_sigma=log_sd, covariance=cov, correlation=corr, start=start_values,
        residuals_start_db=residual_start, residuals_db=residual, chi2=float(r @ r), iterations=iterations,
        evaluations=evaluations, converged=converged, seconds=time.perf_counter() - t0, identifiability=report,
        history=tuple(history), scattering=rough, scattering_share=share, scattering_share_sigma=share_sd,
        search_evaluations=searched)
