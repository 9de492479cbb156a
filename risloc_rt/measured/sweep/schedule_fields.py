"""The sweep schedule's TOML fields: readers that refuse a bad value in one line, the memory checks, the writer's values.

Shared by the one-RIS schedule (:mod:`.schedule`, :class:`SweepSchedule`) and the several-RIS one
(:mod:`.schedules`, :class:`SweepSchedules`); the file format is ``docs/formats.md`` "Sweep schedule
files". Every reader raises a one-line :class:`MeasuredFormatError` naming the file, the key and the
fix; sizes are checked against the memory limit (``$RISLOC_MEMORY_LIMIT``,
:func:`dsp.budget.check_memory`) before anything of that size exists.
"""

from __future__ import annotations

import difflib
import math
from typing import Any

import numpy as np

from dsp.budget import check_memory

from ..errors import MeasuredFormatError
from .ris_timing import MAX_SYNC_CHIPS

__all__ = ["BEAM_BYTES", "ON_OFF_KEYS", "RIS_BYTES_PER_ELEMENT_BEAM", "RIS_KEYS", "SWEEP_KEYS", "SYNC_KEYS",
           "TOLERANCE_KEYS", "TOP_KEYS", "TRUTH_KEYS", "beam_angles", "check_keys", "frame_fields", "read_int",
           "refuse_large_ris", "ris_fields", "ris_memory", "ris_values", "sync_fields", "tolerance_fields",
           "toml_table", "toml_value", "truth_position"]

#: Top-level keys of a one-RIS schedule; the tables' keys below.
TOP_KEYS = ("frames_per_beam", "beam_dwell_ms", "first_frame", "channel", "max_clock_drift", "sweep", "ris",
            "truth", "sync", "tolerance")
TOLERANCE_KEYS = ("position_m", "yaw_deg", "element_spacing")
SYNC_KEYS = ("on_frames", "off_frames", "cycles", "gap_frames", "pattern", "chip_ms", "gap_ms", "repeat_after")
ON_OFF_KEYS = ("on_frames", "off_frames", "cycles")
SWEEP_KEYS = ("start_deg", "stop_deg", "step_deg", "elevation_deg", "angles_deg")
RIS_KEYS = ("position", "facing", "loopback_delay_ns", "mode", "rows", "columns", "element_spacing",
            "relay_rx_angle_deg", "yaw_deg")
TRUTH_KEYS = ("ue_position",)
#: Bytes of one beam of an azimuth grid while it is parsed: its float64 angle, the ``(az, el)`` tuple
#: of two floats (56 + 2·24 B) and the tuple's pointer, rounded up.
BEAM_BYTES = 128
#: Bytes the model's RIS response holds per element and beam (:func:`ris_memory`).
RIS_BYTES_PER_ELEMENT_BEAM = 32


def _where(source: str, key: str) -> str:
    return f"{source}: {key}"


def check_keys(table: dict[str, Any], allowed: tuple[str, ...], source: str, prefix: str) -> None:
    """Refuse a key not in ``allowed`` with a did-you-mean (one line).

    Parameters
    ----------
    table : dict
        A TOML table.
    allowed : tuple of str
        Its keys.
    source : str
        The file the message names.
    prefix : str
        The table's dotted prefix in messages (``"ris."``; ``""`` for the top level).
    """
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.5)
            hint = f"did you mean {prefix}{close[0]!r}?" if close else f"allowed: {', '.join(allowed)}"
            raise MeasuredFormatError(f"{source}: unknown key {prefix}{key!r}; {hint}")


def read_int(value: Any, source: str, key: str, *, minimum: int, fix: str) -> int:
    """An integer ≥ ``minimum`` (not a bool), or a one-line error naming the key and ``fix``.

    Parameters
    ----------
    value : Any
        The TOML value.
    source, key : str
        The file and the dotted key the message names.
    minimum : int
        Smallest allowed value.
    fix : str
        How to fix it, appended to the message.

    Returns
    -------
    int
    """
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


