"""When each RIS of a hall sweeps: a time-division schedule of slots, one RIS sweeping per slot.

With several RISs in one hall, their sweeps must not overlap: the radar cannot tell two
beam-dependent returns of two sweeping RISs apart by their modulation. risloc-rt models time
division (``docs/ray-tracing.md`` "Several RISs"): in slot k the RIS ``order[k]`` sweeps its M
beams while the others are idle — ``"off"`` (a relay's amplifier off: only its panel's structural
echo remains) or ``"parked"`` (it holds one beam: its loop-back is a static echo); a reflective
RIS cannot be switched off and always holds its parked beam. Slot k of cycle c starts at

    t(c, k) = c · T_cycle + s_k,   s_k = k · (T_sweep + T_gap) by default, or as given,

with ``T_sweep = M · beam_interval`` and ``T_cycle`` the end of the last slot plus one gap. Each
slot's measurement refers to the middle of its sweep (``model.motion.sweep_reference_time``).

The TOML form (a ``[schedule]`` table, the same in a sweep schedule file and a ``--schedule``
file; ``docs/formats.md`` "Several RISs")::

    [schedule]
    order = ["ris0", "ris1"]     # RIS names in slot order (default: every RIS of the scene)
    gap_ms = 0.0                 # idle time between slots [ms]
    idle = "off"                 # or "parked"
    parked_deg = [0.0, 0.0]      # the beam a parked RIS holds [az, el] [deg]
    start_ms = [0.0, 400.0]      # optional: each slot's start within the cycle [ms]
    cycle_ms = 800.0             # optional: the cycle (default: last slot's end + gap)
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["TimeDivision", "SCHEDULE_KEYS", "parse_time_division"]

#: The keys of a ``[schedule]`` table.
SCHEDULE_KEYS = ("order", "gap_ms", "idle", "parked_deg", "start_ms", "cycle_ms")
_IDLE = ("off", "parked")


@dataclass(frozen=True)
class TimeDivision:
    """A time-division schedule: which RIS sweeps in which slot, and when.

    Attributes
    ----------
    order : tuple of str
        RIS names in slot order (each once).
    sweep_duration : float
        T_sweep, one slot's sweep: M beams × the radar's beam interval [s].
    starts : tuple of float
        s_k, each slot's start within the cycle [s] (increasing, ≥ 0).
    cycle : float
        T_cycle, the time after which the slots repeat [s] (≥ the last slot's end).
    idle : {"off", "parked"}
        What the other RISs do during a slot.
    parked_beam : float array [2]
        ``[az, el]`` a parked RIS holds, its own frame [rad].
    """

    order: tuple[str, ...]
    sweep_duration: float
    starts: tuple[float, ...]
    cycle: float
    idle: str = "off"
    parked_beam: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        order = tuple(str(x) for x in self.order)
        if not order:
            raise ValueError("a schedule needs at least one RIS in its order")
        if len(set(order)) != len(order):
            raise ValueError(f"order {list(order)} names a RIS twice; each RIS sweeps in one slot per cycle")
        t = float(self.sweep_duration)
        if not math.isfinite(t) or t <= 0:
            raise ValueError(f"sweep_duration={self.sweep_duration!r} must be a positive number of seconds")
        starts = tuple(float(s) for s in self.starts)
        if len(starts) != len(order):
            raise ValueError(f"starts has {len(starts)} entries for {len(order)} slots; give one start per RIS of order")
        if any(not math.isfinite(s) or s < 0 for s in starts):
            raise ValueError(f"slot starts {list(starts)} s must be finite and >= 0")
        for k in range(1, len(starts)):
            if starts[k] < starts[k - 1] + t * (1 - 1e-12):
                raise ValueError(
                    f"the slots of {order[k - 1]} [{starts[k - 1] * 1e3:g}, {(starts[k - 1] + t) * 1e3:g}) ms and "
                    f"{order[k]} [{starts[k] * 1e3:g}, {(starts[k] + t) * 1e3:g}) ms overlap (a sweep lasts "
                    f"{t * 1e3:g} ms): two RISs sweeping at once cannot be told apart; start each slot after the "
                    "previous one ends")
        cycle = float(self.cycle)
        if not math.isfinite(cycle) or cycle < starts[-1] + t * (1 - 1e-12):
            raise ValueError(f"cycle={cycle * 1e3:g} ms ends before the last slot ({order[-1]}) does at "
                             f"{(starts[-1] + t) * 1e3:g} ms; make the cycle at least that long")
        if self.idle not in _IDLE:
            raise ValueError(f"idle={self.idle!r} must be one of {_IDLE} (what the other RISs do during a slot)")
        beam = tuple(float(x) for x in self.parked_beam)
        if len(beam) != 2 or not all(math.isfinite(x) and abs(x) <= math.pi / 2 for x in beam):
            raise ValueError(f"parked_beam={list(beam)} must be [az, el] within ±90° of broadside [rad]")
        object.__setattr__(self, "order", order)
        object.__setattr__(self, "sweep_duration", t)
        object.__setattr__(self, "starts", starts)
        object.__setattr__(self, "cycle", cycle)
        object.__setattr__(self, "parked_beam", beam)

    @classmethod
    def consecutive(cls, order: Any, sweep_duration: float, *, gap: float = 0.0, idle: str = "off",
                    parked_beam: Any = (0.0, 0.0)) -> "TimeDivision":
        """Slots one after another, ``gap`` [s] between them and before the next cycle.

        Parameters
        ----------
        order : sequence of str
            RIS names in slot order.
        sweep_duration : float
            T_sweep [s].
        gap : float
            T_gap ≥ 0 [s].
        idle, parked_beam
            As the attributes.

        Returns
        -------
        TimeDivision
        """
        gap = float(gap)
        if not math.isfinite(gap) or gap < 0:
            raise ValueError(f"gap={gap!r} must be a non-negative number of seconds")
        order = tuple(order)
        starts = tuple(k * (float(sweep_duration) + gap) for k in range(len(order)))
        return cls(order=order, sweep_duration=sweep_duration, starts=starts,
                   cycle=len(order) * (float(sweep_duration) + gap), idle=idle, parked_beam=tuple(parked_beam))

    @property
    def num_slots(self) -> int:
        """Slots per cycle (one per RIS)."""
        return len(self.order)

    def slot_start(self, index: int) -> float:
        """Start of the ``index``-th slot from the schedule's start, counting on across cycles [s].

        Parameters
        ----------
        index : int
            0, 1, ...: slot ``index % num_slots`` of cycle ``index // num_slots``.

        Returns
        -------
        float
        """
        cycle, slot = divmod(int(index), self.num_slots)
        return cycle * self.cycle + self.starts[slot]

    def ris_of(self, index: int) -> str:
        """The RIS that sweeps in the ``index``-th slot (counting on across cycles).

        Parameters
        ----------
        index : int
            0, 1, ...

        Returns
        -------
        str
            Its name.
        """
        return self.order[int(index) % self.num_slots]

    def count_until(self, end: float) -> int:
        """How many slots' sweeps end by ``end`` (from the schedule's start): :meth:`slots_until`'s length,
        in closed form (no list of a long walk's slots is built to count them).

        Parameters
        ----------
        end : float
            The time [s].

        Returns
        -------
        int
        """
        if not math.isfinite(end) or end < self.sweep_duration:
            return 0
        limit = end * (1 + 1e-12)

        def ends_by(k: int) -> bool:
            return self.slot_start(k) + self.sweep_duration <= limit

        # slot starts increase with the index, so the slots that end by ``end`` are 0 … S − 1
        cycles = max(int((limit - self.sweep_duration) // self.cycle) - 1, 0)
        count = cycles * self.num_slots
        while ends_by(count):
            count += 1
        while count > 0 and not ends_by(count - 1):
            count -= 1
        return count

    def slots_until(self, end: float) -> np.ndarray:
        """Indices of every slot whose sweep ends by ``end`` (from the schedule's start).

        Parameters
        ----------
        end : float
            The time [s].

        Returns
        -------
        int array [S]
            0, 1, ..., S − 1 (empty when no sweep has ended; S = :meth:`count_until`).
        """
        return np.arange(self.count_until(end), dtype=int)

    def to_dict(self) -> dict[str, Any]:
        """The ``[schedule]`` table of this schedule (ms and degrees, as in the file).

        Returns
        -------
        dict
            ``order``, ``idle``, ``parked_deg``, ``start_ms``, ``cycle_ms``: :func:`parse_time_division`
            reads it back to an equal schedule.
        """
        return {"order": list(self.order), "idle": self.idle,
                "parked_deg": [float(np.rad2deg(x)) for x in self.parked_beam],
                "start_ms": [s * 1e3 for s in self.starts], "cycle_ms": self.cycle * 1e3}


def parse_time_division(table: Any, *, ris_names: Any, sweep_duration: float, where: str = "[schedule]",
                        error: type[Exception] = ValueError) -> TimeDivision:
    """A ``[schedule]`` table (module notes) → :class:`TimeDivision`, every bad value one line.

    Parameters
    ----------
    table : dict or None
        The parsed table; None or ``{}``: every RIS in ``ris_names`` order, back to back, idle off.
    ris_names : sequence of str
        The RISs the scene (or recording) has.
    sweep_duration : float
        T_sweep [s] of the radar and sweep in use.
    where : str
        The file and table, for the messages.
    error : type
        The exception raised (a package's format error).

    Returns
    -------
    TimeDivision
    """
    names = [str(n) for n in ris_names]
    table = {} if table is None else table
    if not isinstance(table, dict):
        raise error(f"{where} must be a table, e.g. [schedule] order = {names!r}")
    for key in table:
        if key not in SCHEDULE_KEYS:
            near = difflib.get_close_matches(str(key), SCHEDULE_KEYS, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else f"; the keys are {', '.join(SCHEDULE_KEYS)}"
            raise error(f"{where}: unknown key {key!r}{hint}")

    def number(key: str, default: float, *, minimum: float = 0.0) -> float:
        value = table.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < minimum:
            raise error(f"{where}: {key} = {value!r} must be a number >= {minimum:g}")
        return float(value)

    order = table.get("order", names)
    if not isinstance(order, list) or not order or not all(isinstance(x, str) for x in order):
        raise error(f"{where}: order = {order!r} must be a non-empty list of RIS names, e.g. {names!r}")
    for name in order:
        if name not in names:
            raise error(f"{where}: order names RIS {name!r}, which the scene does not have; it has "
                        f"{', '.join(names) or 'none'}")
    if len(set(order)) != len(order):
        raise error(f"{where}: order = {order!r} names a RIS twice; each RIS sweeps once per cycle")
    idle = table.get("idle", "off")
    if idle not in _IDLE:
        raise error(f"{where}: idle = {idle!r} must be \"off\" (a relay's amplifier off) or \"parked\" (holds a beam)")
    parked = table.get("parked_deg", [0.0, 0.0])
    if (not isinstance(parked, list) or len(parked) != 2 or not all(isinstance(x, (int, float)) and not
                                                                     isinstance(x, bool) and math.isfinite(x)
                                                                     and abs(x) <= 90 for x in parked)):
        raise error(f"{where}: parked_deg = {parked!r} must be [az, el] in degrees within ±90")
    gap = number("gap_ms", 0.0) * 1e-3
    try:
        if "start_ms" in table:
            starts = table["start_ms"]
            if not isinstance(starts, list) or len(starts) != len(order):
                raise error(f"{where}: start_ms = {starts!r} must list one start per RIS of order ({len(order)})")
            starts_s = []
            for i, s in enumerate(starts):
                if isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or s < 0:
                    raise error(f"{where}: start_ms[{i}] = {s!r} must be a number >= 0 [ms]")
                starts_s.append(float(s) * 1e-3)
            cycle = number("cycle_ms", 0.0) * 1e-3 if "cycle_ms" in table else starts_s[-1] + sweep_duration + gap
            return TimeDivision(order=tuple(order), sweep_duration=sweep_duration, starts=tuple(starts_s), cycle=cycle,
                                idle=idle, parked_beam=tuple(np.deg2rad(parked)))
        schedule = TimeDivision.consecutive(order, sweep_duration, gap=gap, idle=idle,
                                            parked_beam=tuple(np.deg2rad(parked)))
        if "cycle_ms" in table:
            schedule = TimeDivision(order=schedule.order, sweep_duration=sweep_duration, starts=schedule.starts,
                                    cycle=number("cycle_ms", 0.0) * 1e-3, idle=idle, parked_beam=schedule.parked_beam)
        return schedule
    except ValueError as exc:
        if str(exc).startswith(where):  # already one of ours
            raise
        raise error(f"{where}: {exc}") from None
