"""Quality of one triangle mesh, numpy only: degenerate faces, non-manifold edges, winding, volume.

Used by :mod:`.check` on every mesh of a built scene. Vertices that are bit-identical are the same
point (the builder writes shared corners once, trimesh merges them on import), so the topology is
that of the file, not of a tolerance-merged copy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MeshReport", "DEGENERATE_HEIGHT", "FACE_BYTES", "mesh_memory", "mesh_report"]

#: A face whose height over its longest edge is below this is degenerate [m]: 1 µm is half the
#: float32 spacing of coordinates near 30 m (1.9 µm), so rounding alone never makes a face degenerate,
#: and far below any real feature of a hall.
DEGENERATE_HEIGHT = 1e-6


#: Peak memory per triangle of building, loading and checking a generated mesh [bytes]: its vertex
#: and face arrays, the PLY bytes, trimesh's processed copy and :func:`mesh_report`'s edge tables.
#: Measured 850 B per face in ``risloc scene check`` of a pillar of 10⁵ and 3·10⁵ segments.
FACE_BYTES = 1024


def mesh_memory(num_faces: int) -> int:
    """Peak bytes of building, loading and checking a mesh of ``num_faces`` triangles: ``F · FACE_BYTES``."""
    return int(num_faces) * FACE_BYTES


@dataclass(frozen=True)
class MeshReport:
    """What :func:`mesh_report` found.

    Attributes
    ----------
    num_faces : int
    degenerate : int array [D]
        Indices of faces with zero area or collinear corners (height < :data:`DEGENERATE_HEIGHT`).
    non_manifold : float array [E, 2, 3]
        End points of the edges shared by three or more (non-degenerate) faces [m].
    boundary_edges : int
        Edges used by one face only (holes, open sheets).
    misoriented_edges : int
        Edges shared by two faces that run along it in the same direction (inconsistent winding).
    volume : float
        Signed volume [m³] (divergence theorem) when the mesh is closed and consistently wound:
        positive when the normals point out; NaN otherwise.
    """

    num_faces: int
    degenerate: np.ndarray
    non_manifold: np.ndarray
    boundary_edges: int
    misoriented_edges: int
    volume: float

    @property
    def closed(self) -> bool:
        """Watertight: every edge shared by exactly two faces."""
        return self.boundary_edges == 0 and len(self.non_manifold) == 0

    @property
    def flipped(self) -> bool:
        """Closed, consistently wound, and its normals point into the solid (volume < 0)."""
        return bool(self.volume < 0)


def face_heights(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Height of each triangle over its longest edge, ``2·area / longest edge`` [F] [m] (0 if all corners coincide)."""
    tri = vertices[faces]  # [F, 3, 3]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    longest = np.max(np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2), axis=1)
    return np.divide(area2, longest, out=np.zeros_like(area2), where=longest > 0)


def mesh_report(vertices: np.ndarray, faces: np.ndarray) -> MeshReport:
    """Degenerate faces, non-manifold and boundary edges, winding and signed volume of a mesh.

    Parameters
    ----------
    vertices : float array [V, 3]
        [m].
    faces : int array [F, 3]
        Triangles, counter-clockwise seen from the side their normal points to.

    Notes
    -----
    Degenerate faces are left out of the edge analysis (their edges say nothing about how the
    surface closes). The signed volume is ``Σ v0·(v1 × v2) / 6`` over the faces.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    # Bit-identical vertices are one point.
    v, inverse = np.unique(v, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[f]
    degenerate = np.flatnonzero(face_heights(v, f) < DEGENERATE_HEIGHT)
    good = np.delete(f, degenerate, axis=0)
    directed = np.concatenate([good[:, [0, 1]], good[:, [1, 2]], good[:, [2, 0]]])  # [3F', 2]
    undirected = np.sort(directed, axis=1)
    edges, counts = np.unique(undirected, axis=0, return_counts=True)
    non_manifold = v[edges[counts > 2]]  # [E, 2, 3]
    boundary = int(np.count_nonzero(counts == 1))
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    misoriented = int(np.count_nonzero(dcounts > 1))
    volume = math.nan
    if boundary == 0 and len(non_manifold) == 0 and misoriented == 0 and len(good):
        tri = v[good]
        volume = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)
    return MeshReport(num_faces=len(f), degenerate=degenerate, non_manifold=non_manifold,
                      boundary_edges=boundary, misoriented_edges=misoriented, volume=volume)
