"""A time-division recording of several RISs: each RIS sweeps in its own slot, one after another.

:func:`emulate_time_division` writes the DCA1000 folder of one recording (``adc_data_Raw_0.bin``,
``adc_data.cfg``, ``sweep.toml`` of the several-RIS form, ``docs/formats.md`` "Several RISs") from
one simulated :class:`~risloc_rt.model.capture.Capture` per slot, one frame per beam: slot k's
frames are the capture of RIS k sweeping while the others are idle (off or parked, as the
captures were simulated: ``risloc_rt.hall.scenario.hall_scenario(ris=..., idle=...)``). Frames
outside every slot (gaps of the schedule) hold the idle scene, ``idle_frame`` (the paths that do not
pass through a sweeping RIS) plus receiver noise. A slot whose RIS cannot reach the radar (it
stands behind the panel; no capture) holds the idle scene too: the RIS sweeps, the radar sees no
return. The radar is frozen (a static UE): one truth for every slot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsp import BeamSweep

from ...model.beat import beat_cube
from ...model.capture import Capture
from ...model.paths import PathSet, select_paths
from ...model.ris import RisConfig
from ...model.scenario import Scenario
from ...model.time_division import TimeDivision
from ..errors import MeasuredFormatError
from ..sweep.schedules import SweepSchedules, write_sweep_schedules
from .experiment import (PREFIX, SCHEDULE_NAME, check_folder, schedule_fields, sweep_schedule_of, write_frames)
from .raw_files import EmulatedCapture

__all__ = ["EmulatedTimeDivision", "emulate_time_division", "idle_frame", "slot_first_frames"]


@dataclass(frozen=True)
class EmulatedTimeDivision:
    """What :func:`emulate_time_division` wrote.

    Attributes
    ----------
    folder : Path
    raw : EmulatedCapture
        The raw files and the ``.cfg``.
    schedule_path : Path
        ``sweep.toml``.
    schedules : SweepSchedules
        Its content: every RIS with its slot's first frame.
    first_frames : tuple of int
        Each RIS's first frame (the ``names`` order).
    num_frames : int
        Frames recorded.
    full_scale : float
        Input amplitude of the top ADC code [√W].
    counts_per_unit : float
        ADC counts per √W.
    """

    folder: Path
    raw: EmulatedCapture
    schedule_path: Path
    schedules: SweepSchedules
    first_frames: tuple[int, ...]
    num_frames: int
    full_scale: float
    counts_per_unit: float

    @property
    def raw_path(self) -> Path:
        """The first raw file (``adc_data_Raw_0.bin``)."""
        return self.raw.files[0]

    @property
    def config_path(self) -> Path:
        """The mmWave SDK ``.cfg``."""
        return self.raw.cfg_path


def idle_frame(scenario: Scenario, paths: PathSet) -> np.ndarray:
    """One noiseless frame of the idle scene: every path but the sweeping RIS's loop-back.

    Parameters
    ----------
    scenario : Scenario
        Radar and RIS of one slot.
    paths : PathSet
        That slot's paths (``hall_paths(...).paths``): the hall's echoes, the panels' structural
        echoes and the parked RISs' loop-back (static), and the sweeping RIS's loop-back (left out).

    Returns
    -------
    complex array [K, N]
        Beat samples [√W].
    """
    static = select_paths(paths, ~paths.via_ris)
    return beat_cube(static, radar=scenario.radar, sweep=BeamSweep(np.zeros((1, 2))), ris=scenario.ris)[0]


def slot_first_frames(division: TimeDivision, frame_interval: float, *, first_frame: int = 0) -> tuple[int, ...]:
    """Each slot's first frame: ``first_frame + s_k / T_f`` (a whole frame), in ``division.order``.

    Parameters
    ----------
    division : TimeDivision
        Slot starts [s]; its sweep duration must be the slot's frames × T_f.
    frame_interval : float
        The radar's frame period T_f [s].
    first_frame : int
        The first slot's first frame.

    Returns
    -------
    tuple of int
    """
    out = []
    for name, start in zip(division.order, division.starts):
        frames = start / float(frame_interval)
        if abs(frames - round(frames)) > 1e-6:
            raise MeasuredFormatError(
                f"[schedule]: the slot of {name!r} starts at {start * 1e3:g} ms = {frames:.4g} frames of "
                f"{frame_interval * 1e3:g} ms; a recording's slots start on whole frames: give start_ms and gap_ms "
                "in multiples of the frame period")
        out.append(int(first_frame) + int(round(frames)))
    return tuple(out)


def _recording(captures: Sequence[Capture | None], idle: np.ndarray, firsts: Sequence[int], tail_frames: int,
               rng: np.random.Generator, noise: bool) -> np.ndarray:
    """The frames [F, K, N] [√W]: each slot's capture at its first frame, the idle scene (+ noise) elsewhere."""
    known = [c for c in captures if c is not None]
    M = known[0].cube.shape[0]
    F = max(firsts) + M + int(tail_frames)
    K, N = idle.shape
    if F * K * N > 60_000_000:
        raise MeasuredFormatError(f"the recording would hold {F} frames x {K} x {N} samples; use fewer or closer slots "
                                  "or a smaller radar")
    frames = np.empty((F, K, N), np.complex128)
    frames[:] = idle[None]
    filled = np.zeros(F, bool)
    for cap, first in zip(captures, firsts):
        if cap is not None:
            frames[first:first + M] = cap.cube
            filled[first:first + M] = True
    if noise and not filled.all():
        sigma = math.sqrt(known[0].radar.noise_power / 2)
        rest = frames[~filled]
        frames[~filled] = rest + sigma * (rng.standard_normal(rest.shape) + 1j * rng.standard_normal(rest.shape))
    return frames


