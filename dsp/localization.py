"""The result of a localization, and the paper's method on a beam scan (Sec. III-B and III-C).

:class:`Localization` is what :func:`dsp.self_localize` returns; :func:`localize` is the paper's
estimate from a :class:`BeamScan` (best beam by P_ave, its grid peak); :func:`no_position` is the
result without a detection (no numbers, the flags that say why).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from typing import Any

from .validation import fields_equal, non_negative
from .beamscan import BeamScan
from .detection import Detection
from .flags import Flag
from .geometry import RisPose, direction_from_angles
from .qualify import Uncertainty
from .radar import SPEED_OF_LIGHT, RadarConfig

__all__ = ["Alternative", "Localization", "NoPositionError", "localize", "no_position"]


class NoPositionError(ValueError):
    """Raised by :meth:`Localization.checked_position` when nothing was detected."""


@dataclass(frozen=True, eq=False)
class Alternative:
    """A position the estimator did not choose but the data allow: another maximum of the AoD fit.

    Attributes
    ----------
    aod : float array [2]
        ``[az, el]`` at the RIS, RIS frame [rad] (el as the estimate's: assumed or solved from a height).
    position : float array [3]
        The position it gives at the estimated distance, world frame [m].
    level_db : float
        The beam-pattern fit there relative to the chosen estimate's fit, a power ratio [dB]
        (profiled objective ``(Σ|A_m| r_m)²/ΣA_m²``, the least-squares fit of the per-beam
        magnitudes): 0 dB is a tie (a grating-lobe twin), -10 dB a maximum 10 dB weaker.
    kind : {"grating-twin", "fit-maximum"}
        ``"grating-twin"``: the estimate's grating-lobe translate beyond the swept span, which the
        beam powers cannot tell from it; ``"fit-maximum"``: another local maximum of the fit inside
        the span (a grating lobe or a sidelobe).
    reason : str
        Why it was not chosen.
    offset : float
        Its distance from the estimated position [m].
    """

    aod: np.ndarray
    position: np.ndarray
    level_db: float
    kind: str
    reason: str
    offset: float

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary: ``aod`` [rad], ``aod_deg`` [deg], ``position`` [m], ``level_db``, ``kind``,
        ``reason``, ``offset`` [m]."""
        return {"aod": [float(v) for v in self.aod], "aod_deg": [float(v) for v in np.rad2deg(self.aod)],
                "position": [float(v) for v in self.position], "level_db": float(self.level_db),
                "kind": self.kind, "reason": self.reason, "offset": float(self.offset)}

    def __eq__(self, other: object) -> bool:
        return fields_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


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
    scan : BeamScan or None
        The paper's per-beam grid results (the estimate's source with the paper's estimator, the
        P_ave profile reports plot); None when :func:`self_localize` was asked not to compute it.
    detection : Detection or None
        The detector's outcome (:func:`self_localize`); None from :func:`localize`, which runs
        the paper's method on a scan without a detector.
    std : Uncertainty or None
        1σ of distance, velocity, AoD and position from the CRB at the measured SNR; None
        without a detection.
    flags : tuple of Flag
        Named warnings with cause and remedy (``docs/flags.md``).
    estimator : {"paper", "refined"}
        Which estimator produced the numbers.
    reference_time : float
        Time the position refers to, from the start of the sweep's first frame [s]
        (``docs/estimation.md``); NaN from :func:`localize`.
    alternatives : tuple of Alternative
        Every other AoD the beam-pattern fit allows (its other maxima in the swept span, the
        estimate's grating-lobe twins beyond it), each with its position, fit level and why it was
        not chosen (``grating-lobe`` in ``docs/flags.md``); empty from :func:`localize` and without
        a detection.

    Notes
    -----
    **No detection, no position.** When ``detection.detected`` is False, ``aod``, ``delay``,
    ``distance``, ``delay_rate``, ``velocity``, ``direction`` and ``position`` are all NaN
    (arithmetic on them stays NaN, comparisons are False), ``flags`` starts with
    ``no-detection`` and :meth:`checked_position` raises. ``beam_index`` then names the scan's
    strongest beam (for plots; without a scan the detector's strongest beam, -1 if it found no
    cell), not an AoD.
    """

    beam_index: int
    aod: np.ndarray
    delay: float
    distance: float
    delay_rate: float
    velocity: float
    direction: np.ndarray
    position: np.ndarray
    scan: BeamScan | None
    detection: Detection | None = None
    std: Uncertainty | None = None
    flags: tuple[Flag, ...] = ()
    estimator: str = "paper"
    reference_time: float = math.nan
    alternatives: tuple[Alternative, ...] = ()

    @property
    def detected(self) -> bool:
        """False when the detector found no RIS return (then every estimate is NaN)."""
        return self.detection is None or bool(self.detection.detected)

    @property
    def flag_codes(self) -> tuple[str, ...]:
        """The codes of :attr:`flags`."""
        return tuple(f.code for f in self.flags)

    def checked_position(self) -> np.ndarray:
        """The position [3] [m], or :class:`NoPositionError` when nothing was detected."""
        if not self.detected:
            raise NoPositionError("no RIS return was detected in this capture: there is no position "
                                  f"({'; '.join(str(f) for f in self.flags)})")
        return self.position


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


def _strongest_beam(scan: BeamScan | None, det: Detection) -> int:
    """The scan's best beam, else the beam strongest in the detector's best cell (-1: none)."""
    if scan is not None:
        return scan.best_beam
    power = det.beam_power
    return int(np.argmax(power)) if power is not None and np.size(power) else -1


def no_position(scan: BeamScan | None, det: Detection) -> Localization:
    """The :class:`Localization` of a capture without a detection: the detector's outcome, no numbers.

    Parameters
    ----------
    scan : BeamScan or None
        The per-beam grid results, kept for plots (its best beam becomes ``beam_index``).
    det : Detection
        The detector's outcome, ``det.detected`` False.

    Returns
    -------
    Localization
        Every estimate NaN, ``std`` None, ``estimator`` ``"none"``; ``flags`` starts with
        ``no-detection`` (then ``no-beam-dependence`` when returns crossed the threshold but none
        followed the sweep).
    """
    nan2, nan3 = np.full(2, np.nan), np.full(3, np.nan)
    if det.rejected:
        flag = Flag("no-beam-dependence",
                    f"{det.rejected} return(s) crossed the detection threshold ({det.threshold_db:.1f} dB) but none "
                    "follows the sweep: they are clutter, not the RIS; no position. Check that the RIS sweeps its "
                    "beam during the capture and that the frames are aligned with the sweep angles")
    else:
        flag = Flag("no-detection",
                    f"no beam-dependent return above the threshold: SNR {det.snr_db:.1f} dB (integrated over "
                    f"{det.integrated_beams} beams) < "
                    f"{det.threshold_db:.1f} dB at P_FA = {det.false_alarm_probability:g}; no position. Move closer, "
                    "raise the transmit power or the RIS gain, or accept a higher pfa")
    flags = (flag,) if flag.code == "no-detection" else (Flag("no-detection", "no RIS return detected: no position"), flag)
    return Localization(
        beam_index=_strongest_beam(scan, det), aod=nan2, delay=math.nan, distance=math.nan, delay_rate=math.nan,
        velocity=math.nan, direction=nan3, position=nan3, scan=scan, detection=det, std=None, flags=flags,
        estimator="none", reference_time=math.nan,
    )
