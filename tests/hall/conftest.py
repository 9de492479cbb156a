"""Fixtures of the hall tests: a small closed box hall written as a Mitsuba XML scene plus six PLY walls.

The hall spans ``[0, L] × [0, W] × [0, H]``; each wall is a separate two-triangle mesh written with
trimesh's PLY export, so sionna-rt keeps every wall as its own object (``merge_shapes=False``).
``box_hall.planes`` gives each wall's plane, from which the tests build image sources.
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
