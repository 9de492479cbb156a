"""Sweep schedule files of several RISs in time division: ``[[ris]]`` tables, each RIS in its own slot.

A file with one ``[ris]`` table is the one-RIS form (:mod:`.schedule`); an array of ``[[ris]]``
tables names each RIS and gives its slot's ``first_frame``, or a ``[schedule]`` table places the
slots in time (``docs/formats.md`` "Several RISs"). The fields are read by :mod:`.schedule_fields`,
with the same one-line errors.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..._files import atomic_write_bytes
from ..._outputs import safe_name
from ...model.time_division import TimeDivision, parse_time_division
from ..errors import MeasuredFormatError, read_text_file
from .schedule import SweepSchedule, format_sweep_schedule, parse_sweep_schedule, schedule_document
from .schedule_fields import (RIS_KEYS, SWEEP_KEYS, TOP_KEYS, beam_angles, check_keys, frame_fields, read_int,
                              refuse_large_ris, ris_values, sync_fields, toml_table, toml_value, tolerance_fields,
                              truth_position)

__all__ = ["SweepSchedules", "format_sweep_schedules", "parse_sweep_schedules", "read_sweep_schedules",
           "write_sweep_schedules"]

_MULTI_TOP = TOP_KEYS + ("schedule",)
_MULTI_RIS = ("name", "first_frame") + RIS_KEYS
#: ``[schedule]`` keys that place the slots in time (refused when every ``[[ris]]`` gives its ``first_frame``).
_PLACING = ("start_ms", "gap_ms", "cycle_ms")


@dataclass(frozen=True)
class SweepSchedules:
    """The sweep schedule of a recording with one or several RISs (time division: one RIS sweeps per slot).

    A file with one ``[ris]`` table is the one-RIS form (:class:`SweepSchedule`); a file with an array
    of ``[[ris]]`` tables names each RIS and gives its slot (``docs/formats.md`` "Several RISs").

    Attributes
    ----------
    names : tuple of str
        The RISs, in file order (``("",)`` for the one-RIS form, whose ``[ris]`` has no name).
    schedules : tuple of SweepSchedule
        Each RIS's schedule (the shared sweep, frames per beam, channel and truth; its own RIS); its
        ``first_frame`` is the slot's first recorded frame, or None where ``[schedule]`` places it
        (:meth:`first_frames`).
    first_frame : int or None
        The top-level ``first_frame``: the first slot's first frame when ``[schedule]`` places the slots.
    division : dict or None
        The ``[schedule]`` table as given (keys of :data:`risloc_rt.model.time_division.SCHEDULE_KEYS`).
    several : bool
        The file uses ``[[ris]]`` tables (False: the one-RIS ``[ris]`` form).
    source : str
        The file, for messages (not compared).
    """

    names: tuple[str, ...]
    schedules: tuple[SweepSchedule, ...]
    first_frame: int | None = None
    division: dict[str, Any] | None = None
    several: bool = True
    source: str = field(default="<sweep schedule>", compare=False)

    @classmethod
    def single(cls, schedule: SweepSchedule, *, source: str = "<sweep schedule>") -> "SweepSchedules":
        """The one-RIS form of ``schedule`` (name ``""``).

        Parameters
        ----------
        schedule : SweepSchedule
            The one RIS's schedule.
        source : str
            The file, for messages.

        Returns
        -------
        SweepSchedules
        """
        return cls(names=("",), schedules=(schedule,), first_frame=schedule.first_frame, several=False,
                   source=source)

    def index(self, ris: int | str | None, *, where: str = "--ris") -> int:
        """The index of RIS ``ris`` (a name, or an index in file order); None: the only RIS.

        Parameters
        ----------
        ris : str, int or None
            The RIS's ``name`` in its ``[[ris]]`` table, or its index (0-based, file order).
        where : str
            What gave ``ris``, for the message.

        Returns
        -------
        int
        """
        if not self.several:
            if ris is None:
                return 0
            raise MeasuredFormatError(f"{where} {ris}: {self.source} describes one RIS in a [ris] table (no names); "
                                      f"leave out {where}")
        if ris is None:
            if len(self.names) == 1:
                return 0
            raise MeasuredFormatError(f"{self.source} describes {len(self.names)} RISs ({', '.join(self.names)}); "
                                      f"choose one with {where} NAME, or import them all")
        if isinstance(ris, str) and ris in self.names:
            return self.names.index(ris)
        text = str(ris)
        if text.isdigit() and int(text) < len(self.names):
            return int(text)
        raise MeasuredFormatError(f"{where} {ris}: {self.source} has no such RIS; it has {', '.join(self.names)} "
                                  f"(give a name or an index 0..{len(self.names) - 1})")

    def _slot_frames(self, frame_interval: float | None) -> float:
        """One slot's length [frames]: M × frames per beam (or × beam_dwell_ms / T_f)."""
        s = self.schedules[0]
        if s.frames_per_beam is not None:
            return float(s.num_beams * s.frames_per_beam)
        if frame_interval is None:
            raise MeasuredFormatError(f"{self.source}: beam_dwell_ms is on the RIS's clock; the radar's frame period "
                                      "(the configuration's frameCfg) is needed to place the slots in frames")
        return s.num_beams * s.beam_dwell_ms * 1e-3 / float(frame_interval)

    def time_division(self, frame_interval: float) -> TimeDivision:
        """The slots in time (:class:`risloc_rt.model.time_division.TimeDivision`), from the recording's first frame.

        Parameters
        ----------
        frame_interval : float
            The radar's frame period T_f [s].

        Returns
        -------
        TimeDivision
            Slot starts [s] after frame 0 (relative to the first slot when ``[schedule]`` places them).
        """
        tf = float(frame_interval)
        sweep = self._slot_frames(tf) * tf
        where = f"{self.source}: [schedule]"
        if self.schedules[0].first_frame is None or not self.several:
            return parse_time_division(self.division, ris_names=self.names, sweep_duration=sweep, where=where,
                                       error=MeasuredFormatError)
        table = dict(self.division or {})
        ordered = sorted(range(len(self.names)), key=lambda i: self.schedules[i].first_frame)
        starts = [self.schedules[i].first_frame * tf for i in ordered]
        table.update(order=[self.names[i] for i in ordered], start_ms=[s * 1e3 for s in starts])
        return parse_time_division(table, ris_names=self.names, sweep_duration=sweep, where=where,
                                   error=MeasuredFormatError)

    def first_frames(self, frame_interval: float | None = None) -> tuple[int, ...]:
        """Each RIS's first recorded frame (file order): as given, or placed by ``[schedule]``.

        Parameters
        ----------
        frame_interval : float, optional
            The radar's frame period T_f [s]; needed when ``[schedule]`` places the slots (its
            times are in milliseconds: slot k starts at ``first_frame + start_k / T_f``, a whole
            frame) or the dwell is in milliseconds.

        Returns
        -------
        tuple of int
        """
        given = [s.first_frame for s in self.schedules]
        if all(f is not None for f in given):
            if frame_interval is not None or self.schedules[0].frames_per_beam is not None:
                _check_slots(self.names, given, self._slot_frames(frame_interval), self.source)
            return tuple(int(f) for f in given)
        if frame_interval is None:
            raise MeasuredFormatError(f"{self.source}: [schedule] places the slots in milliseconds; the radar's frame "
                                      "period (the configuration's frameCfg) is needed to find their frames")
        td = self.time_division(frame_interval)
        out = []
        for name in self.names:
            start = self.first_frame + td.starts[td.order.index(name)] / float(frame_interval)
            if abs(start - round(start)) > 1e-6:
                raise MeasuredFormatError(
                    f"{self.source}: [schedule] starts RIS {name!r} at frame {start:.4g} (frame period "
                    f"{frame_interval * 1e3:g} ms), not on a whole frame; give start_ms and gap_ms in whole frames, or "
                    "each [[ris]] its first_frame")
            out.append(int(round(start)))
        return tuple(out)

    def schedule(self, ris: int | str | None = None, *, frame_interval: float | None = None,
                 where: str = "--ris") -> SweepSchedule:
        """One RIS's :class:`SweepSchedule`, its ``first_frame`` that of its slot.

        Parameters
        ----------
        ris : str, int or None
            As :meth:`index`.
        frame_interval : float, optional
            As :meth:`first_frames` [s].
        where : str
            What gave ``ris``, for messages.

        Returns
        -------
        SweepSchedule
        """
        i = self.index(ris, where=where)
        if not self.several:
            return self.schedules[0]
        return replace(self.schedules[i], first_frame=self.first_frames(frame_interval)[i])


