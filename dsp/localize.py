"""AoD, distance, velocity and position of the UE from a beam scan (Sec. III-B and III-C)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import non_negative
from .beamscan import BeamScan, scan_beams
from .geometry import RisPose, direction_from_angles
from .processing import ProcessingConfig
from .radar import SPEED_OF_LIGHT, RadarConfig
from .sweep import BeamSweep

__all__ = ["Localization", "localize", "self_localize"]


@dataclass(frozen=True)
class Localization:
    """The UE's self-localization from one RIS sweep.

    Attributes
    ----------
    beam_index : int
        m̂, the beam with the largest average power.
    aod : float array [2]
        θ̂ = φ_m̂, ``[az, el]`` at the RIS, RIS frame [rad].
    delay : float
        τ̂: the peak delay of beam m̂, corrected for range-Doppler coupling,
        ``τ_m̂ - f_c ν̂ / S`` [s].
    distance : float
        d̂ = (τ̂ - τ_RB)·c/2, UE-RIS distance [m].
    delay_rate : float
        ν̂ [s/s].
    velocity : float
        v̂ = ν̂·c/2, radial velocity, positive when the UE-RIS distance grows [m/s].
    direction : float array [3]
        d(θ̂), unit vector from the RIS toward the UE, world frame.
    position : float array [3]
        x̂_UE = x_RIS + d̂ · d(θ̂), world frame [m].
    scan : BeamScan
        The per-beam results the estimate was taken from.
    """

    beam_index: int
    aod: np.ndarray
    delay: float
    distance: float
    delay_rate: float
    velocity: float
    direction: np.ndarray
    position: np.ndarray
    scan: BeamScan


def localize(scan: BeamScan, *, radar: RadarConfig, pose: RisPose, loopback_delay: float) -> Localization:
    """Estimate the UE position from a :class:`BeamScan`.

    Parameters
    ----------
    scan : BeamScan
        Output of :func:`dsp.scan_beams`.
    radar : RadarConfig
        The radar that recorded the cube (for f_c and S).
    pose : RisPose
        Pose of the RIS whose beams were swept.
    loopback_delay : float
        τ_RB, the RIS's internal receive-to-transmit delay [s].

    Returns
    -------
    Localization
    """
    if not isinstance(scan, BeamScan):
        raise TypeError(f"scan must be a BeamScan from dsp.scan_beams, got {type(scan).__name__}")
    if not isinstance(pose, RisPose):
        raise TypeError(f"pose must be a RisPose, got {type(pose).__name__}")
    tau_rb = non_negative(loopback_delay, "loopback_delay", "s")
    m = scan.best_beam
    aod = np.array(scan.angles[m], dtype=float)
    nu = float(scan.delay_rate[m])
    tau = float(scan.delay[m]) - radar.carrier_frequency * nu / radar.slope
    distance = (tau - tau_rb) * SPEED_OF_LIGHT / 2.0
    direction = pose.to_world(direction_from_angles(aod))
    return Localization(
        beam_index=m,
        aod=aod,
        delay=tau,
        distance=float(distance),
        delay_rate=nu,
        velocity=nu * SPEED_OF_LIGHT / 2.0,
        direction=direction,
        position=pose.position + distance * direction,
        scan=scan,
    )


def self_localize(
    cube: Any,
    *,
    sweep: BeamSweep,
    radar: RadarConfig,
    processing: ProcessingConfig,
    pose: RisPose,
    loopback_delay: float,
) -> Localization:
    """:func:`scan_beams` followed by :func:`localize`: beat cube ``[M, K, N]`` -> position."""
    return localize(scan_beams(cube, sweep, radar, processing), radar=radar, pose=pose,
                    loopback_delay=loopback_delay)
