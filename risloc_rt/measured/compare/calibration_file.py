"""Calibration files (``risloc calibrate -o calibration.toml``): what a measured radar and RIS add to the model.

Five quantities, each with its 1σ (``docs/formats.md``, "Calibration files"):

- ``range_offset`` [m]: the radar's internal range offset; every measured delay is longer by
  ``2·range_offset/c`` than the geometry gives;
- ``loopback_delay`` τ_RB [s] and ``amplification_db`` ζ [dB] of the RIS;
- ``noise_power_dbm``: the receiver noise per complex sample at the ADC input [dBm];
- ``power_offset_db``: ``10·log10`` of the ADC counts² per watt at the ADC input (the receiver
  gain the link budget does not know) [dB].

:func:`apply_to_capture` makes ``risloc locate`` use them (τ_RB + the range offset's delay as the
capture's loop-back delay); :func:`apply_to_scenario` and :func:`calibrated_paths` make
``risloc simulate`` and ``risloc compare`` synthesise what the calibrated radar measures.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from dsp.radar import SPEED_OF_LIGHT

from ..._files import atomic_write_bytes
from ...model.capture import Capture
from ...model.paths import PathSet, shift_paths
from ...model.scenario import Scenario, analytic_paths
from ..errors import MeasuredFormatError, read_text_file

__all__ = ["Calibration", "adc_power_offset_db", "apply_to_capture", "apply_to_scenario", "as_dict",
           "calibrated_paths", "calibration_delay", "read_calibration", "write_calibration"]

FORMAT = "risloc-calibration"
VERSION = 1
_FIELDS = ("range_offset", "loopback_delay", "amplification_db", "noise_power_dbm", "power_offset_db")
_FILE_KEYS = {"range_offset": ("radar", "range_offset_m", 1.0), "noise_power_dbm": ("radar", "noise_power_dbm", 1.0),
              "power_offset_db": ("radar", "power_offset_db", 1.0),
              "loopback_delay": ("ris", "loopback_delay_ns", 1e-9), "amplification_db": ("ris", "amplification_db", 1.0)}


@dataclass(frozen=True)
class Calibration:
    """Fitted radar and RIS parameters, SI units, each with its 1σ (``<name>_std``; NaN when unknown)."""

    range_offset: float
    loopback_delay: float
    amplification_db: float
    noise_power_dbm: float
    power_offset_db: float
    range_offset_std: float = math.nan
    loopback_delay_std: float = math.nan
    amplification_db_std: float = math.nan
    noise_power_dbm_std: float = math.nan
    power_offset_db_std: float = math.nan
    details: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        for name in _FIELDS:
            if not math.isfinite(float(getattr(self, name))):
                raise MeasuredFormatError(f"calibration {name} = {getattr(self, name)!r} must be a finite number")
        if self.loopback_delay < 0:
            raise MeasuredFormatError(f"calibration loopback_delay = {self.loopback_delay!r} s must be >= 0")

    def to_document(self) -> dict[str, Any]:
        """The file's content.

        Returns
        -------
        dict
            ``format``, ``version``, the ``radar`` and ``ris`` tables (τ_RB in ns, the rest SI; std as
            ``<key>_std`` when known) and the fit's details.
        """
        doc: dict[str, Any] = {"format": FORMAT, "version": VERSION, "radar": {}, "ris": {}}
        for name, (table, key, unit) in _FILE_KEYS.items():
            doc[table][key] = float(getattr(self, name)) / unit
            std = float(getattr(self, f"{name}_std"))
            if math.isfinite(std):
                doc[table][f"{key}_std"] = std / unit
        if self.details:
            doc["fit"] = self.details
        return doc


def _toml(doc: dict[str, Any]) -> str:
    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v) if math.isfinite(v) else '"nan"'
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        raise TypeError(f"cannot write {type(v).__name__} to TOML")
    lines = ["# risloc calibration (docs/formats.md, \"Calibration files\"); SI units unless the key says otherwise"]
    lines += [f"{k} = {value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    for table, content in doc.items():
        if isinstance(content, dict):
            lines += ["", f"[{table}]"] + [f"{k} = {value(v)}" for k, v in content.items()]
    return "\n".join(lines) + "\n"


def write_calibration(calibration: Calibration, path: str | Path) -> Path:
    """Write ``.toml`` (default) or ``.json`` atomically.

    Parameters
    ----------
    calibration : Calibration
    path : path
        A ``.json`` suffix writes JSON, any other TOML.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    doc = calibration.to_document()
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n" if path.suffix == ".json" else _toml(doc)
    return atomic_write_bytes(path, text.encode("utf-8"))