def _check_captures(names: Sequence[str], ris: Sequence[RisConfig], captures: Sequence[Capture | None]) -> None:
    """Every slot a name and a RIS; the captures share the radar and the sweep, one frame per beam."""
    if not (len(names) == len(ris) == len(captures)) or not names:
        raise MeasuredFormatError(f"{len(names)} names, {len(ris)} RISs and {len(captures)} captures: give one of each "
                                  "per slot")
    known = [c for c in captures if c is not None]
    if not known:
        raise MeasuredFormatError("no slot has a capture: the radar stands behind every RIS (no RIS can reach it)")
    first = known[0]
    for c in known:
        if c.radar != first.radar or not np.array_equal(c.sweep.angles, first.sweep.angles):
            raise MeasuredFormatError("the slots' captures must share the radar and the sweep (one recording)")
        if c.radar.frames_per_beam != 1:
            raise MeasuredFormatError(f"a capture has frames_per_beam={c.radar.frames_per_beam}; the emulator writes "
                                      "one frame per beam")


def emulate_time_division(names: Sequence[str], ris: Sequence[RisConfig], captures: Sequence[Capture | None],
                          folder: str | Path, *, idle: np.ndarray, rng: np.random.Generator,
                          first_frames: Sequence[int] | None = None, division: dict[str, Any] | None = None,
                          tail_frames: int = 0, noise: bool = True, **adc: Any) -> EmulatedTimeDivision:
    """Write a time-division recording of several RISs into ``folder`` (module docstring).

    Parameters
    ----------
    names : sequence of str
        The RISs in slot order (the written ``[[ris]]`` tables' names).
    ris : sequence of RisConfig
        Each RIS (pose [m], τ_RB [s], hardware), for the schedule.
    captures : sequence of Capture or None
        Each slot's capture (radar from ``dca1000_radar``, one frame per beam, every slot the same
        radar and sweep); None: the RIS cannot reach the radar (its slot holds the idle scene).
    folder : path
        Created if missing; refused if it holds a capture already.
    idle : complex array [K, N]
        The idle scene's frame (:func:`idle_frame`) [√W].
    rng : numpy.random.Generator
        The noise of the idle frames, lost packets.
    first_frames : sequence of int, optional
        Each slot's first frame (default: back to back from frame 0: ``k·M``).
    division : dict, optional
        The ``[schedule]`` table written with them (order, idle, parked_deg: what the idle RISs did).
    tail_frames : int
        Frames of the idle scene recorded after the last slot.
    noise : bool
        Add receiver noise to the idle frames (the captures carry their own).
    **adc
        ``adc_bits``, ``dropped_packets_rate``, ``dc_offset``, ``iq_gain_db``, ``power_offset_db``
        (:func:`~.experiment.write_frames`).

    Returns
    -------
    EmulatedTimeDivision
    """
    _check_captures(names, ris, captures)
    known = next(c for c in captures if c is not None)
    M = known.cube.shape[0]
    firsts = tuple(k * M for k in range(len(names))) if first_frames is None else tuple(int(f) for f in first_frames)
    if len(firsts) != len(names) or min(firsts) < 0:
        raise MeasuredFormatError(f"first_frames {list(firsts)} must give one frame >= 0 per slot ({len(names)})")
    folder = check_folder(folder)
    frames = _recording(captures, np.asarray(idle, complex), firsts, tail_frames, rng, noise)
    raw, fs, counts = write_frames(frames, known.radar, folder, rng=rng, **adc)
    per_ris = tuple(sweep_schedule_of(np.rad2deg(known.sweep.angles), frames_per_beam=1, first_frame=first, channel=0,
                                      **schedule_fields(r, known.truth))
                    for r, first in zip(ris, firsts))
    schedules = SweepSchedules(names=tuple(names), schedules=per_ris, division=division, source=str(folder /
                                                                                                      SCHEDULE_NAME))
    schedules.first_frames()                                      # overlapping slots: refused before it is written
    path = write_sweep_schedules(schedules, folder / SCHEDULE_NAME, comment=(
        f"risloc simulate --format dca1000: {len(names)} RISs in time division, {M} beams each, one frame per beam; "
        f"{frames.shape[0]} frames in {PREFIX}_Raw_*.bin; full scale {fs:.6g} sqrt(W)"))
    return EmulatedTimeDivision(folder=folder, raw=raw, schedule_path=path, schedules=schedules, first_frames=firsts,
                                num_frames=int(frames.shape[0]), full_scale=fs, counts_per_unit=counts)
