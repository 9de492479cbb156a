"""Radio materials of a hall spec: ITU-R P.2040 types and custom slabs, checked at the carrier.

sionna-rt models every surface as a thin slab of one material: ITU-R P.2040 types
(``itu-radio-material``, ε_r and σ follow the carrier frequency) or a custom material
(``radio-material`` with a fixed ε_r and σ). This module decides, without importing sionna, whether
sionna-rt 2.2 can evaluate a material at the carrier and how the builder must write it.

Two traps it handles (``/tmp/rt_research/FINDINGS.md`` §6):

* sionna-rt evaluates the frequency in float32: ``float32(60e9) / 1e9 = 60.0000038`` GHz, so
  marble (valid to 60 GHz) is refused at exactly 60e9 Hz. :func:`itu_frequency_range`
  reproduces that arithmetic.
* ITU materials are first evaluated at sionna-rt's default frequency, 3.5 GHz, while the XML
  loads; floorboard (50–100 GHz) fails there. Such a material is written as a custom
  ``radio-material`` with ε_r and σ evaluated at the spec's carrier (:meth:`MaterialSpec.needs_freeze`).
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._parse import SpecError, Table, toml_type

__all__ = [
    "ITU_MATERIALS", "LOAD_FREQUENCY", "MaterialSpec", "check_name", "itu_properties", "itu_valid",
    "parse_material", "register", "valid_at",
]

#: ITU-R P.2040 Table 3 as tabulated by sionna-rt 2.2 (``sionna/rt/radio_materials/itu.py``):
#: name -> ((f_min [GHz], f_max [GHz], a, b, c, d), ...), ε_r = a·f^b, σ = c·f^d [S/m], f in GHz.
#: The first range that contains f is used, as in sionna-rt. A test compares it with sionna's table.
ITU_MATERIALS: dict[str, tuple[tuple[float, float, float, float, float, float], ...]] = {
    "vacuum": ((0.001, 100.0, 1.0, 0.0, 0.0, 0.0),),
    "concrete": ((1.0, 100.0, 5.24, 0.0, 0.0462, 0.7822), (110.0, 330.0, 5.17, 0.0, 0.0145, 1.09)),
    "brick": ((1.0, 40.0, 3.91, 0.0, 0.0238, 0.16), (110.0, 330.0, 4.15, 0.0, 0.0006, 1.5712)),
    "plasterboard": ((1.0, 100.0, 2.73, 0.0, 0.0085, 0.9395), (110.0, 330.0, 2.56, 0.0, 0.0001, 1.7799),
                     (100.0, 400.0, 2.65, 0.0, 0.0002, 1.598)),
    "wood": ((0.001, 100.0, 1.99, 0.0, 0.0047, 1.0718), (110.0, 330.0, 1.82, 0.0, 0.004, 1.0761),
             (100.0, 400.0, 2.1183, 0.0, 0.0055, 1.1113)),
    "glass": ((0.1, 100.0, 6.31, 0.0, 0.0036, 1.3394), (220.0, 450.0, 5.79, 0.0, 0.0004, 1.658),
              (100.0, 400.0, 6.5767, 0.0, 0.0012, 1.4697)),
    "clear_acrylic": ((110.0, 330.0, 2.58, 0.0, 0.0001, 1.6524),),
    "ceiling_board": ((1.0, 100.0, 1.48, 0.0, 0.0011, 1.075), (220.0, 450.0, 1.52, 0.0, 0.0029, 1.029),
                      (100.0, 400.0, 1.2567, 0.0, 0.00013, 1.454)),
    "chipboard": ((1.0, 100.0, 2.58, 0.0, 0.0217, 0.78), (100.0, 200.0, 2.16, 0.0, 0.0023, 1.359)),
    "plywood": ((1.0, 40.0, 2.71, 0.0, 0.33, 0.0), (110.0, 330.0, 1.94, 0.0, 0.0067, 0.9982),
                (100.0, 400.0, 2.17, 0.0, 0.0063, 1.045)),
    "marble": ((1.0, 60.0, 7.074, 0.0, 0.0055, 0.9262), (110.0, 330.0, 7.94, 0.0, 0.0001, 1.733),
               (100.0, 400.0, 8.62, 0.0, 0.0027, 1.15)),
    "floorboard": ((50.0, 100.0, 3.66, 0.0, 0.0044, 1.3515), (220.0, 300.0, 5.27, 0.0, 2.22e-17, 7.3413),
                   (300.0, 400.0, 5.27, 0.0, 0.0003, 2.0298), (400.0, 450.0, 5.27, 0.0, 49.8726, 0.0),
                   (100.0, 400.0, 3.1575, 0.0, 0.001675, 1.32775)),
    "vinyl_tile": ((1.0, 40.0, 3.62, 0.0, 0.0051, 0.8422),),
    "carpet_tile": ((1.0, 40.0, 2.08, 0.0, 0.0009, 0.82),),
    "asphalt_concrete": ((1.0, 40.0, 4.83, 0.0, 0.0108, 1.3969),),
    "metal": ((1.0, 100.0, 1.0, 0.0, 1e7, 0.0),),
    "very_dry_ground": ((1.0, 10.0, 3.0, 0.0, 0.00015, 2.52),),
    "medium_dry_ground": ((1.0, 10.0, 15.0, -0.1, 0.035, 1.63),),
    "wet_ground": ((1.0, 10.0, 30.0, -0.4, 0.15, 1.3),),
}

#: Frequency at which sionna-rt 2.2 evaluates ITU materials while loading a scene [Hz].
LOAD_FREQUENCY = 3.5e9

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")


def _itu_row(itu: str, frequency: float) -> tuple[float, ...] | None:
    """The table row sionna-rt picks at ``frequency`` [Hz] (float32 arithmetic), or None."""
    f_ghz = np.float32(frequency) / np.float32(1e9)  # as drjit does it: float32 throughout
    for row in ITU_MATERIALS[itu]:
        if np.float32(row[0]) <= f_ghz <= np.float32(row[1]):
            return row
    return None


def itu_valid(itu: str, frequency: float) -> bool:
    """Whether sionna-rt 2.2 can evaluate ITU material ``itu`` at ``frequency`` [Hz].

    Notes
    -----
    Reproduces sionna-rt's float32 test ``f_min <= float32(f)/1e9 <= f_max``, so marble is
    refused at exactly 60e9 Hz (60.0000038 GHz) and accepted at 59.99e9 Hz.
    """
    if itu not in ITU_MATERIALS:
        raise ValueError(f"unknown ITU material {itu!r}; known: {', '.join(sorted(ITU_MATERIALS))}")
    return _itu_row(itu, frequency) is not None


def itu_properties(itu: str, frequency: float) -> tuple[float, float]:
    """(ε_r, σ [S/m]) of ITU material ``itu`` at ``frequency`` [Hz], ITU-R P.2040 eq. (28)-(29).

    Notes
    -----
    ε_r = a·f^b and σ = c·f^d with f in GHz, evaluated in float64 with the row sionna-rt selects.
    """
    row = _itu_row(itu, frequency)
    if row is None:
        raise ValueError(f"ITU material {itu!r} is not defined at {frequency / 1e9:g} GHz "
                         f"(ranges {_ranges(itu)})")
    f_ghz = frequency / 1e9
    _, _, a, b, c, d = row
    return a * f_ghz**b, c * f_ghz**d


def _ranges(itu: str) -> str:
    return ", ".join(f"{r[0]:g}–{r[1]:g} GHz" for r in ITU_MATERIALS[itu])


def valid_at(frequency: float) -> list[str]:
    """ITU materials sionna-rt 2.2 can evaluate at ``frequency`` [Hz], sorted."""
    return sorted(m for m in ITU_MATERIALS if _itu_row(m, frequency) is not None)


@dataclass(frozen=True)
class MaterialSpec:
    """One radio material of the scene.

    Parameters
    ----------
    name : str
        Material name in sionna-rt (the XML ``bsdf`` id without its ``mat-`` prefix). Never an ITU
        type name and never ``itu_...``/``itu-...``: sionna-rt reinterprets those (FINDINGS §6).
    thickness : float
        Slab thickness [m].
    itu : str or None
        ITU-R P.2040 type; ``None`` for a custom material.
    permittivity : float or None
        Real relative permittivity ε_r of a custom material [unitless], >= 1.
    conductivity : float or None
        Conductivity σ of a custom material [S/m], >= 0.
    scattering_coefficient : float
        sionna-rt's scattering coefficient S in [0, 1] [unitless] (default 0, a smooth surface): a
        share S² of the reflected power leaves diffusely (Lambertian pattern), the specular
        reflection keeps √(1 − S²) of its amplitude. A scene with a material of S > 0 is traced with
        diffuse reflection on (:func:`risloc_rt.hall.raytrace.trace_scene`).
    """

    name: str
    thickness: float
    itu: str | None = None
    permittivity: float | None = None
    conductivity: float | None = None
    scattering_coefficient: float = 0.0

    @property
    def bsdf_id(self) -> str:
        """XML id of the material: ``"mat-" + name``."""
        return f"mat-{self.name}"

    def properties(self, frequency: float) -> tuple[float, float]:
        """(ε_r, σ [S/m]) at ``frequency`` [Hz]."""
        if self.itu is not None:
            return itu_properties(self.itu, frequency)
        return float(self.permittivity), float(self.conductivity)  # type: ignore[arg-type]

    def needs_freeze(self) -> bool:
        """True for an ITU type that sionna-rt cannot evaluate at :data:`LOAD_FREQUENCY`.

        The builder then writes it as a custom material with ε_r, σ at the spec's carrier.
        """
        return self.itu is not None and not itu_valid(self.itu, LOAD_FREQUENCY)

    def describe(self) -> str:
        """Short human-readable description, e.g. ``"concrete, 0.2 m"``."""
        kind = self.itu if self.itu is not None else f"ε_r={self.permittivity:g}, σ={self.conductivity:g} S/m"
        rough = f", S={self.scattering_coefficient:g}" if self.scattering_coefficient > 0 else ""
        return f"{kind}, {self.thickness:g} m{rough}"


def _mm(thickness: float) -> str:
    return f"{thickness * 1000:.6g}".replace(".", "p") + "mm"


def _tag(x: float) -> str:
    return f"{x:.6g}".replace(".", "p").replace("+", "").replace("-", "m")


def check_name(name: Any, key: str, *, what: str) -> str:
    """A scene name (object or material): letters, digits, ``_`` and ``-``, starting with a letter."""
    if not isinstance(name, str):
        raise SpecError(key, f"must be a string, got a {toml_type(name)} ({name!r})", 'write e.g. name = "rack_1"')
    if not _NAME.match(name):
        raise SpecError(key, f"{what} name {name!r} is not allowed",
                        "use letters, digits, '_' and '-', starting with a letter")
    return name


def parse_material(value: Any, key: str, *, default_thickness: float, frequency: float) -> MaterialSpec:
    """Read a material: ``"concrete"``, ``{itu, thickness, name}`` or ``{permittivity, conductivity, thickness, name}``.

    Either table may add ``scattering_coefficient`` (S in [0, 1], default 0); a material with S > 0
    and no ``name`` is named with an ``-S<value>`` suffix (``concrete-200mm-S0p3``).

    Parameters
    ----------
    value : str or dict
        The TOML value.
    key : str
        Its key path, for errors.
    default_thickness : float
        Thickness when the value gives none [m].
    frequency : float
        Carrier [Hz]; an ITU type undefined there raises :class:`SpecError`.
    """
    scattering = 0.0
    if isinstance(value, str):
        itu, thickness, name, eps, sigma = value, default_thickness, None, None, None
        itu_key = key
    elif isinstance(value, dict):
        t = Table(value, key)
        thickness = t.number("thickness", unit="m", default=default_thickness, minimum=0.0, strict=True)
        name = check_name(t.raw("name"), t.key("name"), what="material") if t.has("name") else None
        if t.has("scattering_coefficient"):
            scattering = t.number("scattering_coefficient", unit="unitless, sionna-rt's S", minimum=0.0, example="0.3")
            if not scattering <= 1.0:
                raise SpecError(t.key("scattering_coefficient"), f"is {scattering:g}: a scattering coefficient lies in "
                                "[0, 1]", "write e.g. scattering_coefficient = 0.3 (rough concrete), or leave it out "
                                "for a smooth surface (0)")
        has_itu, has_custom = t.has("itu"), t.has("permittivity") or t.has("conductivity")
        if has_itu and has_custom:
            raise SpecError(key, "gives both 'itu' and 'permittivity'/'conductivity'",
                            "keep 'itu' for an ITU-R P.2040 material or the two numbers for a custom one")
        if has_itu:
            itu, itu_key, eps, sigma = t.string("itu"), t.key("itu"), None, None
        elif has_custom:
            itu = None
            eps = t.number("permittivity", unit="relative, real part", minimum=1.0, example="5.24")
            sigma = t.number("conductivity", unit="S/m", minimum=0.0, example="1.14")
        else:
            raise SpecError(key, "has neither 'itu' nor 'permittivity' and 'conductivity'",
                            'write e.g. {itu = "concrete", thickness = 0.2} or '
                            "{permittivity = 5.24, conductivity = 1.14, thickness = 0.2}")
        t.finish()
    else:
        raise SpecError(key, f"must be an ITU material name or a table, got a {toml_type(value)} ({value!r})",
                        'write e.g. "concrete" or {itu = "concrete", thickness = 0.2}')
    if itu is not None:
        if itu not in ITU_MATERIALS:
            close = difflib.get_close_matches(itu, list(ITU_MATERIALS), n=1)
            raise SpecError(itu_key, f"unknown ITU material type {itu!r}",
                            (f"did you mean {close[0]!r}? " if close else "")
                            + f"ITU types valid at {frequency / 1e9:g} GHz: {', '.join(valid_at(frequency))}; "
                            "or give {permittivity, conductivity, thickness} for a custom material")
        if not itu_valid(itu, frequency):
            raise SpecError(itu_key, f"ITU material {itu!r} is defined for {_ranges(itu)} only, not at "
                            f"{frequency / 1e9:.9g} GHz (sionna-rt compares in float32: "
                            f"{float(np.float32(frequency) / np.float32(1e9)):.9g} GHz)",
                            f"use one valid there ({', '.join(valid_at(frequency))}) or a custom "
                            "{permittivity, conductivity, thickness}", code="material.frequency")
        default_name = f"{itu}-{_mm(thickness)}"
    else:
        default_name = f"eps{_tag(eps)}-sig{_tag(sigma)}-{_mm(thickness)}"  # type: ignore[arg-type]
    if scattering > 0:
        default_name += f"-S{_tag(scattering)}"
    name = name or default_name
    if name in ITU_MATERIALS or name.lower().startswith(("itu_", "itu-")):
        raise SpecError(f"{key}.name", f"material name {name!r} collides with sionna-rt's ITU naming "
                        "(an ITU type name, or the itu_/itu- prefix it turns into an ITU material)",
                        "choose another name, e.g. 'wall-concrete'")
    if not math.isfinite(thickness):
        raise SpecError(f"{key}.thickness", "must be finite", "use a thickness in metres")
    return MaterialSpec(name=name, thickness=float(thickness), itu=itu,
                        permittivity=None if eps is None else float(eps),
                        conductivity=None if sigma is None else float(sigma), scattering_coefficient=float(scattering))


def register(materials: dict[str, MaterialSpec], material: MaterialSpec, key: str) -> None:
    """Add ``material`` to ``materials`` (by name), refusing two different materials with one name."""
    old = materials.get(material.name)
    if old is not None and old != material:
        raise SpecError(key, f"material name {material.name!r} is already used for {old.describe()} "
                        f"and here for {material.describe()}", "give one of them another 'name'")
    materials.setdefault(material.name, material)

