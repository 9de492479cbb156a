"""A radar that moves: an extended Kalman filter on each RIS's measurement as it arrives (issue 22, first part).

State ``s = [x, y, z, vx, vy, vz]`` (world frame) [m, m/s], nearly constant velocity: white
acceleration noise of spectral density ``q`` [m²/s³] per axis, so over a step Δt

    F = [[I, Δt I], [0, I]],   Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]].

A measurement is one RIS's answer for one sweep, at that sweep's reference time
(``Localization.reference_time`` plus the sweep's start): the distance, the azimuth (and the
elevation where the sweep sees it) and the radial velocity, each with its 1σ
(:class:`RisMeasurement`). The filter updates on each as it arrives — one RIS at a time, not only
on fused fixes — with the measurement function

    h(s) = (‖p − pᵢ‖, az(Rᵢᵀ(p − pᵢ)), el(…), v · (p − pᵢ)/‖p − pᵢ‖),

its Jacobian in closed form (:meth:`RisMeasurement.linearised`), the azimuth innovation wrapped to (−π, π],
relinearised at the updated state until it settles (the iterated extended Kalman filter: a prior a metre wide
against millimetre measurements is beyond one linearisation, whose update was overconfident, NEES 27 for 6),
and the Joseph form of the covariance update (symmetric and positive definite in floating
point). Each update's
normalised innovation squared (NIS) is χ² with as many degrees of freedom as the measurement has
numbers when the filter is consistent; a measurement whose NIS exceeds its χ² level at ``gate_pfa``
is not used (a grating twin, a path taken for the return) and is returned as rejected. A sweep with
no detection gives no measurement: the filter coasts (predicts only), and its covariance says how
far it may have drifted.

**A known height.** A sweep in azimuth only gives distance, azimuth and radial velocity: with the
RISs at the radar's height the height is unobservable (its mirror image below the sweep plane gives
the same numbers). A radar carried at a known height (a robot, a trolley: the one-RIS CLI's
``--ue-height``) adds one pseudo-measurement to every update, ``z = h ± σ_h`` (``height=(h, σ_h)``
of :func:`start_track` and :func:`update`); the filter then tracks the horizontal position and
velocity, and its consistency is judged on those (:func:`nees` with ``axes=HORIZONTAL``).

**Manoeuvres.** A walker goes straight and turns; one white-acceleration density cannot serve both
(loose enough for a turn, the track copies every fix on the straight legs; tight, it falls behind at
the turn). :class:`Manoeuvres` holds two nearly-constant-velocity models, quiet (q₀) and turning
(q₁), switching as a two-state Markov chain in continuous time; :func:`imm_start`,
:func:`imm_predict` and :func:`imm_update` are the interacting multiple model filter over them
(mixing, each model predicted and updated with the iterated update above, each model's probability
reweighted by the likelihood of the measurement under its prediction); :class:`ImmState` gives the
mixture's mean and covariance (the models' spread included), which :func:`nees` reads as it reads a
:class:`TrackState`. A measurement beyond both models' gates is rejected; a model whose own gate it
is beyond keeps its prediction. ``docs/tracking.md``, "Manoeuvres", has the calibration and the
measured consistency.

Why not filterpy or Stone Soup (``docs/tracking.md``, "Why our own filter"): the filter here is
about a hundred lines of NumPy around one measurement function that must wrap the azimuth, drop
the angles a sweep cannot see and append the known height. filterpy's ``ExtendedKalmanFilter``
(last release 2018) has no iterated update, which this problem needs (a first fix metres wide
against millimetre measurements), so the relinearisation loop would be ours anyway. Stone Soup
has what is needed — a constant-velocity transition model with this Q and an
``IteratedKalmanUpdater`` of the same equations — but it is a framework (its own state,
hypothesis and model types, and ruamel.yaml, pymap3d, utm, rtree among its dependencies) that
``dsp/`` may not import (numpy and scipy only, ``docs/architecture.md``); wrapping our
measurement function in its model types would give the same filter. Ours is not a better filter
than Stone Soup's; it is the same filter without the framework, tested by the same NEES/NIS
consistency checks a library filter would need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats

from .fusion import RisFix, central_jacobian
from .validation import finite, positive

__all__ = ["RisMeasurement", "TrackState", "TrackUpdate", "predict", "update", "start_track", "nees", "HORIZONTAL",
           "ALL_AXES", "nees_band", "Manoeuvres", "ImmState", "imm_start", "imm_predict", "imm_update"]

#: State indices of the horizontal position and velocity (x, y, vx, vy).
HORIZONTAL = (0, 1, 3, 4)
#: Every state index (x, y, z, vx, vy, vz).
ALL_AXES = (0, 1, 2, 3, 4, 5)


def _height(height: Any) -> tuple[float, float] | None:
    """``(h, σ_h)`` [m] checked, or None."""
    if height is None:
        return None
    try:
        h, sd = (float(x) for x in height)
    except (TypeError, ValueError):
        raise ValueError(f"height={height!r} must be (h, σ_h) [m], e.g. (1.2, 0.01)") from None
    return finite(h, "height", "m"), positive(sd, "height σ", "m")


@dataclass(frozen=True, eq=False)
class RisMeasurement:
    """One RIS's answer for one sweep, at the time it refers to.

    Attributes
    ----------
    time : float
        The sweep's reference time (its start plus ``Localization.reference_time``) [s].
    fix : RisFix
        The RIS, the distance and AoD with their 1σ.
    velocity : float
        Radial velocity, positive receding from the RIS [m/s]; NaN when not measured.
    std_velocity : float
        Its 1σ [m/s]; NaN when not measured.
    """

    time: float
    fix: RisFix
    velocity: float = float("nan")
    std_velocity: float = float("nan")

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", finite(self.time, "RisMeasurement time", "s"))
        if not isinstance(self.fix, RisFix):
            raise TypeError(f"RisMeasurement fix must be a dsp.RisFix, got {type(self.fix).__name__}")
        if np.isfinite(self.velocity) != np.isfinite(self.std_velocity):
            raise ValueError(f"RIS {self.fix.name}: give the radial velocity and its 1σ together (or neither)")
        if np.isfinite(self.std_velocity):
            positive(self.std_velocity, f"RIS {self.fix.name}: std_velocity", "m/s")

    def _radial(self, state: np.ndarray) -> tuple[float, np.ndarray, float]:
        """v_r = v·u [m/s], u = (x − p)/d [3] and d [m] at ``state`` (v_r 0 and u 0 at the RIS)."""
        rel = state[:3] - self.fix.pose.position
        dist = float(np.linalg.norm(rel))
        if not dist > 0:
            return 0.0, np.zeros(3), 0.0
        unit = rel / dist
        return float(state[3:] @ unit), unit, dist

    def normalised_residuals(self, state: np.ndarray) -> np.ndarray:
        """(z − h(s)) / σ for every number the measurement has [unitless]."""
        r = self.fix.residuals(state[:3])
        if np.isfinite(self.std_velocity):
            r = np.append(r, (self.velocity - self._radial(state)[0]) / self.std_velocity)
        return r

    def linearised(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normalised residuals at ``state`` and their Jacobian ∂r/∂s [n], [n, 6] [1/m, s/m].

        The fix's rows from :meth:`dsp.fusion.RisFix.linearised` (zero in velocity); the radial velocity's
        v_r = v·u (u = (x − p)/d) gives ∂v_r/∂x = (v − v_r u)/d and ∂v_r/∂v = u.
        """
        state = np.asarray(state, dtype=float)
        r, jac_x = self.fix.linearised(state[:3])
        jac = np.zeros((jac_x.shape[0], 6))
        jac[:, :3] = jac_x
        if np.isfinite(self.std_velocity):
            v_r, unit, dist = self._radial(state)
            row = np.zeros(6)
            if dist > 0:
                row[:3], row[3:] = -(state[3:] - v_r * unit) / dist, -unit
            r = np.append(r, (self.velocity - v_r) / self.std_velocity)
            jac = np.vstack([jac, row / self.std_velocity])
        return r, jac


