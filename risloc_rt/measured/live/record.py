"""A whole live recording: the radar's ``.cfg`` and a DCA1000, to a folder every command reads unchanged.

:func:`record` runs, in this order:

1. the ``.cfg`` parsed and checked against the device family (LVDS lanes, data format, frame size,
   data rate: :func:`~risloc_rt.measured.ti.devices.check_device_config`); the out folder prepared
   (refused when it holds a recording; the ``.cfg`` copied as ``adc_data.cfg``, the sweep schedule as
   ``sweep.toml``, so ``risloc capture import DIR/adc_data_Raw_0.bin --config DIR/adc_data.cfg
   --sweep DIR/sweep.toml`` reads it);
2. the data port bound (:class:`~.receiver.DatagramReceiver`), the DCA1000 connected, configured
   (lanes and ADC bits from the ``.cfg``) and told RECORD_START (:class:`~.dca1000_link.Dca1000Link`);
3. the radar (its port opened first) sent the ``.cfg`` line by line, then ``sensorStart`` (:class:`~.radar_cli.RadarCli`);
4. datagrams written (:class:`~.recording_writer.RecordingWriter`) until the frames asked (or the
   ``.cfg``'s ``numFrames``), the duration, Ctrl-C or a silent link;
5. ``sensorStop``, RECORD_STOP, the datagrams still in flight drained, everything closed.

On any failure or ``KeyboardInterrupt`` the radar gets ``sensorStop`` and the DCA1000 RECORD_STOP
(best effort), the writer is closed (the recording is complete and readable up to what arrived),
the exception is re-raised carrying the :class:`RecordingSummary` (:func:`recording_summary`).
"""

from __future__ import annotations

import shutil
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..dca1000.packets import MAX_PAYLOAD, DroppedPackets
from ..errors import MeasuredFormatError
from .addresses import Endpoints
from .receiver import DEFAULT_RCVBUF, DatagramReceiver, SocketBuffer
from .recording_writer import DEFAULT_SPLIT_SIZE, LOST_PACKETS_NAME, RecordingWriter, existing_recording, log_name

__all__ = ["CONFIG_NAME", "SCHEDULE_NAME", "STOP_REASONS", "RecordPlan", "RecordingError", "RecordingProgress",
           "RecordingSummary", "record", "recording_summary"]

#: The ``.cfg``'s name in the out folder (what the emulators write, ``capture import --config``).
CONFIG_NAME = "adc_data.cfg"
#: The sweep schedule's name in the out folder.
SCHEDULE_NAME = "sweep.toml"
#: Why a recording stopped: the frames asked were recorded, the duration passed, Ctrl-C, the data
#: stopped coming (cable, power, the radar), or another error.
STOP_REASONS = ("frames", "duration", "interrupted", "link-lost", "error")
#: The recording's file prefix (TI's CLI and mmWave Studio).
PREFIX = "adc_data"


class RecordingError(MeasuredFormatError):
    """A recording that could not go on: no data from the DCA1000, or the data stopped (one line)."""


@dataclass(frozen=True)
class RecordPlan:
    """What to record, where, from which radar and DCA1000.

    Parameters
    ----------
    config : path
        The radar's mmWave SDK ``.cfg``.
    serial_port : str
        The radar's CLI (user) UART, e.g. ``/dev/ttyUSB0``.
    out : path
        The folder to write (created; refused when it holds a recording).
    frames : int, optional
        Stop after this many frames (at most the ``.cfg``'s ``numFrames`` when that is not 0).
    duration : float, optional
        Stop after this long [s].
    sweep : path, optional
        The sweep schedule (``sweep.toml``), copied into the folder.
    endpoints : Endpoints, default ``Endpoints()``
        The host's and the DCA1000's addresses and ports.
    device : str, default "IWR6843"
        The radar's device family (:func:`~risloc_rt.measured.ti.devices.device_family`).
    split_size : int, default :data:`~.recording_writer.DEFAULT_SPLIT_SIZE`
        File size limit [bytes].
    baudrate : int, default 115200
        The CLI UART's baud rate [bit/s].
    """

    config: Path
    serial_port: str
    out: Path
    frames: int | None = None
    duration: float | None = None
    sweep: Path | None = None
    endpoints: Endpoints = field(default_factory=Endpoints)
    device: str = "IWR6843"
    split_size: int = DEFAULT_SPLIT_SIZE
    baudrate: int = 115200

    def __post_init__(self) -> None:
        object.__setattr__(self, "config", Path(self.config))
        object.__setattr__(self, "out", Path(self.out))
        if self.sweep is not None:
            object.__setattr__(self, "sweep", Path(self.sweep))
        if self.frames is not None and (isinstance(self.frames, bool) or not isinstance(self.frames, int)
                                        or self.frames < 1):
            raise MeasuredFormatError(f"--frames {self.frames!r} must be a whole number of frames >= 1")
        if self.duration is not None and not float(self.duration) > 0:
            raise MeasuredFormatError(f"--duration {self.duration!r} must be a time > 0 s")


