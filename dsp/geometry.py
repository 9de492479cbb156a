"""RIS frame and the azimuth/elevation convention (see ``docs/conventions.md``).

The RIS frame is right-handed, with unit vectors, in world coordinates,

* ``row_axis`` **u**: along the element rows (the long, 16-element side); azimuth turns
  toward +u,
* ``column_axis`` **w**: along the element columns (the short, 4-element side); elevation
  turns toward +w,
* ``normal`` **n** = u × w: broadside, pointing from the panel into the room.

A direction with azimuth ``az`` and elevation ``el`` relative to broadside is the unit vector

    d(az, el) = cos(el) sin(az) u + sin(el) w + cos(el) cos(az) n,

so that ``[0, 0]`` is broadside, ``az`` is measured in the (u, n) plane and ``el`` out of it.
The wavenumber vector used by the array model is ``g = 2π/λ · d``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .validation import as_finite_array

__all__ = ["RisPose", "direction_from_angles", "angles_from_direction"]


def direction_from_angles(angles: Any) -> np.ndarray:
    """Unit direction in the RIS frame ``(u, w, n)`` for azimuth/elevation pairs.

    Parameters
    ----------
    angles : float array [..., 2]
        ``[az, el]`` relative to RIS broadside [rad].

    Returns
    -------
    float array [..., 3]
        Components along ``(u, w, n)``: ``[cos el sin az, sin el, cos el cos az]``.
    """
    a = as_finite_array(angles, "angles", trailing=(2,))
    az, el = a[..., 0], a[..., 1]
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)


def angles_from_direction(direction: Any) -> np.ndarray:
    """Azimuth/elevation of directions given in the RIS frame ``(u, w, n)``.

    Parameters
    ----------
    direction : float array [..., 3]
        Directions (need not be unit length, must be non-zero) [any length unit].

    Returns
    -------
    float array [..., 2]
        ``[az, el]`` [rad]; ``az`` in (-π, π], ``el`` in [-π/2, π/2]. Inverse of
        :func:`direction_from_angles` for unit vectors.
    """
    d = as_finite_array(direction, "direction", trailing=(3,))
    norm = np.linalg.norm(d, axis=-1)
    if np.any(norm == 0):
        raise ValueError("direction contains a zero vector; a direction needs a non-zero length")
    d = d / norm[..., None]
    el = np.arcsin(np.clip(d[..., 1], -1.0, 1.0))
    az = np.arctan2(d[..., 0], d[..., 2])
    return np.stack([az, el], axis=-1)


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    n = np.linalg.norm(v)
    if not n > 0:
        raise ValueError(f"{name}={v.tolist()} must be a non-zero vector")
    return v / n


@dataclass(frozen=True)
class RisPose:
    """Position and orientation of a RIS panel in the world frame.

    Parameters
    ----------
    position : float array [3]
        Geometric centre of the element grid, world frame [m].
    normal : float array [3]
        Broadside direction, pointing from the panel into the room (any non-zero length;
        stored normalised).
    up : float array [3], default ``[0, 0, 1]``
        A direction that, projected onto the panel plane, gives the column axis **w**
        (elevation turns toward it). Must not be parallel to ``normal``.

    Notes
    -----
    ``column_axis = normalise(up - (up·n) n)``, ``row_axis = column_axis × normal`` so that
    ``row_axis × column_axis = normal``. :meth:`facing` builds the pose of a panel whose
    broadside points at a given point.
    """

    position: np.ndarray
    normal: np.ndarray
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        pos = as_finite_array(self.position, "position", shape=(3,))
        normal = _unit(as_finite_array(self.normal, "normal", shape=(3,)), "normal")
        up = _unit(as_finite_array(self.up, "up", shape=(3,)), "up")
        if abs(float(up @ normal)) > 1 - 1e-9:
            raise ValueError(
                f"up={up.tolist()} is parallel to normal={normal.tolist()}; choose an 'up' "
                "direction that lies (at least partly) in the panel plane"
            )
        for name, value in (("position", pos), ("normal", normal), ("up", up)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def facing(cls, position: Any, target: Any, *, yaw: float = 0.0, up: Any = (0.0, 0.0, 1.0)) -> "RisPose":
        """Pose of a panel at ``position`` whose broadside points at ``target``.

        Parameters
        ----------
        position, target : float array [3]
            Panel centre and the point it faces, world frame [m].
        yaw : float, default 0
            Extra rotation of the panel about ``up`` [rad]; with ``yaw = ψ`` the target is seen
            at azimuth ``-ψ`` (when it lies in the plane normal to ``up``).
        up : float array [3]
            World "up" [unitless].
        """
        p = as_finite_array(position, "position", shape=(3,))
        t = as_finite_array(target, "target", shape=(3,))
        up_v = _unit(as_finite_array(up, "up", shape=(3,)), "up")
        n = t - p
        if not np.linalg.norm(n) > 0:
            raise ValueError("target coincides with position; a panel cannot face itself")
        n = _unit(n, "target - position")
        if yaw:
            # Rodrigues rotation of n about up by yaw.
            n = (n * np.cos(yaw) + np.cross(up_v, n) * np.sin(yaw)
                 + up_v * (up_v @ n) * (1 - np.cos(yaw)))
        return cls(position=p, normal=n, up=up_v)

    @property
    def column_axis(self) -> np.ndarray:
        """Column axis **w** (elevation turns toward it), world frame, unit [3]."""
        w = self.up - (self.up @ self.normal) * self.normal
        return w / np.linalg.norm(w)

    @property
    def row_axis(self) -> np.ndarray:
        """Row axis **u** = w × n (azimuth turns toward it), world frame, unit [3]."""
        return np.cross(self.column_axis, self.normal)

    @functools.cached_property
    def rotation(self) -> np.ndarray:
        """Rotation matrix [3, 3] whose columns are ``(u, w, n)``: ``world = R @ local`` (read-only, computed once)."""
        rot = np.column_stack([self.row_axis, self.column_axis, self.normal])
        rot.setflags(write=False)
        return rot

    def to_world(self, local: Any) -> np.ndarray:
        """Directions [..., 3] in the RIS frame ``(u, w, n)`` -> world frame (no translation)."""
        return as_finite_array(local, "local", trailing=(3,)) @ self.rotation.T

    def to_local(self, world: Any) -> np.ndarray:
        """Directions [..., 3] in the world frame -> RIS frame ``(u, w, n)`` (no translation)."""
        return as_finite_array(world, "world", trailing=(3,)) @ self.rotation

    def angles_to(self, points: Any) -> np.ndarray:
        """Azimuth/elevation [..., 2] [rad] at which the RIS sees world ``points`` [..., 3] [m]."""
        p = as_finite_array(points, "points", trailing=(3,))
        return angles_from_direction(self.to_local(p - self.position))

    def point_at(self, angles: Any, distance: Any) -> np.ndarray:
        """World points [..., 3] [m] at ``distance`` [...] [m] from the RIS along ``angles`` [..., 2] [rad]."""
        d = as_finite_array(distance, "distance")
        return self.position + d[..., None] * self.to_world(direction_from_angles(angles))
