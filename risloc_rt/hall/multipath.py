"""Traced paths -> the beat model's PathSet: hall echoes, the RIS loop-back and the panel's reflection.

Pure numpy; the ray tracer hands over :class:`~risloc_rt.hall.traced.TracedPaths`.

All gains follow the paper's link budget with the traced one-way coefficients in place of the
free-space ``λ/(4π d)``: a monostatic path gets ``sqrt(P G_trx g_t g_r) · a``, a RIS loop-back
leg pair (out via p, back via q) ``sqrt(P G_trx ζ g_p g_q) · a_p a_q · r_m(θ_p, θ_q)``, and a
structural leg pair ``sqrt(P G_trx g_p g_q) · a_p S_pq a_q`` with S the plate's physical-optics
amplitude. Each carries its carrier phase ``exp(-j2π f_c τ)``.
"""

from __future__ import annotations

import numpy as np

from dsp import BeamSweep, RadarConfig

from .antenna import RadarAntenna
from ..model.link_budget import carrier_phase
from ..model.paths import PathSet
from ..model.plate import Plate, plate_scattering
from ..model.ris import RisConfig, ris_response
from .traced import TracedPaths

__all__ = ["idle_parked_paths", "idle_structure_paths", "monostatic_paths", "ris_loopback_paths", "ris_structure_paths",
           "leg_pairs"]


def _describe_all(traced: TracedPaths) -> list[str]:
    return [traced.describe(i) for i in range(len(traced))]


def monostatic_paths(traced: TracedPaths, *, radar: RadarConfig, antenna: RadarAntenna) -> PathSet:
    """Round-trip hall echoes (radar → walls/objects → radar) as tones of eq. (1).

    Parameters
    ----------
    traced : TracedPaths
        Monostatic trace (Tx and Rx at the radar).
    radar : RadarConfig
    antenna : RadarAntenna

    Returns
    -------
    PathSet
        One path per traced path, labelled ``"hall: <interactions>"``.
    """
    g = antenna.gain(traced.departure) * antenna.gain(traced.arrival)
    gain = np.sqrt(radar.tx_power * radar.antenna_gain * g) * traced.amplitude
    gain = gain * carrier_phase(traced.delay, radar.carrier_frequency)
    n = len(traced)
    return PathSet(
        gain=gain, delay=traced.delay, delay_rate=traced.delay_rate,
        ris_incidence=np.full((n, 2), np.nan), ris_departure=np.full((n, 2), np.nan),
        labels=tuple(f"hall: {d}" for d in _describe_all(traced)),
    )


def leg_pairs(leg: TracedPaths) -> tuple[np.ndarray, np.ndarray]:
    """Indices (p, q) [L²] of every ordered pair of one-way legs: out via p, back via q."""
    n = len(leg)
    p, q = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return p.ravel(), q.ravel()


def _pair_labels(leg: TracedPaths, kind: str, p: np.ndarray, q: np.ndarray) -> tuple[str, ...]:
    desc = _describe_all(leg)
    return tuple(f"{kind}: out {desc[i]} | back {desc[j]}" for i, j in zip(p, q))


def ris_loopback_paths(leg: TracedPaths, *, radar: RadarConfig, ris: RisConfig, antenna: RadarAntenna) -> PathSet:
    """RIS re-transmissions for every leg pair, to be weighted by the RIS response per beam.

    Parameters
    ----------
    leg : TracedPaths
        One-way paths radar → RIS centre (Tx at the radar, Rx at the RIS).
    radar : RadarConfig
    ris : RisConfig
    antenna : RadarAntenna

    Returns
    -------
    PathSet
        L² paths: delay ``τ_p + τ_q + τ_RB``, delay rate ``ν_p + ν_q``, RIS incidence θ_p (where
        leg p arrives from) and departure θ_q (where leg q leaves toward), gain
        ``sqrt(P G_trx ζ g(k_p) g(k_q)) a_p a_q exp(-j2π f_c τ)``. With only the direct leg in free
        space, ``|gain|² = P G_trx |γ_UR|² ζ |γ_RU|²``, the paper's formula.
    """
    p, q = leg_pairs(leg)
    angles = ris.pose.angles_to(ris.pose.position + leg.arrival) if len(leg) else np.zeros((0, 2))
    g = antenna.gain(leg.departure)
    delay = leg.delay[p] + leg.delay[q] + ris.loopback_delay
    gain = (np.sqrt(radar.tx_power * radar.antenna_gain * ris.amplification * g[p] * g[q])
            * leg.amplitude[p] * leg.amplitude[q] * carrier_phase(delay, radar.carrier_frequency))
    return PathSet(
        gain=gain, delay=delay, delay_rate=leg.delay_rate[p] + leg.delay_rate[q],
        ris_incidence=angles[p], ris_departure=angles[q],
        labels=_pair_labels(leg, "ris_loopback", p, q),
    )