@dataclass(frozen=True, eq=False)
class TrackState:
    """The filter's estimate at one time.

    Attributes
    ----------
    time : float
        [s].
    mean : float array [6]
        [x, y, z, vx, vy, vz] [m, m/s].
    covariance : float array [6, 6]
        [m², m²/s, m²/s²].
    """

    time: float
    mean: np.ndarray
    covariance: np.ndarray

    @property
    def position_std(self) -> np.ndarray:
        """1σ of x, y, z [3] [m]."""
        return np.sqrt(np.diag(self.covariance)[:3])


@dataclass(frozen=True, eq=False)
class TrackUpdate:
    """What one measurement did to the track.

    Attributes
    ----------
    state : TrackState
        After the update (the prediction when rejected).
    nis : float
        The normalised innovation squared at the prediction [unitless].
    dof : int
        Its degrees of freedom (the measurement's numbers).
    gate : float
        The χ² level it was held against.
    accepted : bool
        The NIS was within the gate and the update made.
    ris : str
        The RIS it came from.
    """

    state: TrackState
    nis: float
    dof: int
    gate: float
    accepted: bool
    ris: str = field(default="")


def start_track(measurement: RisMeasurement, *, speed_std: float = 1.0, height: Any = None) -> TrackState:
    """A track from one measurement: its own position (elevation 0 where unseen, with a 1σ of its distance
    along the unseen direction), velocity 0 ± ``speed_std`` [m/s] per axis.

    Parameters
    ----------
    measurement : RisMeasurement
    speed_std : float
        1σ of the unknown starting velocity per axis [m/s].
    height : (float, float), optional
        A known height ``(h, σ_h)`` [m] (module notes): an unseen elevation is the one that puts the
        radar at h, and z starts at h ± σ_h.

    Returns
    -------
    TrackState
    """
    fix = measurement.fix
    speed_std = positive(speed_std, "speed_std", "m/s")
    known = _height(height)
    sees_el = bool(np.isfinite(fix.std_aod[1]))
    el0 = fix.aod[1] if sees_el else 0.0
    if known is not None and not sees_el:  # the elevation that puts the radar at h (the nearest end if none does)
        def above(el: float) -> float:
            return float(fix.pose.point_at(np.array([fix.aod[0], el]), fix.distance)[2]) - known[0]

        ends = (-0.5 * math.pi, 0.5 * math.pi)
        if above(ends[0]) * above(ends[1]) < 0:
            el0 = float(scipy.optimize.brentq(above, *ends, xtol=1e-12))
        else:
            el0 = min(ends, key=lambda e: abs(above(e)))
    params = np.array([fix.distance, fix.aod[0], el0])
    # 1σ of distance, azimuth and elevation; an elevation the sweep cannot see: ±1 rad, a broad prior
    sigma = np.array([fix.std_distance, fix.std_aod[0] if np.isfinite(fix.std_aod[0]) else math.pi,
                      fix.std_aod[1] if sees_el else 1.0])

    def place(p: np.ndarray) -> np.ndarray:
        return fix.pose.point_at(p[1:], p[0])

    jac = central_jacobian(place, params)  # ∂position/∂(d, az, el)
    big = np.zeros((6, 6))
    big[:3, :3] = jac @ np.diag(sigma**2) @ jac.T
    big[3:, 3:] = np.eye(3) * speed_std**2
    mean = np.concatenate([place(params), np.zeros(3)])
    if known is not None:  # z is given: h ± σ_h, uncorrelated with the rest
        mean[2] = known[0]
        big[2, :] = big[:, 2] = 0.0
        big[2, 2] = known[1] ** 2
    return TrackState(time=measurement.time, mean=mean, covariance=big)


