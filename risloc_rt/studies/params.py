"""The parameters a study may vary or fix, their units and their checks.

Human-edited values (study files, ``--vary``) use the units in the names (``tx_power_dbm``,
``sweep_step_deg``, ``aod_deg``); :func:`build_point` converts them to SI when it builds the
scenario. Every point of a study is a plain ``dict[str, bool | int | float | str]`` holding
**every** parameter (defaults filled in), so a point is self-describing in ``summary.json`` and
in the Parquet table.

Range checks go through :mod:`dsp.validation` (the one validation idiom): a value out of range
is a :class:`ValueError` naming the parameter, the value, the rule and the unit.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Callable

from dsp.validation import integer, interval, one_of, positive

__all__ = ["PARAMETERS", "Parameter", "check_value", "complete_point", "parse_values", "ris_size"]


@dataclass(frozen=True)
class Parameter:
    """One study parameter.

    Attributes
    ----------
    kind : {"float", "int", "str", "bool"}
    default : value
        The paper's setting (Table I, the analytic scenario) where there is one.
    unit : str
        Unit of the value as written in a study file ("" for none).
    help : str
        One line for ``risloc study sweep --help`` and docs/studies.md.
    check : callable, optional
        ``check(value, name, unit)`` raises :class:`ValueError` (a :mod:`dsp.validation` check) for
        a value out of range; it sees the value already converted to ``kind``.
    """

    kind: str
    default: Any
    unit: str
    help: str
    check: Callable[[Any, str, str], Any] | None = None


def _positive(value: Any, name: str, unit: str) -> float:
    return positive(value, name, unit, error=ValueError)


def _at_least(minimum: int) -> Callable[[Any, str, str], int]:
    return lambda value, name, unit: integer(value, name, minimum=minimum, error=ValueError)


def _within(low: float, high: float, closed: str = "neither") -> Callable[[Any, str, str], float]:
    return lambda value, name, unit: interval(value, name, unit, low=low, high=high, closed=closed, error=ValueError)


def _in(*choices: str) -> Callable[[Any, str, str], Any]:
    return lambda value, name, unit: one_of(value, name, choices, error=ValueError)


_SIZE = re.compile(r"^\s*(\d+)\s*[xX×]\s*(\d+)\s*$")


def ris_size(text: str) -> tuple[int, int]:
    """``"16x4"`` -> (16, 4): RIS rows (along azimuth) × columns (along elevation).

    Parameters
    ----------
    text : str
        ``ROWSxCOLUMNS`` (``x``, ``X`` or ``×``), positive integers.

    Returns
    -------
    (int, int)
        Rows and columns of elements.

    Raises
    ------
    ValueError
        ``text`` is not of that form.
    """
    m = _SIZE.match(str(text))
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise ValueError(f"ris_size={text!r} must be ROWSxCOLUMNS with positive integers, e.g. 16x4")
    return int(m.group(1)), int(m.group(2))


def _size_check(value: Any, name: str, unit: str) -> tuple[int, int]:
    return ris_size(value)


#: Every parameter a study knows. Unknown names are refused with this list.
PARAMETERS: dict[str, Parameter] = {
    "estimator": Parameter("str", "paper", "", "'paper' (the seed paper's grid method) or 'refined'",
                           _in("paper", "refined")),
    "tx_power_dbm": Parameter("float", 20.0, "dBm", "transmit power P (Table I: 20 dBm)"),
    "sweep_step_deg": Parameter("float", 1.5, "deg", "RIS sweep step (Table I: 1.5°)", _positive),
    "sweep_span_deg": Parameter("float", 45.0, "deg", "the sweep covers ±span in azimuth (paper: 45°)", _positive),
    "ris_size": Parameter("str", "16x4", "", "RIS elements ROWSxCOLUMNS (azimuth × elevation; paper 16x4)",
                          _size_check),
    "distance": Parameter("float", 13.38, "m", "UE–RIS distance (paper: 13.38 m)", _positive),
    "aod_deg": Parameter("float", 0.0, "deg", "UE azimuth seen from the RIS, RIS frame (paper: 0°)",
                         _within(-90.0, 90.0)),
    "aod_spread_deg": Parameter("float", 0.0, "deg", "each run draws the UE azimuth uniformly within aod_deg ± spread/2 "
                                "(its own noiseless cube per run: slower); the bound is at aod_deg",
                                _within(0.0, 90.0, closed="low")),
    "speed": Parameter("float", 0.0, "m/s", "UE radial speed, away from the RIS > 0 (moves during the sweep)"),
    "mode": Parameter("str", "relay", "", "RIS mode: 'relay' (the experiment) or 'reflective' (eq. (1))",
                      _in("relay", "reflective")),
    "structure": Parameter("bool", True, "", "include the RIS panel's structural reflection (σ = 19 m²)"),
    "pfa": Parameter("float", 1e-3, "", "detector false-alarm probability per capture",
                     _within(0.0, 1.0)),
    "num_chirps": Parameter("int", 128, "", "chirps per frame K (Table I: 128)", _at_least(1)),
    "num_samples": Parameter("int", 600, "", "ADC samples per chirp N (Table I: 600)", _at_least(1)),
    "n_dft": Parameter("int", 1199, "", "fast-time DFT length N_DFT (Table I: 1199)", _at_least(1)),
    "k_dft": Parameter("int", 4793, "", "slow-time DFT length K_DFT (Table I: 4793)", _at_least(1)),
    "scene": Parameter("str", "", "", "a hall in scenes/ (e.g. paper_hall): traced paths instead of the analytic ones"),
    "radar_index": Parameter("int", 0, "", "which radar position of the hall's spec", _at_least(0)),
    "depth": Parameter("int", 3, "", "ray-tracing depth for halls", _at_least(1)),
    "samples": Parameter("int", 100_000, "", "rays per source for halls", _at_least(1)),
}

#: Parameters of the analytic geometry that a hall (``scene``) takes from its spec instead.
ANALYTIC_ONLY = ("ris_size", "distance", "aod_deg", "aod_spread_deg", "speed", "structure")


def check_value(name: str, value: Any) -> Any:
    """``value`` converted to the parameter's kind and checked against its range.

    Parameters
    ----------
    name : str
        A key of :data:`PARAMETERS`.
    value
        As written (a study file's value or a ``--vary``/``--set`` string), in the parameter's unit.

    Returns
    -------
    bool, int, float or str
        The value as the parameter's kind.

    Raises
    ------
    ValueError
        Unknown parameter, a value not of its kind, or out of its range (one line naming it).
    """
    if name not in PARAMETERS:
        raise ValueError(f"unknown study parameter {name!r}; known: {', '.join(PARAMETERS)}")
    p = PARAMETERS[name]
    try:
        if p.kind == "float":
            if isinstance(value, bool):
                raise ValueError
            out: Any = float(value)
            if not math.isfinite(out):
                raise ValueError
        elif p.kind == "int":
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise ValueError
            out = int(value)
        elif p.kind == "bool":
            if isinstance(value, str):
                if value.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError
                out = value.lower() in ("true", "1", "yes")
            else:
                out = bool(value)
        else:
            out = str(value).strip()
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is not a {p.kind}" + (f" [{p.unit}]" if p.unit else "")) from None
    if p.check is not None:
        p.check(out, name, p.unit)
    return out


def parse_values(name: str, text: str) -> list[Any]:
    """``"0,10,20"`` -> [0.0, 10.0, 20.0] for ``--vary NAME=...`` (``lo:hi:step`` ranges too).

    Parameters
    ----------
    name : str
        The parameter.
    text : str
        Comma-separated values, or ``LO:HI:STEP`` ranges for numeric parameters (HI included), in
        the parameter's unit.

    Returns
    -------
    list
        The checked values (:func:`check_value`), in order.

    Raises
    ------
    ValueError
        No value, a bad range (STEP <= 0, HI < LO, more than 10000 values) or a bad value.
    """
    items = [t.strip() for t in str(text).split(",") if t.strip()]
    if not items:
        raise ValueError(f"--vary {name}= has no values; give them as {name}=V1,V2,... or {name}=LO:HI:STEP")
    out: list[Any] = []
    for item in items:
        if item.count(":") == 2 and PARAMETERS.get(name, Parameter("str", "", "", "")).kind in ("float", "int"):
            lo, hi, step = (float(x) for x in item.split(":"))
            if step <= 0 or hi < lo:
                raise ValueError(f"--vary {name}={item}: a range LO:HI:STEP needs STEP > 0 and HI >= LO")
            count = int(math.floor((hi - lo) / step + 1e-9)) + 1
            if count > 10_000:
                raise ValueError(f"--vary {name}={item} makes {count} values (more than 10000); use a larger STEP")
            out += [check_value(name, round(lo + i * step, 12)) for i in range(count)]
        else:
            out.append(check_value(name, item))
    return out


def complete_point(values: dict[str, Any]) -> dict[str, Any]:
    """Every parameter: ``values`` (checked) over the defaults; refuses analytic-only ones for halls.

    Parameters
    ----------
    values : dict
        Parameter name -> value (units as in :data:`PARAMETERS`).

    Returns
    -------
    dict
        Every parameter of :data:`PARAMETERS`, in its order, with its kind.

    Raises
    ------
    ValueError
        A bad value, or an analytic-only parameter (:data:`ANALYTIC_ONLY`) given for a hall.
    """
    point = {name: p.default for name, p in PARAMETERS.items()}
    for name, value in values.items():
        point[name] = check_value(name, value)
    if point["scene"]:
        given = [n for n in ANALYTIC_ONLY if n in values]
        if given:
            raise ValueError(f"{', '.join(given)} cannot be set for a hall (scene={point['scene']!r}): the hall's "
                             "spec places the radar and the RIS; vary radar_index, depth, samples, tx_power_dbm instead")
    return point