def ris_structure_paths(
    leg: TracedPaths, *, radar: RadarConfig, ris: RisConfig, plate: Plate, antenna: RadarAntenna
) -> PathSet:
    """The RIS panel's own (structural) reflection for every leg pair, by physical optics.

    Parameters
    ----------
    leg : TracedPaths
        One-way paths radar → RIS centre.
    radar, ris, plate, antenna
        The panel lies in the RIS plane, centred on the RIS.

    Returns
    -------
    PathSet
        Ordered pairs (p, q) and (q, p) have the same delay and the same (reciprocal) amplitude;
        they are merged into one path of twice the amplitude, so the set has L(L+1)/2 paths:
        delay ``τ_p + τ_q`` (no τ_RB), gain ``sqrt(P G_trx g_p g_q) a_p S_pq a_q exp(-j2π f_c τ)``.
    """
    p, q = leg_pairs(leg)
    keep = p <= q
    p, q = p[keep], q[keep]
    multiplicity = np.where(p == q, 1.0, 2.0)
    s = plate_scattering(plate, ris.pose, leg.arrival[p], leg.arrival[q], wavelength=radar.wavelength)
    g = antenna.gain(leg.departure)
    delay = leg.delay[p] + leg.delay[q]
    gain = (multiplicity * np.sqrt(radar.tx_power * radar.antenna_gain * g[p] * g[q])
            * leg.amplitude[p] * s * leg.amplitude[q] * carrier_phase(delay, radar.carrier_frequency))
    n = len(p)
    return PathSet(
        gain=gain, delay=delay, delay_rate=leg.delay_rate[p] + leg.delay_rate[q],
        ris_incidence=np.full((n, 2), np.nan), ris_departure=np.full((n, 2), np.nan),
        labels=_pair_labels(leg, "ris_structure", p, q),
    )


def _relabelled(paths: PathSet, kind: str, name: str) -> PathSet:
    labels = tuple(f"{kind}[{name}]:{lab.split(':', 1)[1]}" for lab in paths.labels)
    return PathSet(gain=paths.gain, delay=paths.delay, delay_rate=paths.delay_rate,
                   ris_incidence=paths.ris_incidence, ris_departure=paths.ris_departure, labels=labels)


def idle_structure_paths(leg: TracedPaths, idle, *, radar: RadarConfig, antenna: RadarAntenna) -> PathSet:
    """The panel of a RIS that does not sweep in this slot: a static echo of the hall.

    Parameters
    ----------
    leg : TracedPaths
        One-way paths radar → the idle RIS's centre.
    idle : risloc_rt.hall.scenario.IdleRis
        The idle RIS (its pose, hardware and plate).
    radar, antenna
        As :func:`ris_structure_paths`.

    Returns
    -------
    PathSet
        :func:`ris_structure_paths` of the idle RIS, labelled ``"ris_structure[<name>]: ..."``.
    """
    paths = ris_structure_paths(leg, radar=radar, ris=idle.ris, plate=idle.plate, antenna=antenna)
    return _relabelled(paths, "ris_structure", idle.name)


def idle_parked_paths(leg: TracedPaths, idle, *, radar: RadarConfig, antenna: RadarAntenna) -> PathSet:
    """The loop-back of a RIS that holds one parked beam while another sweeps: a static echo.

    Parameters
    ----------
    leg : TracedPaths
        One-way paths radar → the idle RIS's centre.
    idle : risloc_rt.hall.scenario.IdleRis
        The idle RIS, with ``parked_beam`` set [rad].
    radar, antenna
        As :func:`ris_loopback_paths`.

    Returns
    -------
    PathSet
        :func:`ris_loopback_paths` of the idle RIS with its response to the parked beam,
        ``r(θ_p, θ_q)`` of :func:`risloc_rt.model.ris.ris_response` for that one beam, folded into the
        gain: the same in every beam of the sweeping RIS, so not a RIS path of the sweep (NaN
        angles), labelled ``"ris_parked[<name>]: ..."``.
    """
    if idle.parked_beam is None:
        raise ValueError(f"RIS {idle.name!r} is switched off (parked_beam=None): it has no loop-back")
    paths = ris_loopback_paths(leg, radar=radar, ris=idle.ris, antenna=antenna)
    n = len(paths)
    if n:
        r = ris_response(idle.ris, BeamSweep(np.asarray(idle.parked_beam)[None, :]), paths.ris_incidence,
                         paths.ris_departure, wavelength=radar.wavelength)[0]
    else:
        r = np.zeros(0, complex)
    static = PathSet(gain=paths.gain * r, delay=paths.delay, delay_rate=paths.delay_rate,
                     ris_incidence=np.full((n, 2), np.nan), ris_departure=np.full((n, 2), np.nan),
                     labels=paths.labels)
    return _relabelled(static, "ris_parked", idle.name)
