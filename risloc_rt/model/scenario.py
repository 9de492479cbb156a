"""Analytic scenarios: the seed paper's point-target simulator (RIS loop-back + targets with an RCS)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from dsp import SPEED_OF_LIGHT, BeamSweep, ProcessingConfig, RadarConfig, RisPose
from dsp.validation import as_finite_array, non_negative

from .link_budget import carrier_phase, point_target_gain, ris_loopback_gain
from .paths import PathSet
from .ris import RisConfig, RisMode

__all__ = ["PointTarget", "Scenario", "Truth", "analytic_paths", "paper_scenario", "PAPER_CASES"]

#: UE-RIS distance of the paper's experiment and simulator [m].
PAPER_DISTANCE = 13.38
#: RCS of the paper's "other objects", used for the RIS panel's structural reflection [m²].
PAPER_RCS = 19.0
#: Built-in cases of :func:`paper_scenario`: name -> yaw of the RIS panel [deg].
PAPER_CASES: dict[str, float] = {"broadside": 0.0, "off-broadside": -21.0}


@dataclass(frozen=True)
class PointTarget:
    """A point scatterer with a constant radar cross-section.

    Parameters
    ----------
    position : float array [3]
        World frame [m].
    rcs : float
        σ [m²].
    velocity : float array [3], default 0
        World frame [m/s].
    label : str
        Name reported for its path.
    """

    position: np.ndarray
    rcs: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    label: str = "target"

    def __post_init__(self) -> None:
        for name in ("position", "velocity"):
            v = as_finite_array(getattr(self, name), name, shape=(3,)).copy()
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        object.__setattr__(self, "rcs", non_negative(self.rcs, "rcs", "m²"))


@dataclass(frozen=True)
class Truth:
    """Ground truth of one UE placement (what the DSP should estimate).

    Attributes
    ----------
    ue_position : float array [3]
        Where the UE is at ``reference_time``, world frame [m].
    ue_velocity : float array [3]
        World frame, constant over the sweep [m/s].
    distance : float
        UE-RIS distance at ``reference_time`` [m].
    velocity : float
        Rate of change of the UE-RIS distance at ``reference_time``, positive receding [m/s].
    aod : float array [2]
        ``[az, el]`` of the UE seen from the RIS at ``reference_time``, RIS frame [rad].
    reference_time : float or None, default None
        Time at which the position, distance and AoD hold, from the start of the sweep's first
        frame (the clock of ``RadarConfig.beam_times``): the middle of the sweep,
        ``mean(beam_times(M))`` (:func:`risloc_rt.model.motion.sweep_reference_time`) [s].
        ``None`` in captures written before the radar moved during a sweep (frozen geometry:
        the truth held over the whole sweep).
    """

    ue_position: np.ndarray
    ue_velocity: np.ndarray
    distance: float
    velocity: float
    aod: np.ndarray
    reference_time: float | None = None

    def position_at(self, time: float) -> np.ndarray:
        """The UE's position at ``time`` from the sweep start, ``p + v (t - t_ref)`` [3] [m].

        With no ``reference_time`` (a frozen-geometry capture) the position is the same at
        every time.
        """
        if self.reference_time is None:
            return np.asarray(self.ue_position, dtype=float).copy()
        return self.ue_position + self.ue_velocity * (float(time) - self.reference_time)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary [SI units, rad]."""
        return {"ue_position": np.asarray(self.ue_position).tolist(),
                "ue_velocity": np.asarray(self.ue_velocity).tolist(),
                "distance": float(self.distance), "velocity": float(self.velocity),
                "aod": np.asarray(self.aod).tolist(),
                "reference_time": None if self.reference_time is None else float(self.reference_time)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Truth":
        """Inverse of :meth:`to_dict`; files without ``reference_time`` (older) read it as None."""
        from dsp.validation import dataclass_from_dict

        if isinstance(data, dict):
            data = {"reference_time": None, **data}
        t = dataclass_from_dict(cls, data, "truth", require_all=True)
        return cls(
            ue_position=as_finite_array(t.ue_position, "truth.ue_position", shape=(3,)),
            ue_velocity=as_finite_array(t.ue_velocity, "truth.ue_velocity", shape=(3,)),
            distance=float(t.distance), velocity=float(t.velocity),
            aod=as_finite_array(t.aod, "truth.aod", shape=(2,)),
            reference_time=None if t.reference_time is None else float(t.reference_time),
        )


@dataclass(frozen=True)
class Scenario:
    """Everything needed to simulate and process one UE placement.

    Parameters
    ----------
    radar, ris, sweep, processing
        Radar, RIS, beam sweep and processing parameters.
    ue_position : float array [3]
        Where the UE is at the middle of the sweep, t_ref = ``mean(radar.beam_times(M))``
        (:func:`risloc_rt.model.motion.sweep_reference_time`), world frame [m].
    ue_velocity : float array [3], default 0
        World frame, constant [m/s]: the UE is at ``ue_position + ue_velocity (t - t_ref)`` at
        time t from the sweep start. :func:`risloc_rt.model.simulate.simulate` places it there
        in every frame (``motion="sweep"``, ``docs/moving-radar.md``), or freezes the geometry
        at t_ref as eq. (1) does (``motion="frozen"``: the velocity only sets the delay rates).
    targets : tuple of PointTarget
        Other scatterers (the paper's l > 0 paths); ``position`` is theirs at t_ref too.
    name : str
    """

    radar: RadarConfig
    ris: RisConfig
    sweep: BeamSweep
    processing: ProcessingConfig
    ue_position: np.ndarray
    ue_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    targets: tuple[PointTarget, ...] = ()
    name: str = "scenario"

    def __post_init__(self) -> None:
        for name in ("ue_position", "ue_velocity"):
            v = as_finite_array(getattr(self, name), name, shape=(3,)).copy()
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        object.__setattr__(self, "targets", tuple(self.targets))
        for t in self.targets:
            if not isinstance(t, PointTarget):
                raise TypeError(f"targets must be PointTarget instances, got {type(t).__name__}")
        d = float(np.linalg.norm(self.ue_position - self.ris.pose.position))
        if d <= 0:
            raise ValueError("ue_position coincides with the RIS position; they must be apart")
        aod = self.ris.pose.angles_to(self.ue_position)
        if abs(aod[0]) >= np.pi / 2 or abs(aod[1]) >= np.pi / 2:
            raise ValueError(
                f"the UE at {self.ue_position.tolist()} is behind the RIS panel (azimuth "
                f"{np.rad2deg(aod[0]):.1f}°, elevation {np.rad2deg(aod[1]):.1f}°); turn the RIS normal "
                "toward the room"
            )
        self.processing.check_against(self.radar.num_samples, self.radar.num_chirps)

    @property
    def truth(self) -> Truth:
        """The quantities the DSP should recover, at the middle of the sweep (``reference_time``)."""
        offset = self.ue_position - self.ris.pose.position
        d = float(np.linalg.norm(offset))
        return Truth(
            ue_position=self.ue_position,
            ue_velocity=self.ue_velocity,
            distance=d,
            velocity=float(self.ue_velocity @ offset / d),
            aod=self.ris.pose.angles_to(self.ue_position),
            reference_time=float(np.mean(self.radar.beam_times(self.sweep.num_beams))),
        )


def analytic_paths(scenario: Scenario) -> PathSet:
    """The paper's paths: the RIS loop-back (l = 0) and one path per point target (l > 0).

    Returns
    -------
    PathSet
        Loop-back: ``|γ_0|² = P G_trx |γ_UR|² ζ |γ_RU|²``, delay ``2 d_0/c + τ_RB``, RIS incidence
        and departure both at the UE's angle. Targets: ``|γ_l|² = P G_trx σ λ²/((4π)³ d_l⁴)``,
        delay ``2 d_l/c``. Every gain carries the carrier phase ``exp(-j2π f_c τ_l)``.
    """
    radar, ris, truth = scenario.radar, scenario.ris, scenario.truth
    gains, delays, rates, inc, labels = [], [], [], [], []

    tau0 = 2 * truth.distance / SPEED_OF_LIGHT + ris.loopback_delay
    gains.append(ris_loopback_gain(radar, truth.distance, ris.amplification) * carrier_phase(tau0, radar.carrier_frequency))
    delays.append(tau0)
    rates.append(2 * truth.velocity / SPEED_OF_LIGHT)
    inc.append(truth.aod)
    labels.append("ris_loopback")

    for t in scenario.targets:
        offset = scenario.ue_position - t.position
        d = float(np.linalg.norm(offset))
        if d <= 0:
            raise ValueError(f"target {t.label!r} sits on the UE; move it away")
        tau = 2 * d / SPEED_OF_LIGHT
        gains.append(point_target_gain(radar, d, t.rcs) * carrier_phase(tau, radar.carrier_frequency))
        delays.append(tau)
        rates.append(2 * float((scenario.ue_velocity - t.velocity) @ offset / d) / SPEED_OF_LIGHT)
        inc.append([np.nan, np.nan])
        labels.append(t.label)

    angles = np.array(inc, dtype=float)
    return PathSet(
        gain=np.array(gains, dtype=complex).ravel(),
        delay=np.array(delays),
        delay_rate=np.array(rates),
        ris_incidence=angles,
        ris_departure=angles,
        labels=tuple(labels),
    )


def paper_scenario(
    case: Literal["broadside", "off-broadside"] = "broadside",
    *,
    mode: RisMode = "relay",
    radar: RadarConfig | None = None,
    processing: ProcessingConfig | None = None,
) -> Scenario:
    """The seed paper's scenario (Table I): UE at the origin, RIS 13.38 m away along +y, facing it.

    Parameters
    ----------
    case : {"broadside", "off-broadside"}
        ``"broadside"``: the panel faces the UE (AoD [0°, 0°], the experiment).
        ``"off-broadside"``: the panel is turned 21° about the vertical, so the UE is seen at
        azimuth 21° (on the 1.5° sweep grid).
    mode : {"relay", "reflective"}
        RIS mode; in relay mode the Rx beam points at the UE, as in the experiment.
    radar, processing
        Overrides of Table I's radar and processing parameters.

    Notes
    -----
    The paths are the RIS loop-back and the panel's structural reflection, modelled as in the
    paper's simulator by a point target of σ = 19 m² at the RIS centre.
    """
    if case not in PAPER_CASES:
        raise ValueError(f"case={case!r} is not a paper case; choose one of {sorted(PAPER_CASES)}")
    ue = np.zeros(3)
    ris_position = np.array([0.0, PAPER_DISTANCE, 0.0])
    pose = RisPose.facing(ris_position, ue, yaw=np.deg2rad(PAPER_CASES[case]))
    ris = RisConfig(pose=pose, mode=mode).with_rx_toward(ue)
    return Scenario(
        radar=radar or RadarConfig(),
        ris=ris,
        sweep=BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5])),
        processing=processing or ProcessingConfig(),
        ue_position=ue,
        targets=(PointTarget(position=ris_position, rcs=PAPER_RCS, label="ris_structure"),),
        name=f"paper-{case}",
    )
