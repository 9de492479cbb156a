"""A moving radar: the paths of each frame of the sweep, from where the UE is during that frame.

Eq. (1) freezes the geometry over a sweep. A radar at walking speed moves decimetres to metres
during the 61 frames of a sweep, so the delay, delay rate, gain and RIS angles of every path
change from beam to beam. This module builds one set of paths per frame (``PathFrames``):

- analytic scenarios (:func:`analytic_frame_paths`): the UE and the point targets are placed
  where they are at the centre of each frame and every path is recomputed exactly;
- any static ``PathSet``, e.g. a ray-traced hall (:func:`advance_paths`): first order in time,
  each path's delay advanced by its delay rate, its angles and amplitude kept (re-tracing 61
  frames would cost 61 traces).

Time runs from the start of the sweep's first frame (the clock of ``RadarConfig.beam_times``).
A scenario's positions are those at the middle of the sweep, :func:`sweep_reference_time`.
See ``docs/moving-radar.md``.
"""

from __future__ import annotations

import numpy as np

from dsp import SPEED_OF_LIGHT, RadarConfig

from .link_budget import carrier_phase, point_target_gain, ris_loopback_gain
from .paths import PathFrames, PathSet
from .scenario import Scenario, analytic_paths

__all__ = ["advance_paths", "analytic_frame_paths", "frame_start_times", "sweep_reference_time", "ue_positions"]


def sweep_reference_time(radar: RadarConfig, num_beams: int) -> float:
    """t_ref, the middle of the sweep: ``mean(radar.beam_times(M))`` [s].

    The centre of the middle beam's frame for an odd M (beam 30 of the paper's 61), measured
    from the start of the first frame. Scenario positions and the ``Truth`` refer to it.
    """
    return float(np.mean(radar.beam_times(num_beams)))


def frame_start_times(radar: RadarConfig, num_beams: int) -> np.ndarray:
    """Start of each beam's frame (its first chirp), ``beam_times - K·T_c/2`` [M] [s]."""
    return radar.beam_times(num_beams) - 0.5 * radar.frame_duration


def ue_positions(scenario: Scenario) -> np.ndarray:
    """Where the UE is at the centre of each frame, ``p + v (t_m - t_ref)`` [M, 3] [m]."""
    radar, m = scenario.radar, scenario.sweep.num_beams
    dt = radar.beam_times(m) - sweep_reference_time(radar, m)
    return scenario.ue_position + dt[:, None] * scenario.ue_velocity


def _is_static(scenario: Scenario) -> bool:
    return not scenario.ue_velocity.any() and not any(t.velocity.any() for t in scenario.targets)


def analytic_frame_paths(scenario: Scenario) -> PathSet | PathFrames:
    """The paper's paths (:func:`risloc_rt.model.scenario.analytic_paths`) in every frame.

    Returns
    -------
    PathSet or PathFrames
        ``analytic_paths(scenario)`` itself when nothing moves (the static cube, bit for bit);
        otherwise one frame per beam: the UE at ``p_m = p + v (t_m - t_ref)`` and target j at
        ``q_j + w_j (t_m - t_ref)``, t_m the frame centre (``radar.beam_times``), and every
        delay (``2 d_m/c``, plus τ_RB for the loop-back), delay rate, gain and RIS angle
        computed there.

    Notes
    -----
    Within a frame eq. (1) holds: the delay rate carries the motion across the chirps and the
    beat frequency keeps the delay of the frame centre (no range migration: at 2 m/s the UE
    moves 1.3 cm during a Table I frame, a third of the 3.6 cm range resolution). The carrier
    phase in each gain is that of the frame's first chirp, ``exp(-j2π f_c (τ_m - ν_m K T_c/2))``,
    matching eq. (1)'s slow-time phase, which starts at 0 on chirp k = 0.
    """
    if _is_static(scenario):
        return analytic_paths(scenario)
    radar, ris, m = scenario.radar, scenario.ris, scenario.sweep.num_beams
    times = radar.beam_times(m)
    dt = times - sweep_reference_time(radar, m)  # [M]
    ue = ue_positions(scenario)  # [M, 3]
    half_frame = 0.5 * radar.frame_duration
    c = SPEED_OF_LIGHT

    offset = ue - ris.pose.position  # [M, 3]
    d0 = np.linalg.norm(offset, axis=1)  # [M]
    aod = ris.pose.angles_to(ue)  # [M, 2]
    if np.any(d0 <= 0) or np.any(np.abs(aod) >= np.pi / 2):
        bad = int(np.flatnonzero((d0 <= 0) | np.any(np.abs(aod) >= np.pi / 2, axis=1))[0])
        raise ValueError(f"the moving UE reaches {ue[bad].tolist()} (frame {bad}), on or behind the RIS panel; "
                         "shorten the sweep or slow the UE")
    tau, nu = [2 * d0 / c + ris.loopback_delay], [2 * (offset @ scenario.ue_velocity) / d0 / c]
    amp = [ris_loopback_gain(radar, d0, ris.amplification)]
    inc = [aod]
    labels = ["ris_loopback"]
    for t in scenario.targets:
        rel = ue - (t.position + dt[:, None] * t.velocity)  # [M, 3], target -> UE
        d = np.linalg.norm(rel, axis=1)
        if np.any(d <= 0):
            raise ValueError(f"target {t.label!r} meets the moving UE during the sweep; move it away")
        tau.append(2 * d / c)
        nu.append(2 * (rel @ (scenario.ue_velocity - t.velocity)) / d / c)
        amp.append(point_target_gain(radar, d, t.rcs))
        inc.append(np.full((m, 2), np.nan))
        labels.append(t.label)
    tau_m, nu_m = np.stack(tau, axis=1), np.stack(nu, axis=1)  # [M, L]
    gain = np.stack(amp, axis=1) * carrier_phase(tau_m - nu_m * half_frame, radar.carrier_frequency)
    angles = np.stack(inc, axis=1)  # [M, L, 2]
    return PathFrames(gain=gain, delay=tau_m, delay_rate=nu_m, ris_incidence=angles, ris_departure=angles,
                      labels=tuple(labels), times=times)


