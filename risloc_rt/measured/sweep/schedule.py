"""Sweep schedule files: which recorded frames belong to which RIS beam, and the RIS the DSP needs.

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
the beams of an azimuth grid (:data:`BEAM_BYTES` each) and the RIS's elements × beams
(:func:`ris_memory`); a :class:`dsp.budget.BudgetError` names the key, the estimate and the limit.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dsp.budget import check_memory

from ..._files import atomic_write_bytes
from ..._outputs import safe_name
from ...model.time_division import TimeDivision, parse_time_division
from ..errors import MeasuredFormatError, read_text_file
from .ris_timing import MAX_SYNC_CHIPS, RisProgram

__all__ = ["SweepSchedule", "SweepSchedules", "read_sweep_schedule", "parse_sweep_schedule", "format_sweep_schedule",
           "ris_memory", "write_sweep_schedule", "parse_sweep_schedules", "read_sweep_schedules",
           "format_sweep_schedules", "write_sweep_schedules"]

_TOP = ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift", "sweep", "ris", "truth",
        "sync", "tolerance")
_TOLERANCE = ("position_m", "yaw_deg", "element_spacing")
_SYNC = ("on_frames", "off_frames", "cycles", "gap_frames", "pattern", "chip_ms", "gap_ms", "repeat_after")
_ON_OFF = ("on_frames", "off_frames", "cycles")
_SWEEP = ("start_deg", "stop_deg", "step_deg", "elevation_deg", "angles_deg")
_RIS = ("position", "facing", "loopback_delay_ns", "mode", "rows", "columns", "element_spacing",
        "relay_rx_angle_deg", "yaw_deg")
_TRUTH = ("ue_position",)
#: Bytes of one beam of an azimuth grid while it is parsed: its float64 angle, the ``(az, el)`` tuple
#: of two floats (56 + 2·24 B) and the tuple's pointer, rounded up.
BEAM_BYTES = 128
#: Bytes the model's RIS response holds per element and beam (:func:`ris_memory`).
RIS_BYTES_PER_ELEMENT_BEAM = 32


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
        angles, grid = _angles({"start_deg": start_deg, "stop_deg": stop_deg, "step_deg": step_deg,
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
        return _as_document(self)


# ---------------------------------------------------------------------------------------------- parse

def _where(source: str, key: str) -> str:
    return f"{source}: {key}"


def _check_keys(table: dict[str, Any], allowed: tuple[str, ...], source: str, prefix: str) -> None:
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.5)
            hint = f"did you mean {prefix}{close[0]!r}?" if close else f"allowed: {', '.join(allowed)}"
            raise MeasuredFormatError(f"{source}: unknown key {prefix}{key!r}; {hint}")


def _int(value: Any, source: str, key: str, *, minimum: int, fix: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise MeasuredFormatError(f"{_where(source, key)} = {value!r} must be an integer >= {minimum}; {fix}")
    return int(value)


def _float(value: Any, source: str, key: str, *, fix: str, minimum: float | None = None,
           positive: bool = False) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if ok and positive and not value > 0:
        ok = False
    if ok and minimum is not None and value < minimum:
        ok = False
    if not ok:
        need = "a finite number" + (" > 0" if positive else f" >= {minimum:g}" if minimum is not None else "")
        raise MeasuredFormatError(f"{_where(source, key)} = {value!r} must be {need}; {fix}")
    return float(value)


def _vector(value: Any, source: str, key: str, size: int, *, fix: str) -> tuple[float, ...]:
    if (not isinstance(value, list) or len(value) != size
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise MeasuredFormatError(f"{_where(source, key)} = {value!r} must be a list of {size} finite numbers; {fix}")
    return tuple(float(v) for v in value)


def _table(doc: dict[str, Any], name: str, source: str, *, required: bool) -> dict[str, Any] | None:
    value = doc.get(name)
    if value is None:
        if required:
            raise MeasuredFormatError(f"{source}: the [{name}] table is missing; add it (docs/formats.md, "
                                      "\"Sweep schedule files\")")
        return None
    if not isinstance(value, dict):
        raise MeasuredFormatError(f"{source}: {name} must be a table [{name}], got {value!r}")
    return value


def _angles(sweep: dict[str, Any], source: str) -> tuple[tuple[tuple[float, float], ...],
                                                         tuple[float, float, float, float] | None]:
    grid_keys = [k for k in ("start_deg", "stop_deg", "step_deg", "elevation_deg") if k in sweep]
    if "angles_deg" in sweep:
        if grid_keys:
            raise MeasuredFormatError(f"{source}: sweep.angles_deg and sweep.{grid_keys[0]} both give the beams; "
                                      "keep one: an explicit list or start_deg/stop_deg/step_deg")
        raw = sweep["angles_deg"]
        fix = "give sweep.angles_deg = [[az, el], ...] in degrees, one pair per beam"
        if not isinstance(raw, list) or not raw:
            raise MeasuredFormatError(f"{_where(source, 'sweep.angles_deg')} = {raw!r} must be a non-empty list; {fix}")
        pairs = tuple(_vector(p, source, f"sweep.angles_deg[{i}]", 2, fix=fix) for i, p in enumerate(raw))
        return tuple((a, e) for a, e in pairs), None
    missing = [k for k in ("start_deg", "stop_deg", "step_deg") if k not in sweep]
    if missing:
        raise MeasuredFormatError(f"{source}: sweep.{missing[0]} is missing; give start_deg, stop_deg and step_deg "
                                  "(an azimuth sweep) or angles_deg = [[az, el], ...]")
    fix = "angles in degrees, e.g. start_deg = -45.0, stop_deg = 45.0, step_deg = 1.5"
    start = _float(sweep["start_deg"], source, "sweep.start_deg", fix=fix)
    stop = _float(sweep["stop_deg"], source, "sweep.stop_deg", fix=fix)
    step = _float(sweep["step_deg"], source, "sweep.step_deg", fix=fix, positive=True)
    elevation = _float(sweep.get("elevation_deg", 0.0), source, "sweep.elevation_deg", fix=fix)
    if stop < start:
        raise MeasuredFormatError(f"{source}: sweep.stop_deg = {stop:g} is below sweep.start_deg = {start:g}; "
                                  "give the azimuths in increasing order")
    count = (stop - start) / step
    n = int(round(count))
    if abs(count - n) > 1e-6:
        raise MeasuredFormatError(f"{source}: sweep.step_deg = {step:g} does not divide stop_deg - start_deg = "
                                  f"{stop - start:g} ({count:.6g} steps); choose a step that lands on stop_deg")
    check_memory((n + 1) * BEAM_BYTES, f"{source}: sweep.step_deg = {step:g} from {start:g} to {stop:g} deg declares "
                 f"{n + 1:,} beams (about {BEAM_BYTES} B each as the schedule's angle list)",
                 fix="a sweep has one beam per recorded frame or few; check start_deg, stop_deg and step_deg")
    az = np.linspace(start, stop, n + 1)
    return tuple((float(a), elevation) for a in az), (start, stop, step, elevation)


def _frame_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """``frames_per_beam`` or ``beam_dwell_ms`` [ms], ``first_frame`` (None for ``"auto"``) and ``channel``."""
    if "frames_per_beam" in doc and "beam_dwell_ms" in doc:
        raise MeasuredFormatError(f"{source}: frames_per_beam and beam_dwell_ms both give the RIS's time per beam; "
                                  "keep one (beam_dwell_ms when the RIS's own clock sets it, e.g. 25.0)")
    if "frames_per_beam" not in doc and "beam_dwell_ms" not in doc:
        raise MeasuredFormatError(f"{source}: frames_per_beam is missing; add e.g. frames_per_beam = 1 (recorded "
                                  "frames per RIS beam), or beam_dwell_ms = 25.0 (the RIS's own time per beam)")
    fpb: int | None = None
    dwell_ms: float | None = None
    if "frames_per_beam" in doc:
        fpb = _int(doc["frames_per_beam"], source, "frames_per_beam", minimum=1,
                   fix="give the number of recorded frames the RIS holds each beam, e.g. frames_per_beam = 1, or "
                       "beam_dwell_ms = 25.0 for a time per beam that is not a whole number of frames")
    else:
        dwell_ms = _float(doc["beam_dwell_ms"], source, "beam_dwell_ms", positive=True,
                          fix="give the time the RIS holds each beam on its own clock in milliseconds, e.g. 25.0")
    if "first_frame" not in doc:
        raise MeasuredFormatError(f"{source}: first_frame is missing; add the index of the sweep's first frame in "
                                  "the recording, e.g. first_frame = 0")
    first: int | None
    if doc["first_frame"] == "auto":
        first = None
    else:
        first = _int(doc["first_frame"], source, "first_frame", minimum=0,
                     fix="give the index of the sweep's first frame in the recording (0-based), or \"auto\"")
    channel = _int(doc.get("channel", 0), source, "channel", minimum=0,
                   fix="give the virtual channel index v = chirp·num_rx + rx used for localization, e.g. channel = 0")
    return {"frames_per_beam": fpb, "beam_dwell_ms": dwell_ms, "first_frame": first, "channel": channel}


def _ris_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[ris]`` table: pose [m], τ_RB [ns], mode, element grid and pitch [m], relay Rx beam and yaw [deg]."""
    ris = _table(doc, "ris", source, required=True)
    _check_keys(ris, _RIS, source, "ris.")
    return _ris_values(ris, source, "ris.")


