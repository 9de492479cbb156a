"""The uncertainty budget of a measured localization: every term of its 1σ, named, and the total.

A simulated capture's 1σ is the noise's (the Cramér–Rao bound at the measured SNR). A measurement
also carries what the model was told rather than what it measured: the chirp the device really
runs (TI's truncated slope and start-frequency registers), the RIS loop-back delay τ_RB and the
radar's internal range offset (nominal unless a calibration file gives them, with its own σ), the
RIS pose and its element spacing (their tolerances, ``[tolerance]`` of the sweep schedule).
:func:`measured_budget` lists each as a :class:`BudgetTerm` (name, quantity, 1σ, unit, source, and
the correction already applied where the term is a known bias), and gives the total as a
``dsp.Uncertainty`` of kind ``"budget"`` (terms in quadrature; position through the Jacobian of
``position = p_RIS + d·R·u(az, el)``). Without a calibration file the nominal τ_RB and range offset
are **biases** of unknown sign, not noise: they are listed with no σ, left out of the total, and
:func:`apply_budget` flags the localization ``uncalibrated`` with the size of the distance bias
they may hide. ``docs/measured-captures.md``, "Uncertainty budget".
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dsp import Flag, Localization
from dsp.qualify import Uncertainty, position_at
from dsp.radar import SPEED_OF_LIGHT

from ...model.capture import Capture
from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig
from ..ti.sdk_cfg import parse_sdk_cfg
from ..ti.studio_json import parse_studio_json

__all__ = ["BudgetTerm", "RisTolerances", "UNCALIBRATED_LOOPBACK_FRACTION", "UNCALIBRATED_RANGE_OFFSET",
           "UncertaintyBudget", "apply_budget", "measured_budget", "ris_tolerances"]

#: Size of a TI radar's internal range offset that a missing calibration may hide [m]: evaluation
#: boards measure a few centimetres (the mmWave SDK's ``compRangeBiasAndRxChanPhase`` range bias).
UNCALIBRATED_RANGE_OFFSET = 0.05
#: Fraction of the nominal τ_RB that a RIS's real loop-back delay may differ by without calibration.
UNCALIBRATED_LOOPBACK_FRACTION = 0.10


@dataclass(frozen=True)
class BudgetTerm:
    """One term of a measured estimate's uncertainty.

    Attributes
    ----------
    name : str
        What it is (``"noise"``, ``"slope register"``, ``"loop-back delay τ_RB"`` …).
    quantity : {"distance", "velocity", "aod_az", "position"}
        The estimate it enters.
    value : float or None
        Its 1σ in ``unit``; None when not known (a nominal value with no stated tolerance: then it
        is not in the total, and its possible size is in ``bound``).
    unit : str
        ``"m"``, ``"m/s"`` or ``"deg"``.
    source : str
        Where the number comes from.
    correction : float or None
        A known bias already removed from the estimate, in ``unit`` (e.g. what the ``.cfg``'s
        untruncated slope would have added).
    bound : float or None
        For a term with no σ: the size of the bias it may hide, in ``unit``.
    """

    name: str
    quantity: str
    value: float | None
    unit: str
    source: str
    correction: float | None = None
    bound: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON: every attribute (None where not applicable).

        Returns
        -------
        dict
            ``name``, ``quantity``, ``value``, ``unit``, ``source``, ``correction``, ``bound``.
        """
        return {"name": self.name, "quantity": self.quantity, "value": self.value, "unit": self.unit,
                "source": self.source, "correction": self.correction, "bound": self.bound}


@dataclass(frozen=True)
class RisTolerances:
    """1σ of what the sweep schedule says about the RIS (NaN: not stated).

    Attributes
    ----------
    position : float
        Of each coordinate of the RIS centre [m].
    yaw : float
        Of the panel's azimuth (its normal about world up) [rad].
    element_spacing : float
        Relative, of the element pitch (e.g. 0.01 for 1 %) [-].
    """

    position: float = math.nan
    yaw: float = math.nan
    element_spacing: float = math.nan


@dataclass(frozen=True)
class UncertaintyBudget:
    """The terms and their total.

    Attributes
    ----------
    terms : tuple of BudgetTerm
    total : dsp.qualify.Uncertainty
        ``kind="budget"``: the noise's σ with every term of known σ added in quadrature.
    uncalibrated_bias : float or None
        Without a calibration: the distance bias the nominal τ_RB and range offset may hide [m].
    """

    terms: tuple[BudgetTerm, ...]
    total: Uncertainty
    uncalibrated_bias: float | None

    def to_list(self) -> list[dict[str, Any]]:
        """The terms as plain JSON (``result.json``: ``estimate.uncertainty_budget``).

        Returns
        -------
        list of dict
            :meth:`BudgetTerm.to_dict` of each term.
        """
        return [t.to_dict() for t in self.terms]


def _configuration(capture: Capture) -> TiChirpConfig | None:
    text = (capture.provenance.get("config") or {}).get("text")
    if not isinstance(text, str) or not text.strip():
        return None
    try:
        if text.lstrip().startswith("{"):
            return parse_studio_json(json.loads(text)).config
        return parse_sdk_cfg(text, strict=False).config
    except (MeasuredFormatError, ValueError, TypeError):
        return None


