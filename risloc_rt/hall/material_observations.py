"""The material fit's observations: radar positions with their peaks, and the peaks' model powers.

An :class:`Observation` is one radar position [m] and its observed peaks, each a round-trip delay
[s] (as the tracer reports delays), a power [dB] and its 1σ [dB]. A peak is *explained* by the
traced monostatic paths whose delay lies within ``window`` of it (:func:`assign_paths`; default
:data:`DEFAULT_WINDOW`, half the radar's Rayleigh delay resolution: the paths one beat peak
merges); a path within the window of two peaks goes to the nearer one. :func:`peak_model` gives
each peak's model power, the incoherent sum of its paths' powers (why incoherent:
:mod:`risloc_rt.hall.material_fit`, "Model"), and its Jacobian with respect to the fit's
parameters. :func:`synthetic_observations` makes observations with the tracer itself at given
material values: the fit's self-consistency oracle.

The fit that uses them is :func:`risloc_rt.hall.material_fit.fit_materials`; measured peaks become
observations in :mod:`risloc_rt.measured.compare.material_peaks`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp import RadarConfig
from dsp.validation import as_finite_array

from .raytrace.material_gradients import MaterialJacobian, material_jacobian
from .raytrace.result import TraceSettings

__all__ = ["DEFAULT_WINDOW", "Observation", "assign_paths", "peak_model", "synthetic_observations"]

#: Default delay window [s]: half Table I's Rayleigh delay resolution (the paths one beat peak merges).
DEFAULT_WINDOW: float = RadarConfig().delay_resolution / 2.0
_DB = 10.0 / math.log(10.0)


@dataclass(frozen=True)
class Observation:
    """One radar position and the peaks observed there.

    Parameters
    ----------
    radar_position : float array [3]
        Radar position, world frame [m].
    delay : float array [K]
        Round-trip delay of each observed peak [s] (as the tracer reports path delays).
    power_db : float array [K]
        Observed power of each peak [dB], in units of |a|² plus ``offset_db``.
    sigma_db : float array [K] or float
        1σ of each observed power [dB], > 0 (a scalar applies to every peak).
    offset_db : float or float array [K]
        Known constant added to the model power of this position's peaks (radar/RIS link budget)
        [dB]: one number for every peak, or one per peak (e.g. a measured capture's link budget
        from |a|² to the peak's power in the range profile, which includes the antenna gains
        toward that path and the coherent merging of the peak's paths:
        :mod:`risloc_rt.measured.compare.material_peaks`). Stored as given (a float, or a
        read-only array); :meth:`offsets` gives it per peak.
    path_weight : float array [P], optional
        A weight >= 0 [unitless] per monostatic path of the material tracer at this position (in
        :func:`~risloc_rt.hall.raytrace.material_gradients.material_jacobian`'s order, which does
        not depend on the materials): a peak's model power is then ``Σ_{p∈k} w_p |a_p|²``. A
        capture's paths reach the receiver through the radar's antenna pattern, which weights the
        paths of one peak differently (a double bounce arriving from behind the radar against a
        triple bounce at the same delay); a path the simulator prunes has weight 0. ``None``: all 1.
    """

    radar_position: np.ndarray
    delay: np.ndarray
    power_db: np.ndarray
    sigma_db: np.ndarray
    offset_db: float | np.ndarray = 0.0
    path_weight: np.ndarray | None = None

    def __post_init__(self) -> None:
        pos = as_finite_array(self.radar_position, "radar_position", shape=(3,))
        delay = np.array(self.delay, dtype=float).reshape(-1)
        k = delay.size
        power = np.array(self.power_db, dtype=float).reshape(-1)
        sigma = np.broadcast_to(np.array(self.sigma_db, dtype=float), (k,)).copy() if np.ndim(self.sigma_db) == 0 \
            else np.array(self.sigma_db, dtype=float).reshape(-1)
        if k == 0:
            raise ValueError("an Observation needs at least one peak (delay is empty)")
        if power.size != k or sigma.size != k:
            raise ValueError(f"delay, power_db and sigma_db must have one entry per peak; got {k}, {power.size}, "
                             f"{sigma.size}")
        if not (np.all(np.isfinite(delay)) and np.all(delay > 0)):
            raise ValueError("delay must be finite and > 0 [s]")
        if not np.all(np.isfinite(power)):
            raise ValueError("power_db must be finite [dB]")
        if not (np.all(np.isfinite(sigma)) and np.all(sigma > 0)):
            raise ValueError("sigma_db must be finite and > 0 [dB]")
        if np.ndim(self.offset_db) == 0:
            if not math.isfinite(float(self.offset_db)):
                raise ValueError(f"offset_db={self.offset_db!r} must be finite [dB]")
            offset: float | np.ndarray = float(self.offset_db)
        else:
            offset = np.array(self.offset_db, dtype=float).reshape(-1)
            if offset.size != k or not np.all(np.isfinite(offset)):
                raise ValueError(f"offset_db must be one finite number or one per peak ({k}) [dB]; got "
                                 f"{offset.size} value(s)")
            offset.setflags(write=False)
        for name, value in (("radar_position", pos), ("delay", delay), ("power_db", power), ("sigma_db", sigma)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "offset_db", offset)
        if self.path_weight is not None:
            weight = np.array(self.path_weight, dtype=float).reshape(-1)
            if not (np.all(np.isfinite(weight)) and np.all(weight >= 0)):
                raise ValueError("path_weight must be finite and >= 0 (one per traced monostatic path)")
            weight.setflags(write=False)
            object.__setattr__(self, "path_weight", weight)

    def __len__(self) -> int:
        return int(self.delay.size)

    def offsets(self) -> np.ndarray:
        """The offset of every peak [dB].

        Returns
        -------
        float array [K]
            ``offset_db`` broadcast to one value per peak [dB].
        """
        return np.broadcast_to(np.asarray(self.offset_db, dtype=float), (len(self),))


def assign_paths(path_delay: np.ndarray, peak_delay: np.ndarray, window: float) -> np.ndarray:
    """The peak that explains each traced path: the nearest one within ``window``, else -1.

    Parameters
    ----------
    path_delay : float array [P]
        Round-trip delays of the traced paths [s].
    peak_delay : float array [K]
        Round-trip delays of the observed peaks [s].
    window : float
        Largest |path delay − peak delay| that explains the path [s].

    Returns
    -------
    int array [P]
        Peak index per path, -1 for a path no peak explains.
    """
    path_delay = np.asarray(path_delay, dtype=float).reshape(-1)
    peak_delay = np.asarray(peak_delay, dtype=float).reshape(-1)
    if path_delay.size == 0 or peak_delay.size == 0:
        return np.full(path_delay.size, -1, dtype=np.int64)
    dist = np.abs(path_delay[:, None] - peak_delay[None, :])
    best = np.argmin(dist, axis=1)
    return np.where(dist[np.arange(path_delay.size), best] <= window, best, -1).astype(np.int64)


def peak_model(jac: MaterialJacobian, assign: np.ndarray, k: int,
                weight: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-peak model power [dB, without offset], its Jacobian w.r.t. (ε_r, ln σ) and S², and what it touches.

    Parameters
    ----------
    jac : MaterialJacobian
        The traced paths of one radar position with their gains and derivatives.
    assign : int array [P]
        The peak each path explains (:func:`assign_paths`; -1 for none).
    k : int
        Number of peaks.
    weight : float array [P], optional
        Per-path power weight [unitless] (the antenna pattern toward the path; 1 if None).

    Returns
    -------
    db : float array [K]
        ``10 log10 Σ_p w_p |a_p|²`` per peak [dB]; NaN for a peak no path explains.
    jdb : float array [K, 2Q + Q_s]
        Its derivatives w.r.t. (ε_r, ln σ) per material, then S² per scattering material [dB per unit].
    touches : bool array [K, Q]
        Peak k has a path interacting with material q.
    explained : bool array [K]
        Peak k has at least one path.
    """
    q = len(jac.materials)
    qs = len(jac.scattering)
    power = np.zeros(k)
    d_power = np.zeros((k, 2 * q + qs))
    # ∂/∂(S²) = ∂/∂S / (2S); S = 0 only at a scene's own smooth values, which no fit step uses (SHARE_RANGE).
    s_at = np.array([jac.scattering_coefficient[jac.materials.index(m)] for m in jac.scattering])
    per_share = np.divide(0.5, s_at, out=np.zeros(qs), where=s_at > 0)
    touches = np.zeros((k, q), dtype=bool)
    a = jac.a
    sig = jac.conductivity
    if weight is None:
        weight = np.ones(a.size)
    elif weight.size != a.size:
        raise ValueError(f"path_weight has {weight.size} entries for the {a.size} traced monostatic paths at "
                         f"{np.round(jac.paths.tx_position, 3).tolist()} m: give one per path of the material tracer")
    for i in range(k):
        m = (assign == i) & (weight > 0)
        if not m.any():
            continue
        power[i] = float(np.sum(weight[m] * np.abs(a[m]) ** 2))
        conj = (weight[m] * np.conj(a[m]))[:, None]
        d_power[i, 0:2 * q:2] = np.sum(2.0 * np.real(conj * jac.d_eps[m]), axis=0)
        d_power[i, 1:2 * q:2] = np.sum(2.0 * np.real(conj * jac.d_sigma[m]), axis=0) * sig
        if qs:
            d_power[i, 2 * q:] = np.sum(2.0 * np.real(conj * jac.d_scattering[m]), axis=0) * per_share
        touches[i] = jac.touches[m].any(axis=0)
    explained = power > 0
    db = np.full(k, np.nan)
    jdb = np.zeros((k, 2 * q + qs))
    db[explained] = _DB * np.log(power[explained])
    jdb[explained] = _DB * d_power[explained] / power[explained, None]
    return db, jdb, touches, explained


