"""Sweep schedule files of one RIS: which recorded frames belong to which beam, and the RIS the DSP needs.

Several RISs in time division (``[[ris]]`` tables): :mod:`.schedules`; the TOML fields both read:
:mod:`.schedule_fields`.

A measured RIS sweep is a plain DCA1000 recording; the radar does not know the RIS's beam. The
schedule (TOML, ``docs/formats.md`` "Sweep schedule files") says where the sweep starts in the
recording, how many frames each beam lasts, the beam angles, the virtual channel to localize
with, the RIS pose and hardware, and optionally the truth::

    frames_per_beam = 1          # or the RIS's own time per beam: beam_dwell_ms = 25.0
    first_frame = 0              # or "auto"; also channel = 0, max_clock_drift = 0.02
    [sweep]                      # also elevation_deg, or angles_deg = [[az, el], ...]
    start_deg = -45.0
    stop_deg = 45.0
    step_deg = 1.5
    [ris]
    position = [0.0, 13.38, 0.0]
    facing = [0.0, 0.0, 0.0]
    loopback_delay_ns = 1.78     # and mode = "relay", rows = 16, columns = 4 ...
    [sync]                       # optional; also off_frames, cycles, gap_frames
    on_frames = 5                # or pattern = "1111100110101", chip_ms = 20.0, gap_ms, repeat_after
    [truth]                      # optional
    ue_position = [0.0, 0.0, 0.0]

Every bad value raises a one-line :class:`MeasuredFormatError` naming the file, the key and
the fix; unknown keys are refused with a did-you-mean. Sizes are checked against the memory limit
(``$RISLOC_MEMORY_LIMIT``, :func:`dsp.budget.check_memory`) before anything of that size exists:
the beams of an azimuth grid (:data:`risloc_rt.measured.sweep.schedule_fields.BEAM_BYTES` each) and
the RIS's elements × beams (:func:`risloc_rt.measured.sweep.schedule_fields.ris_memory`); a
:class:`dsp.budget.BudgetError` names the key, the estimate and the limit.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..._files import atomic_write_bytes
from ..errors import MeasuredFormatError, read_text_file
from .ris_timing import RisProgram
from .schedule_fields import (SWEEP_KEYS, TOLERANCE_KEYS, TOP_KEYS, beam_angles, check_keys,
                              frame_fields, refuse_large_ris, ris_fields, ris_memory, sync_fields, tolerance_fields,
                              toml_table, toml_value, truth_position)

__all__ = ["SweepSchedule", "format_sweep_schedule", "parse_sweep_schedule", "read_sweep_schedule", "ris_memory",
           "schedule_document", "write_sweep_schedule"]


@dataclass(frozen=True)
class SweepSchedule:
    """A parsed sweep schedule (degrees and metres, as in the file).

    Attributes
    ----------
    angles_deg : tuple of (az, el)
        RIS beam of each of the M sweep steps, RIS frame [deg].
    frames_per_beam : int or None
        Recorded frames per beam (>= 1); None when ``beam_dwell_ms`` gives the RIS's own time.
    first_frame : int or None
        Index of the sweep's first frame in the recording; ``None`` is ``"auto"`` (found on import,
        :mod:`.alignment`).
    channel : int
        Virtual channel used for localization.
    ris_position, ris_facing : tuple of 3 floats
        RIS centre and the point its broadside faces, world frame [m].
    loopback_delay_ns : float
        τ_RB [ns].
    ris_mode : {"relay", "reflective"}
    ris_rows, ris_columns : int
    ris_element_spacing : float or None
        Element pitch [m]; None: λ/2 at 60 GHz (``RisConfig``'s default).
    relay_rx_angle_deg : tuple of 2 floats
        Fixed relay Rx beam [az, el] [deg].
    yaw_deg : float
        Extra panel rotation about world up [deg] (``dsp.RisPose.facing``'s yaw).
    grid : tuple (start, stop, step, elevation) or None
        The azimuth grid the angles came from (kept so that the file can be written back the same way).
    truth_ue_position : tuple of 3 floats or None
    sync_on_frames, sync_off_frames, sync_cycles, sync_gap_frames : int
        The RIS's on/off sync pattern before the sweep (``[sync]``; 0: none), nominal frames.
    max_clock_drift : float
        Largest RIS clock rate error ``first_frame = "auto"`` searches (default 0.02 = 2 %).
    beam_dwell_ms : float or None
        The RIS's own time per beam [ms] (instead of ``frames_per_beam``).
    sync_pattern : str
        The sync code, one chip a character ('1' on at the sync beam, '0' off); '' without.
    sync_chip_ms : float or None
        One chip of ``sync_pattern`` on the RIS's clock [ms].
    sync_gap_ms : float or None
        RIS off between the code and the sweep [ms] (instead of ``sync_gap_frames``).
    sync_repeat_after : bool
        The sync code is sent again after the sweep (after the same gap).
    tolerance_position_m, tolerance_yaw_deg, tolerance_element_spacing : float or None
        ``[tolerance]``: 1σ of each RIS coordinate [m], of its yaw [deg] and, relative, of its element
        pitch [-]; None when not stated (the uncertainty budget then lists them as unknown).
    """

    angles_deg: tuple[tuple[float, float], ...]
    frames_per_beam: int | None
    first_frame: int | None
    ris_position: tuple[float, float, float]
    ris_facing: tuple[float, float, float]
    loopback_delay_ns: float
    ris_mode: str = "relay"
    ris_rows: int = 16
    ris_columns: int = 4
    channel: int = 0
    ris_element_spacing: float | None = None
    relay_rx_angle_deg: tuple[float, float] = (0.0, 0.0)
    yaw_deg: float = 0.0
    grid: tuple[float, float, float, float] | None = None
    truth_ue_position: tuple[float, float, float] | None = None
    sync_on_frames: int = 0
    sync_off_frames: int = 0
    sync_cycles: int = 0
    sync_gap_frames: int = 0
    max_clock_drift: float = 0.02
    beam_dwell_ms: float | None = None
    sync_pattern: str = ""
    sync_chip_ms: float | None = None
    sync_gap_ms: float | None = None
    sync_repeat_after: bool = False
    tolerance_position_m: float | None = None
    tolerance_yaw_deg: float | None = None
    tolerance_element_spacing: float | None = None

    def __post_init__(self) -> None:
        if (self.frames_per_beam is None) == (self.beam_dwell_ms is None):
            raise MeasuredFormatError("give exactly one of frames_per_beam (recorded frames per beam) and "
                                      "beam_dwell_ms (the RIS's own time per beam)")
        if bool(self.sync_pattern) != (self.sync_chip_ms is not None):
            raise MeasuredFormatError("sync.pattern and sync.chip_ms go together (the code and one chip's duration)")
        if self.sync_pattern and (self.sync_on_frames or self.sync_off_frames or self.sync_cycles):
            raise MeasuredFormatError("give the sync as sync.pattern or as sync.on_frames/off_frames/cycles, not both")
        if self.sync_gap_ms is not None and self.sync_gap_frames:
            raise MeasuredFormatError("give sync.gap_frames or sync.gap_ms, not both")

    @property
    def uses_ris_clock(self) -> bool:
        """Some duration is on the RIS's own clock [ms] (the radar's frame period converts it)."""
        return self.beam_dwell_ms is not None or self.sync_chip_ms is not None or self.sync_gap_ms is not None

    def program(self, frame_interval: float | None = None) -> RisProgram:
        """The RIS's program (sync code, gap, beams) in nominal frames (:class:`.ris_timing.RisProgram`).

        Parameters
        ----------
        frame_interval : float, optional
            The radar's frame period T_f [s] (``TiChirpConfig.frame_periodicity``); needed when a
            duration is in milliseconds (``beam_dwell_ms``, ``sync.chip_ms``, ``sync.gap_ms``):
            ``x_ms·1e-3 / T_f`` nominal frames.

        Returns
        -------
        RisProgram
        """
        if self.uses_ris_clock and frame_interval is None:
            raise MeasuredFormatError("the sweep schedule gives the RIS's timing in milliseconds; the radar's frame "
                                      "period (the configuration's frameCfg) is needed to place it in frames")
        tf = 1.0 if frame_interval is None else float(frame_interval)
        if not tf > 0:
            raise MeasuredFormatError(f"frame_interval={frame_interval!r} must be > 0 [s]; check the configuration's "
                                      "frame periodicity")
        fpb = self.frames_per_beam if self.beam_dwell_ms is None else self.beam_dwell_ms * 1e-3 / tf
        gap = self.sync_gap_frames if self.sync_gap_ms is None else self.sync_gap_ms * 1e-3 / tf
        return RisProgram(num_beams=self.num_beams, frames_per_beam=fpb, sync_on=self.sync_on_frames,
                          sync_off=self.sync_off_frames, sync_cycles=self.sync_cycles, sync_gap=gap,
                          sync_pattern=self.sync_pattern,
                          chip_frames=1.0 if self.sync_chip_ms is None else self.sync_chip_ms * 1e-3 / tf,
                          repeat_after=self.sync_repeat_after)

    @classmethod
    def azimuth(cls, start_deg: float, stop_deg: float, step_deg: float, *, elevation_deg: float = 0.0,
                **fields: Any) -> "SweepSchedule":
        """A schedule of an azimuth grid (checked as the parser checks it); ``fields`` are the other attributes."""
        angles, grid = beam_angles({"start_deg": start_deg, "stop_deg": stop_deg, "step_deg": step_deg,
                                "elevation_deg": elevation_deg}, "SweepSchedule.azimuth")
        return cls(angles_deg=angles, grid=grid, **fields)

    @property
    def num_beams(self) -> int:
        """M, the number of beams of the sweep."""
        return len(self.angles_deg)

    def frame_indices(self) -> np.ndarray:
        """Recorded frame of each beam: ``first_frame + m·frames_per_beam``.

        Returns
        -------
        int64 array [M]
        """
        if self.first_frame is None:
            raise MeasuredFormatError(
                "first_frame = \"auto\" is found from the recording on import (import_capture); give the first sweep "
                "frame, e.g. first_frame = 0, to list the frames without the recording")
        if self.frames_per_beam is None:
            raise MeasuredFormatError(
                "with beam_dwell_ms the frames of each beam depend on the radar's frame period; import_capture lists "
                "them (the capture's frame_index and provenance)")
        return self.first_frame + self.frames_per_beam * np.arange(self.num_beams, dtype=np.int64)

    @property
    def frames_needed(self) -> int:
        """Frames the recording must hold: ``first_frame + (M − 1)·frames_per_beam + 1``."""
        return int(self.frame_indices()[-1]) + 1

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary in the file's own layout (for provenance).

        Returns
        -------
        dict
            Degrees, metres and nanoseconds, as in the file.
        """
        return schedule_document(self)


# ---------------------------------------------------------------------------------------------- parse

def parse_sweep_schedule(text: str, *, source: str = "<sweep schedule>") -> SweepSchedule:
    """Parse the TOML text of a sweep schedule (see the module docstring).

    Parameters
    ----------
    text : str
        The file's content (TOML).
    source : str
        The name the messages give (the file's path).

    Returns
    -------
    SweepSchedule
        Angles [deg], positions [m], τ_RB [ns], frame counts, as in the file.

    Raises
    ------
    MeasuredFormatError
        Invalid TOML, an unknown or missing key, or a bad value; the message names the key and the fix.
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MeasuredFormatError(f"{source}: not valid TOML ({exc}); check quotes, brackets and '=' signs") from None
    if isinstance(doc.get("ris"), list):
        names = [t.get("name", "?") if isinstance(t, dict) else "?" for t in doc["ris"]]
        raise MeasuredFormatError(
            f"{source}: describes {len(names)} RIS(s) in [[ris]] tables ({', '.join(map(str, names))}); read it with "
            "read_sweep_schedules (risloc_rt.measured.sweep.schedules), or import one RIS with --ris NAME")
    check_keys(doc, TOP_KEYS, source, "")
    frames = frame_fields(doc, source)
    sweep = toml_table(doc, "sweep", source, required=True)
    check_keys(sweep, SWEEP_KEYS, source, "sweep.")
    angles, grid = beam_angles(sweep, source)
    ris = ris_fields(doc, source)
    refuse_large_ris(len(angles), ris["ris_rows"], ris["ris_columns"], source)
    sync = sync_fields(doc, source)
    return SweepSchedule(angles_deg=angles, grid=grid, truth_ue_position=truth_position(doc, source), **frames,
                         **ris, **sync, **tolerance_fields(doc, source))


def read_sweep_schedule(path: str | Path) -> SweepSchedule:
    """Read a sweep schedule file (TOML); errors name the file and the key.

    Parameters
    ----------
    path : path
        The ``sweep.toml``.

    Returns
    -------
    SweepSchedule
    """
    path = Path(path)
    text = read_text_file(path, "sweep schedule",
                          'give the .toml written with the recording (docs/formats.md, "Sweep schedule files")')
    return parse_sweep_schedule(text, source=str(path))


# ---------------------------------------------------------------------------------------------- format

def schedule_document(s: SweepSchedule) -> dict[str, Any]:
    """The schedule as the TOML document :func:`format_sweep_schedule` writes (plain dicts and lists).

    Parameters
    ----------
    s : SweepSchedule

    Returns
    -------
    dict
    """
    doc: dict[str, Any] = ({"frames_per_beam": s.frames_per_beam} if s.beam_dwell_ms is None
                           else {"beam_dwell_ms": s.beam_dwell_ms})
    doc.update({"first_frame": "auto" if s.first_frame is None else s.first_frame, "channel": s.channel})
    if s.max_clock_drift != 0.02:
        doc["max_clock_drift"] = s.max_clock_drift
    if s.grid is not None:
        doc["sweep"] = {"start_deg": s.grid[0], "stop_deg": s.grid[1], "step_deg": s.grid[2],
                        "elevation_deg": s.grid[3]}
    else:
        doc["sweep"] = {"angles_deg": [list(p) for p in s.angles_deg]}
    ris: dict[str, Any] = {"position": list(s.ris_position), "facing": list(s.ris_facing),
                           "loopback_delay_ns": s.loopback_delay_ns, "mode": s.ris_mode, "rows": s.ris_rows,
                           "columns": s.ris_columns}
    if s.ris_element_spacing is not None:
        ris["element_spacing"] = s.ris_element_spacing
    if tuple(s.relay_rx_angle_deg) != (0.0, 0.0):
        ris["relay_rx_angle_deg"] = list(s.relay_rx_angle_deg)
    if s.yaw_deg:
        ris["yaw_deg"] = s.yaw_deg
    doc["ris"] = ris
    sync: dict[str, Any] = {}
    if s.sync_pattern:
        sync.update({"pattern": s.sync_pattern, "chip_ms": s.sync_chip_ms})
    elif s.sync_cycles or s.sync_on_frames or s.sync_off_frames or s.sync_gap_frames:
        sync.update({"on_frames": s.sync_on_frames, "off_frames": s.sync_off_frames, "cycles": s.sync_cycles})
    if s.sync_gap_ms is not None:
        sync["gap_ms"] = s.sync_gap_ms
    elif sync or s.sync_gap_frames:
        sync["gap_frames"] = s.sync_gap_frames
    if s.sync_repeat_after:
        sync["repeat_after"] = True
    if sync:
        doc["sync"] = sync
    if s.truth_ue_position is not None:
        doc["truth"] = {"ue_position": list(s.truth_ue_position)}
    tol = {k: getattr(s, f"tolerance_{k}") for k in TOLERANCE_KEYS if getattr(s, f"tolerance_{k}") is not None}
    if tol:
        doc["tolerance"] = tol
    return doc


def format_sweep_schedule(schedule: SweepSchedule, *, comment: str | None = None) -> str:
    """The TOML text of ``schedule``; ``parse_sweep_schedule(format_sweep_schedule(s)) == s``.

    Parameters
    ----------
    schedule : SweepSchedule
    comment : str, optional
        Lines written first, each after ``#`` (default: a one-line header).

    Returns
    -------
    str
    """
    doc = schedule_document(schedule)
    lines = [f"# {line}" for line in (comment or "risloc sweep schedule (docs/formats.md)").splitlines()]
    for key in ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift"):
        if key in doc:
            lines.append(f"{key} = {toml_value(doc[key])}")
    for table in ("sweep", "ris", "sync", "truth", "tolerance"):
        if table in doc:
            lines.append("")
            lines.append(f"[{table}]")
            lines.extend(f"{k} = {toml_value(v)}" for k, v in doc[table].items())
    return "\n".join(lines) + "\n"


def write_sweep_schedule(schedule: SweepSchedule, path: str | Path, *, comment: str | None = None) -> Path:
    """Write :func:`format_sweep_schedule` to ``path`` atomically.

    Parameters
    ----------
    schedule : SweepSchedule
    path : path
        The ``.toml`` to write (replaced when it exists).
    comment : str, optional
        As :func:`format_sweep_schedule`.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_bytes(path, format_sweep_schedule(schedule, comment=comment).encode("utf-8"))