def advance_paths(paths: PathSet, *, radar: RadarConfig, num_beams: int,
                  reference_time: float | None = None) -> PathSet | PathFrames:
    """First-order motion of a static path set over the sweep: ``τ_m = τ + ν (t_m - t_ref)``.

    Parameters
    ----------
    paths : PathSet
        The paths at ``reference_time`` (e.g. traced at the UE's position there).
    radar : RadarConfig
    num_beams : int
        M, one frame per beam.
    reference_time : float, optional
        When ``paths`` hold, from the sweep start [s]; by default the middle of the sweep
        (:func:`sweep_reference_time`), as a scenario's ``ue_position``.

    Returns
    -------
    PathSet or PathFrames
        ``paths`` itself when no path has a delay rate (a radar at rest); otherwise per frame
        m: delay ``τ + ν (t_m - t_ref)`` at the frame centre t_m, the same rate ν, the gain's
        carrier phase moved to the frame's first chirp, ``γ exp(-j2π f_c ν (t_m - K T_c/2 -
        t_ref))``, and the same amplitude and RIS angles.

    Notes
    -----
    The update neglects the second-order term of each leg's length, ``v_⊥² Δt² / (2 d)`` for
    the velocity component v_⊥ across the leg: at the ends of a Table I sweep (Δt = ±0.195 s)
    at 1 m/s tangential and d = 13.4 m, 1.4 mm. It keeps the angles of t_ref, while a UE moving
    tangentially at v turns the RIS-frame AoD by ``v Δt / d``: 0.83° at the sweep's ends at
    1 m/s, d = 13.4 m, half a 1.5° sweep step; the sweep's power pattern then no longer peaks
    quite where the geometry says. Use :func:`analytic_frame_paths` where that matters, or trace
    several positions.
    """
    if not np.any(paths.delay_rate):
        return paths
    times = radar.beam_times(num_beams)
    t_ref = sweep_reference_time(radar, num_beams) if reference_time is None else float(reference_time)
    dt = times - t_ref  # [M]
    nu = np.broadcast_to(paths.delay_rate, (num_beams, len(paths)))
    delay = paths.delay + dt[:, None] * paths.delay_rate  # [M, L]
    if np.any(delay < 0):
        raise ValueError("advancing the paths over the sweep makes a delay negative; the sweep is too long "
                         "for the first-order update (trace the geometry at several times)")
    start_shift = (dt - 0.5 * radar.frame_duration)[:, None] * paths.delay_rate  # [M, L]
    gain = paths.gain * carrier_phase(start_shift, radar.carrier_frequency)
    tile = lambda x: np.broadcast_to(x, (num_beams,) + x.shape)  # noqa: E731
    return PathFrames(gain=gain, delay=delay, delay_rate=nu, ris_incidence=tile(paths.ris_incidence),
                      ris_departure=tile(paths.ris_departure), labels=paths.labels, times=times)