def ris_tolerances(capture: Capture) -> RisTolerances:
    """The ``[tolerance]`` table of the capture's sweep schedule (``position_m``, ``yaw_deg``,
    ``element_spacing``), NaN for what it does not state.

    Parameters
    ----------
    capture : Capture
        Imported; its provenance holds the schedule's text.

    Returns
    -------
    RisTolerances
    """
    text = capture.provenance.get("schedule")
    table: dict[str, Any] = {}
    if isinstance(text, str):
        try:
            table = tomllib.loads(text).get("tolerance") or {}
        except tomllib.TOMLDecodeError:
            table = {}

    def get(key: str, scale: float) -> float:
        v = table.get(key)
        return float(v) * scale if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan

    return RisTolerances(position=get("position_m", 1.0), yaw=get("yaw_deg", math.pi / 180),
                         element_spacing=get("element_spacing", 1.0))


def _chirp_terms(cfg: TiChirpConfig | None, loc: Localization) -> list[BudgetTerm]:
    """The device's registers: what the ``.cfg``'s own values would have added (corrections) and the residual."""
    if cfg is None:
        return [BudgetTerm("chirp registers", "distance", None, "m",
                           "no radar configuration in the capture's provenance: the slope's register step is unknown")]
    s_file, s_dev = cfg.slope, cfg.quantized_slope
    f_file_centre = cfg.band_centre(quantized=False)
    f_dev_centre = cfg.band_centre()
    apparent = loc.delay * SPEED_OF_LIGHT / 2.0                      # the delay's range [m]
    # d ∝ 1/S: the file's slope would have given apparent·s_dev/s_file
    slope_corr = apparent * (1.0 - s_dev / s_file) if s_file else 0.0
    start_corr = loc.velocity * (1.0 - f_dev_centre / f_file_centre)
    carrier_corr = loc.velocity * (1.0 - f_dev_centre / cfg.quantized_start_frequency)
    return [
        BudgetTerm("slope register", "distance", 0.0, "m",
                   f"TI's truncation modelled: {s_file / 1e12:.6g} MHz/us in the .cfg runs as {s_dev / 1e12:.6f} "
                   "(mmWave SDK profileCfg, trunc(S*2^26/(f_ref*900)) steps); slope and ADC clock share the "
                   "reference oscillator, so its error cancels", correction=slope_corr),
        BudgetTerm("start-frequency register", "velocity", 0.0, "m/s",
                   f"TI's truncation modelled: {cfg.start_frequency / 1e9:.9g} GHz runs as "
                   f"{cfg.quantized_start_frequency / 1e9:.9f} GHz (steps of f_ref/2^26)", correction=start_corr),
        BudgetTerm("carrier reference", "velocity", 0.0, "m/s",
                   f"the slow-time phase advances at the ADC window's centre, {f_dev_centre / 1e9:.4f} GHz, not at "
                   f"the start frequency", correction=carrier_corr),
    ]


def _delay_terms(capture: Capture) -> tuple[list[BudgetTerm], float | None]:
    cal = capture.provenance.get("calibration")
    tau = capture.ris.loopback_delay
    if isinstance(cal, dict):
        def std(key: str) -> float | None:
            v = cal.get(key + "_std")
            return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None

        r_std, t_std = std("range_offset"), std("loopback_delay")
        return [
            BudgetTerm("radar range offset", "distance", r_std, "m",
                       "calibration file" + ("" if r_std is not None else " (gives no σ)")),
            BudgetTerm("loop-back delay τ_RB", "distance", None if t_std is None else t_std * SPEED_OF_LIGHT / 2, "m",
                       "calibration file" + ("" if t_std is not None else " (gives no σ)")),
        ], None
    r_bound = UNCALIBRATED_RANGE_OFFSET
    t_bound = UNCALIBRATED_LOOPBACK_FRACTION * tau * SPEED_OF_LIGHT / 2
    return [
        BudgetTerm("radar range offset", "distance", None, "m",
                   "not calibrated: a TI board's internal range bias is centimetres (compRangeBiasAndRxChanPhase)",
                   bound=r_bound),
        BudgetTerm("loop-back delay τ_RB", "distance", None, "m",
                   f"nominal {tau * 1e9:.4g} ns from the sweep schedule, not calibrated "
                   f"(±{UNCALIBRATED_LOOPBACK_FRACTION:.0%} assumed)", bound=t_bound),
    ], math.hypot(r_bound, t_bound)