def _ris_values(ris: dict[str, Any], source: str, prefix: str) -> dict[str, Any]:
    """One RIS table's values (keys checked by the caller); ``prefix`` names it in messages (``ris.``, ``ris[1].``)."""
    for key in ("position", "facing", "loopback_delay_ns"):
        if key not in ris:
            raise MeasuredFormatError(f"{source}: {prefix}{key} is missing; add it (docs/formats.md, \"Sweep schedule "
                                      "files\": position and facing [m], loopback_delay_ns)")
    position = _vector(ris["position"], source, prefix + "position", 3, fix="give the RIS centre [x, y, z] in metres")
    facing = _vector(ris["facing"], source, prefix + "facing", 3,
                     fix="give the point the RIS broadside faces [x, y, z] in metres")
    if np.allclose(position, facing):
        raise MeasuredFormatError(f"{source}: {prefix}facing equals {prefix}position; give a point the panel faces, "
                                  "e.g. the radar's position")
    delay = _float(ris["loopback_delay_ns"], source, prefix + "loopback_delay_ns", minimum=0.0,
                   fix="give the RIS's receive-to-transmit delay τ_RB in nanoseconds, e.g. 1.78")
    mode = ris.get("mode", "relay")
    if mode not in ("relay", "reflective"):
        raise MeasuredFormatError(f"{_where(source, prefix + 'mode')} = {mode!r} must be \"relay\" or \"reflective\"")
    rows = _int(ris.get("rows", 16), source, prefix + "rows", minimum=1, fix="give the elements along azimuth, e.g. 16")
    columns = _int(ris.get("columns", 4), source, prefix + "columns", minimum=1,
                   fix="give the elements along elevation, e.g. 4")
    spacing = None
    if "element_spacing" in ris:
        spacing = _float(ris["element_spacing"], source, prefix + "element_spacing", positive=True,
                         fix="give the element pitch in metres, e.g. 0.0025")
    rx = _vector(ris.get("relay_rx_angle_deg", [0.0, 0.0]), source, prefix + "relay_rx_angle_deg", 2,
                 fix="give the relay Rx beam [az, el] in degrees")
    yaw = _float(ris.get("yaw_deg", 0.0), source, prefix + "yaw_deg", fix="give the panel yaw in degrees")
    return {"ris_position": position, "ris_facing": facing, "loopback_delay_ns": delay, "ris_mode": mode,
            "ris_rows": rows, "ris_columns": columns, "ris_element_spacing": spacing,
            "relay_rx_angle_deg": (rx[0], rx[1]), "yaw_deg": yaw}