@dataclass(frozen=True)
class RecordingProgress:
    """A recording's state, handed to ``on_progress`` a few times a second.

    Attributes
    ----------
    elapsed : float
        Since the radar was started [s].
    received_bytes : int
        Payload bytes received and placed [bytes].
    final_bytes : int
        The stream prefix ``[0, final_bytes)`` on disk and final (every packet in it arrived or was
        declared lost) [bytes]: frames ``[0, final_bytes // frame_bytes)`` may be read.
    frames : int
        Whole frames in ``final_bytes``.
    frame_bytes : int
        Bytes of one frame [bytes].
    lost_packets : int
        Packets zero-filled so far.
    rate : float
        Mean data rate since the first datagram [bytes/s].
    socket_high_water : int
        Most bytes seen waiting in the data socket [bytes].
    final_time : float or None
        ``time.monotonic()`` when ``final_bytes`` last grew [s].
    folder : Path
        The recording's folder.
    socket_buffer : SocketBuffer or None
        The data socket's receive buffer (its :meth:`~.receiver.SocketBuffer.hint` when too small).
    """

    elapsed: float
    received_bytes: int
    final_bytes: int
    frames: int
    frame_bytes: int
    lost_packets: int
    rate: float
    socket_high_water: int
    final_time: float | None
    folder: Path
    socket_buffer: SocketBuffer | None = None


@dataclass(frozen=True)
class RecordingSummary:
    """What a recording holds and why it stopped.

    Attributes
    ----------
    folder : Path
        The recording's folder.
    files : tuple of Path
        The split files, in order.
    bytes : int
        Stream bytes written, zero-filled gaps included [bytes].
    frames : int
        Whole frames recorded.
    frame_bytes : int
        Bytes of one frame [bytes].
    partial_frame_bytes : int
        Bytes of a final, incomplete frame (readers drop it) [bytes].
    lost : tuple of DroppedPackets
        The zero-filled runs (also in ``lost_packets.csv``).
    duplicates, late, out_of_order : int
        Datagrams dropped as duplicates, dropped as late, and received out of sequence.
    rate : float
        Mean data rate [bytes/s].
    socket_high_water : int
        Most bytes waiting in the data socket [bytes].
    kernel_drops : int or None
        Datagrams the kernel dropped for a full socket buffer (None: unknown).
    socket_buffer : SocketBuffer or None
        The receive buffer granted.
    elapsed : float
        From sensorStart to the stop [s].
    stopped : str
        One of :data:`STOP_REASONS`.
    message : str or None
        The error's one line when ``stopped`` is ``"error"`` or ``"link-lost"``.
    """

    folder: Path
    files: tuple[Path, ...]
    bytes: int
    frames: int
    frame_bytes: int
    partial_frame_bytes: int
    lost: tuple[DroppedPackets, ...]
    duplicates: int
    late: int
    out_of_order: int
    rate: float
    socket_high_water: int
    kernel_drops: int | None
    socket_buffer: SocketBuffer | None
    elapsed: float
    stopped: str
    message: str | None = None

    @property
    def lost_packets(self) -> int:
        """Packets zero-filled."""
        return sum(d.count for d in self.lost)

    def describe(self) -> str:
        """One line: frames, bytes, lost packets, rate, socket high-water mark, why it stopped.

        Returns
        -------
        str
        """
        partial = f" + a partial frame of {self.partial_frame_bytes} B (dropped by readers)" \
            if self.partial_frame_bytes else ""
        lost = f"{self.lost_packets} lost packet(s) zero-filled ({sum(d.num_bytes for d in self.lost)} B)"
        return (f"{self.folder}: {self.frames} frame(s) of {self.frame_bytes} B{partial}, {self.bytes} B in "
                f"{len(self.files)} file(s), {lost}, {self.duplicates} duplicate(s), {self.late} late, "
                f"{self.rate / 1e6:.3g} MB/s, socket high-water {self.socket_high_water} B; stopped: {self.stopped}"
                + (f" ({self.message})" if self.message else ""))


