"""A walk's track smoothed after the walk: the filter run forward and backward, joined at every slot, and a
turn no measurement saw placed where the two straight legs meet (issue 22).

The causal track at a slot knows the measurements up to that slot. Once the walk is over every
measurement is known, and the best estimate of the radar's state at a slot uses them all. Two
filters give it:

- the **forward** filter (the walk's own tracker): at slot k, the measurements up to k;
- the **backward** filter: the same tracker over the measurements in reverse order, in reversed time
  s = −t. A state [p, v] is [p, −v] there and a measured radial velocity changes sign
  (:func:`reversed_measurement`, :func:`reversed_state`); at slot k it knows the measurements from k on.

At slot k the forward estimate after k and the backward estimate after k + 1, predicted to t_k by
the filters' own motion model (``motion``), share no measurement, so they are independent and the
smoothed state is their product (:func:`fuse_estimates`; the two-filter form of the fixed-interval
smoother): x = x_f + K (x_b − x_f), P = P_f − K P_f, K = P_f (P_f + P_b)⁻¹ (``"joined"``). Two-model
estimates enter by their mixture's mean and covariance (:func:`gaussian`). Where one filter has no
estimate the other's is taken (``"forward"``, ``"backward"``).

**A turn between two measurements.** A nearly-constant-velocity smoother cannot place a corner that
no measurement saw: it rounds it, half-way between the two legs (an RTS pass tried on the benchmark
walk: 6 cm off at the slot just past the corner). Between two consecutive slots whose measurement
the forward filter used, a < b at t_a < t_b (the slots between flagged or without a detection), the
forward estimate at a (measurements ≤ a) and the backward one at b (measurements ≥ b) bracket the
gap; each is carried into it by the quiet model (nearly constant velocity, white acceleration q₀).
The turn is placed when

- the forward estimate carried to t_b disagrees with the backward one (χ² of their difference over
  ``axes`` beyond its level at ``gate_pfa``), and
- each filter is on a straight leg at its end of the gap (its quiet model's probability is at least
  ``quiet_share``): the turn lies inside the gap. A turn that the slots around it see (a slow one)
  has the turning model take over there, and the gap is joined as any other.

The path of a walk is straight legs joined at turns; the turn is at the time τ where the two legs
meet, p_a + v_a (τ − t_a) = p_b − v_b (t_b − τ), in least squares over the three axes:

    τ = (g · u) / (u · u),   g = p_a − v_a t_a − p_b + v_b t_b,   u = v_b − v_a,

its 1σ σ_τ to first order from the two estimates' covariances (:func:`turn_time`). A slot at t in the
gap is on the first leg with probability Φ((τ − t)/σ_τ) and on the second otherwise; its estimate is
that mixture of the two carried estimates, mean and covariance (the spread between them included;
``"corner"``). Slot a keeps its forward estimate (``"forward"``): the later measurements reach it
only through a corner whose time and turn are both unknown, so leaving them out loses little and
states no more than is known.

**What the turn model assumes.** One turn in a gap, and the turn sharp against the gap: exact for the
trajectories ``risloc track`` walks (straight segments between waypoints). A turn that takes time and
lies wholly between two measurements cannot be told from a corner by any data: the corner of the two
tangents lies outside the arc, by r (sec(θ/2) − 1) for a turn of θ on a radius r (13 cm for 90° on
0.32 m, a 0.5 s turn at 1 m/s). ``max_turn`` widens the corner's estimates by what such a turn can
put between walker and corner path. ``docs/tracking.md``, "The smoothed track", has the measured
effect of both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import scipy.special
import scipy.stats

from .fusion import central_jacobian
from .tracking import ALL_AXES, Manoeuvres, RisMeasurement, TrackState, imm_predict, predict

__all__ = ["SmoothedTrack", "Turn", "SMOOTH_KINDS", "reversed_measurement", "reversed_state", "gaussian",
           "fuse_estimates", "turn_time", "smooth_track"]

#: What the smoothed estimate of a slot is: ``joined`` (the forward and backward estimates' product),
#: ``corner`` (a mixture over the legs before and after a turn in a gap), ``forward`` (the forward filter's
#: alone: the last slot before a turn, and after the last measurement), ``backward`` (before the first
#: measurement), ``none`` (no estimate).
SMOOTH_KINDS = ("joined", "corner", "forward", "backward", "none")

_FLIP = np.diag([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])


def reversed_measurement(measurement: RisMeasurement) -> RisMeasurement:
    """The measurement as the backward filter sees it: at −t [s], the radial velocity's sign changed [m/s].

    Parameters
    ----------
    measurement : RisMeasurement

    Returns
    -------
    RisMeasurement
        The same fix (distance, AoD, flags); time −t, velocity −v, its 1σ unchanged.
    """
    return RisMeasurement(time=-measurement.time, fix=measurement.fix, velocity=-measurement.velocity,
                          std_velocity=measurement.std_velocity)


def gaussian(estimate: Any) -> TrackState:
    """An estimate as one Gaussian: a :class:`~dsp.tracking.TrackState` as it is, a two-model
    :class:`~dsp.tracking.ImmState` by its mixture's mean and covariance (the models' spread included).

    Parameters
    ----------
    estimate : TrackState or ImmState

    Returns
    -------
    TrackState
    """
    if isinstance(estimate, TrackState):
        return estimate
    return TrackState(time=float(estimate.time), mean=np.asarray(estimate.mean, dtype=float),
                      covariance=np.asarray(estimate.covariance, dtype=float))


def reversed_state(estimate: Any) -> TrackState:
    """An estimate in the other time direction: time −t [s], velocity −v [m/s], the covariance's
    position–velocity blocks negated.

    Parameters
    ----------
    estimate : TrackState or ImmState

    Returns
    -------
    TrackState
    """
    g = gaussian(estimate)
    return TrackState(time=-g.time, mean=_FLIP @ g.mean, covariance=_FLIP @ g.covariance @ _FLIP)


def fuse_estimates(a: TrackState, b: TrackState) -> TrackState:
    """The product of two independent Gaussian estimates of the same state at the same time.

    Parameters
    ----------
    a, b : TrackState
        [m, m/s]; ``b.time`` equal to ``a.time`` (to 1 ns).

    Returns
    -------
    TrackState
        x = x_a + K (x_b − x_a), P = P_a − K P_a, K = P_a (P_a + P_b)⁻¹ (symmetrised).
    """
    if not abs(a.time - b.time) <= 1e-9:
        raise ValueError(f"estimates at {a.time} s and {b.time} s cannot be fused: give both at the same time")
    gain = np.linalg.solve((a.covariance + b.covariance).T, a.covariance.T).T
    cov = a.covariance - gain @ a.covariance
    return TrackState(time=a.time, mean=a.mean + gain @ (b.mean - a.mean), covariance=0.5 * (cov + cov.T))


def _carried(estimate: TrackState, time: float, accel_density: float) -> TrackState:
    """``estimate`` moved to ``time`` [s] by nearly constant velocity, forward or backward in time."""
    if time >= estimate.time:
        return predict(estimate, time, accel_density=accel_density)
    return reversed_state(predict(reversed_state(estimate), -time, accel_density=accel_density))


def _meeting_time(x: np.ndarray, t_a: float, t_b: float) -> float:
    """τ [s] of the module notes from x = [p_a, v_a, p_b, v_b] [12]."""
    p_a, v_a, p_b, v_b = x[:3], x[3:6], x[6:9], x[9:]
    u = v_b - v_a
    uu = float(u @ u)
    return float((p_a - v_a * t_a - p_b + v_b * t_b) @ u / uu) if uu > 0 else 0.5 * (t_a + t_b)


def turn_time(before: TrackState, after: TrackState) -> tuple[float, float]:
    """When the straight leg of ``before`` meets that of ``after`` (module notes, "a turn"), and its 1σ.

    Parameters
    ----------
    before : TrackState
        The estimate at the gap's start t_a (measurements up to it) [m, m/s].
    after : TrackState
        The estimate at its end t_b > t_a (measurements from it on), independent of ``before``.

    Returns
    -------
    (float, float)
        τ and σ_τ [s]; σ_τ is inf when the two velocities are the same (no turn to place).
    """
    t_a, t_b = float(before.time), float(after.time)
    if not t_b > t_a:
        raise ValueError(f"the gap's end {t_b} s must come after its start {t_a} s")
    x = np.concatenate([before.mean, after.mean])
    if not float(np.sum((after.mean[3:] - before.mean[3:]) ** 2)) > 0:
        return 0.5 * (t_a + t_b), math.inf
    tau = _meeting_time(x, t_a, t_b)
    jac = central_jacobian(lambda s: np.array([_meeting_time(s, t_a, t_b)]), x)
    cov = np.zeros((12, 12))
    cov[:6, :6], cov[6:, 6:] = before.covariance, after.covariance
    return tau, float(np.sqrt(max(float((jac @ cov @ jac.T)[0, 0]), 0.0)))


def _mixture(parts: Sequence[tuple[float, TrackState]]) -> TrackState:
    """The mean and covariance of a mixture of Gaussians ``(weight, estimate)`` (weights sum to 1)."""
    mean = sum(w * s.mean for w, s in parts)
    cov = sum(w * (s.covariance + np.outer(s.mean - mean, s.mean - mean)) for w, s in parts)
    return TrackState(time=parts[0][1].time, mean=mean, covariance=0.5 * (cov + cov.T))


@dataclass(frozen=True)
class Turn:
    """A turn placed in a gap between two used measurements (module notes).

    Attributes
    ----------
    start, end : float
        The gap: the times of the used measurements before and after it [s].
    time : float
        τ, when the two legs meet [s].
    std_time : float
        Its 1σ [s].
    chi2 : float
        The straight test's χ² of the two estimates' difference [unitless].
    dof : int
        Its degrees of freedom.
    """

    start: float
    end: float
    time: float
    std_time: float
    chi2: float
    dof: int


@dataclass(frozen=True, eq=False)
class SmoothedTrack:
    """The smoothed estimate of every slot of a walk.

    Attributes
    ----------
    times : float array [n]
        The slots' times [s].
    states : tuple of (TrackState or None)
        The smoothed estimate per slot [m, m/s] (None: no filter had one).
    kinds : tuple of str
        How each was made (:data:`SMOOTH_KINDS`).
    turns : tuple of Turn
        The turns placed in gaps.
    """

    times: np.ndarray
    states: tuple[TrackState | None, ...]
    kinds: tuple[str, ...]
    turns: tuple[Turn, ...]


def _gap_test(before: TrackState, after: TrackState, accel_density: float, axes: np.ndarray,
              level: float) -> tuple[float, bool]:
    """χ² of (after − before carried to after's time) over ``axes``, and whether it is within ``level``."""
    ahead = _carried(before, after.time, accel_density)
    e = (after.mean - ahead.mean)[axes]
    s = (after.covariance + ahead.covariance)[np.ix_(axes, axes)]
    chi2 = float(e @ np.linalg.solve(s, e))
    return chi2, chi2 <= level


def _widened(state: TrackState, before: TrackState, after: TrackState, max_turn: float,
             axes: np.ndarray) -> TrackState:
    """``state`` with what a turn of up to ``max_turn`` [s] can put between the walker and the corner path
    added on ``axes``: 1σ v̄ D/2 in position (the walker covers v̄ D in the turn, the corner path as much),
    |v_b − v_a|/2 in velocity."""
    speed = 0.5 * (np.linalg.norm(before.mean[3:]) + np.linalg.norm(after.mean[3:]))
    extra = np.zeros(6)
    extra[:3] = (0.5 * speed * max_turn) ** 2
    extra[3:] = (0.5 * np.linalg.norm(after.mean[3:] - before.mean[3:])) ** 2
    cov = state.covariance.copy()
    cov[axes, axes] += extra[axes]
    return TrackState(time=state.time, mean=state.mean, covariance=cov)


def _quiet_weight(estimate: Any) -> float:
    """The quiet model's probability in a two-model estimate (1 for one model) [unitless]."""
    weights = getattr(estimate, "weights", None)
    return 1.0 if weights is None else float(weights[0])


def smooth_track(times: Any, forward: Sequence[Any], backward: Sequence[Any], used: Sequence[bool], *,
                 motion: Any, axes: Any = ALL_AXES, gate_pfa: float = 1e-3,
                 quiet_share: float = 0.5, max_turn: float = 0.0) -> SmoothedTrack:
    """The walk's smoothed track from its forward and backward filters (module notes).

    Parameters
    ----------
    times : float array [n]
        The slots' times, increasing [s].
    forward : sequence of (TrackState or ImmState or None) [n]
        The forward filter's estimate after slot k (updated, or predicted only) [m, m/s].
    backward : sequence of (TrackState or ImmState or None) [n]
        The backward filter's estimate after slot k, as that filter gives it: at −t_k, velocity reversed
        (it ran over :func:`reversed_measurement` of each slot's measurement, last slot first).
    used : sequence of bool [n]
        The forward filter updated on slot k's measurement (started on it, used it or restarted on it).
    motion : Manoeuvres or float
        The filters' motion model: the two models of an :class:`~dsp.tracking.ImmState` track, or the
        white acceleration density q [m²/s³] of a one-model :class:`~dsp.tracking.TrackState` track. It
        predicts the backward estimate of slot k + 1 to slot k; its quiet q (or q) carries estimates
        into a gap with a turn.
    axes : sequence of int
        The state indices the straight test compares (:data:`dsp.tracking.HORIZONTAL` with a known height).
    gate_pfa : float
        Probability that a straight walk's gap is taken for a turn (the test's χ² level).
    quiet_share : float
        The quiet model's probability both filters must give at their end of a gap for a turn in it to be
        placed as a corner (each filter on a straight leg there) [unitless, in (0, 1)].
    max_turn : float
        The longest a turn placed as a corner may have taken [s] (≥ 0; 0: turns at once, as ``risloc
        track``'s walks do). Slots within ``max_turn``/2 (and 2σ_τ) of τ have their covariance widened by
        what such a turn can put between the walker and the corner path (module notes, "What the turn
        model assumes").

    Returns
    -------
    SmoothedTrack
    """
    t = np.asarray(times, dtype=float)
    n = t.size
    if t.ndim != 1 or not (len(forward) == len(backward) == len(used) == n):
        raise ValueError(f"times, forward, backward and used must be equally long sequences; got {t.size}, "
                         f"{len(forward)}, {len(backward)}, {len(used)}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be finite and increasing [s]")
    if isinstance(motion, Manoeuvres):
        q = motion.quiet

        def back_predict(state: Any, time: float) -> Any:
            return imm_predict(state, time, motion)
    else:
        try:
            q = float(motion)
        except (TypeError, ValueError):
            q = math.nan
        if not (math.isfinite(q) and q > 0):
            raise ValueError(f"motion={motion!r} must be a dsp.tracking.Manoeuvres or a q > 0 [m²/s³], e.g. 0.5")

        def back_predict(state: Any, time: float) -> Any:
            return predict(state, time, accel_density=q)
    if not 0 < gate_pfa < 1:
        raise ValueError(f"gate_pfa={gate_pfa!r} must lie in (0, 1), e.g. 1e-3")
    if not 0 < quiet_share < 1:
        raise ValueError(f"quiet_share={quiet_share!r} must lie in (0, 1), e.g. 0.5")
    if not (math.isfinite(max_turn) and max_turn >= 0):
        raise ValueError(f"max_turn={max_turn!r} must be >= 0 [s], e.g. 0 (turns at once) or 1.0")
    idx = np.asarray(axes, dtype=int)
    level = float(scipy.stats.chi2.isf(gate_pfa, idx.size))
    fwd = [None if s is None else gaussian(s) for s in forward]
    states: list[TrackState | None] = [None] * n
    kinds = ["none"] * n
    for k in range(n):  # the two filters joined: the forward estimate after k, the backward one predicted to k
        ahead = None if k + 1 >= n or backward[k + 1] is None else reversed_state(back_predict(backward[k + 1], -t[k]))
        if fwd[k] is not None and ahead is not None:
            states[k], kinds[k] = fuse_estimates(fwd[k], ahead), "joined"
        elif fwd[k] is not None:
            states[k], kinds[k] = fwd[k], "forward"
        elif backward[k] is not None:
            states[k], kinds[k] = reversed_state(backward[k]), "backward"
    turns = []
    marks = [k for k in range(n) if used[k] and fwd[k] is not None]
    for a, b in zip(marks, marks[1:]):  # a turn in a gap, each filter on a straight leg at its end: a corner
        if backward[b] is None or min(_quiet_weight(forward[a]), _quiet_weight(backward[b])) < quiet_share:
            continue
        before, after = fwd[a], reversed_state(backward[b])
        chi2, straight = _gap_test(before, after, q, idx, level)
        if straight:
            continue
        tau, sd = turn_time(before, after)
        turns.append(Turn(start=float(t[a]), end=float(t[b]), time=tau, std_time=sd, chi2=chi2, dof=int(idx.size)))
        states[a], kinds[a] = before, "forward"
        for k in range(a + 1, b):
            if not math.isfinite(sd):
                first = 0.5
            elif sd > 0:
                first = 0.5 * float(scipy.special.erfc((t[k] - tau) / (sd * math.sqrt(2.0))))
            else:
                first = float(t[k] < tau)
            state = _mixture([(first, _carried(before, t[k], q)), (1.0 - first, _carried(after, t[k], q))])
            if max_turn > 0 and abs(t[k] - tau) <= 0.5 * max_turn + 2 * sd:
                state = _widened(state, before, after, max_turn, idx)
            states[k], kinds[k] = state, "corner"
    return SmoothedTrack(times=t, states=tuple(states), kinds=tuple(kinds), turns=tuple(turns))