def toml_table(doc: dict[str, Any], name: str, source: str, *, required: bool) -> dict[str, Any] | None:
    """The table ``[name]`` of ``doc``, None when absent and not ``required``.

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    name : str
        The table.
    source : str
        The file the message names.
    required : bool
        A missing table is an error.

    Returns
    -------
    dict or None
    """
    value = doc.get(name)
    if value is None:
        if required:
            raise MeasuredFormatError(f"{source}: the [{name}] table is missing; add it (docs/formats.md, "
                                      "\"Sweep schedule files\")")
        return None
    if not isinstance(value, dict):
        raise MeasuredFormatError(f"{source}: {name} must be a table [{name}], got {value!r}")
    return value


def beam_angles(sweep: dict[str, Any], source: str) -> tuple[tuple[tuple[float, float], ...],
                                                         tuple[float, float, float, float] | None]:
    """The beams of ``[sweep]``: an explicit ``angles_deg`` list or a ``start/stop/step`` grid (its size checked
    against the memory limit first, :data:`BEAM_BYTES` a beam).

    Parameters
    ----------
    sweep : dict
        The ``[sweep]`` table.
    source : str
        The file the messages name.

    Returns
    -------
    (tuple of (float, float), tuple of 4 float or None)
        The (az, el) of every beam [deg], and the grid (start, stop, step, elevation) [deg] when given as one.
    """
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


