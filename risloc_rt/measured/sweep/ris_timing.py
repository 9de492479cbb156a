"""The RIS's program in radar time: on/off sync frames, then one dwell per beam, on the RIS's own clock.

A measured sweep is two free-running devices: the radar records frames at its frame interval,
the RIS controller runs its program on its own clock. In **nominal frames** (radar frames as the
experimenter planned them) the program is::

    sync:  cycles x (on_frames RIS on at the sync beam, off_frames RIS off)
    gap:   gap_frames RIS off
    sweep: beam 0 for frames_per_beam, beam 1 for frames_per_beam, ..., beam M-1
    then:  RIS off

In radar time the program starts somewhere in the recording and every nominal duration is
stretched by the RIS clock's rate against the radar's: a beam lasts ``dwell = frames_per_beam ·
(1 + drift)`` radar frames (not necessarily a whole number). ``start`` is the radar time of the
first beam's switch-on [frames from the recording's first frame]. The sync pattern sits
``sync_length · (1 + drift)`` frames before it. :func:`chirp_states` evaluates the program at
chirp times; the emulator (:mod:`..emulate.recording`) synthesises with it and the aligner
(:mod:`.alignment`) fits it, so both share one definition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeasuredFormatError

__all__ = ["OFF", "SYNC", "RisProgram", "chirp_fractions", "chirp_states"]

OFF = -1
"""State code: the RIS does not re-transmit (amplifier off)."""
SYNC = -2
"""State code: the RIS re-transmits at its sync beam (the on half of a sync cycle)."""


@dataclass(frozen=True)
class RisProgram:
    """What the RIS controller runs, in nominal frames (see the module docstring).

    Parameters
    ----------
    num_beams : int
        M, beams of the sweep.
    frames_per_beam : int
        Nominal frames per beam (>= 1).
    sync_on, sync_off, sync_cycles, sync_gap : int
        Sync pattern before the sweep: ``sync_cycles`` × (``sync_on`` on, ``sync_off`` off), then
        ``sync_gap`` off frames [nominal frames]; all 0: no sync pattern.
    """

    num_beams: int
    frames_per_beam: int
    sync_on: int = 0
    sync_off: int = 0
    sync_cycles: int = 0
    sync_gap: int = 0

    def __post_init__(self) -> None:
        for name in ("num_beams", "frames_per_beam"):
            if int(getattr(self, name)) < 1:
                raise MeasuredFormatError(f"{name}={getattr(self, name)} must be >= 1")
        for name in ("sync_on", "sync_off", "sync_cycles", "sync_gap"):
            if int(getattr(self, name)) < 0:
                raise MeasuredFormatError(f"{name}={getattr(self, name)} must be >= 0")
        if self.sync_cycles and not self.sync_on:
            raise MeasuredFormatError(f"sync_cycles={self.sync_cycles} needs sync_on >= 1 (frames the RIS is on)")

    @property
    def has_sync(self) -> bool:
        """The program starts with on/off sync cycles."""
        return self.sync_cycles > 0 and self.sync_on > 0

    @property
    def sync_length(self) -> int:
        """Nominal frames from the sync's start to the sweep's start: cycles·(on + off) + gap."""
        return self.sync_cycles * (self.sync_on + self.sync_off) + self.sync_gap

    @property
    def sweep_length(self) -> int:
        """Nominal frames of the sweep: M · frames_per_beam."""
        return self.num_beams * self.frames_per_beam


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
    """
    t = np.asarray(times, float)
    rate = np.asarray(dwell, float) / program.frames_per_beam        # radar frames per nominal frame
    u = (t - np.asarray(start, float)) / rate                        # nominal frames from the sweep start
    beam = np.floor(u / program.frames_per_beam)
    state = np.where((u >= 0) & (beam < program.num_beams), beam, OFF).astype(np.int64)
    if program.has_sync:
        v = u + program.sync_length                                  # nominal frames from the sync start
        period = program.sync_on + program.sync_off
        in_sync = (v >= 0) & (v < program.sync_cycles * period)
        on = in_sync & (np.mod(v, period) < program.sync_on)
        state = np.where(on, SYNC, state)
    return state