def _check_slots(names: Any, firsts: Any, length: float, source: str) -> None:
    """Refuse overlapping slots: each lasts ``length`` frames from its first frame."""
    order = sorted(range(len(names)), key=lambda i: firsts[i])
    for a, b in zip(order, order[1:]):
        end = firsts[a] + length
        if firsts[b] < end - 1e-9:
            raise MeasuredFormatError(
                f"{source}: ris[{b}].first_frame = {firsts[b]}: the slot of {names[b]!r} overlaps that of {names[a]!r} "
                f"(frames {firsts[a]} to {math.ceil(end) - 1}, {length:g} frames); two RISs sweeping at once cannot be "
                f"told apart: start {names[b]!r} at frame {math.ceil(end)} or later")


def _multi_ris(doc: dict[str, Any], source: str) -> tuple[list[str], list[dict[str, Any]], list[int | None]]:
    """The ``[[ris]]`` tables: names, RIS fields, given first frames (None: placed by ``[schedule]``)."""
    tables = doc["ris"]
    if not tables or not all(isinstance(t, dict) for t in tables):
        raise MeasuredFormatError(f"{source}: ris must be [[ris]] tables, one per RIS, each with a name")
    names: list[str] = []
    fields: list[dict[str, Any]] = []
    firsts: list[int | None] = []
    for i, table in enumerate(tables):
        prefix = f"ris[{i}]."
        check_keys(table, _MULTI_RIS, source, prefix)
        name = table.get("name")
        if not isinstance(name, str) or not name or safe_name(name) != name:
            raise MeasuredFormatError(f"{source}: {prefix}name = {name!r} must be the RIS's name, a plain word such "
                                      "as \"ris1\" (it names its capture file on import)")
        if name in names:
            raise MeasuredFormatError(f"{source}: {prefix}name = {name!r} is the name of ris[{names.index(name)}] too; "
                                      "give each RIS its own name")
        names.append(name)
        fields.append(ris_values(table, source, prefix))
        first = table.get("first_frame")
        if first == "auto":
            raise MeasuredFormatError(f"{source}: {prefix}first_frame = \"auto\": with several RISs each slot's first "
                                      "frame is given (the sweeps look alike to the aligner); give the frame index")
        firsts.append(None if first is None else read_int(first, source, prefix + "first_frame", minimum=0,
                                                      fix="give the slot's first recorded frame (0-based)"))
    return names, fields, firsts