def frame_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """``frames_per_beam`` or ``beam_dwell_ms``, ``first_frame`` (or ``"auto"``), ``channel``, ``max_clock_drift``.

    Parameters
    ----------
    doc : dict
        The parsed TOML document (top level).
    source : str
        The file the messages name.

    Returns
    -------
    dict
        :class:`risloc_rt.measured.sweep.schedule.SweepSchedule` fields [frames, ms].
    """
    if "frames_per_beam" in doc and "beam_dwell_ms" in doc:
        raise MeasuredFormatError(f"{source}: frames_per_beam and beam_dwell_ms both give the RIS's time per beam; "
                                  "keep one (beam_dwell_ms when the RIS's own clock sets it, e.g. 25.0)")
    if "frames_per_beam" not in doc and "beam_dwell_ms" not in doc:
        raise MeasuredFormatError(f"{source}: frames_per_beam is missing; add e.g. frames_per_beam = 1 (recorded "
                                  "frames per RIS beam), or beam_dwell_ms = 25.0 (the RIS's own time per beam)")
    fpb: int | None = None
    dwell_ms: float | None = None
    if "frames_per_beam" in doc:
        fpb = read_int(doc["frames_per_beam"], source, "frames_per_beam", minimum=1,
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
        first = read_int(doc["first_frame"], source, "first_frame", minimum=0,
                     fix="give the index of the sweep's first frame in the recording (0-based), or \"auto\"")
    channel = read_int(doc.get("channel", 0), source, "channel", minimum=0,
                   fix="give the virtual channel index v = chirp·num_rx + rx used for localization, e.g. channel = 0")
    return {"frames_per_beam": fpb, "beam_dwell_ms": dwell_ms, "first_frame": first, "channel": channel}


def ris_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[ris]`` table's :class:`risloc_rt.measured.sweep.schedule.SweepSchedule` fields (:func:`ris_values`).

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    source : str
        The file the messages name.

    Returns
    -------
    dict
    """
    ris = toml_table(doc, "ris", source, required=True)
    check_keys(ris, RIS_KEYS, source, "ris.")
    return ris_values(ris, source, "ris.")


def ris_values(ris: dict[str, Any], source: str, prefix: str) -> dict[str, Any]:
    """One RIS table's pose, τ_RB, mode and element grid as schedule fields [m, ns, deg].

    Parameters
    ----------
    ris : dict
        A ``[ris]`` (or ``[[ris]]``) table.
    source : str
        The file the messages name.
    prefix : str
        The table's prefix in messages (``"ris."``, ``"ris[1]."``).

    Returns
    -------
    dict
    """
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
    rows = read_int(ris.get("rows", 16), source, prefix + "rows", minimum=1, fix="give the elements along azimuth, e.g. 16")
    columns = read_int(ris.get("columns", 4), source, prefix + "columns", minimum=1,
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


def sync_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[sync]`` table's fields (an on/off code in frames, or a chip pattern in ms), empty without one.

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    source : str
        The file the messages name.

    Returns
    -------
    dict
    """
    drift = _float(doc.get("max_clock_drift", 0.02), source, "max_clock_drift", minimum=0.0,
                   fix="give the largest RIS clock rate error to search as a fraction, e.g. 0.02 (2 %), below 0.5")
    if drift >= 0.5:
        raise MeasuredFormatError(f"{source}: max_clock_drift = {drift:g} must be below 0.5; e.g. 0.02 (2 %)")
    sync = toml_table(doc, "sync", source, required=False)
    sync_values: dict[str, Any] = {k: 0 for k in ("on_frames", "off_frames", "cycles", "gap_frames")}
    out: dict[str, Any] = {"max_clock_drift": drift}
    if sync is not None:
        check_keys(sync, SYNC_KEYS, source, "sync.")
        for key in sync_values:
            sync_values[key] = read_int(sync.get(key, 0), source, f"sync.{key}", minimum=0,
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
        on_off = [k for k in ON_OFF_KEYS if k in sync]
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
        if not (out.get("sync_pattern") or any(k in sync for k in ON_OFF_KEYS)):
            raise MeasuredFormatError(f"{source}: sync.repeat_after needs a sync code to repeat (sync.pattern or "
                                      "on_frames/cycles)")
        out["sync_repeat_after"] = sync["repeat_after"]
    return out


def tolerance_fields(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """The ``[tolerance]`` table's fields (``position_m`` [m], ``yaw_deg`` [deg], ``element_spacing``).

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    source : str
        The file the messages name.

    Returns
    -------
    dict
    """
    table = toml_table(doc, "tolerance", source, required=False)
    if table is None:
        return {}
    check_keys(table, TOLERANCE_KEYS, source, "tolerance.")
    fixes = {"position_m": "give the 1σ of each RIS coordinate in metres, e.g. 0.005",
             "yaw_deg": "give the 1σ of the panel's yaw in degrees, e.g. 0.5",
             "element_spacing": "give the relative 1σ of the element pitch, e.g. 0.01 for 1 %"}
    return {f"tolerance_{k}": _float(table[k], source, f"tolerance.{k}", minimum=0.0, fix=fixes[k])
            for k in TOLERANCE_KEYS if k in table}


def truth_position(doc: dict[str, Any], source: str) -> tuple[float, ...] | None:
    """``[truth] ue_position`` [m], or None without a ``[truth]`` table.

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    source : str
        The file the messages name.

    Returns
    -------
    tuple of 3 float or None
    """
    truth = toml_table(doc, "truth", source, required=False)
    if truth is None:
        return None
    check_keys(truth, TRUTH_KEYS, source, "truth.")
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


def refuse_large_ris(num_beams: int, rows: int, columns: int, source: str) -> None:
    """Refuse (:class:`dsp.budget.BudgetError`) a RIS whose beam patterns would not fit the memory limit.

    Parameters
    ----------
    num_beams, rows, columns : int
        M, the RIS's rows and columns.
    source : str
        The file the message names.
    """
    check_memory(ris_memory(num_beams, rows, columns),
                 f"{source}: ris.rows = {rows} x ris.columns = {columns} ({rows * columns:,} elements) with {num_beams} "
                 f"beams (the RIS's beam weights, {RIS_BYTES_PER_ELEMENT_BEAM} B per element and beam)",
                 fix="give the panel's real element grid (the paper's RIS: rows = 16, columns = 4)")


def toml_value(v: Any) -> str:
    """One value as TOML text (strings quoted, floats as their shortest round-trip text, lists).

    Parameters
    ----------
    v : str, bool, int, float or list
        The value.

    Returns
    -------
    str
    """
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)  # shortest round-trip text
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")