def recording_summary(exc: BaseException) -> RecordingSummary | None:
    """The summary a failed or interrupted :func:`record` attached to its exception.

    Parameters
    ----------
    exc : BaseException
        What :func:`record` raised.

    Returns
    -------
    RecordingSummary or None
        None when the exception came before anything was recorded.
    """
    return getattr(exc, "recording_summary", None)


@dataclass(frozen=True)
class _Setup:
    """The checked configuration of a plan."""

    frame_bytes: int
    target_frames: int | None
    lanes: int
    fpga: object


def _check(plan: RecordPlan) -> _Setup:
    """Parse and check the ``.cfg`` against the device; the frames to record (no hardware touched)."""
    from ..dca1000.control import FpgaConfig
    from ..ti.devices import check_device_config, device_family
    from ..ti.sdk_cfg import read_sdk_cfg

    if plan.config.suffix.lower() != ".cfg" or not plan.config.is_file():
        raise MeasuredFormatError(f"--config {plan.config}: give the radar's mmWave SDK .cfg file (it is sent to the "
                                  "radar's CLI port)")
    parsed = read_sdk_cfg(plan.config)
    check = check_device_config(parsed, device_family(plan.device))
    cfg = parsed.config
    target = plan.frames
    if cfg.num_frames:
        if target is not None and target > cfg.num_frames:
            raise MeasuredFormatError(f"--frames {target} is more than the {cfg.num_frames} frames the .cfg's "
                                      f"frameCfg asks of the radar ({plan.config}): lower --frames, or set numFrames "
                                      "to 0 (until stopped) or more")
        target = cfg.num_frames if target is None else target
    elif target is None and plan.duration is None:
        raise MeasuredFormatError(f"{plan.config}: frameCfg numFrames is 0 (the radar runs until stopped): give "
                                  "--frames N or --duration S")
    return _Setup(frame_bytes=check.frame_bytes, target_frames=target,
                  lanes=check.lanes, fpga=FpgaConfig.from_chirp_config(cfg, lanes=check.lanes))


def _prepare_folder(plan: RecordPlan) -> bool:
    """Refuse a folder holding a recording (or its ``.cfg``/schedule copies); copy the ``.cfg`` and schedule.
    Whether the folder was made here (:func:`_undo_folder` removes it again when nothing was recorded)."""
    out = plan.out
    if out.exists() and not out.is_dir():
        raise MeasuredFormatError(f"--out {out} is a file: give a folder (new or empty) for the recording")
    taken = existing_recording(out, PREFIX) + [n for n in (CONFIG_NAME, SCHEDULE_NAME) if (out / n).exists()]
    if taken:
        raise MeasuredFormatError(f"--out {out} already holds a recording ({', '.join(sorted(taken)[:3])}); risloc "
                                  "does not overwrite one: give a new or empty folder")
    if plan.sweep is not None:
        from ..sweep.schedules import read_sweep_schedules

        read_sweep_schedules(plan.sweep)                     # a bad schedule: one line, before the hardware
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    with open(plan.config, "rb") as src, open(out / CONFIG_NAME, "xb") as dst:
        shutil.copyfileobj(src, dst)
    if plan.sweep is not None:
        with open(plan.sweep, "rb") as src, open(out / SCHEDULE_NAME, "xb") as dst:
            shutil.copyfileobj(src, dst)
    return made


def _undo_folder(plan: RecordPlan, made: bool) -> None:
    """A session that failed before any data arrived leaves nothing: the files this run wrote into ``--out``
    (the ``.cfg`` and schedule copies, the empty log, lost-packet list and raw files; the folder was refused
    if any of them was there before, so none is the user's) and the folder itself when this run made it.
    Then the same command can simply be run again."""
    out = plan.out
    ours = {CONFIG_NAME, SCHEDULE_NAME, log_name(PREFIX), LOST_PACKETS_NAME}
    for name in sorted(ours | set(existing_recording(out, PREFIX))):
        path = out / name
        if path.is_file() and (name in ours or path.stat().st_size == 0):   # raw files: only empty ones
            path.unlink()
    if made:
        try:
            out.rmdir()                          # only when empty: anything else stays
        except OSError:
            pass