def synthetic_observations(
    scene: str | os.PathLike[str],
    positions: Any,
    values: Mapping[str, tuple[float, float]],
    *,
    sigma_db: float,
    rng: np.random.Generator | None,
    settings: TraceSettings | None = None,
    window: float = DEFAULT_WINDOW,
    offset_db: float = 0.0,
) -> tuple[list[Observation], list[np.ndarray]]:
    """Observations made by the tracer itself at given material values (the fit's self-consistency oracle).

    The traced paths of each position are grouped into peaks (a group starts at the first path
    not yet grouped and takes every path up to ``window`` later); a peak's delay is its paths'
    power-weighted mean delay; its power is the model's (:func:`assign_paths` then the incoherent
    sum) plus Gaussian noise of 1σ ``sigma_db``.

    Parameters
    ----------
    scene : path-like
        Scene folder or its ``scene.xml``.
    positions : float array [N, 3]
        Radar positions [m].
    values : mapping
        ``{material: (ε_r [unitless], σ [S/m])}`` the "true" hall is traced with (at least one),
        or ``(ε_r, σ, S)`` triples with the scattering coefficient.
    sigma_db : float
        1σ of the Gaussian power noise and the stated σ of every peak [dB], > 0.
    rng : numpy.random.Generator or None
        Noise source; None for noise-free powers.
    settings : TraceSettings, optional
        Solver options (as for the fit).
    window : float
        Delay window [s] (as for the fit).
    offset_db : float
        Constant added to every power [dB] (stored as each observation's ``offset_db``).

    Returns
    -------
    observations : list of Observation
        One per position.
    truth_db : list of float array
        The noise-free powers of each observation's peaks [dB].
    """
    if not values:
        raise ValueError("values is empty: name at least one material with its (eps_r, sigma [S/m])")
    if not (isinstance(sigma_db, (int, float)) and math.isfinite(sigma_db) and sigma_db > 0):
        raise ValueError(f"sigma_db={sigma_db!r} must be finite and > 0 [dB]")
    pos = np.asarray(positions, dtype=float).reshape(-1, 3)
    observations, truths = [], []
    for p in pos:
        jac = material_jacobian(scene, p, [next(iter(values))], values=values, settings=settings)
        d = jac.delay
        order = np.argsort(d, kind="stable")
        groups: list[list[int]] = []
        for i in order:
            if groups and d[i] - d[groups[-1][0]] <= window:
                groups[-1].append(int(i))
            else:
                groups.append([int(i)])
        power = np.abs(jac.a) ** 2
        delays = np.array([np.sum(d[g] * power[g]) / np.sum(power[g]) for g in groups])
        assign = assign_paths(d, delays, window)
        db, _, _, explained = peak_model(jac, assign, delays.size)
        delays, db = delays[explained], db[explained] + offset_db
        noisy = db + (rng.normal(0.0, sigma_db, db.size) if rng is not None else 0.0)
        observations.append(Observation(p, delays, noisy, sigma_db, offset_db=offset_db))
        truths.append(db)
    return observations, truths