def _sync_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """``max_clock_drift`` [fraction] and the ``[sync]`` table's on/off/cycles/gap [nominal frames] (0 without it)."""
    drift = _float(doc.get("max_clock_drift", 0.02), source, "max_clock_drift", minimum=0.0,
                   fix="give the largest RIS clock rate error to search as a fraction, e.g. 0.02 (2 %), below 0.5")
    if drift >= 0.5:
        raise MeasuredFormatError(f"{source}: max_clock_drift = {drift:g} must be below 0.5; e.g. 0.02 (2 %)")
    sync = _table(doc, "sync", source, required=False)
    sync_values: dict[str, Any] = {k: 0 for k in ("on_frames", "off_frames", "cycles", "gap_frames")}
    out: dict[str, Any] = {"max_clock_drift": drift}
    if sync is not None:
        _check_keys(sync, _SYNC, source, "sync.")
        for key in sync_values:
            sync_values[key] = _int(sync.get(key, 0), source, f"sync.{key}", minimum=0,
                                    fix="give whole nominal frames, e.g. [sync] on_frames = 5, off_frames = 5, "
                                        "cycles = 3, gap_frames = 2")
        if sync_values["cycles"] and not sync_values["on_frames"]:
            raise MeasuredFormatError(f"{source}: sync.cycles = {sync_values['cycles']} needs sync.on_frames >= 1 "
                                      "(the frames the RIS is on in each cycle)")
        out.update(_sync_code(sync, source))
    return {**out, "sync_on_frames": sync_values["on_frames"], "sync_off_frames": sync_values["off_frames"],
            "sync_cycles": sync_values["cycles"], "sync_gap_frames": sync_values["gap_frames"]}


