"""Analytic scenarios in one call: a UE placed by position or by RIS-frame distance and AoD.

:func:`analytic_scenario` builds the paper's point-target scenario around any UE placement: the
RIS loop-back, the panel's structural reflection (on by default, σ = 19 m² at the RIS centre, as
the paper's simulator), Table I's radar, the paper's ±45°/1.5° sweep. A relay RIS steers its
receive beam toward the UE unless told otherwise; a receive beam that misses the UE by more than
its half-power beamwidth raises :class:`RisMisconfiguredWarning`, because the RIS then returns
almost nothing and the DSP would localize on clutter.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from dsp import BeamSweep, ProcessingConfig, RadarConfig, RisPose, direction_from_angles
from dsp.validation import as_finite_array, positive

from .ris import RisConfig, RisMode
from .scenario import PAPER_DISTANCE, PAPER_RCS, PointTarget, Scenario

__all__ = ["RisMisconfiguredWarning", "analytic_scenario", "relay_rx_gain"]

#: The paper's RIS position: 13.38 m along +y from the origin, at the UE's height [m].
PAPER_RIS_POSITION = (0.0, PAPER_DISTANCE, 0.0)


class RisMisconfiguredWarning(UserWarning):
    """The relay RIS's receive beam does not point at the UE: its re-transmission is weak."""


def relay_rx_gain(ris: RisConfig, point: Any, *, wavelength: float) -> float:
    """|a(θ)ᵀ w_Rx| / N_RIS: the relay receive beam's gain toward ``point``, 1 on its peak.

    Parameters
    ----------
    ris : RisConfig
    point : float array [3]
        World frame [m].
    wavelength : float
        λ [m].
    """
    k = 2 * np.pi / positive(wavelength, "wavelength", "m")
    x = ris.element_positions  # [N, 3]
    d_ue = direction_from_angles(ris.pose.angles_to(as_finite_array(point, "point", shape=(3,))))
    d_rx = direction_from_angles(ris.relay_rx_angle)
    return float(abs(np.sum(np.exp(1j * k * (x @ (d_ue - d_rx))))) / ris.num_elements)


def analytic_scenario(
    *,
    ue_position: Any = None,
    distance: float | None = None,
    aod: Any = None,
    ue_velocity: Any = (0.0, 0.0, 0.0),
    mode: RisMode = "relay",
    tx_power_dbm: float | None = None,
    ris_position: Any = PAPER_RIS_POSITION,
    ris_facing: Any = (0.0, 0.0, 0.0),
    ris_yaw: float = 0.0,
    ris_pose: RisPose | None = None,
    relay_rx_angle: Any = None,
    structure: bool = True,
    structure_rcs: float = PAPER_RCS,
    radar: RadarConfig | None = None,
    sweep: BeamSweep | None = None,
    processing: ProcessingConfig | None = None,
    name: str | None = None,
) -> Scenario:
    """The paper's analytic scenario for any UE placement.

    Give the UE either as ``ue_position`` or as ``distance`` and ``aod`` in the RIS frame.

    Parameters
    ----------
    ue_position : float array [3], optional
        World frame [m].
    distance : float, optional
        UE-RIS distance [m] (with ``aod``).
    aod : float array [2], optional
        ``[az, el]`` of the UE seen from the RIS, RIS frame [rad] (with ``distance``).
    ue_velocity : float array [3], default 0
        World frame [m/s].
    mode : {"relay", "reflective"}, default "relay"
    tx_power_dbm : float, optional
        Transmit power [dBm]; default Table I's 20 dBm (or ``radar``'s).
    ris_position : float array [3], default [0, 13.38, 0]
        World frame [m].
    ris_facing : float array [3], default the origin
        The point the RIS normal looks at, world frame [m]; with ``ris_yaw`` [rad] the panel is
        turned about the vertical from there (the paper's off-broadside case is yaw -21°).
    ris_pose : RisPose, optional
        The whole pose instead of ``ris_position``/``ris_facing``/``ris_yaw``.
    relay_rx_angle : float array [2], optional
        ``[az, el]`` of the relay RIS's fixed receive beam, RIS frame [rad]; default: toward the
        UE (as in the paper's experiment). A beam that misses the UE by more than its
        half-power width warns (:class:`RisMisconfiguredWarning`).
    structure : bool, default True
        Add the panel's structural reflection as a point target at the RIS centre.
    structure_rcs : float, default 19
        Its RCS σ [m²] (the paper's value for "other objects").
    radar, sweep, processing
        Overrides of Table I's radar, the paper's sweep (-45° … 45°, 1.5°) and the processing.
    name : str, optional

    Returns
    -------
    Scenario

    Raises
    ------
    ValueError
        Both or neither UE placements given, a non-positive distance, a UE behind the panel.
    """
    if (ue_position is None) == (distance is None and aod is None):
        raise ValueError("place the UE either by ue_position=[x, y, z] or by distance=... and aod=[az, el], not both/neither")
    pose = ris_pose if ris_pose is not None else RisPose.facing(
        as_finite_array(ris_position, "ris_position", shape=(3,)),
        as_finite_array(ris_facing, "ris_facing", shape=(3,)), yaw=float(ris_yaw))
    if not isinstance(pose, RisPose):
        raise TypeError(f"ris_pose must be a dsp.RisPose, got {type(pose).__name__}")
    if ue_position is None:
        if distance is None or aod is None:
            raise ValueError("distance and aod go together: give both (distance [m], aod [az, el] [rad])")
        d = positive(distance, "distance", "m")
        angles = as_finite_array(aod, "aod", shape=(2,))
        ue = pose.position + d * pose.to_world(direction_from_angles(angles))
    else:
        ue = as_finite_array(ue_position, "ue_position", shape=(3,))
    radar = radar or RadarConfig()
    if tx_power_dbm is not None:
        from dataclasses import replace

        radar = replace(radar, tx_power_dbm=tx_power_dbm)
    ris = RisConfig(pose=pose, mode=mode)
    ris = ris.with_rx_toward(ue) if relay_rx_angle is None else \
        RisConfig(pose=pose, mode=mode, relay_rx_angle=as_finite_array(relay_rx_angle, "relay_rx_angle", shape=(2,)))
    targets = (PointTarget(position=pose.position, rcs=structure_rcs, label="ris_structure"),) if structure else ()
    scenario = Scenario(
        radar=radar,
        ris=ris,
        sweep=sweep or BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5])),
        processing=processing or ProcessingConfig(),
        ue_position=ue,
        ue_velocity=as_finite_array(ue_velocity, "ue_velocity", shape=(3,)),
        targets=targets,
        name=name or "analytic",
    )
    if mode == "relay":
        gain = relay_rx_gain(ris, ue, wavelength=radar.wavelength)
        if gain < np.sqrt(0.5):
            warnings.warn(
                f"the relay RIS's receive beam at {np.rad2deg(ris.relay_rx_angle).round(2).tolist()}° misses the UE at "
                f"{np.rad2deg(scenario.truth.aod).round(2).tolist()}° ({-20 * np.log10(max(gain, 1e-12)):.1f} dB below its "
                "peak): the RIS will return little and the DSP may localize on clutter; leave relay_rx_angle unset "
                "to point it at the UE",
                RisMisconfiguredWarning, stacklevel=2)
    return scenario
