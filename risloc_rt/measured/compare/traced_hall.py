"""The ray-traced hall seen by a measured capture: the model side of ``risloc calibrate`` and ``risloc compare``.

The hall's scenario takes the capture's radar, sweep and RIS (the sweep schedule's pose, τ_RB,
mode and ζ) and a radar position: the capture's truth, or one given; the traced paths are built
with them (``hall.hall_paths``, pruned to what the radar can see).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ...hall.pruning import AliasWarning
from ...hall.scenario import HallPaths, HallScenario, hall_paths, hall_scenario
from ...model.capture import Capture
from ...model.ris import RisConfig
from ..errors import MeasuredFormatError

__all__ = ["HallModel", "MAX_NORMAL_MISMATCH", "hall_model", "ue_position_of"]

#: Largest angle between the capture's RIS normal and the scene's before they count as two panels [rad].
MAX_NORMAL_MISMATCH = np.deg2rad(10.0)


@dataclass(frozen=True)
class HallModel:
    """A traced hall for one capture: the scenario and its kept paths (√W, delays with τ_RB)."""

    scenario: HallScenario
    traced: HallPaths
    ue_position: np.ndarray
    ue_source: str


def ue_position_of(capture: Capture, ue: Any = None, *, estimate: Any = None) -> tuple[np.ndarray, str]:
    """The radar position to model: ``ue`` if given, else the capture's truth, else ``estimate``; and which.

    Parameters
    ----------
    capture : Capture
    ue : array [3], optional
        Given position [m].
    estimate : array [3], optional
        The localization's estimate [m], the last resort.

    Returns
    -------
    (float array [3], str)
        The position [m] and ``"given"``, ``"truth"`` or ``"estimate"``.
    """
    if ue is not None:
        return np.asarray(ue, float), "given"
    if capture.truth is not None:
        return np.asarray(capture.truth.ue_position, float), "truth"
    if estimate is not None:
        return np.asarray(estimate, float), "estimate"
    raise MeasuredFormatError("the capture has no truth (no [truth] ue_position in its sweep schedule); give the "
                              "radar's position with --ue X,Y,Z")


def hall_model(capture: Capture, scene: str | Path, ue_position: np.ndarray, *, ue_source: str = "given",
               ris: RisConfig | None = None, trace: Any = None, cache: Any = None) -> HallModel:
    """Trace ``scene`` for the capture's radar, sweep and RIS (or ``ris``) with the radar at ``ue_position``.

    In a hall with several RISs the sweeping one is the scene's RIS at the capture's RIS position (the
    others idle and off, their panels echoes), so a capture of any RIS's slot is compared in that slot.

    Parameters
    ----------
    capture : Capture
        Its radar, sweep, processing and RIS.
    scene : str or path
        A scene name in ``scenes/`` or a folder; its RIS must be within 5 cm of the capture's and
        face the same way (normals within :data:`MAX_NORMAL_MISMATCH`).
    ue_position : array [3]
        The radar's position [m].
    ue_source : str
        Where the position came from (``"given"``, ``"truth"``, ``"estimate"``).
    ris : RisConfig, optional
        Replaces the capture's RIS (e.g. calibrated τ_RB and ζ).
    trace : TraceSettings, optional
        Ray-tracing settings.
    cache : TraceCache, optional
        Reuse traced paths.

    Returns
    -------
    HallModel
        The hall scenario and its kept paths (√W, delays with τ_RB [s]).

    Raises
    ------
    MeasuredFormatError
        The capture's RIS is not the scene's (position, or the way it faces: without a truth,
        this is how a reversed ``[ris] facing`` in a sweep schedule is caught, whose estimates
        are all mirror images through the panel).
    ValueError
        The radar position lies behind the scene's RIS panel (:func:`risloc_rt.hall.hall_scenario`).
    """
    ris = capture.ris if ris is None else ris
    hs = hall_scenario(scene, radar=capture.radar, sweep=capture.sweep, processing=capture.processing,
                       ue_position=ue_position, ue_velocity=np.zeros(3), trace=trace,
                       ris=_sweeping_ris(scene, ris))
    if np.linalg.norm(ris.pose.position - hs.base.ris.pose.position) > 0.05:
        raise MeasuredFormatError(
            f"the capture's RIS is at {np.round(ris.pose.position, 3).tolist()} m but the scene's is at "
            f"{np.round(hs.base.ris.pose.position, 3).tolist()} m; give the scene the experiment was done in (or fix "
            "the sweep schedule's [ris] position)")
    _check_facing(ris, hs.base.ris)
    hs = replace(hs, base=replace(hs.base, ris=ris))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AliasWarning)
        traced = hall_paths(hs, cache=cache)
    return HallModel(scenario=hs, traced=traced, ue_position=np.asarray(ue_position, float), ue_source=ue_source)


def _sweeping_ris(scene: Any, ris: RisConfig) -> int:
    """The index of the scene's RIS at the capture's RIS position (within 5 cm): in a hall with several
    RISs, the one whose slot the capture recorded (the others idle, off); the first when none is there
    (then :func:`hall_model` says the positions differ)."""
    from ...authoring.scene_folder import scene_directory
    from ...authoring.spec import load_spec

    configs = load_spec(scene_directory(scene) / "spec.toml").ris_configs()
    near = [i for i, c in enumerate(configs) if np.linalg.norm(c.pose.position - ris.pose.position) <= 0.05]
    return near[0] if near else 0


def _check_facing(ris: RisConfig, scene_ris: RisConfig) -> None:
    """Refuse a capture RIS that faces another way than the scene's.

    A radar position behind the panel is refused before, by :func:`risloc_rt.hall.hall_scenario`
    (the scene's RIS, which this check makes the capture's too).

    Parameters
    ----------
    ris : RisConfig
        The capture's RIS (its sweep schedule's ``[ris]`` pose).
    scene_ris : RisConfig
        The scene's RIS at the same place.
    """
    normal, scene_normal = ris.pose.normal, scene_ris.pose.normal
    angle = float(np.arccos(np.clip(normal @ scene_normal, -1.0, 1.0)))
    if angle > MAX_NORMAL_MISMATCH:
        raise MeasuredFormatError(
            f"the capture's RIS faces {np.round(normal, 3).tolist()} but the scene's faces "
            f"{np.round(scene_normal, 3).tolist()} ({np.rad2deg(angle):.0f}° apart); fix the sweep schedule's [ris] "
            "facing/normal (it points from the panel toward the side the radar is on), or give the scene the "
            "experiment was done in")