def _division_table(doc: dict[str, Any], names: list[str], firsts: list[int | None],
                    source: str) -> dict[str, Any] | None:
    """The ``[schedule]`` table, checked against the ``[[ris]]`` tables (its timing is checked on use)."""
    table = toml_table(doc, "schedule", source, required=False)
    given = [f is not None for f in firsts]
    if any(given) and not all(given):
        missing = names[given.index(False)]
        raise MeasuredFormatError(f"{source}: some [[ris]] tables give first_frame and {missing!r} does not; give "
                                  "every RIS its first_frame, or none (then [schedule] places the slots)")
    if table is None:
        if not all(given):
            raise MeasuredFormatError(f"{source}: ris[0].first_frame is missing; give each [[ris]] its slot's first "
                                      "frame, or add a [schedule] table (and a top-level first_frame) to place them")
        return None
    where = f"{source}: [schedule]"
    order = table.get("order", names)
    for name in order if isinstance(order, list) else ():
        if name not in names:
            raise MeasuredFormatError(f"{where}: order names RIS {name!r}, which has no [[ris]] table; add one (name, "
                                      f"position, facing, loopback_delay_ns) or use one of {', '.join(names)}")
    try:                                   # keys, names, idle, parked_deg now; the slots' timing once T_f is known
        parse_time_division(table, ris_names=names, sweep_duration=1e-9, where=where, error=MeasuredFormatError)
    except MeasuredFormatError as exc:
        if "overlap" not in str(exc) and "cycle" not in str(exc):
            raise
        raise MeasuredFormatError(f"{where}: start_ms = {table.get('start_ms')!r} and cycle_ms must increase, one "
                                  "start per RIS of order, the cycle after the last") from None
    left = [n for n in names if n not in order]
    if left:
        raise MeasuredFormatError(f"{where}: order leaves out RIS {left[0]!r}, which has a [[ris]] table; add it to "
                                  "order (each RIS of the recording sweeps in one slot)")
    if all(given):
        placing = [k for k in _PLACING if k in table]
        if placing:
            raise MeasuredFormatError(f"{where}: {placing[0]} and each [[ris]] first_frame both place the slots; keep "
                                      "one (with first_frame, [schedule] only says order, idle and parked_deg)")
        by_frame = sorted(names, key=lambda n: firsts[names.index(n)])
        if "order" in table and list(order) != by_frame:
            raise MeasuredFormatError(f"{where}: order = {list(order)} but the first frames put the slots in the order "
                                      f"{by_frame}; make them agree")
    elif "first_frame" not in doc:
        raise MeasuredFormatError(f"{source}: first_frame is missing; [schedule] places the slots from it: add the "
                                  "first slot's first frame, e.g. first_frame = 0")
    return dict(table)