def predict(state: TrackState, time: float, *, accel_density: float) -> TrackState:
    """The state at ``time`` under nearly constant velocity (module notes).

    Parameters
    ----------
    state : TrackState
    time : float
        [s], not before ``state.time``.
    accel_density : float
        q, the white acceleration's spectral density [m²/s³] per axis (e.g. 0.5 for a walking person).

    Returns
    -------
    TrackState
    """
    t = finite(time, "time", "s")
    dt = t - state.time
    if dt < 0:
        raise ValueError(f"time {t} s is before the track's {state.time} s: measurements must come in time order")
    q = positive(accel_density, "accel_density", "m²/s³")
    f = np.eye(6)
    f[:3, 3:] = np.eye(3) * dt
    qm = np.zeros((6, 6))
    qm[:3, :3] = np.eye(3) * dt**3 / 3
    qm[:3, 3:] = qm[3:, :3] = np.eye(3) * dt**2 / 2
    qm[3:, 3:] = np.eye(3) * dt
    cov = f @ state.covariance @ f.T + q * qm
    return TrackState(time=t, mean=f @ state.mean, covariance=0.5 * (cov + cov.T))


def _linearised(measurement: RisMeasurement, x: np.ndarray,
                height: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The innovation (z − h(x))/σ and ∂h/∂s/σ at x [n], [n, 6] (analytic, :meth:`RisMeasurement.linearised`); a
    known height appends (h − z)/σ_h."""
    r, jac = measurement.linearised(x)
    if height is not None:
        row = np.zeros((1, 6))
        row[0, 2] = -1.0 / height[1]
        r, jac = np.append(r, (height[0] - x[2]) / height[1]), np.vstack([jac, row])
    return r, -jac


def nees(state: TrackState, truth: Any, *, axes: Any = ALL_AXES) -> float:
    """The normalised estimation error squared (x − x̂)ᵀ P⁻¹ (x − x̂) over ``axes`` [unitless].

    χ² with ``len(axes)`` degrees of freedom when the filter's covariance is honest.

    Parameters
    ----------
    state : TrackState
    truth : float array [6]
        The true [x, y, z, vx, vy, vz] at ``state.time`` [m, m/s].
    axes : sequence of int
        The state indices judged (:data:`HORIZONTAL` when the height is given).

    Returns
    -------
    float
    """
    idx = np.asarray(axes, dtype=int)
    e = (np.asarray(truth, dtype=float) - state.mean)[idx]
    return float(e @ np.linalg.solve(state.covariance[np.ix_(idx, idx)], e))


#: Relinearisations of the iterated update at most.
_ITERATIONS = 10


def _innovation(prior: TrackState, measurement: RisMeasurement,
                known: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """At the prediction: the normalised innovation r, its Jacobian H, its covariance S = H P Hᵀ + I and the NIS."""
    r0, h0 = _linearised(measurement, prior.mean, known)
    s_cov = h0 @ prior.covariance @ h0.T + np.eye(r0.size)
    return r0, h0, s_cov, float(r0 @ np.linalg.solve(s_cov, r0))


def _iterated(prior: TrackState, measurement: RisMeasurement, known: tuple[float, float] | None,
              r0: np.ndarray, h0: np.ndarray) -> TrackState:
    """The iterated EKF update of ``prior`` on ``measurement`` (module notes), Joseph-form covariance."""
    # iterated update: relinearise h at the updated state (Gauss-Newton on the posterior); a prior metres wide
    # against millimetre measurements is far outside one linearisation's reach (NEES 27 for 6 after one step)
    x0, p0 = prior.mean, prior.covariance
    x, r, h_jac = x0, r0, h0
    for _ in range(_ITERATIONS):
        s_cov = h_jac @ p0 @ h_jac.T + np.eye(r.size)
        gain = p0 @ h_jac.T @ np.linalg.inv(s_cov)
        x_new = x0 + gain @ (r - h_jac @ (x0 - x))
        done = float(np.max(np.abs(x_new - x))) < 1e-9
        x = x_new
        r, h_jac = _linearised(measurement, x, known)
        if done:
            break
    s_cov = h_jac @ p0 @ h_jac.T + np.eye(r.size)
    gain = p0 @ h_jac.T @ np.linalg.inv(s_cov)
    ikh = np.eye(6) - gain @ h_jac
    cov = ikh @ p0 @ ikh.T + gain @ gain.T  # Joseph form (R = I in σ units)
    cov = 0.5 * (cov + cov.T)
    if not math.isfinite(float(np.sum(cov))):
        raise ValueError(f"RIS {measurement.fix.name}: the update at t = {measurement.time} s is not finite")
    return TrackState(time=prior.time, mean=x, covariance=cov)


def _gate_pfa(gate_pfa: Any) -> float:
    if not 0 < gate_pfa < 1:
        raise ValueError(f"gate_pfa={gate_pfa!r} must lie in (0, 1), e.g. 1e-3")
    return float(gate_pfa)


def update(state: TrackState, measurement: RisMeasurement, *, accel_density: float,
           gate_pfa: float = 1e-3, height: Any = None) -> TrackUpdate:
    """Predict to the measurement's time and update on it (or reject it at the gate).

    Parameters
    ----------
    state : TrackState
    measurement : RisMeasurement
    accel_density : float
        q [m²/s³] (:func:`predict`).
    gate_pfa : float
        Probability that a consistent measurement is rejected (χ² gate on the NIS).
    height : (float, float), optional
        A known height ``(h, σ_h)`` [m]: one more number in the update (module notes); it counts
        in the NIS and its degrees of freedom.

    Returns
    -------
    TrackUpdate
    """
    gate_pfa = _gate_pfa(gate_pfa)
    known = _height(height)
    prior = predict(state, measurement.time, accel_density=accel_density)
    r0, h0, _, nis = _innovation(prior, measurement, known)
    dof = int(r0.size)
    gate = float(scipy.stats.chi2.isf(gate_pfa, dof))
    if not nis <= gate:
        return TrackUpdate(state=prior, nis=nis, dof=dof, gate=gate, accepted=False, ris=measurement.fix.name)
    return TrackUpdate(state=_iterated(prior, measurement, known, r0, h0), nis=nis, dof=dof, gate=gate,
                       accepted=True, ris=measurement.fix.name)


def nees_band(dof: int, count: int, level: float = 0.95) -> tuple[float, float]:
    """The two-sided ``level`` band of the mean of ``count`` independent χ²(``dof``) values [unitless].

    Parameters
    ----------
    dof : int
        Degrees of freedom of each.
    count : int
        How many are averaged (1: the band of one value).
    level : float
        Probability inside the band.

    Returns
    -------
    (float, float)
    """
    lo, hi = scipy.stats.chi2.ppf([(1 - level) / 2, (1 + level) / 2], dof * count) / count
    return float(lo), float(hi)


@dataclass(frozen=True)
class Manoeuvres:
    """Two nearly-constant-velocity models for a walker who goes straight and turns (module notes, "Manoeuvres").

    Model 0 is quiet (``quiet`` q, straight walking), model 1 manoeuvres (``turning`` q, a turn). The
    walker switches between them as a Markov chain in continuous time: it leaves the quiet model at the
    rate 1/``quiet_time`` and the turning one at 1/``turning_time`` (:meth:`transition`).

    Attributes
    ----------
    quiet : float
        q of the quiet model [m²/s³] (> 0).
    turning : float
        q of the turning model [m²/s³] (> ``quiet``).
    quiet_time : float
        Mean time spent in the quiet model, the mean time between turns [s] (> 0).
    turning_time : float
        Mean time spent turning [s] (> 0).
    """

    quiet: float
    turning: float
    quiet_time: float
    turning_time: float

    def __post_init__(self) -> None:
        for name, unit in (("quiet", "m²/s³"), ("turning", "m²/s³"), ("quiet_time", "s"), ("turning_time", "s")):
            object.__setattr__(self, name, positive(getattr(self, name), f"Manoeuvres {name}", unit))
        if not self.turning > self.quiet:
            raise ValueError(f"Manoeuvres turning={self.turning!r} must exceed quiet={self.quiet!r} [m²/s³] (the "
                             "turning model is the looser one), e.g. Manoeuvres(1e-4, 2.6, 8.4, 0.39)")

    @property
    def densities(self) -> tuple[float, float]:
        """(quiet, turning) q [m²/s³]."""
        return (self.quiet, self.turning)

    def transition(self, dt: float) -> np.ndarray:
        """The model switching probabilities over ``dt`` [s]: p[i, j] = P(model j at t + dt | model i at t) [2, 2].

        The two-state chain in continuous time (rates a = 1/τ₀ out of quiet, b = 1/τ₁ out of turning):
        p₀₁ = a/(a+b) (1 − e^{−(a+b)Δt}), p₁₀ = b/(a+b) (1 − e^{−(a+b)Δt}); over a long coast the weights
        tend to the stationary shares (τ₀, τ₁)/(τ₀ + τ₁).

        Parameters
        ----------
        dt : float
            The step [s] (negative counts as 0).

        Returns
        -------
        float array [2, 2]
        """
        a, b = 1.0 / self.quiet_time, 1.0 / self.turning_time
        moved = -math.expm1(-(a + b) * max(float(dt), 0.0)) / (a + b)
        return np.array([[1.0 - a * moved, a * moved], [b * moved, 1.0 - b * moved]])


@dataclass(frozen=True, eq=False)
class ImmState:
    """The two-model filter's estimate at one time: each model's state and its probability.

    Attributes
    ----------
    time : float
        [s].
    models : tuple of TrackState
        The quiet and the turning model's estimates [m, m/s].
    weights : float array [2]
        Their probabilities given the measurements so far [unitless, sum 1].
    """

    time: float
    models: tuple[TrackState, TrackState]
    weights: np.ndarray

    @property
    def mean(self) -> np.ndarray:
        """The mixture's mean [x, y, z, vx, vy, vz] [6] [m, m/s]."""
        return np.einsum("i,ij->j", self.weights, np.stack([m.mean for m in self.models]))

    @property
    def covariance(self) -> np.ndarray:
        """The mixture's covariance, the models' spread included [6, 6] [m², m²/s, m²/s²]."""
        x = self.mean
        return sum(w * (m.covariance + np.outer(m.mean - x, m.mean - x)) for w, m in zip(self.weights, self.models))

    @property
    def position_std(self) -> np.ndarray:
        """1σ of x, y, z [3] [m]."""
        return np.sqrt(np.diag(self.covariance)[:3])


def _mixed(state: ImmState, time: float, manoeuvres: Manoeuvres) -> tuple[list[TrackState], np.ndarray]:
    """The IMM's mixing step: each model's starting state for the step to ``time`` and the models' predicted
    probabilities (``c_j = Σᵢ p_ij μᵢ``)."""
    p = manoeuvres.transition(time - state.time)
    c = state.weights @ p
    out = []
    for j in range(2):
        w = state.weights * p[:, j] / c[j]  # μ_{i|j}
        x = sum(w[i] * state.models[i].mean for i in range(2))
        cov = sum(w[i] * (state.models[i].covariance + np.outer(state.models[i].mean - x, state.models[i].mean - x))
                  for i in range(2))
        out.append(TrackState(time=state.time, mean=x, covariance=0.5 * (cov + cov.T)))
    return out, c


def imm_start(measurement: RisMeasurement, *, speed_std: float = 1.0, height: Any = None,
              turning_share: float = 0.5) -> ImmState:
    """A two-model track from one measurement (both models start as :func:`start_track`).

    Parameters
    ----------
    measurement : RisMeasurement
    speed_std : float
        1σ of the unknown starting velocity per axis [m/s].
    height : (float, float), optional
        A known height ``(h, σ_h)`` [m].
    turning_share : float
        The starting probability of the turning model [unitless, in (0, 1)].

    Returns
    -------
    ImmState
    """
    if not 0 < turning_share < 1:
        raise ValueError(f"turning_share={turning_share!r} must lie in (0, 1), e.g. 0.5")
    first = start_track(measurement, speed_std=speed_std, height=height)
    return ImmState(time=first.time, models=(first, first), weights=np.array([1.0 - turning_share, turning_share]))


def imm_predict(state: ImmState, time: float, manoeuvres: Manoeuvres) -> ImmState:
    """The two-model state at ``time``: mixed, each model predicted with its q (no measurement: coasting).

    Parameters
    ----------
    state : ImmState
    time : float
        [s], not before ``state.time``.
    manoeuvres : Manoeuvres

    Returns
    -------
    ImmState
    """
    t = finite(time, "time", "s")
    if t < state.time:
        raise ValueError(f"time {t} s is before the track's {state.time} s: measurements must come in time order")
    mixed, c = _mixed(state, t, manoeuvres)
    return ImmState(time=t, models=tuple(predict(m, t, accel_density=q) for m, q in zip(mixed, manoeuvres.densities)),
                    weights=c)


def imm_update(state: ImmState, measurement: RisMeasurement, manoeuvres: Manoeuvres, *, gate_pfa: float = 1e-3,
               height: Any = None) -> TrackUpdate:
    """Interacting multiple model step: mix, predict each model to the measurement, update each on it, reweigh.

    Each model's probability is multiplied by the likelihood of the measurement under its prediction,
    N(ν; 0, S), and renormalised. The NIS reported is that of the mixture's prediction (its mean and
    covariance, the models' spread included), χ²(n) when the filter is consistent. The measurement is
    rejected (a grating twin, a path taken for the return) when it lies beyond the gate of every model's
    prediction — the turning model's included, so that a turn is not taken for an outlier; a model whose
    own gate it is beyond keeps its prediction (and loses weight by the likelihood), so that an outlier the
    turning model accepts does not drag the quiet model along.

    Parameters
    ----------
    state : ImmState
    measurement : RisMeasurement
    manoeuvres : Manoeuvres
        The two models and their switching.
    gate_pfa : float
        Probability that a consistent measurement is rejected (χ² gate on each model's NIS).
    height : (float, float), optional
        A known height ``(h, σ_h)`` [m] (:func:`update`).

    Returns
    -------
    TrackUpdate
        ``state`` is an :class:`ImmState` (the prediction when rejected).
    """
    gate_pfa = _gate_pfa(gate_pfa)
    known = _height(height)
    prior = imm_predict(state, measurement.time, manoeuvres)
    parts = [_innovation(m, measurement, known) for m in prior.models]
    dof = int(parts[0][0].size)
    gate = float(scipy.stats.chi2.isf(gate_pfa, dof))
    mixture = TrackState(time=prior.time, mean=prior.mean, covariance=prior.covariance)
    nis = _innovation(mixture, measurement, known)[3]
    if not min(p[3] for p in parts) <= gate:
        return TrackUpdate(state=prior, nis=nis, dof=dof, gate=gate, accepted=False, ris=measurement.fix.name)
    log_like = np.array([-0.5 * p[3] - 0.5 * np.linalg.slogdet(p[2])[1] for p in parts])
    weights = prior.weights * np.exp(log_like - log_like.max())
    # a model whose own gate the measurement is beyond keeps its prediction (its weight falls by the likelihood):
    # an outlier the turning model accepts does not drag the quiet model, a turn re-seeds it at the next mixing
    models = tuple(_iterated(m, measurement, known, p[0], p[1]) if p[3] <= gate else m
                   for m, p in zip(prior.models, parts))
    return TrackUpdate(state=ImmState(time=prior.time, models=models, weights=weights / weights.sum()), nis=nis,
                       dof=dof, gate=gate, accepted=True, ris=measurement.fix.name)
