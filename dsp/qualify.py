"""What qualifies an estimate: its 1σ uncertainty, the flags, a known radar height, the time reference.

Used by :func:`dsp.self_localize`; the formulas are in ``docs/estimation.md`` and the flags in
``docs/flags.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize

from .validation import fields_equal
from .detection import Detection
from .drift import DelayDrift
from .flags import Flag
from .geometry import RisPose, direction_from_angles
from .radar import SPEED_OF_LIGHT, RadarConfig
from .aod_fit import AodFit
from .sweep import BeamSweep

__all__ = ["Uncertainty", "GRATING_LOBE_DB", "is_one_dimensional", "elevation_for_height", "sweep_flags"]

#: A second lobe of the AoD fit within this many dB of the best raises ``grating-lobe`` [dB].
GRATING_LOBE_DB = 3.0


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """1σ of an estimate, from the Cramér–Rao bound at the measured SNR (``docs/estimation.md``).

    Attributes
    ----------
    distance : float
        [m].
    velocity : float
        [m/s].
    aod : float array [2]
        [az, el] [rad]; el is NaN when the sweep cannot see it and no height was given.
    position : float array [3]
        Along the world x, y, z axes [m] (elevation error not included when el is NaN).
    peak_snr_db : float
        The measured post-integration SNR at the pattern peak the bound was evaluated at [dB].
    kind : str
        ``"crb"`` (refined estimator: the bound itself) or ``"crb+grid"`` (paper estimator: the
        single-beam bound plus the grid quantisation, step²/12, of delay and AoD). The bound is
        :func:`dsp.sweep_crb` with ``phases="random"``: what an estimator blind to the per-beam
        phases can reach (above the fixed-phase CRB when many beams are near the noise).
    """

    distance: float
    velocity: float
    aod: np.ndarray
    position: np.ndarray
    peak_snr_db: float
    kind: str

    @property
    def peb(self) -> float:
        """Position error bound sqrt(σ_x² + σ_y² + σ_z²) [m]."""
        return float(np.sqrt(np.sum(np.square(self.position))))

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary (NaN where not estimated)."""
        return {"distance": float(self.distance), "velocity": float(self.velocity),
                "aod": [float(v) for v in self.aod], "position": [float(v) for v in self.position],
                "peb": self.peb, "peak_snr_db": float(self.peak_snr_db), "kind": self.kind}

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]

def is_one_dimensional(sweep: BeamSweep) -> bool:
    """All beams at one elevation: the sweep measures only u = cos(el)·sin(az)."""
    return bool(np.ptp(sweep.angles[:, 1]) < 1e-12)


def _position(pose: RisPose, distance: float, az: float, el: float) -> np.ndarray:
    return pose.position + distance * pose.to_world(direction_from_angles(np.array([az, el])))


def elevation_for_height(pose: RisPose, distance: float, u: float, height: float, *,
                         near: float = 0.0) -> tuple[float, float] | None:
    """(az, el) with cos(el)·sin(az) = u that put the UE at world z = ``height``.

    Parameters
    ----------
    pose : RisPose
    distance : float
        RIS–UE distance [m].
    u : float
        Measured direction cosine along the row axis [unitless].
    height : float
        World z of the radar [m].
    near : float
        When several elevations fit, the one closest to this [rad].

    Returns
    -------
    (float, float) or None
        [rad]; None when no elevation reaches that height.
    """
    if not (distance > 0 and abs(u) < 1):
        return None
    el_max = float(np.arccos(min(abs(u), 1.0))) * (1 - 1e-12)

    def z(el: float) -> float:
        az = float(np.arcsin(np.clip(u / np.cos(el), -1, 1)))
        return float(_position(pose, distance, az, el)[2]) - height

    grid = np.linspace(-el_max, el_max, 181)
    vals = np.array([z(e) for e in grid])
    roots = []
    for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) <= 0):
        if vals[i] == 0:
            roots.append(grid[i])
            continue
        roots.append(scipy.optimize.brentq(z, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15))
    if not roots:
        return None
    el = float(min(roots, key=lambda e: abs(e - near)))
    return float(np.arcsin(np.clip(u / np.cos(el), -1, 1))), el


def _deg(x: float) -> str:
    return f"{np.rad2deg(x):+.2f}°"


