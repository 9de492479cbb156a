"""Live sweeps: a position ± σ for every complete RIS sweep of a DCA1000 recording that is still growing.

A live recording (``risloc locate --live``; :mod:`.recording_writer`) is written in place: the
stream prefix ``[0, final_bytes)`` is on disk and final (every packet in it arrived or was declared
lost and zero-filled). :class:`SweepWatcher` is fed ``final_bytes`` as it grows and says which
sweeps are now complete; for each it imports **exactly that sweep's frames** with the code of
``risloc capture import`` (:func:`risloc_rt.measured.sweep.importer.import_capture`) and
localizes the capture with the code of ``risloc locate`` (:func:`locate_capture`, or the CLI's
own), one frozen :class:`LiveFix` per sweep and RIS slot, and with several RISs in time division a
:class:`FusedLiveFix` per round (:func:`risloc_rt.io.fused.fuse_cases`, as ``risloc locate a.npz
b.npz``).

**Which frames.** The sweep schedule (``sweep.toml``, one RIS or several ``[[ris]]`` slots) gives
the first sweep; sweeps repeat with a period: the time-division cycle (several RISs), else the
RIS's program (sync code + gap + beams + the repeated code), or ``period_frames``. Sweep c of the
RIS in slot k starts at frame ``first_frame_k + round(c·period)``.

- A fixed first frame (the schedule's, or ``first_frame=N``): the sweep's frames are known in
  advance (:func:`~risloc_rt.measured.sweep.alignment.manual_alignment`); the sweep is complete
  when the packet holding its last frame's last byte is final.
- ``first_frame = "auto"`` (one RIS): the first sweep is searched in the final frames (at most
  :attr:`SweepWatcher.search_frames` of them, the latest) every time they grew by a quarter sweep;
  it is accepted when the import's alignment is confident (``min_confidence``) **and** the fitted
  sweep ends at least ``margin_frames`` before the last final frame (a sweep still running cannot be
  pressed into the final frames). So the first fix needs the lead frames + the sync code + the
  sweep (each stretched by the RIS clock's drift) + ``margin_frames`` (default one beam's frames + 1)
  to be final. Each later sweep is searched in a window around where the last one's start and dwell
  put it (± ``slack_frames``, default 2 + half a beam), once that window is final.

**The window imported.** The sweep's frames (and, for a fixed first frame, the sync code's frames
before them) are copied from the recording's split files into a temporary folder and imported from
there, with the recording's own ``.cfg`` (so the capture's provenance and uncertainty budget read
the same configuration) — memory and disk: one sweep, not the recording. A raw stream's lost packets
are found by the reader as whole 1456-byte packets of zeros **on the stream's packet grid**; a window
that starts elsewhere would move the grid, so when any packet of the window is all zeros, the window
starts earlier, at the nearest frame on the grid (at most ``1456 / gcd(frame bytes, 1456) − 1``
frames earlier), and runs on to the end of the packet holding the sweep's last byte: the reader then
finds the same lost packets as in the whole recording, and the same beams are damaged.

**What equals the file import.** The beams' chirps (the cube) are the same as importing the
finished recording with ``--first-frame`` of that sweep (or ``auto`` for a recording of one sweep),
so the position, σ and flags are the same bit for bit (``tests/measured/live/test_live_sweeps.py``).
What can differ: ``--leakage background`` (the RIS-off frames of the window, not of the recording),
and the check of a given first frame (fitted on the window, not the whole recording) in a
recording where it is borderline.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ...io.fused import fuse_cases
from ...io.report import CaseResult, json_safe, report_capture
from ..dca1000.packets import MAX_PAYLOAD
from ..dca1000.raw_layout import RawLayout
from ..dca1000.split_files import capture_files, split_name
from ..errors import MeasuredFormatError
from ..sweep.alignment import DEFAULT_ASSEMBLE, manual_alignment
from ..sweep.importer import import_capture
from ..sweep.ris_timing import chirp_fractions
from ..sweep.schedules import SweepSchedules, read_sweep_schedules
from ..ti.chirp_config import TiChirpConfig
from ..ti.config_file import load_config

__all__ = ["HISTORY", "FusedLiveFix", "LiveFix", "SweepWatcher", "grid_frame", "locate_capture", "read_stream"]

_MIB = 1 << 20
#: Progress reports remembered to date when a sweep's last frame became final (a few a second: an hour or more).
HISTORY = 20_000
Localizer = Callable[[str, Any], CaseResult]


def locate_capture(name: str, capture: Any, *, estimator: str = "refined", ue_height: float | None = None,
                   pfa: float | None = None, backend: Any = None) -> CaseResult:
    """Localize one capture as ``risloc locate`` does (no figures): the DSP, its flags, a measured capture's budget.

    Parameters
    ----------
    name : str
        The case's name (``risloc locate`` uses the capture file's stem; the live path the RIS's name).
    capture : risloc_rt.model.Capture
        An imported capture (``provenance["source"] == "measurement"``: its σ is the uncertainty
        budget's total, :func:`risloc_rt.measured.compare.uncertainty_budget.apply_budget`).
    estimator : {"refined", "paper"}
        As ``risloc locate --estimator``.
    ue_height : float, optional
        Known radar height [m] (``--ue-height``).
    pfa : float, optional
        Detector false-alarm probability (``--pfa``).
    backend : dsp.ArrayBackend, optional
        Where the DSP's whole-cube work runs (``--device``).

    Returns
    -------
    CaseResult
        The localization (position [m], σ [m], flags).
    """
    budget = None
    if capture.provenance.get("source") == "measurement":
        from ..compare.uncertainty_budget import apply_budget as budget
    return report_capture(name, capture, out_dir=None, processing=capture.processing, timing={}, budget=budget,
                          estimator=estimator, ue_height=ue_height, pfa=pfa, backend=backend)


def read_stream(files: Sequence[Path], start: int, stop: int) -> bytes:
    """Bytes ``[start, stop)`` of a recording's stream, read across its split files.

    Parameters
    ----------
    files : sequence of Path
        The split files in stream order; every file but the last is complete (a recorder starts a
        file when the one before it is full).
    start, stop : int
        Stream offsets [bytes], ``0 <= start <= stop``; ``stop`` within the final prefix.

    Returns
    -------
    bytes
        ``stop - start`` bytes.

    Raises
    ------
    MeasuredFormatError
        The files hold fewer bytes than asked for.
    """
    out = bytearray()
    pos = 0
    for f in files:
        size = f.stat().st_size
        lo, hi = max(start, pos), min(stop, pos + size)
        if lo < hi:
            with open(f, "rb") as fh:
                fh.seek(lo - pos)
                out += fh.read(hi - lo)
        pos += size
        if pos >= stop:
            break
    if len(out) != stop - start:
        raise MeasuredFormatError(f"{files[0].parent}: the recording holds {pos} bytes, fewer than the {stop} its "
                                  "final prefix claims; a split file was removed or truncated while recording")
    return bytes(out)


def grid_frame(frame: int, frame_bytes: int, payload: int = MAX_PAYLOAD) -> int:
    """The last frame at or before ``frame`` whose first byte starts a packet: ``frame·B ≡ 0 (mod P)``.

    Parameters
    ----------
    frame : int
        A recorded frame.
    frame_bytes : int
        B, bytes per frame [bytes].
    payload : int
        P, bytes per DCA1000 packet [bytes] (1456).

    Returns
    -------
    int
        A multiple of ``P / gcd(B, P)`` frames.
    """
    step = payload // math.gcd(int(frame_bytes), int(payload))
    return int(frame) // step * step


def _zero_packet(data: bytes, payload: int) -> bool:
    """Whether a whole packet of ``data`` (which starts on the packet grid) is all zeros."""
    n = len(data) // payload
    if n == 0:
        return False
    words = np.frombuffer(data, np.uint8, count=n * payload).reshape(n, payload)
    return bool(np.any(~words.any(axis=1)))


def _vector(values: Any) -> tuple[float, ...]:
    return tuple(float(v) for v in np.asarray(values, float).ravel())


@dataclass(frozen=True)
class LiveFix:
    """The fix of one complete sweep of one RIS.

    Attributes
    ----------
    sweep : int
        The sweep's index in the recording (the round of a time-division cycle), from 0.
    ris : str
        The RIS (its ``[[ris]]`` name; ``""`` for the one-RIS form).
    frames : tuple of int
        The recorded frame of each beam (the one holding most of its chirps).
    detected : bool
        The RIS return was detected (else the position is NaN).
    position : tuple of 3 floats
        The radar's position, world frame [m].
    std : tuple of 3 floats
        Its 1σ per axis [m] (``inf``: the sweep cannot see that axis; NaN: not estimated).
    peb : float
        ``sqrt(σx² + σy² + σz²)`` [m].
    flags : tuple of (str, str)
        ``(code, message)`` of each flag, as ``risloc locate`` gives them.
    lost_packets : int
        Lost DCA1000 packets (zero-filled) whose bytes lie in a beam's frame.
    final_time : float
        ``time.monotonic()`` when the sweep's last frame became final [s]: interpolated at the data rate
        between the progress report that first covered it and the one before.
    fix_time : float
        ``time.monotonic()`` when the fix was made [s].
    window : tuple of (int, int)
        The recorded frames read: ``[start, stop)``.
    error : str or None
        Why there is no fix (an automatic alignment that failed), else None.
    case : CaseResult or None
        The localization (not compared).
    """

    sweep: int
    ris: str
    frames: tuple[int, ...]
    detected: bool
    position: tuple[float, ...]
    std: tuple[float, ...]
    peb: float
    flags: tuple[tuple[str, str], ...]
    lost_packets: int
    final_time: float
    fix_time: float
    window: tuple[int, int]
    error: str | None = None
    case: Any = field(default=None, compare=False, repr=False)

    @property
    def latency(self) -> float:
        """From the sweep's last frame final to the fix [s]."""
        return self.fix_time - self.final_time

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON (one line of the JSON lines file; NaN and inf as null).

        Returns
        -------
        dict
            ``kind = "fix"``, ``sweep``, ``ris``, ``frames`` (first and last beam's), ``detected``,
            ``position`` [m], ``std`` [m], ``peb`` [m], ``flags``, ``lost_packets``, ``latency`` [s],
            ``window``, ``error``.
        """
        return json_safe({"kind": "fix", "sweep": self.sweep, "ris": self.ris,
                          "frames": [self.frames[0], self.frames[-1]] if self.frames else [],
                          "detected": self.detected, "position": list(self.position), "std": list(self.std),
                          "peb": self.peb, "flags": [{"code": c, "message": m} for c, m in self.flags],
                          "lost_packets": self.lost_packets, "latency": self.latency, "window": list(self.window),
                          "error": self.error})


@dataclass(frozen=True)
class FusedLiveFix:
    """The fused fix of one time-division round (every RIS's sweep of one cycle), as ``risloc locate a.npz b.npz``.

    Attributes
    ----------
    sweep : int
        The round (cycle) index, from 0.
    used : tuple of str
        The RISs in the fusion.
    excluded : tuple of (str, str)
        The RISs left out and why.
    detected : bool
        Some RIS was detected (else no position).
    position : tuple of 3 floats
        World frame [m].
    std : tuple of 3 floats
        1σ per axis [m] (``inf``: unobservable).
    peb : float
        [m].
    flags : tuple of (str, str)
        The fusion's flags.
    final_time, fix_time : float
        ``time.monotonic()`` when the round's last sweep became final, and of the fused fix [s].
    error : str or None
        Why the fixes could not be fused (one line), else None.
    fused : dsp.fusion.FusedFix or None
        Not compared.
    """

    sweep: int
    used: tuple[str, ...]
    excluded: tuple[tuple[str, str], ...]
    detected: bool
    position: tuple[float, ...]
    std: tuple[float, ...]
    peb: float
    flags: tuple[tuple[str, str], ...]
    final_time: float
    fix_time: float
    error: str | None = None
    fused: Any = field(default=None, compare=False, repr=False)

    @property
    def latency(self) -> float:
        """From the round's last frame final to the fused fix [s]."""
        return self.fix_time - self.final_time

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON (one line of the JSON lines file).

        Returns
        -------
        dict
            ``kind = "fused"``, ``sweep``, ``used``, ``excluded``, ``detected``, ``position`` [m],
            ``std`` [m], ``peb`` [m], ``flags``, ``latency`` [s], ``error``.
        """
        return json_safe({"kind": "fused", "sweep": self.sweep, "used": list(self.used),
                          "excluded": [list(e) for e in self.excluded], "detected": self.detected,
                          "position": list(self.position), "std": list(self.std), "peb": self.peb,
                          "flags": [{"code": c, "message": m} for c, m in self.flags], "latency": self.latency,
                          "error": self.error})


@dataclass(frozen=True)
class _Slot:
    """One sweep to import: its RIS, index, first frame (``None``: search) and the frames to read ``[start, stop)``."""

    sweep: int
    ris_index: int
    first_frame: int | None
    start: int
    stop: int


def _lost_in_beams(capture: Any, frame_bytes: int) -> int:
    """Lost packets (the reader's list, window offsets) whose bytes lie in a beam's frame."""
    beams = {int(f) for f in capture.frame_index}
    lost = 0
    for run in capture.provenance["reader"]["dropped_packets"]:
        per = max(int(run["num_bytes"]) // max(int(run["count"]), 1), 1)
        for i in range(int(run["count"])):
            lo = int(run["stream_offset"]) + i * per
            frames = range(lo // frame_bytes, (lo + per - 1) // frame_bytes + 1)
            lost += any(f in beams for f in frames)
    return lost


class SweepWatcher:
    """Says which sweeps of a growing recording are complete, and localizes each (module docstring).

    Parameters
    ----------
    folder : path
        The recording's folder (``<prefix>_Raw_0.bin``, ``_Raw_1.bin``, ... written in place).
    config : path, optional
        The radar's mmWave SDK ``.cfg`` (or Studio ``.json``); default ``folder/adc_data.cfg``.
    schedule : path or SweepSchedules, optional
        The sweep schedule (one RIS or several ``[[ris]]`` slots); default ``folder/sweep.toml``.
    prefix : str
        The split files' prefix (``adc_data``).
    first_frame : int or "auto", optional
        Overrides the schedule's first frame (one RIS only), as ``--first-frame``.
    period_frames : float, optional
        Frames from one sweep's start to the next (default: the time-division cycle, else the RIS's
        program: sync code + gap + beams + the repeated code) [frames].
    localize : callable, optional
        ``localize(name, capture) -> CaseResult``; default :func:`locate_capture` (``risloc locate``'s
        defaults).
    import_options : dict, optional
        Keywords of :func:`~risloc_rt.measured.sweep.importer.import_capture` (``lanes``, ``iq_swap``,
        ``form``, ``leakage``, ``gate_range`` [m], ``channels``, ``min_confidence``, ``assemble``,
        ``check_schedule``, ``frames_per_block``), as ``risloc capture import`` passes them.
    margin_frames : int, optional
        ``"auto"``: final frames needed after a fitted sweep's end (default one beam's frames + 1).
    slack_frames : float, optional
        ``"auto"``: frames searched on either side of a predicted sweep (default 2 + half a beam).
    clock : callable
        The clock of the fix times [s] (``time.monotonic``).
    workdir : path, optional
        Where the temporary window folders go (default the system's temporary folder).
    fuse_height : float, optional
        The radar's known height z [m] (``--ue-height``): a round's fused fix takes it as one more
        measurement (:func:`risloc_rt.io.fused.fuse_cases`).

    Raises
    ------
    MeasuredFormatError
        A bad configuration or schedule, an override with several RISs, ``"auto"`` with several RISs.
    """

    def __init__(self, folder: str | Path, config: str | Path | None = None,
                 schedule: str | Path | SweepSchedules | None = None, *, prefix: str = "adc_data",
                 first_frame: int | str | None = None, period_frames: float | None = None,
                 localize: Localizer | None = None, import_options: dict[str, Any] | None = None,
                 margin_frames: int | None = None, slack_frames: float | None = None,
                 clock: Callable[[], float] = time.monotonic, workdir: str | Path | None = None,
                 fuse_height: float | None = None) -> None:
        self.folder = Path(folder)
        self.fuse_height = fuse_height
        self.prefix = prefix
        self.config_path = Path(config) if config is not None else self.folder / f"{prefix}.cfg"
        if not self.config_path.is_file():
            raise MeasuredFormatError(f"radar configuration {self.config_path} does not exist; give the .cfg the radar "
                                      "runs (--config)")
        cfg, cfg_lanes = load_config(self.config_path)
        self.options = dict(import_options or {})
        for bad in ("ris", "first_frame", "series_cache"):
            if bad in self.options:
                raise TypeError(f"import_options may not set {bad!r}: the watcher chooses it per sweep")
        lanes = self.options.get("lanes") or cfg_lanes or 2
        self.frame_bytes = RawLayout.from_config(cfg, lanes=lanes).frame_bytes
        self.payload = MAX_PAYLOAD
        radar = cfg.to_radar_config()
        self._num_chirps = radar.num_chirps
        self._fractions = chirp_fractions(radar.num_chirps, radar.chirp_interval, radar.frame_interval)
        self._width = radar.frame_duration / radar.frame_interval
        sched = schedule if schedule is not None else self.folder / "sweep.toml"
        self.schedules = sched if isinstance(sched, SweepSchedules) else read_sweep_schedules(sched)
        self._setup_slots(cfg, first_frame, period_frames)
        fpb = float(self.program.frames_per_beam)
        self.margin_frames = int(math.ceil(fpb)) + 1 if margin_frames is None else int(margin_frames)
        self.slack_frames = 2.0 + 0.5 * fpb if slack_frames is None else float(slack_frames)
        self._localize = localize or locate_capture
        self._clock = clock
        self._workdir = None if workdir is None else Path(workdir)
        self._next = (0, 0)                       # (sweep, position in the slot order) of the next fixed slot
        self._anchor: tuple[int, float, float] | None = None     # "auto": (sweep, start, dwell) of the last found
        self._next_auto = 0
        self._searched = -1                       # "auto": final frames at the last search for the first sweep
        self._last_error = ""
        self._rounds: dict[int, list[LiveFix]] = {}
        self._history: deque[tuple[int, float]] = deque(maxlen=HISTORY)   # (final bytes, when they grew)
        self._finished = False

    def _setup_slots(self, cfg: TiChirpConfig, first_frame: int | str | None, period_frames: float | None) -> None:
        """The RISs' first frames, slot order, program and period from the schedule (and the overrides)."""
        s = self.schedules
        tf = cfg.to_radar_config().frame_interval
        if first_frame is not None and len(s.names) > 1:
            raise MeasuredFormatError(f"--first-frame: {s.source} describes {len(s.names)} RISs in time division; "
                                      "give each [[ris]] its slot's first_frame in the schedule instead")
        one = s.schedule(s.names[0] if s.several else None, frame_interval=tf)
        self.program = one.program(tf)
        self.auto = len(s.names) == 1 and (first_frame == "auto" or (first_frame is None and one.first_frame is None))
        if self.auto:
            firsts: tuple[int, ...] = (0,)
        elif first_frame is not None:
            if isinstance(first_frame, bool) or not isinstance(first_frame, (int, np.integer)) or first_frame < 0:
                raise MeasuredFormatError(f"first frame {first_frame!r} must be an integer >= 0 or 'auto'")
            firsts = (int(first_frame),)
        else:
            firsts = s.first_frames(tf) if s.several else (int(one.first_frame),)
        self.first_frames = tuple(int(f) for f in firsts)
        self.order = tuple(sorted(range(len(s.names)), key=lambda i: self.first_frames[i]))
        p = self.program
        if period_frames is not None:
            period = float(period_frames)
        elif len(s.names) > 1:
            period = s.time_division(tf).cycle / tf
        else:
            period = p.sync_length + p.sweep_length + p.after_length
        if not math.isfinite(period) or period < p.sweep_length - 1e-9:
            raise MeasuredFormatError(f"sweep period {period:g} frames is shorter than one sweep "
                                      f"({p.sweep_length:g} frames); give a period of at least that")
        self.period = period

    # ------------------------------------------------------------------------------------------ frames and bytes

    def _files(self) -> tuple[Path, ...]:
        return capture_files(self.folder / split_name(self.prefix, 0))

    def _ready_bytes(self, stop: int) -> int:
        """Final bytes a window ``[.., stop)`` needs: to the end of the packet holding its last byte."""
        end = stop * self.frame_bytes
        return -(-end // self.payload) * self.payload

    def _is_final(self, stop: int, final_bytes: int, finished: bool) -> bool:
        return final_bytes >= self._ready_bytes(stop) or (finished and final_bytes >= stop * self.frame_bytes)

    def _final_frames(self, final_bytes: int, finished: bool) -> int:
        """Whole frames that are final (with the packet holding each frame's last byte)."""
        if finished:
            return final_bytes // self.frame_bytes
        return (final_bytes // self.payload * self.payload) // self.frame_bytes

    def _window(self, start: int, stop: int, final_bytes: int, target: Path) -> int:
        """Copy frames ``[start, stop)`` into ``target/<prefix>_Raw_0.bin`` (module docstring, "The window imported");
        returns the first frame copied (earlier than ``start`` when the window holds a lost packet)."""
        fb, P = self.frame_bytes, self.payload
        files = self._files()
        a = start * fb // P * P
        b = min(self._ready_bytes(stop), final_bytes)
        data = read_stream(files, a, b)
        if _zero_packet(data, P):
            start = grid_frame(start, fb, P)
            body = read_stream(files, start * fb, b)
        else:
            body = data[start * fb - a:stop * fb - a]
        first = target / split_name(self.prefix, 0)
        if len(body) % _MIB == 0 and len(body) > 2:          # not "a split file is missing" (exactly k MiB)
            first.write_bytes(body[:-2])
            (target / split_name(self.prefix, 1)).write_bytes(body[-2:])
        else:
            first.write_bytes(body)
        return start

    def _import(self, slot: _Slot, final_bytes: int) -> tuple[Any, int]:
        """The capture of ``slot``'s window (import_capture), and the recorded frame of the window's frame 0."""
        name = self.schedules.names[slot.ris_index] if self.schedules.several else None
        with tempfile.TemporaryDirectory(prefix="risloc-live-", dir=self._workdir) as tmp:
            start = self._window(slot.start, slot.stop, final_bytes, Path(tmp))
            first = "auto" if slot.first_frame is None else slot.first_frame - start
            capture = import_capture(Path(tmp) / split_name(self.prefix, 0), self.config_path, self.schedules,
                                     ris=name, first_frame=first, **self.options)
        return capture, start

    # ------------------------------------------------------------------------------------------ which sweeps

    def _fixed_slot(self, sweep: int, position: int) -> _Slot:
        """Sweep ``sweep`` of the RIS at ``position`` in the slot order: its frames from the schedule's timing."""
        k = self.order[position]
        first = self.first_frames[k] + int(round(sweep * self.period))
        p = self.program
        align = manual_alignment(p, first, num_frames=first + int(math.ceil(p.sweep_length)) + 2,
                                 fractions=self._fractions, frame_width=self._width,
                                 assemble=self.options.get("assemble", DEFAULT_ASSEMBLE))
        stop = int((align.chirp_start[-1] + self._num_chirps - 1) // self._num_chirps) + 1
        return _Slot(sweep=sweep, ris_index=k, first_frame=first,
                     start=max(0, first - int(math.ceil(p.sync_length))), stop=stop)

    def _predicted_slot(self) -> tuple[_Slot, float]:
        """``"auto"``: the window of the next sweep, around where the last one found puts it, and its predicted
        end [frames]."""
        sweep, start, dwell = self._anchor  # type: ignore[misc]
        p = self.program
        rate = dwell / float(p.frames_per_beam)
        t = start + (self._next_auto - sweep) * self.period * rate
        lo = int(math.floor(t - p.sync_length * rate - self.slack_frames))
        hi = int(math.ceil(t + (p.sweep_length + p.after_length) * rate + self.slack_frames)) + self.margin_frames
        end = t + (p.sweep_length + p.after_length) * rate
        return _Slot(sweep=self._next_auto, ris_index=0, first_frame=None, start=max(0, lo), stop=hi), end

    @property
    def search_frames(self) -> int:
        """``"auto"``: the latest final frames the first sweep is searched in: twice the RIS's program (at the
        largest clock drift searched) + the margin [frames]."""
        drift = 1.0 + self.schedules.schedules[0].max_clock_drift
        p = self.program
        return int(math.ceil(2 * (p.sync_length + p.sweep_length + p.after_length) * drift)) + 2 * self.margin_frames

    @property
    def first_fix_frames(self) -> int:
        """Final frames the first fix needs at least [frames]: a fixed first frame's last beam frame + 1, or
        (``"auto"``) the program at the slowest RIS clock searched + the margin, after the lead frames."""
        if not self.auto:
            return self._fixed_slot(0, 0).stop
        drift = 1.0 + self.schedules.schedules[0].max_clock_drift
        p = self.program
        return int(math.ceil((p.sync_length + p.sweep_length + p.after_length) * drift)) + self.margin_frames

    # ------------------------------------------------------------------------------------------ the fixes

    def _became_final(self, capture: Any, start: int) -> float:
        """When the capture's last recorded frame (the last beam's last chirp) became final [s]: between the first
        progress report that covers it and the one before, interpolated at the data rate in between."""
        chirps = capture.provenance["alignment"]["beam_chirps"]
        stop = start + max(seg[0] for beam in chirps for seg in beam) + 1
        need = self._ready_bytes(stop)
        if self._finished:
            need = min(need, stop * self.frame_bytes)
        before = None
        for grown, when in self._history:
            if grown >= need:
                if before is None or grown == before[0]:
                    return when
                share = (need - before[0]) / (grown - before[0])
                return before[1] + share * (when - before[1])
            before = (grown, when)
        return self._history[-1][1]

    def _fix(self, slot: _Slot, capture: Any, start: int) -> LiveFix:
        """Localize ``capture`` (``slot``'s) and make its :class:`LiveFix`."""
        final_time = self._became_final(capture, start)
        name = self.schedules.names[slot.ris_index]
        case = self._localize(name or "sweep", capture)
        loc = case.localization
        std = loc.std
        nan3 = (math.nan,) * 3
        return LiveFix(sweep=slot.sweep, ris=name, frames=tuple(int(f) + start for f in capture.frame_index),
                       detected=bool(loc.detected), position=_vector(loc.position) if loc.detected else nan3,
                       std=_vector(std.position) if std is not None else nan3,
                       peb=float(std.peb) if std is not None else math.nan,
                       flags=tuple((f.code, f.message) for f in loc.flags),
                       lost_packets=_lost_in_beams(capture, self.frame_bytes), final_time=final_time,
                       fix_time=self._clock(), window=(start, start + int(capture.provenance["reader"]
                                                                           ["frames_recorded"])), case=case)

    def _failed(self, slot: _Slot, error: str, final_time: float) -> LiveFix:
        nan3 = (math.nan,) * 3
        return LiveFix(sweep=slot.sweep, ris=self.schedules.names[slot.ris_index], frames=(), detected=False,
                       position=nan3, std=nan3, peb=math.nan, flags=(), lost_packets=0, final_time=final_time,
                       fix_time=self._clock(), window=(slot.start, slot.stop), error=error)

    def _round(self, fix: LiveFix) -> list[Any]:
        """``fix`` and, when it completes a time-division round of several RISs, the round's fused fix."""
        if len(self.schedules.names) < 2:
            return [fix]
        done = self._rounds.setdefault(fix.sweep, [])
        done.append(fix)
        if len(done) < len(self.schedules.names):
            return [fix]
        del self._rounds[fix.sweep]
        cases = [f.case for f in done if f.case is not None]
        error = None
        try:
            fused = fuse_cases(cases, height=self.fuse_height) if cases else None
        except ValueError as exc:                   # e.g. two slots of one RIS: no fused fix, said why
            fused, error = None, " ".join(str(exc).split())
        nan3 = (math.nan,) * 3
        out = FusedLiveFix(
            sweep=fix.sweep, used=() if fused is None else tuple(fused.used),
            excluded=() if fused is None else tuple((str(a), str(b)) for a, b in fused.excluded),
            detected=fused is not None, position=nan3 if fused is None else _vector(fused.position),
            std=nan3 if fused is None else _vector(fused.std), peb=math.nan if fused is None else float(fused.peb),
            flags=() if fused is None else tuple((f.code, f.message) for f in fused.flags),
            final_time=max(f.final_time for f in done), fix_time=self._clock(), error=error, fused=fused)
        return [fix, out]

    def _localized(self, slot: _Slot, final_bytes: int) -> LiveFix:
        """Import and localize ``slot``; a sweep the import refuses gives a fix with its one-line error."""
        try:
            capture, start = self._import(slot, final_bytes)
        except MeasuredFormatError as exc:
            return self._failed(slot, str(exc), self._history[-1][1])
        if self.auto:
            a = capture.provenance["alignment"]
            self._anchor = (slot.sweep, start + float(a["start"]), float(a["dwell"]))
        return self._fix(slot, capture, start)

    def _search_first(self, final_bytes: int, frames: int) -> LiveFix | None:
        """``"auto"``: look for the first sweep in the latest final frames (module docstring); its fix, or None."""
        p = self.program
        drift = self.schedules.schedules[0].max_clock_drift
        least = int(math.ceil((p.sync_length + p.sweep_length) * (1 - drift))) + self.margin_frames
        step = max(1, int(p.sweep_length // 4))
        if frames < least or frames == self._searched or (not self._finished and self._searched >= 0
                                                           and frames - self._searched < step):
            return None
        self._searched = frames
        slot = _Slot(sweep=0, ris_index=0, first_frame=None, start=max(0, frames - self.search_frames), stop=frames)
        try:
            capture, start = self._import(slot, final_bytes)
        except MeasuredFormatError as exc:
            self._last_error = str(exc)
            return None
        a = capture.provenance["alignment"]
        end = start + float(a["start"]) + (p.sweep_length + p.after_length) * float(a["dwell"]) / p.frames_per_beam
        if end > frames - self.margin_frames:
            self._last_error = (f"the sweep found ends at frame {end:.2f}, less than {self.margin_frames} frame(s) "
                                f"before the last final frame {frames}: it may still be running")
            return None
        self._anchor = (0, start + float(a["start"]), float(a["dwell"]))
        self._next_auto = 1
        return self._fix(slot, capture, start)

    def _advance(self, final_bytes: int) -> list[Any]:
        """Every sweep now complete, in recording order: its fix (and a round's fused fix)."""
        out: list[Any] = []
        if not self.auto:
            while True:
                slot = self._fixed_slot(*self._next)
                if not self._is_final(slot.stop, final_bytes, self._finished):
                    return out
                sweep, position = self._next
                self._next = (sweep + 1, 0) if position + 1 == len(self.order) else (sweep, position + 1)
                out += self._round(self._localized(slot, final_bytes))
        frames = self._final_frames(final_bytes, self._finished)
        if self._anchor is None:
            fix = self._search_first(final_bytes, frames)
            if fix is None:
                return out
            out.append(fix)
        while True:
            slot, end = self._predicted_slot()
            if slot.stop > frames and self._finished and end <= frames:     # the recording's end cuts the slack
                slot = _Slot(sweep=slot.sweep, ris_index=0, first_frame=None, start=slot.start, stop=frames)
            if slot.stop > frames:
                return out
            self._next_auto += 1
            out.append(self._localized(slot, final_bytes))

    def update(self, final_bytes: int, final_time: float | None = None) -> list[Any]:
        """Take the recording's final prefix; localize every sweep it completes.

        Parameters
        ----------
        final_bytes : int
            The stream prefix ``[0, final_bytes)`` on disk and final [bytes] (it only grows).
        final_time : float, optional
            When it last grew, on the watcher's clock [s] (default: now).

        Returns
        -------
        list of LiveFix and FusedLiveFix
            The sweeps completed since the last call, in recording order (each once); a round's fused
            fix after its last RIS's fix.
        """
        final_bytes = int(final_bytes)
        if self._history and final_bytes < self._history[-1][0]:
            raise MeasuredFormatError(f"final_bytes went back from {self._history[-1][0]} to {final_bytes}: the "
                                      "final prefix of a recording only grows")
        if not self._history or final_bytes > self._history[-1][0]:
            self._history.append((final_bytes, self._clock() if final_time is None else float(final_time)))
        return self._advance(final_bytes)

    def finish(self, final_bytes: int, final_time: float | None = None) -> list[Any]:
        """The recording has stopped: localize what its last bytes complete (a partial final frame is ignored).

        Parameters
        ----------
        final_bytes : int
            The recording's length [bytes].
        final_time : float, optional
            When it last grew [s] (default: now).

        Returns
        -------
        list of LiveFix and FusedLiveFix
            As :meth:`update`; with ``"auto"`` and no sweep found, one fix whose ``error`` says why.
        """
        self._finished = True
        out = self.update(final_bytes, final_time)
        if self.auto and self._anchor is None and self._history:
            slot = _Slot(sweep=0, ris_index=0, first_frame=None, start=0, stop=self._final_frames(final_bytes, True))
            out.append(self._failed(slot, f"no sweep found in the {slot.stop} frame(s) recorded"
                                    + (f": {self._last_error}" if self._last_error else ""), self._history[-1][1]))
        return out