def _sync_code(sync: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[sync]`` table's code form: ``pattern``, ``chip_ms`` [ms], ``gap_ms`` [ms], ``repeat_after``."""
    out: dict[str, Any] = {}
    if "pattern" in sync:
        pattern = sync["pattern"]
        fix = 'give the chips as a string of 1 (on at the sync beam) and 0 (off), e.g. pattern = "1111100110101"'
        if not isinstance(pattern, str) or not pattern or set(pattern) - {"0", "1"}:
            raise MeasuredFormatError(f"{_where(source, 'sync.pattern')} = {pattern!r} must be a non-empty string of "
                                      f"'1' and '0'; {fix}")
        if len(pattern) > MAX_SYNC_CHIPS:
            raise MeasuredFormatError(f"{source}: sync.pattern has {len(pattern):,} chips, more than "
                                      f"{MAX_SYNC_CHIPS}; {fix}")
        if "1" not in pattern:
            raise MeasuredFormatError(f"{source}: sync.pattern = {pattern!r} has no 1 chip (the RIS is never on); {fix}")
        on_off = [k for k in _ON_OFF if k in sync]
        if on_off:
            raise MeasuredFormatError(f"{source}: sync.pattern and sync.{on_off[0]} both describe the sync; keep one "
                                      "(pattern with chip_ms, or on_frames/off_frames/cycles)")
        if "chip_ms" not in sync:
            raise MeasuredFormatError(f"{source}: sync.pattern needs sync.chip_ms, the duration of one chip on the "
                                      "RIS's clock in milliseconds, e.g. chip_ms = 20.0")
        out["sync_pattern"] = pattern
        out["sync_chip_ms"] = _float(sync["chip_ms"], source, "sync.chip_ms", positive=True,
                                     fix="give one chip's duration on the RIS's clock in milliseconds, e.g. 20.0")
    elif "chip_ms" in sync:
        raise MeasuredFormatError(f"{source}: sync.chip_ms needs sync.pattern (the chips, e.g. \"1111100110101\")")
    if "gap_ms" in sync:
        if "gap_frames" in sync:
            raise MeasuredFormatError(f"{source}: sync.gap_frames and sync.gap_ms both give the gap; keep one")
        out["sync_gap_ms"] = _float(sync["gap_ms"], source, "sync.gap_ms", minimum=0.0,
                                    fix="give the RIS-off time between the sync code and the sweep in milliseconds")
    if "repeat_after" in sync:
        if not isinstance(sync["repeat_after"], bool):
            raise MeasuredFormatError(f"{_where(source, 'sync.repeat_after')} = {sync['repeat_after']!r} must be true "
                                      "or false (the sync code is sent again after the sweep)")
        if not (out.get("sync_pattern") or any(k in sync for k in _ON_OFF)):
            raise MeasuredFormatError(f"{source}: sync.repeat_after needs a sync code to repeat (sync.pattern or "
                                      "on_frames/cycles)")
        out["sync_repeat_after"] = sync["repeat_after"]
    return out


def _tolerance_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[tolerance]`` table: 1σ of the RIS position [m], yaw [deg], element pitch [relative]."""
    table = _table(doc, "tolerance", source, required=False)
    if table is None:
        return {}
    _check_keys(table, _TOLERANCE, source, "tolerance.")
    fixes = {"position_m": "give the 1σ of each RIS coordinate in metres, e.g. 0.005",
             "yaw_deg": "give the 1σ of the panel's yaw in degrees, e.g. 0.5",
             "element_spacing": "give the relative 1σ of the element pitch, e.g. 0.01 for 1 %"}
    return {f"tolerance_{k}": _float(table[k], source, f"tolerance.{k}", minimum=0.0, fix=fixes[k])
            for k in _TOLERANCE if k in table}


def _truth_position(doc: dict[str, Any], source: str) -> tuple[float, ...] | None:
    """The ``[truth]`` table's ``ue_position`` [m], or None without the table."""
    truth = _table(doc, "truth", source, required=False)
    if truth is None:
        return None
    _check_keys(truth, _TRUTH, source, "truth.")
    if "ue_position" not in truth:
        raise MeasuredFormatError(f"{source}: [truth] needs ue_position = [x, y, z] [m]; add it or remove [truth]")
    return _vector(truth["ue_position"], source, "truth.ue_position", 3,
                   fix="give the radar's true position [x, y, z] in metres")


def ris_memory(num_beams: int, rows: int, columns: int) -> int:
    """Bytes the model allocates for this RIS and sweep: ``RIS_BYTES_PER_ELEMENT_BEAM · M · rows · columns``.

    The RIS response (:func:`risloc_rt.model.ris.ris_response`, used when a capture is simulated,
    compared or calibrated) holds the beam weights ``exp(-j k g(φ_m)·x_n)`` ``[M, rows·columns]``
    complex128 (16 B) and their float64 phase argument ``g(φ_m)·x_n`` (8 B) with the complex
    temporary of the exponent: 33 B per element and beam measured (tracemalloc peak, 300 × 300
    elements, 61 beams), so 32 B is a lower bound; the element positions ``[rows·columns, 3]``
    are negligible beside it.

    Parameters
    ----------
    num_beams, rows, columns : int
        M, the RIS's rows and columns.

    Returns
    -------
    int
        [bytes].
    """
    return RIS_BYTES_PER_ELEMENT_BEAM * int(num_beams) * int(rows) * int(columns)


def _check_ris_memory(num_beams: int, rows: int, columns: int, source: str) -> None:
    """Refuse (:class:`dsp.budget.BudgetError`) a RIS whose beam patterns would not fit the memory limit."""
    check_memory(ris_memory(num_beams, rows, columns),
                 f"{source}: ris.rows = {rows} x ris.columns = {columns} ({rows * columns:,} elements) with {num_beams} "
                 f"beams (the RIS's beam weights, {RIS_BYTES_PER_ELEMENT_BEAM} B per element and beam)",
                 fix="give the panel's real element grid (the paper's RIS: rows = 16, columns = 4)")


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
            "read_sweep_schedules (risloc_rt.measured.sweep.schedule), or import one RIS with --ris NAME")
    _check_keys(doc, _TOP, source, "")
    frames = _frame_fields(doc, source)
    sweep = _table(doc, "sweep", source, required=True)
    _check_keys(sweep, _SWEEP, source, "sweep.")
    angles, grid = _angles(sweep, source)
    ris = _ris_fields(doc, source)
    _check_ris_memory(len(angles), ris["ris_rows"], ris["ris_columns"], source)
    sync = _sync_fields(doc, source)
    return SweepSchedule(angles_deg=angles, grid=grid, truth_ue_position=_truth_position(doc, source), **frames,
                         **ris, **sync, **_tolerance_fields(doc, source))


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