def sweep_flags(
    *,
    detection: Detection,
    fit: AodFit,
    magnitudes: np.ndarray,
    sweep: BeamSweep,
    radar: RadarConfig,
    pose: RisPose,
    delay: float,
    apparent_delay: float,
    delay_rate: float,
    loopback_delay: float,
    distance: float,
    aod: np.ndarray,
    unresolved: tuple[float, float] | None,
    ue_height: float | None,
    height_solved: bool,
    height_range: float,
    drift: DelayDrift | None = None,
) -> tuple[Flag, ...]:
    """The flags of a detected estimate (``docs/flags.md``), in a fixed order."""
    flags: list[Flag] = []
    if detection.rejected:
        flags.append(Flag("no-beam-dependence",
                          f"{detection.rejected} return(s) stronger than the one used crossed the detection threshold "
                          "but do not follow the sweep (clutter, the panel's structure, leakage): they were skipped; "
                          "check that the right return was taken (raise min_range to skip near ones)"))
    strong = fit.candidates[fit.candidates[:, 1] >= -GRATING_LOBE_DB] if fit.candidates.size else fit.candidates
    if strong.size:
        others = ", ".join(f"{_deg(a)} ({lvl:+.1f} dB)" for a, lvl in strong)
        flags.append(Flag("grating-lobe",
                          f"the AoD is ambiguous: the beam-pattern fit peaks at az {_deg(aod[0])} and also at {others}; "
                          "a reflective RIS with λ/2 spacing has grating lobes beyond ±17°: use a relay RIS, a narrower "
                          "sweep, or a second sweep/RIS to decide"))
    az_lo, az_hi = float(sweep.angles[:, 0].min()), float(sweep.angles[:, 0].max())
    best = int(np.argmax(magnitudes))
    at_edge = best in (0, sweep.num_beams - 1)
    outside = not (az_lo + 1e-9 < float(aod[0]) < az_hi - 1e-9)
    if is_one_dimensional(sweep) and (at_edge or outside):
        where = (f"the strongest beam is the {'first' if best == 0 else 'last'} of the sweep "
                 f"(az {_deg(sweep.angles[best, 0])})" if at_edge else
                 f"the AoD az {_deg(aod[0])} lies at or beyond the edge of the swept span "
                 f"[{_deg(az_lo)}, {_deg(az_hi)}]")
        flags.append(Flag("beam-edge",
                          f"{where}: the UE may lie outside the swept span, where the AoD is pulled to the edge or "
                          "taken from a sidelobe; widen the sweep"))
    edge = 2.0 * radar.delay_resolution
    near_wrap = apparent_delay < edge or apparent_delay > radar.max_delay - edge
    above_if = apparent_delay * radar.slope > radar.if_bandwidth
    fast_doppler = abs(delay_rate) > 0.9 * radar.max_delay_rate
    wrapped_doppler = drift is not None and \
        abs(drift.rate - delay_rate) > max(radar.max_delay_rate, 5.0 * drift.std)
    if near_wrap or above_if or fast_doppler or wrapped_doppler:
        why = []
        if near_wrap:
            why.append(f"the return sits within {edge * SPEED_OF_LIGHT / 2 * 100:.1f} cm of the range wrap (0 or "
                       f"{radar.max_range:.2f} m)")
        if above_if:
            why.append(f"its beat frequency {apparent_delay * radar.slope / 1e6:.2f} MHz is above the IF bandwidth "
                       f"{radar.if_bandwidth / 1e6:.2f} MHz")
        if fast_doppler:
            why.append(f"|v| = {abs(delay_rate) * SPEED_OF_LIGHT / 2:.2f} m/s is near the unambiguous "
                       f"{radar.max_velocity:.2f} m/s")
        if wrapped_doppler:
            span = 2 * radar.max_delay_rate
            unwrapped = delay_rate + span * round((drift.rate - delay_rate) / span)
            why.append(f"the delay drifts across the sweep at {drift.rate * SPEED_OF_LIGHT / 2:+.2f} m/s "
                       f"(±{drift.std * SPEED_OF_LIGHT / 2:.2f}) but the Doppler reads "
                       f"{delay_rate * SPEED_OF_LIGHT / 2:+.2f} m/s: the velocity is beyond ±{radar.max_velocity:.2f} m/s "
                       f"and wrapped, probably {unwrapped * SPEED_OF_LIGHT / 2:+.2f} m/s (shorten the chirp period)")
        flags.append(Flag("aliased",
                          "; ".join(why) + f": the true return may lie {radar.max_range:.2f} m (or one velocity "
                          "span) further; check with a second chirp configuration or the expected geometry"))
    if unresolved is not None:
        stat, thr = unresolved
        flags.append(Flag("unresolved-peaks",
                          f"after removing the fitted RIS tone the residual within half a resolution cell is "
                          f"{10 * np.log10(max(stat, 1e-30)):.1f} dB (threshold {10 * np.log10(thr):.1f} dB): a second "
                          f"return lies within {radar.range_resolution * 100:.1f} cm / {radar.velocity_resolution:.2f} m/s "
                          "and biases delay and AoD; move the radar or use more bandwidth/chirps"))
    if delay < loopback_delay:
        flags.append(Flag("before-ris-delay",
                          f"the delay {delay * 1e9:.3f} ns is shorter than the RIS loop-back delay τ_RB = "
                          f"{loopback_delay * 1e9:.3f} ns: distance {distance:+.3f} m is negative and the position "
                          "lies behind the panel; check τ_RB, or the return is the panel's structural reflection "
                          "or an aliased one"))
    if is_one_dimensional(sweep) and ue_height is None:
        el_assumed = float(aod[1])
        if distance > 0:
            u = float(np.cos(el_assumed) * np.sin(aod[0]))
            base = _position(pose, distance, float(aod[0]), el_assumed)
            worst = 0.0
            for sign in (-1.0, 1.0):
                el = el_assumed + sign * float(np.arcsin(min(height_range / distance, 1.0)))
                if abs(u) < np.cos(el):
                    az = float(np.arcsin(u / np.cos(el)))
                    worst = max(worst, float(np.linalg.norm(_position(pose, distance, az, el) - base)))
            extra = (f"; a UE ±{height_range:.2f} m off that plane would be misplaced by up to {worst:.3f} m "
                     f"(mostly vertically)")
        else:
            extra = ""
        flags.append(Flag("elevation-assumed",
                          f"a 1-D sweep cannot see elevation: the position assumes the UE in the sweep plane "
                          f"(el {_deg(el_assumed)}){extra}; give ue_height (the radar's known height) to solve it"))
    elif ue_height is not None and not height_solved:
        flags.append(Flag("elevation-assumed",
                          f"ue_height={ue_height:.3f} m cannot be reached at distance {distance:.3f} m along the "
                          f"measured azimuth: the position assumes el {_deg(float(aod[1]))}; check the height "
                          "(world z) and the RIS pose"))
    return tuple(flags)
