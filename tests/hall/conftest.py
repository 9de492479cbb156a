"""Fixtures of the hall tests: a small closed box hall written as a Mitsuba XML scene plus six PLY walls.

The hall spans ``[0, L] × [0, W] × [0, H]``; each wall is a separate two-triangle mesh written with
trimesh's PLY export, so sionna-rt keeps every wall as its own object (``merge_shapes=False``).
``box_hall.planes`` gives each wall's plane, from which the tests build image sources.

``stand_in_tracer`` replaces the material tracer by three paths with closed-form powers, for the material
fit's and the profile's tests whose likelihood must be known exactly.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

#: Hall size [m]: length (x), width (y), height (z).
SIZE = (12.0, 8.0, 4.0)


def _planes(size: tuple[float, float, float]) -> Mapping[str, tuple[int, float]]:
    """``{wall name: (axis, coordinate)}``: the wall is the plane ``x[axis] = coordinate`` [m]."""
    length, width, height = size
    return MappingProxyType({
        "floor": (2, 0.0), "ceiling": (2, height),
        "wall_y0": (1, 0.0), "wall_yW": (1, width),
        "wall_x0": (0, 0.0), "wall_xL": (0, length),
    })


def _corners(name: str, size: tuple[float, float, float]) -> np.ndarray:
    length, width, height = size
    box = {
        "floor": [(0, 0, 0), (length, 0, 0), (length, width, 0), (0, width, 0)],
        "ceiling": [(0, 0, height), (0, width, height), (length, width, height), (length, 0, height)],
        "wall_y0": [(0, 0, 0), (0, 0, height), (length, 0, height), (length, 0, 0)],
        "wall_yW": [(0, width, 0), (length, width, 0), (length, width, height), (0, width, height)],
        "wall_x0": [(0, 0, 0), (0, width, 0), (0, width, height), (0, 0, height)],
        "wall_xL": [(length, 0, 0), (length, 0, height), (length, width, height), (length, width, 0)],
    }
    return np.array(box[name], dtype=float)


@dataclasses.dataclass(frozen=True)
class BoxHall:
    """The box hall of ``size`` [m] (length x, width y, height z) and its writers."""

    size: tuple[float, float, float] = SIZE

    @property
    def planes(self) -> Mapping[str, tuple[int, float]]:
        """``{wall name: (axis, coordinate)}``: the wall is the plane ``x[axis] = coordinate`` [m]."""
        return _planes(self.size)

    def reflect(self, point: np.ndarray, wall: str) -> np.ndarray:
        """Mirror image [3] of ``point`` in the plane of ``wall`` [m]."""
        axis, coordinate = self.planes[wall]
        image = np.array(point, dtype=float)
        image[axis] = 2.0 * coordinate - image[axis]
        return image

    @staticmethod
    def write_wall(path: Path, name: str, size: tuple[float, float, float] = SIZE) -> None:
        """Write wall ``name`` of a hall of ``size`` as a binary PLY (two triangles, normals inward)."""
        import trimesh

        mesh = trimesh.Trimesh(vertices=_corners(name, size), faces=[[0, 1, 2], [0, 2, 3]], process=False)
        path.write_bytes(mesh.export(file_type="ply"))

    def make(self, directory: Path, *, material: str = "concrete", thickness: float = 0.2) -> Path:
        """Write ``directory/hall.xml`` and ``directory/meshes/<wall>.ply``; return the XML path.

        Parameters
        ----------
        directory : Path
            Output folder (created).
        material : str
            ITU-R P.2040 material type for all six walls.
        thickness : float
            Wall (slab) thickness [m].
        """
        meshes = directory / "meshes"
        meshes.mkdir(parents=True, exist_ok=True)
        shapes = []
        for name in self.planes:
            self.write_wall(meshes / f"{name}.ply", name, self.size)
            shapes.append(
                f'    <shape type="ply" id="mesh-{name}">\n'
                f'        <string name="filename" value="meshes/{name}.ply"/>\n'
                f'        <boolean name="face_normals" value="true"/>\n'
                f'        <ref id="mat-{material}" name="bsdf"/>\n'
                f"    </shape>"
            )
        xml = (
            '<scene version="2.1.0">\n'
            f'    <bsdf type="itu-radio-material" id="mat-{material}">\n'
            f'        <string name="type" value="{material}"/>\n'
            f'        <float name="thickness" value="{thickness}"/>\n'
            "    </bsdf>\n" + "\n".join(shapes) + "\n</scene>\n"
        )
        path = directory / "hall.xml"
        path.write_text(xml)
        return path


@pytest.fixture(scope="session")
def box_hall() -> BoxHall:
    """The 12 m × 8 m × 4 m box hall: ``size``, ``planes`` ({wall: (axis, coordinate)}),
    ``reflect(point, wall)`` (mirror image in a wall's plane), ``make(folder, material="concrete",
    thickness=0.2) -> hall.xml path`` (XML scene + six PLY walls) and ``write_wall(path, name, size)``
    (one wall as a binary PLY, for a hall of any ``size``)."""
    return BoxHall()


#: The stand-in tracer's peaks: delays [s], the truth (ε_r 6.1, ln σ of 0.6 S/m) and each peak's 1σ [dB].
STAND_IN_DELAYS = np.array([40e-9, 60e-9, 80e-9])


@pytest.fixture
def stand_in_tracer(monkeypatch):
    """``make(sigma_peaks, scattering=None) -> [Observation]``: the material tracer replaced by three paths, one at
    -60 + 3 (ε_r - 6.1) dB and two at -70 and -75 dB + f(ln σ), with ``sigma_peaks(ln σ) -> (f [dB], df/d ln σ)``;
    the returned observation holds the noise-free powers at ε_r 6.1, σ 0.6 S/m, 1σ 0.5 dB per peak. With
    ``scattering = (S_true, bounces)``, the material scatters: peak k loses ``bounces[k]`` × 10 log10(1 − S²) dB (the
    specular loss), its S differentiated (``scattering=[name]``), the scene's own S 0 and the truth S_true."""
    import math
    from types import SimpleNamespace

    import risloc_rt.hall.material_fit as engine

    def make(sigma_peaks, scattering=None):
        s_true, bounces = scattering if scattering is not None else (0.0, (0, 0, 0))
        bounces = np.asarray(bounces, dtype=float)

        def powers(eps, s, rough):
            f, df = sigma_peaks(s)
            p = np.array([-60.0 + 3.0 * (eps - 6.1), -70.0 + f, -75.0 + f]) + bounces * 10 * np.log10(1 - rough ** 2)
            dp_rough = bounces * 10 / math.log(10) * (-2 * rough / (1 - rough ** 2))
            return p, np.array([3.0, 0.0, 0.0]), np.array([0.0, 1.0, 1.0]) * df, dp_rough

        def fake_jacobian(scene, position, materials, *, values=None, settings=None, scattering=(), derivatives=True):
            name = materials[0] if not isinstance(materials, str) else materials
            eps, sigma, *rest = (values or {}).get(name, (5.24, 1.136))
            rough = rest[0] if rest else 0.0
            p, dp_eps, dp_s, dp_rough = powers(eps, math.log(sigma), rough)
            a = 10 ** (p / 20)
            scale = a * math.log(10) / 20  # d|a| per dB
            keep = 1.0 if derivatives else 0.0  # derivatives=False: the gains only
            return SimpleNamespace(materials=(name,), relative_permittivity=np.array([eps]),
                                   conductivity=np.array([sigma]), delay=STAND_IN_DELAYS, a=a.astype(complex),
                                   d_eps=(keep * scale * dp_eps)[:, None].astype(complex),
                                   d_sigma=(keep * scale * dp_s / sigma)[:, None].astype(complex),
                                   touches=np.ones((3, 1), bool), paths=SimpleNamespace(tx_position=np.zeros(3)),
                                   scattering=tuple(scattering), scattering_coefficient=np.array([rough]),
                                   d_scattering=(keep * scale * dp_rough)[:, None].astype(complex)[:, :len(scattering)])

        monkeypatch.setattr(engine, "material_jacobian", fake_jacobian)
        truth = powers(6.1, math.log(0.6), s_true)[0]
        return [engine.Observation([1.0, 2.0, 1.2], STAND_IN_DELAYS, truth, [0.5] * 3)]

    return make