class _Session:
    """The devices, receiver and writer of one recording, stopped and closed on every path."""

    def __init__(self, plan: RecordPlan, setup: _Setup, options: dict) -> None:
        self.plan, self.setup, self.options = plan, setup, options
        self.receiver: DatagramReceiver | None = None
        self.writer: RecordingWriter | None = None
        self.link = self.radar = None
        self.dca_started = False
        self.t0: float | None = None
        self.stopped, self.message = "error", None

    def start(self, stack: ExitStack) -> None:
        """Open the radar's port, bind the data port, start the DCA1000 recording, configure and start the radar.

        The radar's port is opened first: a wrong port fails before the DCA1000 is touched, and a
        failure at the DCA1000 still reaches the radar with ``sensorStop``.
        """
        from .dca1000_link import Dca1000Link
        from .radar_cli import RadarCli

        o = self.options
        self.radar = stack.enter_context(RadarCli(self.plan.serial_port, self.plan.baudrate, o["serial_timeout"]))
        self.receiver = stack.enter_context(DatagramReceiver(self.plan.endpoints, rcvbuf=o["rcvbuf"],
                                                             silence_timeout=o["silence_timeout"]))
        limit = None if self.setup.target_frames is None else self.setup.target_frames * self.setup.frame_bytes
        self.writer = stack.enter_context(RecordingWriter(self.plan.out, PREFIX, self.plan.split_size, MAX_PAYLOAD,
                                                          lanes=self.setup.lanes, max_bytes=limit))
        self.link = stack.enter_context(Dca1000Link(self.plan.endpoints, timeout=o["link_timeout"]))
        self.link.connect()
        self.link.configure(self.setup.fpga)
        self.dca_started = True
        self.link.start_record()
        self.radar.send_config(self.plan.config, start=False)
        self.radar.sensor_start()
        self.t0 = time.monotonic()

    def progress(self) -> RecordingProgress:
        """The state now."""
        w, r = self.writer, self.receiver
        now = time.monotonic()
        first = r.first_time
        rate = w.received_bytes / (now - first) if first is not None and now > first else 0.0
        return RecordingProgress(elapsed=now - (self.t0 or now), received_bytes=w.received_bytes,
                                 final_bytes=w.final_bytes, frames=w.final_bytes // self.setup.frame_bytes,
                                 frame_bytes=self.setup.frame_bytes, lost_packets=sum(d.count for d in w.lost),
                                 rate=rate, socket_high_water=r.high_water, final_time=w.final_time,
                                 folder=self.plan.out, socket_buffer=r.buffer)

    def run(self, on_progress: Callable[[RecordingProgress], None] | None) -> str:
        """Receive and write until a stop condition; returns the reason."""
        w, r, o = self.writer, self.receiver, self.options
        deadline = None if self.plan.duration is None else self.t0 + float(self.plan.duration)
        next_report = time.monotonic()
        while True:
            data = r.get(timeout=0.02)
            batch = 0
            while data is not None:
                w.write(data)
                batch += 1
                data = r.get_nowait() if batch < 4096 else None
            w.tick()
            if w.full:
                return "frames"
            now = time.monotonic()
            if r.error is not None:
                raise RecordingError(f"the data port failed: {r.error}")
            if deadline is not None and now >= deadline:
                return "duration"
            if r.silent:
                raise RecordingError(f"no data from the DCA1000 for {r.silence_timeout:g} s after "
                                     f"{w.stream_bytes} bytes: the link was lost (Ethernet cable, the DCA1000's "
                                     "power, the radar stopped sending?)", )
            if r.first_time is None and now - self.t0 > o["start_timeout"]:
                raise RecordingError(f"no data from the DCA1000 within {o['start_timeout']:g} s of sensorStart: "
                                     "check the LVDS ribbon between the radar and the DCA1000, the DCA1000's "
                                     "switches (SW2: 'DCA1000 mode'), the .cfg's lvdsStreamCfg (-1 0 1 0) and "
                                     f"that nothing blocks UDP port {self.plan.endpoints.data_port} (firewall)")
            if on_progress is not None and now >= next_report:
                on_progress(self.progress())
                next_report = now + o["progress_interval"]

    def stop(self) -> list[str]:
        """sensorStop, RECORD_STOP, drain the datagrams in flight (best effort, never raises)."""
        problems = []
        if self.radar is not None and self.stopped in ("frames", "duration"):
            try:
                self.radar.sensor_stop()
            except Exception as exc:  # noqa: BLE001 - cleanup: reported, never raised
                problems.append(f"sensorStop: {' '.join(str(exc).split())}")
        elif self.radar is not None and not self.radar.stop_best_effort():
            problems.append("sensorStop: no 'Done' from the radar")
        if self.link is not None and not self.dca_started:
            self.link.stop_record_quietly()                 # never started: one datagram, no wait
        elif self.link is not None:
            try:
                self.link.stop_record()
            except Exception as exc:  # noqa: BLE001
                self.link.stop_record_quietly()
                problems.append(f"RECORD_STOP: {' '.join(str(exc).split())}")
        if self.receiver is not None:
            self.receiver.stop(drain=self.options["drain"])
            if self.writer is not None and not self.writer.closed:
                data = self.receiver.get_nowait()
                while data is not None:
                    self.writer.write(data)
                    data = self.receiver.get_nowait()
        return problems

    def summary(self) -> RecordingSummary | None:
        """The recording's summary (the writer closed first)."""
        w, r = self.writer, self.receiver
        if w is None:
            return None
        w.close()
        stats = r.stats() if r is not None else None
        span = (stats.last_time - stats.first_time) if stats and stats.first_time is not None else 0.0
        fb = self.setup.frame_bytes
        return RecordingSummary(
            folder=self.plan.out, files=tuple(w.files), bytes=w.final_bytes, frames=w.final_bytes // fb,
            frame_bytes=fb, partial_frame_bytes=w.final_bytes % fb, lost=tuple(w.lost), duplicates=w.duplicates,
            late=w.late, out_of_order=w.out_of_sequence, rate=w.received_bytes / span if span > 0 else 0.0,
            socket_high_water=stats.high_water if stats else 0, kernel_drops=stats.kernel_drops if stats else None,
            socket_buffer=r.buffer if r is not None else None,
            elapsed=(time.monotonic() - self.t0) if self.t0 is not None else 0.0,
            stopped=self.stopped, message=self.message)