def parse_sweep_schedules(text: str, *, source: str = "<sweep schedule>") -> SweepSchedules:
    """Parse a sweep schedule of one or several RISs (``docs/formats.md`` "Several RISs").

    Parameters
    ----------
    text : str
        The file's content (TOML): one ``[ris]`` table (:func:`parse_sweep_schedule`), or ``[[ris]]``
        tables, each with ``name``, the ``[ris]`` keys and its slot's ``first_frame``, and an
        optional ``[schedule]`` table (:mod:`risloc_rt.model.time_division`).
    source : str
        The name the messages give (the file's path).

    Returns
    -------
    SweepSchedules
        Angles [deg], positions [m], τ_RB [ns], frame counts, as in the file.

    Raises
    ------
    MeasuredFormatError
        As :func:`parse_sweep_schedule`; also a duplicate RIS name, overlapping slots, a
        ``[schedule]`` naming a RIS without a ``[[ris]]`` table, ``"auto"`` or ``[sync]`` with several RISs.
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MeasuredFormatError(f"{source}: not valid TOML ({exc}); check quotes, brackets and '=' signs") from None
    if not isinstance(doc.get("ris"), list):
        return SweepSchedules.single(parse_sweep_schedule(text, source=source), source=source)
    check_keys(doc, _MULTI_TOP, source, "")
    if "sync" in doc:
        raise MeasuredFormatError(f"{source}: [sync] is for a one-RIS recording; with several [[ris]] give each slot's "
                                  "first_frame (or a [schedule])")
    if doc.get("first_frame") == "auto":
        raise MeasuredFormatError(f"{source}: first_frame = \"auto\" is for a one-RIS recording; with several [[ris]] "
                                  "give the slots' first frames")
    names, ris_fields, firsts = _multi_ris(doc, source)
    division = _division_table(doc, names, firsts, source)
    frames = frame_fields({**doc, "first_frame": doc.get("first_frame", 0)}, source)
    top_first = frames["first_frame"] if "first_frame" in doc else None
    sweep = toml_table(doc, "sweep", source, required=True)
    check_keys(sweep, SWEEP_KEYS, source, "sweep.")
    angles, grid = beam_angles(sweep, source)
    for i, ris in enumerate(ris_fields):
        refuse_large_ris(len(angles), ris["ris_rows"], ris["ris_columns"], f"{source}: ris[{i}]")
    shared = {**frames, **sync_fields(doc, source), **tolerance_fields(doc, source)}
    truth = truth_position(doc, source)
    schedules = tuple(SweepSchedule(angles_deg=angles, grid=grid, truth_ue_position=truth,
                                    **{**shared, "first_frame": first}, **ris)
                      for ris, first in zip(ris_fields, firsts))
    out = SweepSchedules(names=tuple(names), schedules=schedules, first_frame=top_first, division=division,
                         source=source)
    if all(f is not None for f in firsts) and schedules[0].frames_per_beam is not None:
        out.first_frames()                                        # overlapping slots: refused now
    return out


def read_sweep_schedules(path: str | Path) -> SweepSchedules:
    """Read a sweep schedule file of one or several RISs (:func:`parse_sweep_schedules`).

    Parameters
    ----------
    path : path
        The ``sweep.toml``.

    Returns
    -------
    SweepSchedules
    """
    path = Path(path)
    text = read_text_file(path, "sweep schedule",
                          'give the .toml written with the recording (docs/formats.md, "Sweep schedule files")')
    return parse_sweep_schedules(text, source=str(path))


def format_sweep_schedules(schedules: SweepSchedules, *, comment: str | None = None) -> str:
    """The TOML text of ``schedules``; ``parse_sweep_schedules(format_sweep_schedules(s)) == s``.

    Parameters
    ----------
    schedules : SweepSchedules
    comment : str, optional
        Lines written first, each after ``#``.

    Returns
    -------
    str
    """
    if not schedules.several:
        return format_sweep_schedule(schedules.schedules[0], comment=comment)
    doc = schedule_document(schedules.schedules[0])
    doc.pop("first_frame")
    if schedules.first_frame is not None:
        doc["first_frame"] = schedules.first_frame
    lines = [f"# {line}" for line in (comment or "risloc sweep schedule, several RISs (docs/formats.md)").splitlines()]
    for key in ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift"):
        if key in doc:
            lines.append(f"{key} = {toml_value(doc[key])}")
    tables = {"sweep": doc["sweep"], "schedule": schedules.division, "truth": doc.get("truth"),
              "tolerance": doc.get("tolerance")}
    for name, table in tables.items():
        if table:
            lines += ["", f"[{name}]"] + [f"{k} = {toml_value(v)}" for k, v in table.items()]
    for name, s in zip(schedules.names, schedules.schedules):
        ris = {"name": name, **({} if s.first_frame is None else {"first_frame": s.first_frame}),
               **schedule_document(s)["ris"]}
        lines += ["", "[[ris]]"] + [f"{k} = {toml_value(v)}" for k, v in ris.items()]
    return "\n".join(lines) + "\n"


def write_sweep_schedules(schedules: SweepSchedules, path: str | Path, *, comment: str | None = None) -> Path:
    """Write :func:`format_sweep_schedules` to ``path`` atomically.

    Parameters
    ----------
    schedules : SweepSchedules
    path : path
        The ``.toml`` to write (replaced when it exists).
    comment : str, optional
        As :func:`format_sweep_schedules`.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_bytes(path, format_sweep_schedules(schedules, comment=comment).encode("utf-8"))