def read_calibration(path: str | Path) -> Calibration:
    """Read a calibration file (``.toml`` or ``.json``); every problem is one line naming the file and key.

    Parameters
    ----------
    path : path
        A file written by ``risloc calibrate``.

    Returns
    -------
    Calibration
        SI units (τ_RB [s], range offset [m], dB, dBm), each with its 1σ (NaN when unknown).
    """
    path = Path(path)
    text = read_text_file(path, "calibration file",
                          "write one with 'risloc calibrate CAPTURE --scene HALL -o calibration.toml'")
    try:
        doc = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as exc:
        raise MeasuredFormatError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'} ({exc})") from None
    if doc.get("format") != FORMAT or doc.get("version") != VERSION:
        raise MeasuredFormatError(f"{path}: format = {doc.get('format')!r}, version = {doc.get('version')!r}; expected "
                                  f"{FORMAT!r} version {VERSION} (a file written by risloc calibrate)")
    values: dict[str, float] = {}
    for name, (table, key, unit) in _FILE_KEYS.items():
        section = doc.get(table)
        if not isinstance(section, dict) or key not in section:
            raise MeasuredFormatError(f"{path}: {table}.{key} is missing; add it or write the file again with "
                                      "risloc calibrate")
        for suffix in ("", "_std"):
            raw = section.get(key + suffix, math.nan)
            if isinstance(raw, str) and raw == "nan":
                raw = math.nan
            if isinstance(raw, bool) or not isinstance(raw, (int, float)) or (suffix == "" and not math.isfinite(raw)):
                raise MeasuredFormatError(f"{path}: {table}.{key}{suffix} = {raw!r} must be a finite number")
            values[name + suffix] = float(raw) * unit
    return Calibration(**values, details=doc.get("fit"))


def calibration_delay(calibration: Calibration) -> float:
    """The delay every measured path gains from the range offset: ``2·range_offset/c``.

    Parameters
    ----------
    calibration : Calibration

    Returns
    -------
    float
        [s].
    """
    return 2.0 * calibration.range_offset / SPEED_OF_LIGHT


def apply_to_capture(capture: Capture, calibration: Calibration) -> Capture:
    """For localization: the capture's τ_RB becomes ``τ_RB + 2·range_offset/c`` (distance = (τ̂ − that)·c/2).

    Parameters
    ----------
    capture : Capture
        A measured capture.
    calibration : Calibration

    Returns
    -------
    Capture
        Its RIS with the calibrated τ_RB (+ the range offset's delay) [s] and ζ [dB]; the
        calibration recorded in the provenance (``provenance["calibration"]``: the values and,
        where known, their 1σ as ``<name>_std``, which the uncertainty budget reads).
    """
    ris = replace(capture.ris, loopback_delay=calibration.loopback_delay + calibration_delay(calibration),
                  amplification_db=calibration.amplification_db)
    prov = dict(capture.provenance)
    prov["calibration"] = {k: float(getattr(calibration, k)) for k in _FIELDS}
    prov["calibration"].update({f"{k}_std": float(getattr(calibration, f"{k}_std")) for k in _FIELDS
                                if math.isfinite(getattr(calibration, f"{k}_std"))})
    return replace(capture, ris=ris, provenance=prov)


def apply_to_scenario(scenario: Scenario, calibration: Calibration) -> Scenario:
    """For synthesis: the RIS's τ_RB and ζ and the radar's noise power from the calibration.

    The range offset is applied to the paths (:func:`risloc_rt.model.paths.shift_paths` by
    :func:`calibration_delay`), the power offset by the ADC emulation (``power_offset_db``).

    Parameters
    ----------
    scenario : Scenario
    calibration : Calibration

    Returns
    -------
    Scenario
        τ_RB [s], ζ [dB] and ``noise_power_dbm`` [dBm] replaced.
    """
    ris = replace(scenario.ris, loopback_delay=calibration.loopback_delay,
                  amplification_db=calibration.amplification_db)
    radar = replace(scenario.radar, noise_power_dbm=calibration.noise_power_dbm)
    return replace(scenario, ris=ris, radar=radar)


def calibrated_paths(scenario: Scenario, paths: PathSet | None, calibration: Calibration) -> PathSet:
    """``paths`` (default: the scenario's analytic ones, frozen geometry) longer by :func:`calibration_delay`.

    Parameters
    ----------
    scenario : Scenario
        Its radar's carrier [Hz] turns the gains with the delay.
    paths : PathSet or None
        None: :func:`~risloc_rt.model.scenario.analytic_paths` of the scenario.
    calibration : Calibration

    Returns
    -------
    PathSet
    """
    base = analytic_paths(scenario) if paths is None else paths
    return shift_paths(base, calibration_delay(calibration), scenario.radar.carrier_frequency)


def adc_power_offset_db(calibration: Calibration, full_scale_counts_per_unit: float) -> float:
    """The emulator's ``power_offset_db`` that gives the calibration's ADC counts² per W.

    Parameters
    ----------
    calibration : Calibration
    full_scale_counts_per_unit : float
        The emulator's ADC counts per √W without an offset (``2^(b−1)/full_scale``).

    Returns
    -------
    float
        [dB].
    """
    return calibration.power_offset_db - 20 * math.log10(full_scale_counts_per_unit)


def as_dict(calibration: Calibration) -> dict[str, Any]:
    """Plain JSON of the values and their std.

    Parameters
    ----------
    calibration : Calibration

    Returns
    -------
    dict
        SI units, the fit's details left out.
    """
    out = asdict(calibration)
    out.pop("details", None)
    return out