def _as_document(s: SweepSchedule) -> dict[str, Any]:
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
    tol = {k: getattr(s, f"tolerance_{k}") for k in _TOLERANCE if getattr(s, f"tolerance_{k}") is not None}
    if tol:
        doc["tolerance"] = tol
    return doc


def _toml_value(v: Any) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)  # shortest round-trip text
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


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
    doc = _as_document(schedule)
    lines = [f"# {line}" for line in (comment or "risloc sweep schedule (docs/formats.md)").splitlines()]
    for key in ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift"):
        if key in doc:
            lines.append(f"{key} = {_toml_value(doc[key])}")
    for table in ("sweep", "ris", "sync", "truth", "tolerance"):
        if table in doc:
            lines.append("")
            lines.append(f"[{table}]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in doc[table].items())
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


# ---------------------------------------------------------------------------------------------- several RISs

_MULTI_TOP = _TOP + ("schedule",)
_MULTI_RIS = ("name", "first_frame") + _RIS
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
        _check_keys(table, _MULTI_RIS, source, prefix)
        name = table.get("name")
        if not isinstance(name, str) or not name or safe_name(name) != name:
            raise MeasuredFormatError(f"{source}: {prefix}name = {name!r} must be the RIS's name, a plain word such "
                                      "as \"ris1\" (it names its capture file on import)")
        if name in names:
            raise MeasuredFormatError(f"{source}: {prefix}name = {name!r} is the name of ris[{names.index(name)}] too; "
                                      "give each RIS its own name")
        names.append(name)
        fields.append(_ris_values(table, source, prefix))
        first = table.get("first_frame")
        if first == "auto":
            raise MeasuredFormatError(f"{source}: {prefix}first_frame = \"auto\": with several RISs each slot's first "
                                      "frame is given (the sweeps look alike to the aligner); give the frame index")
        firsts.append(None if first is None else _int(first, source, prefix + "first_frame", minimum=0,
                                                      fix="give the slot's first recorded frame (0-based)"))
    return names, fields, firsts


def _division_table(doc: dict[str, Any], names: list[str], firsts: list[int | None],
                    source: str) -> dict[str, Any] | None:
    """The ``[schedule]`` table, checked against the ``[[ris]]`` tables (its timing is checked on use)."""
    table = _table(doc, "schedule", source, required=False)
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
    _check_keys(doc, _MULTI_TOP, source, "")
    if "sync" in doc:
        raise MeasuredFormatError(f"{source}: [sync] is for a one-RIS recording; with several [[ris]] give each slot's "
                                  "first_frame (or a [schedule])")
    if doc.get("first_frame") == "auto":
        raise MeasuredFormatError(f"{source}: first_frame = \"auto\" is for a one-RIS recording; with several [[ris]] "
                                  "give the slots' first frames")
    names, ris_fields, firsts = _multi_ris(doc, source)
    division = _division_table(doc, names, firsts, source)
    frames = _frame_fields({**doc, "first_frame": doc.get("first_frame", 0)}, source)
    top_first = frames["first_frame"] if "first_frame" in doc else None
    sweep = _table(doc, "sweep", source, required=True)
    _check_keys(sweep, _SWEEP, source, "sweep.")
    angles, grid = _angles(sweep, source)
    for i, ris in enumerate(ris_fields):
        _check_ris_memory(len(angles), ris["ris_rows"], ris["ris_columns"], f"{source}: ris[{i}]")
    shared = {**frames, **_sync_fields(doc, source), **_tolerance_fields(doc, source)}
    truth = _truth_position(doc, source)
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
    doc = _as_document(schedules.schedules[0])
    doc.pop("first_frame")
    if schedules.first_frame is not None:
        doc["first_frame"] = schedules.first_frame
    lines = [f"# {line}" for line in (comment or "risloc sweep schedule, several RISs (docs/formats.md)").splitlines()]
    for key in ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift"):
        if key in doc:
            lines.append(f"{key} = {_toml_value(doc[key])}")
    tables = {"sweep": doc["sweep"], "schedule": schedules.division, "truth": doc.get("truth"),
              "tolerance": doc.get("tolerance")}
    for name, table in tables.items():
        if table:
            lines += ["", f"[{name}]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    for name, s in zip(schedules.names, schedules.schedules):
        ris = {"name": name, **({} if s.first_frame is None else {"first_frame": s.first_frame}),
               **_as_document(s)["ris"]}
        lines += ["", "[[ris]]"] + [f"{k} = {_toml_value(v)}" for k, v in ris.items()]
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
