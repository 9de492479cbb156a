"""The RIS's program in radar time: a sync code, then one dwell per beam, on the RIS's own clock.

A measured sweep is two free-running devices: the radar records frames at its frame period
``T_f`` (the ``.cfg``'s ``frameCfg`` periodicity), the RIS controller runs its program on its
own clock. The program is written in **nominal frames**, the RIS's own durations divided by the
radar's frame period (a RIS holding each beam 25 ms against 20 ms frames has a dwell of 1.25
nominal frames; :meth:`RisProgram.from_ris_clock` converts)::

    sync:   the chips of the sync code, chip frames each: '1' on at the sync beam, '0' off
            (the on/off form: cycles x (on_frames '1' chips, off_frames '0' chips), chips of 1 frame)
    gap:    gap frames off
    sweep:  beam 0 for frames_per_beam, beam 1 for frames_per_beam, ..., beam M-1
    after:  RIS off; with repeat_after: gap frames off, then the sync code again, then off

In radar time the program starts somewhere in the recording and every nominal duration is
stretched by the RIS clock's rate against the radar's: a beam lasts ``dwell = frames_per_beam ·
(1 + drift)`` radar frames (not necessarily a whole number). ``start`` is the radar time of the
first beam's switch-on [frames from the recording's first frame]. The sync code sits
``sync_length · (1 + drift)`` frames before it. :func:`chirp_states` evaluates the program at
chirp times; the emulator (:mod:`..emulate.recording`) synthesises with it and the aligner
(:mod:`.alignment`) fits it, so both share one definition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import MeasuredFormatError

__all__ = ["MAX_SYNC_CHIPS", "OFF", "SYNC", "RisProgram", "chirp_fractions", "chirp_states"]

OFF = -1
"""State code: the RIS does not re-transmit (amplifier off)."""
SYNC = -2
"""State code: the RIS re-transmits at its sync beam (a '1' chip of the sync code)."""
MAX_SYNC_CHIPS = 4096
"""Longest sync code accepted [chips] (a RIS's announcement is tens of chips)."""


def _positive(value: float, name: str, unit: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise MeasuredFormatError(f"{name}={value!r} must be a finite number > 0 [{unit}]")
    return v


@dataclass(frozen=True)
class RisProgram:
    """What the RIS controller runs, in nominal frames (see the module docstring).

    Parameters
    ----------
    num_beams : int
        M, beams of the sweep.
    frames_per_beam : float
        The RIS's time per beam [nominal frames] (> 0; need not be whole: 25 ms against 20 ms
        frames is 1.25).
    sync_on, sync_off, sync_cycles : int
        The on/off sync form: ``sync_cycles`` × (``sync_on`` on, ``sync_off`` off) whole nominal
        frames (chips of one frame); 0: none. Not with ``sync_pattern``.
    sync_gap : float
        RIS off between the sync code and the sweep (and, with ``repeat_after``, between the
        sweep and the repeated code) [nominal frames] (>= 0).
    sync_pattern : str
        The sync code, one character per chip: ``'1'`` on at the sync beam, ``'0'`` off (e.g.
        ``"1111100110101"``); empty: the on/off form (or no sync).
    chip_frames : float
        Duration of one chip of ``sync_pattern`` [nominal frames] (> 0).
    repeat_after : bool
        The sync code is sent again after the sweep (after ``sync_gap`` off).
    """

    num_beams: int
    frames_per_beam: float
    sync_on: int = 0
    sync_off: int = 0
    sync_cycles: int = 0
    sync_gap: float = 0.0
    sync_pattern: str = ""
    chip_frames: float = 1.0
    repeat_after: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.num_beams, bool) or int(self.num_beams) != self.num_beams or self.num_beams < 1:
            raise MeasuredFormatError(f"num_beams={self.num_beams!r} must be an integer >= 1")
        _positive(self.frames_per_beam, "frames_per_beam", "nominal frames")
        for name in ("sync_on", "sync_off", "sync_cycles"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 0:
                raise MeasuredFormatError(f"{name}={value!r} must be an integer >= 0")
        if not math.isfinite(float(self.sync_gap)) or self.sync_gap < 0:
            raise MeasuredFormatError(f"sync_gap={self.sync_gap!r} must be a finite number >= 0 [nominal frames]")
        _positive(self.chip_frames, "chip_frames", "nominal frames")
        if self.sync_cycles and not self.sync_on:
            raise MeasuredFormatError(f"sync_cycles={self.sync_cycles} needs sync_on >= 1 (frames the RIS is on)")
        if self.sync_pattern:
            if set(self.sync_pattern) - {"0", "1"} or len(self.sync_pattern) > MAX_SYNC_CHIPS:
                raise MeasuredFormatError(f"sync_pattern={self.sync_pattern[:40]!r} must be up to {MAX_SYNC_CHIPS} "
                                          "characters '1' (on) and '0' (off)")
            if "1" not in self.sync_pattern:
                raise MeasuredFormatError(f"sync_pattern={self.sync_pattern!r} has no '1' chip: the RIS is never on")
            if self.sync_cycles or self.sync_on or self.sync_off:
                raise MeasuredFormatError("give the sync as sync_pattern or as sync_on/sync_off/sync_cycles, not both")

    @classmethod
    def from_ris_clock(cls, num_beams: int, *, beam_dwell: float, frame_interval: float, sync_pattern: str = "",
                       chip: float | None = None, sync_gap: float = 0.0, repeat_after: bool = False) -> "RisProgram":
        """The program of a RIS whose durations are given on its own clock, in seconds.

        Parameters
        ----------
        num_beams : int
            M.
        beam_dwell : float
            Time the RIS holds each beam [s] (its own clock).
        frame_interval : float
            The radar's frame period T_f [s] (the ``.cfg``'s ``frameCfg`` periodicity): one nominal frame.
        sync_pattern : str
            The sync code ('1' on, '0' off), or empty.
        chip : float, optional
            Duration of one chip [s]; required with ``sync_pattern``.
        sync_gap : float
            RIS off between the code and the sweep [s].
        repeat_after : bool
            The code is sent again after the sweep.

        Returns
        -------
        RisProgram
            ``frames_per_beam = beam_dwell / T_f``, ``chip_frames = chip / T_f``, ``sync_gap / T_f``.
        """
        tf = _positive(frame_interval, "frame_interval", "s")
        if sync_pattern and chip is None:
            raise MeasuredFormatError("a sync_pattern needs its chip duration [s]")
        return cls(num_beams=num_beams, frames_per_beam=_positive(beam_dwell, "beam_dwell", "s") / tf,
                   sync_gap=float(sync_gap) / tf, sync_pattern=sync_pattern,
                   chip_frames=1.0 if chip is None else _positive(chip, "chip", "s") / tf, repeat_after=repeat_after)

    @property
    def chips(self) -> str:
        """The sync code as chips ('1' on, '0' off): ``sync_pattern`` or the on/off cycles ('' when none)."""
        if self.sync_pattern:
            return self.sync_pattern
        if self.sync_cycles and self.sync_on:
            return ("1" * self.sync_on + "0" * self.sync_off) * self.sync_cycles
        return ""

    @property
    def chip_length(self) -> float:
        """Nominal frames per chip: ``chip_frames`` for a pattern, 1 for the on/off form."""
        return float(self.chip_frames) if self.sync_pattern else 1.0

    @property
    def has_sync(self) -> bool:
        """The program has sync chips (the RIS is on at its sync beam at some time)."""
        return "1" in self.chips

    @property
    def code_length(self) -> float:
        """Nominal frames of the sync code: ``len(chips) · chip_length``."""
        return len(self.chips) * self.chip_length

    @property
    def sync_length(self) -> float:
        """Nominal frames from the sync's start to the sweep's start: code length + gap."""
        return self.code_length + float(self.sync_gap) if self.chips else float(self.sync_gap)

    @property
    def sweep_length(self) -> float:
        """Nominal frames of the sweep: M · frames_per_beam."""
        return self.num_beams * float(self.frames_per_beam)

    @property
    def after_length(self) -> float:
        """Nominal frames of the program after the sweep: gap + code with ``repeat_after``, else 0."""
        return self.sync_length if (self.repeat_after and self.chips) else 0.0


def chirp_fractions(num_chirps: int, chirp_interval: float, frame_interval: float, *,
                    count: int | None = None) -> np.ndarray:
    """Start times of the chirps within a frame [frames]: ``k·T_c/T_f`` for k = 0 … K−1.

    Parameters
    ----------
    num_chirps : int
        K, chirps per frame.
    chirp_interval : float
        T_c [s].
    frame_interval : float
        T_f [s].
    count : int, optional
        Keep that many evenly spaced chirps (the aligner's sub-sampling; the first and last chirp
        always included).

    Returns
    -------
    float array [K] (or [count])
        [frames].
    """
    k = np.arange(num_chirps, dtype=float)
    if count is not None and count < num_chirps:
        k = np.unique(np.round(np.linspace(0, num_chirps - 1, max(int(count), 2))))
    return k * (chirp_interval / frame_interval)


def _code_states(chips: np.ndarray, v: np.ndarray, chip: float) -> np.ndarray:
    """True where nominal time ``v`` from the code's start falls in a '1' chip."""
    n = chips.size
    idx = np.floor(v / chip)
    inside = (idx >= 0) & (idx < n)
    return inside & chips[np.clip(idx, 0, n - 1).astype(np.int64)]


def chirp_states(program: RisProgram, times: np.ndarray, *, start: float | np.ndarray,
                 dwell: float | np.ndarray) -> np.ndarray:
    """RIS state at radar times ``times`` [frames]: beam index m >= 0, :data:`OFF` or :data:`SYNC`.

    Parameters
    ----------
    program : RisProgram
        In nominal frames.
    times : float array
        Radar times [frames from the recording's first frame].
    start : float or array
        The first beam's switch-on [frames]; may broadcast against ``times`` (the aligner
        evaluates many candidates at once).
    dwell : float or array
        Radar frames per beam [frames]; broadcasts likewise.

    Returns
    -------
    int64 array
        The broadcast shape of the three.

    Notes
    -----
    With the rate ``r = dwell / frames_per_beam`` (radar frames per nominal frame) the nominal
    time from the sweep start is ``u = (t − start)/r``; the state is beam ``⌊u/frames_per_beam⌋``
    for ``0 ≤ u < M·frames_per_beam``, SYNC where ``u + sync_length`` (or, with ``repeat_after``,
    ``u − M·frames_per_beam − sync_gap``) falls in a '1' chip, else OFF.
    """
    t = np.asarray(times, float)
    rate = np.asarray(dwell, float) / program.frames_per_beam        # radar frames per nominal frame
    u = (t - np.asarray(start, float)) / rate                        # nominal frames from the sweep start
    beam = np.floor(u / program.frames_per_beam)
    state = np.where((u >= 0) & (beam < program.num_beams), beam, OFF).astype(np.int64)
    if program.has_sync:
        chips = np.frombuffer(program.chips.encode("ascii"), np.uint8) == ord("1")
        on = _code_states(chips, u + program.sync_length, program.chip_length)
        if program.repeat_after:
            on |= _code_states(chips, u - program.sweep_length - float(program.sync_gap), program.chip_length)
        state = np.where(on, SYNC, state)
    return state
