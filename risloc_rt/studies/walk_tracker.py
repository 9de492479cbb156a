"""The walk's tracker and its smoother: what ``risloc track`` does with each slot's measurement.

:class:`WalkTracker` takes the slots' measurements in order (the two-model filter of
:mod:`dsp.tracking` by default, :data:`WALK_MANOEUVRES`); :func:`smooth_walk` runs its twin backward
over the same measurements and joins the two (:mod:`dsp.smoothing`). :mod:`risloc_rt.studies.walk`
drives both (``docs/tracking.md``).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from dsp.fusion import DOUBT_CODES
from dsp.tracking import Manoeuvres

__all__ = ["UPDATE_KINDS", "SKIP_FLAGS", "WALK_MANOEUVRES", "WalkTracker", "smooth_walk"]

#: What the tracker did in a slot: ``start`` (the track began on this fix), ``used``, ``gated`` (the
#: NIS was beyond the gate: not used), ``restart`` (gated too often in a row: a new track from this
#: fix), ``flagged`` (the fix carries a :data:`SKIP_FLAGS` code: predicted only), ``coast`` (no
#: detection, or the radar behind the RIS: predicted only), ``none`` (no track yet).
UPDATE_KINDS = ("start", "used", "gated", "restart", "flagged", "coast", "none")

#: Fixes carrying one of these flag codes are not given to the tracker (the row says ``flagged``): the
#: gross-error codes the fusion leaves out too (``dsp.fusion.DOUBT_CODES``: ``beam-edge``, an AoD at the edge
#: of the swept span; ``aliased``, a distance folded at the unambiguous range; ``grating-lobe``; ``floor-leg``; …).
SKIP_FLAGS = tuple(sorted(DOUBT_CODES))

#: The two-model tracker's models for a walker (``docs/tracking.md``, "Manoeuvres"): a quiet model of
#: q = 1e-4 m²/s³ (straight walking: the largest q of a grid whose track RMSE ≥ 1.5 s from a turn on the
#: calibration walk is within 5 % of the grid's best, ``benchmarks/calibrate_walk_floors.py``: 0.50 cm
#: against 0.49 cm at 1e-6), a turning model of q = v²/T = 2.56 m²/s³ (a 90° turn at v = 1 m/s changes
#: each horizontal velocity component by up to v within one slot T = 0.3904 s), a mean time between turns
#: of 8.4 s (the calibration walk's 42 s in 5 legs) and a turn lasting one slot.
WALK_MANOEUVRES = Manoeuvres(quiet=1e-4, turning=1.0 / 0.3904, quiet_time=42.0 / 5, turning_time=0.3904)


class WalkTracker:
    """The walk's tracker: what :func:`risloc_rt.studies.walk.run_walk` does with each slot's measurement, in
    slot order.

    The first usable measurement starts the track; a measurement carrying a :data:`SKIP_FLAGS` code is not
    used (``flagged``), no measurement is coasted through (``coast``); otherwise the filter updates on it
    (``used``) or gates it (``gated``), and ``restart_after`` gated measurements in a row restart the track
    from the next one (``restart``). The filter is the two-model IMM of :mod:`dsp.tracking` (``manoeuvres``,
    default :data:`WALK_MANOEUVRES`), or one nearly-constant-velocity model when ``accel_density`` is given.

    Parameters
    ----------
    manoeuvres : dsp.tracking.Manoeuvres, optional
        The two models (default :data:`WALK_MANOEUVRES`).
    accel_density : float, optional
        q [m²/s³] of a single-model filter instead (not with ``manoeuvres``).
    gate_pfa : float
        Probability that a consistent measurement is gated out (χ² on the NIS).
    restart_after : int
        Gated measurements in a row after which the track restarts.

    Attributes
    ----------
    state : dsp.tracking.TrackState or dsp.tracking.ImmState or None
        The track after the last step (None before the first measurement).
    """

    def __init__(self, *, manoeuvres: Any = None, accel_density: float | None = None, gate_pfa: float = 1e-3,
                 restart_after: int = 3) -> None:
        from dsp import tracking

        if manoeuvres is not None and accel_density is not None:
            raise ValueError("give manoeuvres (two models) or accel_density (one model), not both")
        if accel_density is not None:
            accel_density = float(accel_density)
            if not (math.isfinite(accel_density) and accel_density > 0):
                raise ValueError(f"accel_density={accel_density!r} must be > 0 [m²/s³], e.g. 0.5")
        elif manoeuvres is None:
            manoeuvres = WALK_MANOEUVRES
        if manoeuvres is not None and not isinstance(manoeuvres, tracking.Manoeuvres):
            raise ValueError(f"manoeuvres must be a dsp.tracking.Manoeuvres, got {type(manoeuvres).__name__}")
        if not 0 < gate_pfa < 1:
            raise ValueError(f"gate_pfa={gate_pfa!r} must lie in (0, 1), e.g. 1e-3")
        if isinstance(restart_after, bool) or not isinstance(restart_after, int) or restart_after < 1:
            raise ValueError(f"restart_after={restart_after!r} must be an integer >= 1 (gated measurements in a row)")
        self.manoeuvres, self.accel_density = manoeuvres, accel_density
        self.gate_pfa, self.restart_after = float(gate_pfa), restart_after
        self.state: Any = None
        self._gated_run = 0

    def describe(self) -> dict[str, Any]:
        """The filter and its parameters, for ``summary.json`` [m²/s³, s].

        Returns
        -------
        dict
        """
        if self.manoeuvres is None:
            return {"models": "nearly constant velocity", "accel_density_m2_s3": self.accel_density}
        m = self.manoeuvres
        return {"models": "IMM: quiet and turning nearly constant velocity", "quiet_m2_s3": m.quiet,
                "turning_m2_s3": m.turning, "quiet_time_s": m.quiet_time, "turning_time_s": m.turning_time}

    @property
    def motion(self) -> Any:
        """The filter's motion model: its :class:`dsp.tracking.Manoeuvres`, or the one model's q [m²/s³]."""
        return self.manoeuvres if self.manoeuvres is not None else self.accel_density

    def twin(self) -> "WalkTracker":
        """A new tracker with this one's parameters and no track (the smoother's backward filter).

        Returns
        -------
        WalkTracker
        """
        return WalkTracker(manoeuvres=self.manoeuvres, accel_density=self.accel_density, gate_pfa=self.gate_pfa,
                           restart_after=self.restart_after)

    def _start(self, meas: Any, known: Any) -> Any:
        from dsp import tracking

        if self.manoeuvres is None:
            return tracking.start_track(meas, height=known)
        return tracking.imm_start(meas, height=known)

    def _predict(self, time: float) -> Any:
        from dsp import tracking

        if self.manoeuvres is None:
            return tracking.predict(self.state, time, accel_density=self.accel_density)
        return tracking.imm_predict(self.state, time, self.manoeuvres)

    def step(self, time: float, meas: Any, *, height: Any = None) -> tuple[str, float, int]:
        """One slot: the track moved to ``time`` and updated on ``meas`` (module notes).

        Parameters
        ----------
        time : float
            The slot's reference time [s].
        meas : dsp.tracking.RisMeasurement or None
            The slot's measurement (None: no detection, no position, or the radar behind the RIS).
        height : (float, float), optional
            A known height ``(h, σ_h)`` [m].

        Returns
        -------
        (str, float, int)
            What was done (:data:`UPDATE_KINDS`), the NIS [unitless] (NaN when nothing was measured) and
            its degrees of freedom.
        """
        from dsp import tracking

        flagged = meas is not None and bool(set(meas.fix.flags) & set(SKIP_FLAGS))
        if self.state is None:
            if meas is None or flagged:
                return "none", math.nan, 0
            self.state = self._start(meas, height)
            return "start", math.nan, 0
        if meas is None or flagged:
            self.state = self._predict(time)
            return ("flagged" if flagged else "coast"), math.nan, 0
        if self.manoeuvres is None:
            up = tracking.update(self.state, meas, accel_density=self.accel_density, gate_pfa=self.gate_pfa,
                                 height=height)
        else:
            up = tracking.imm_update(self.state, meas, self.manoeuvres, gate_pfa=self.gate_pfa, height=height)
        if up.accepted:
            self.state, self._gated_run = up.state, 0
            return "used", up.nis, up.dof
        self._gated_run += 1
        if self._gated_run >= self.restart_after:
            self.state, self._gated_run = self._start(meas, height), 0
            return "restart", up.nis, up.dof
        self.state = up.state
        return "gated", up.nis, up.dof


def smooth_walk(times: Sequence[float], seen: Sequence[tuple[Any, Any, Any, bool]], tracker: WalkTracker,
                axes: Sequence[int]) -> Any:
    """The walk's smoothed track (:mod:`dsp.smoothing`): ``tracker``'s twin run over the slots' measurements
    last first, in reversed time, joined with the forward track.

    Parameters
    ----------
    times : sequence of float
        The slots' times, increasing [s].
    seen : sequence of (RisMeasurement or None, (float, float) or None, estimate or None, bool)
        Per slot, as the forward pass had them: the measurement, the known height ``(h, σ_h)`` [m], the
        forward track's estimate after the slot, and whether the forward filter updated on it.
    tracker : WalkTracker
        The forward tracker (its parameters make the twin; its state is not touched).
    axes : sequence of int
        The state indices judged (:data:`dsp.tracking.HORIZONTAL` with a known height).

    Returns
    -------
    dsp.smoothing.SmoothedTrack
    """
    from dsp.smoothing import reversed_measurement, smooth_track

    back, backward = tracker.twin(), [None] * len(times)
    for k in range(len(times) - 1, -1, -1):
        meas, known = seen[k][0], seen[k][1]
        back.step(-float(times[k]), None if meas is None else reversed_measurement(meas), height=known)
        backward[k] = back.state
    return smooth_track(list(times), [x[2] for x in seen], backward, [x[3] for x in seen],
                        motion=tracker.motion, axes=axes, gate_pfa=tracker.gate_pfa)