_DEFAULTS = {"rcvbuf": DEFAULT_RCVBUF, "silence_timeout": 2.0, "start_timeout": 5.0, "link_timeout": 1.0,
             "serial_timeout": 2.0, "progress_interval": 0.2, "drain": 0.1}


def record(plan: RecordPlan, on_progress: Callable[[RecordingProgress], None] | None = None,
           **options: float) -> RecordingSummary:
    """Record from the radar and the DCA1000 (module docstring) until the plan's frames or duration.

    Parameters
    ----------
    plan : RecordPlan
        What to record and where.
    on_progress : callable, optional
        Called with a :class:`RecordingProgress` every ``progress_interval`` seconds (0.2 s) while
        recording; an exception it raises (``KeyboardInterrupt`` included) stops the recording
        like any other.
    **options : float
        ``rcvbuf`` [bytes], ``silence_timeout`` (2 s: the link is lost), ``start_timeout`` (5 s:
        no data after sensorStart), ``link_timeout`` (1 s per DCA1000 command), ``serial_timeout``
        (2 s per CLI line), ``progress_interval`` (0.2 s), ``drain`` (0.1 s of silence ends the
        drain after RECORD_STOP) [s].

    Returns
    -------
    RecordingSummary
        When the frames or the duration were reached.

    Raises
    ------
    MeasuredFormatError
        A bad plan, ``.cfg`` or folder (before any device is touched), a radar that refuses a line
        (its own error text), a DCA1000 that does not answer, :class:`RecordingError` (no data, a
        lost link); ``KeyboardInterrupt`` on Ctrl-C. Once the devices were started, the exception
        carries the summary (:func:`recording_summary`) and the recording is complete and readable; when
        no data had arrived, what this run wrote into ``--out`` (and the folder, if it made it) is removed,
        so the same command can be run again.
    """
    unknown = set(options) - set(_DEFAULTS)
    if unknown:
        raise TypeError(f"record() got unknown options {sorted(unknown)}; known: {sorted(_DEFAULTS)}")
    setup = _check(plan)
    made = _prepare_folder(plan)
    session = _Session(plan, setup, {**_DEFAULTS, **options})
    try:
        with ExitStack() as stack:
            try:
                session.start(stack)
                session.stopped = session.run(on_progress)
            except KeyboardInterrupt:
                session.stopped = "interrupted"
                raise
            except RecordingError as exc:
                session.stopped = "error" if session.receiver.first_time is None else "link-lost"
                session.message = " ".join(str(exc).split())
                raise
            except BaseException as exc:
                session.stopped, session.message = "error", " ".join(str(exc).split()) or type(exc).__name__
                raise
            finally:
                problems = session.stop()
                if problems and session.message is None and session.stopped not in ("frames", "duration"):
                    session.message = "; ".join(problems)
    except BaseException as exc:
        summary = session.summary()
        if summary is not None:
            exc.recording_summary = summary
        if session.writer is None or session.writer.received_bytes == 0:
            _undo_folder(plan, made)             # nothing arrived: no half-made folder blocks the next try
        raise
    return session.summary()