def _ris_terms(tol: RisTolerances, az: float) -> list[BudgetTerm]:
    def known(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    how = "[tolerance] {} in the sweep schedule"
    spacing = None if not math.isfinite(tol.element_spacing) else \
        float(np.rad2deg(tol.element_spacing * abs(math.tan(az))))
    return [
        BudgetTerm("RIS yaw", "aod_az", None if not math.isfinite(tol.yaw) else float(np.rad2deg(tol.yaw)), "deg",
                   how.format("yaw_deg") if math.isfinite(tol.yaw) else "not stated: give [tolerance] yaw_deg"),
        BudgetTerm("RIS element spacing", "aod_az", spacing, "deg",
                   (how.format("element_spacing") + ": a beam steered to θ for pitch d points to "
                    "asin(sin θ·d/(d(1+ε))), δθ = ε·tan θ") if spacing is not None else
                   "not stated: give [tolerance] element_spacing (relative)"),
        BudgetTerm("RIS position", "position", known(tol.position), "m",
                   how.format("position_m") + " (each axis)" if math.isfinite(tol.position)
                   else "not stated: give [tolerance] position_m"),
    ]


def measured_budget(capture: Capture, loc: Localization, *, tolerances: RisTolerances | None = None
                    ) -> UncertaintyBudget | None:
    """The uncertainty budget of ``loc``, a localization of the measured ``capture``.

    Parameters
    ----------
    capture : Capture
        Its provenance says it was measured (``source == "measurement"``), holds the radar
        configuration's text, the schedule and, when applied, the calibration.
    loc : dsp.Localization
        With a position and its noise 1σ (``loc.std``).
    tolerances : RisTolerances, optional
        Default: the schedule's ``[tolerance]`` table (:func:`ris_tolerances`).

    Returns
    -------
    UncertaintyBudget or None
        None for a capture that was not measured, or a localization with no position or σ.
    """
    if capture.provenance.get("source") != "measurement" or loc.std is None or not loc.detected:
        return None
    tol = ris_tolerances(capture) if tolerances is None else tolerances
    std = loc.std
    az, el = float(loc.aod[0]), float(loc.aod[1])
    terms = [BudgetTerm("noise", "distance", float(std.distance), "m",
                        f"Cramér–Rao bound at the measured SNR ({std.kind})"),
             BudgetTerm("noise", "velocity", float(std.velocity), "m/s", f"Cramér–Rao bound ({std.kind})"),
             BudgetTerm("noise", "aod_az", float(np.rad2deg(std.aod[0])), "deg", f"Cramér–Rao bound ({std.kind})")]
    terms += _chirp_terms(_configuration(capture), loc)
    delay_terms, bias = _delay_terms(capture)
    terms += delay_terms
    terms += _ris_terms(tol, az)

    def quad(quantity: str, scale: float = 1.0) -> float:
        vals = [t.value * scale for t in terms if t.quantity == quantity and t.value is not None]
        return float(math.sqrt(sum(v * v for v in vals)))

    d_tot, v_tot = quad("distance"), quad("velocity")
    az_tot = quad("aod_az", math.pi / 180)
    pose = capture.ris.pose
    d = loc.distance
    el_ok = math.isfinite(el)
    el_use = el if el_ok else 0.0
    h_d = max(abs(d) * 1e-6, 1e-6)
    j_d = (position_at(pose, d + h_d, az, el_use) - position_at(pose, d - h_d, az, el_use)) / (2 * h_d)
    j_az = (position_at(pose, d, az + 1e-6, el_use) - position_at(pose, d, az - 1e-6, el_use)) / 2e-6
    extra_d = max(d_tot**2 - float(std.distance) ** 2, 0.0)
    extra_az = max(az_tot**2 - float(std.aod[0]) ** 2, 0.0)
    p_var = np.square(np.asarray(std.position, float)) + j_d**2 * extra_d + j_az**2 * extra_az
    p_var = p_var + (tol.position**2 if math.isfinite(tol.position) else 0.0)
    total = Uncertainty(distance=d_tot, velocity=v_tot, aod=np.array([az_tot, float(std.aod[1])]),
                        position=np.sqrt(p_var), peak_snr_db=float(std.peak_snr_db), kind="budget")
    return UncertaintyBudget(terms=tuple(terms), total=total, uncalibrated_bias=bias)


def apply_budget(capture: Capture, loc: Localization, *, tolerances: RisTolerances | None = None
                 ) -> tuple[Localization, UncertaintyBudget | None]:
    """``loc`` with its σ the budget's total and, without a calibration, the ``uncalibrated`` flag.

    Parameters
    ----------
    capture, loc, tolerances
        As :func:`measured_budget`.

    Returns
    -------
    (dsp.Localization, UncertaintyBudget or None)
        Unchanged, with None, when the capture was not measured or nothing was detected.
    """
    budget = measured_budget(capture, loc, tolerances=tolerances)
    if budget is None:
        return loc, None
    flags = loc.flags
    if budget.uncalibrated_bias is not None and "uncalibrated" not in loc.flag_codes:
        tau = capture.ris.loopback_delay
        flags = (*flags, Flag("uncalibrated", (
            f"no calibration file: the radar's range offset and tau_RB = {tau * 1e9:.4g} ns are nominal and may bias "
            f"the distance by ~{budget.uncalibrated_bias * 1e3:.0f} mm (range offset ~{UNCALIBRATED_RANGE_OFFSET * 1e3:.0f} "
            f"mm, tau_RB ±{UNCALIBRATED_LOOPBACK_FRACTION:.0%}), which the 1σ does not include; calibrate once at a "
            "known position (risloc calibrate) and locate with --calibration")))
    return replace(loc, std=budget.total, flags=flags), budget
