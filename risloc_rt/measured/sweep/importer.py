"""A raw DCA1000 recording of a RIS sweep + its radar configuration + a sweep schedule → a ``Capture``.

The one bridge from measured data to the DSP: ``risloc capture import`` writes the result with
``save_capture`` and ``risloc locate`` processes it like a simulated capture.

Frame selection: the RIS's program (:class:`.ris_timing.RisProgram`) comes from the schedule, its
millisecond durations (``beam_dwell_ms``, ``[sync] chip_ms``, ``gap_ms``) converted with the
radar's frame period from the configuration. With a manual ``first_frame`` beam 0 starts with that
frame and every beam lasts the nominal dwell (a whole ``frames_per_beam``: beam m is recorded
frame ``first_frame + m·frames_per_beam``, the **first** frame of each beam); the given frame is
checked against the recording (:func:`.alignment.check_first_frame`): when the data clearly
supports another, the capture's provenance carries a one-line warning (``import_warnings``) and
the flag ``schedule-mismatch`` (``import_flags``). With ``first_frame = "auto"`` the program is
fitted to the recording (:mod:`.alignment`: sync code, the beam-dependent power, a dwell that is
not a whole number of frames, a drifting RIS clock). A beam no frame holds wholly takes its K
chirps across the frame boundary (``assemble="span"``, :func:`.alignment.select_chirps`); the
provenance lists each beam's chirps. One virtual channel
(``schedule.channel``), or several combined (maximal ratio), gives a cube ``[M, K, N]``
complex128 in ADC counts with the project's sign convention (``I − jQ``,
``docs/measured-captures.md``); then the self-interference is removed (:mod:`.leakage`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.fft

from dsp import BeamSweep, ProcessingConfig, RadarConfig, RisPose
from dsp.budget import check_memory

from ..._files import file_sha256
from ...model.capture import Capture, provenance
from ...model.ris import RisConfig
from ...model.scenario import Truth
from ..dca1000.channels import combine_channels, mrc_weights
from ..dca1000.inspection import file_iq_swap
from ..dca1000.raw_layout import RawLayout
from ..dca1000.reader import CaptureInfo, iter_frames, open_raw
from ..errors import MeasuredFormatError
from ..ti.chirp_config import TiChirpConfig
from ..ti.config_file import load_config
from .alignment import (DEFAULT_ASSEMBLE, ScheduleCheck, SweepAlignment, check_first_frame, fit_alignment,
                        manual_alignment, ris_power_series)
from .leakage import DEFAULT_GATE_RANGE, LEAKAGE_METHODS, apply_range_gate, range_gate_basis, subtract_background
from .ris_timing import chirp_fractions
from .schedule import SweepSchedule, format_sweep_schedule
from .schedules import SweepSchedules, read_sweep_schedules

__all__ = ["DEFAULT_LEAKAGE", "default_processing", "import_capture", "import_captures", "import_memory"]

DEFAULT_LEAKAGE = "gate"
"""Self-interference removal on import (chosen by the measurements in docs/measured-captures.md)."""


def default_processing(num_samples: int, num_chirps: int) -> ProcessingConfig:
    """The processing an imported capture recommends.

    ``n_dft = 2N − 1`` (the paper's), ``k_dft = next_fast_len(4K)`` (4× Doppler zero padding
    rounded up to a fast FFT length), other fields default.

    Parameters
    ----------
    num_samples : int
        N, samples per chirp.
    num_chirps : int
        K, chirps per frame.

    Returns
    -------
    ProcessingConfig
    """
    return ProcessingConfig(n_dft=2 * int(num_samples) - 1, k_dft=scipy.fft.next_fast_len(4 * int(num_chirps)))


def import_memory(num_beams: int, num_loops: int, num_channels: int, num_samples: int) -> int:
    """Peak bytes of the beams' frames on import: ``16·M·K·N·(V + 2)``.

    The frames of the beams ``[M, K, V, N]`` complex128, the combined cube ``[M, K, N]`` and its
    copy with the leakage removed (complex128 each).

    Parameters
    ----------
    num_beams, num_loops, num_channels, num_samples : int
        M, K, V (channels imported), N.

    Returns
    -------
    int
        [bytes].
    """
    return 16 * int(num_beams) * int(num_loops) * int(num_samples) * (int(num_channels) + 2)


def _ris(schedule: SweepSchedule) -> RisConfig:
    pose = RisPose.facing(np.asarray(schedule.ris_position, float), np.asarray(schedule.ris_facing, float),
                          yaw=float(np.deg2rad(schedule.yaw_deg)))
    extra: dict[str, Any] = {}
    if schedule.ris_element_spacing is not None:
        extra["element_spacing"] = schedule.ris_element_spacing
    return RisConfig(pose=pose, num_rows=schedule.ris_rows, num_columns=schedule.ris_columns,
                     loopback_delay=schedule.loopback_delay_ns * 1e-9, mode=schedule.ris_mode,
                     relay_rx_angle=np.deg2rad(np.asarray(schedule.relay_rx_angle_deg, float)), **extra)


def _truth(schedule: SweepSchedule, ris: RisConfig) -> Truth | None:
    if schedule.truth_ue_position is None:
        return None
    ue = np.asarray(schedule.truth_ue_position, float)
    return Truth(ue_position=ue, ue_velocity=np.zeros(3), distance=float(np.linalg.norm(ue - ris.pose.position)),
                 velocity=0.0, aod=np.asarray(ris.pose.angles_to(ue), float))


def _channels(channels: Sequence[int] | None, sched: SweepSchedule, cfg: TiChirpConfig) -> tuple[int, ...]:
    chans = (sched.channel,) if channels is None else tuple(int(c) for c in channels)
    if not chans or len(set(chans)) != len(chans):
        raise MeasuredFormatError(f"channels {list(chans)} must be distinct virtual channel indices, e.g. 0,1,2,3")
    for c in chans:
        if not 0 <= c < cfg.num_virtual:
            where = "sweep schedule channel" if channels is None else "channel"
            raise MeasuredFormatError(
                f"{where} = {c} but the configuration has {cfg.num_virtual} virtual channel(s) ({cfg.chirps_per_loop} "
                f"chirp(s) per loop x {cfg.num_rx} rx); give channel = 0 … {cfg.num_virtual - 1}")
    return chans


def _configuration(config: str | Path | TiChirpConfig) -> tuple[TiChirpConfig, int | None, Path | None, str | None]:
    """(configuration, LVDS lanes its file gives, its path, its text); path and text None for a ``TiChirpConfig``."""
    if isinstance(config, TiChirpConfig):
        return config, None, None, None
    config_path = Path(config)
    if not config_path.is_file():
        raise MeasuredFormatError(f"radar configuration {config_path} does not exist; give the mmWave SDK .cfg "
                                  "or mmWave Studio .json the capture was recorded with")
    cfg, cfg_lanes = load_config(config_path)
    return cfg, cfg_lanes, config_path, config_path.read_text(encoding="utf-8", errors="replace")


def _first_frame(first_frame: int | str | None, sched: SweepSchedule) -> int | str:
    """The recorded frame of beam 0 (an int >= 0) or ``"auto"``: the override, else the schedule's."""
    if first_frame is None:
        first_frame = "auto" if sched.first_frame is None else sched.first_frame
    if first_frame != "auto" and (isinstance(first_frame, bool) or not isinstance(first_frame, (int, np.integer))
                                  or first_frame < 0):
        raise MeasuredFormatError(f"first frame {first_frame!r} must be an integer >= 0 or 'auto'")
    return first_frame


def _alignment(info: CaptureInfo, radar: RadarConfig, sched: SweepSchedule, first_frame: int | str,
               chans: tuple[int, ...], *, frames_per_block: int, gate_range: float, min_confidence: float,
               assemble: str) -> SweepAlignment:
    """Which recorded chirps hold each beam: fitted (``"auto"``, refused below ``min_confidence``) or the schedule's
    (:func:`_check_schedule` checks it against the recording)."""
    program = sched.program(radar.frame_interval)
    fractions = chirp_fractions(radar.num_chirps, radar.chirp_interval, radar.frame_interval)
    width = radar.frame_duration / radar.frame_interval

    def blocks():
        return (b.cube[:, :, list(chans), :] for b in iter_frames(info, frames_per_block=frames_per_block))

    if first_frame == "auto":
        series = ris_power_series(blocks, radar, min_range=gate_range)
        align = fit_alignment(series, program, fractions=fractions, max_drift=sched.max_clock_drift,
                              frame_width=width, assemble=assemble)
        if align.confidence < min_confidence:
            runner = align.runner_up or {}
            raise MeasuredFormatError(
                f"{info.files[0]}: the sweep start could not be found reliably (confidence {align.confidence:.2f} < "
                f"{min_confidence:g}; best first frame {align.first_frame}, runner-up {runner.get('first_frame')}; RIS "
                f"return at {align.feature.get('range', float('nan')):.2f} m, {align.feature.get('snr_db', 0):.1f} dB); "
                "give first_frame in the sweep schedule (or --first-frame N), add the RIS's [sync] pattern, or "
                "lower --min-confidence")
        return align
    align = manual_alignment(program, int(first_frame), num_frames=info.num_frames, fractions=fractions,
                             frame_width=width, assemble=assemble)
    needed = int((align.chirp_start[-1] + align.num_chirps - 1) // align.num_chirps) + 1
    if info.num_frames < needed:
        per_beam = (f"frames_per_beam {sched.frames_per_beam}" if sched.beam_dwell_ms is None else
                    f"beam_dwell_ms {sched.beam_dwell_ms:g} = {program.frames_per_beam:.4g} frames")
        raise MeasuredFormatError(
            f"{info.files[0]}: the recording holds {info.num_frames} whole frame(s) but the sweep schedule needs "
            f"{needed} (first_frame {first_frame} + ({sched.num_beams} beams - 1) x {per_beam} + 1); check "
            "first_frame, the time per beam and the sweep's beam count, or whether the recording stopped early")
    return align


def _check_schedule(info: CaptureInfo, radar: RadarConfig, sched: SweepSchedule, first_frame: int,
                    chans: tuple[int, ...], *, frames_per_block: int, gate_range: float,
                    assemble: str, series_cache: dict[Any, Any] | None = None) -> ScheduleCheck:
    """A given first frame checked against the recording (:func:`.alignment.check_first_frame`; reads it twice);
    ``series_cache`` keeps the RIS power per frame for the next RIS of the same recording."""
    def blocks():
        return (b.cube[:, :, list(chans), :] for b in iter_frames(info, frames_per_block=frames_per_block))

    key = (tuple(str(f) for f in info.files), chans, float(gate_range), frames_per_block)
    series = None if series_cache is None else series_cache.get(key)
    if series is None:
        series = ris_power_series(blocks, radar, min_range=gate_range)
        if series_cache is not None:
            series_cache[key] = series
    return check_first_frame(series, sched.program(radar.frame_interval), int(first_frame),
                             fractions=chirp_fractions(radar.num_chirps, radar.chirp_interval, radar.frame_interval),
                             frame_width=radar.frame_duration / radar.frame_interval,
                             max_drift=sched.max_clock_drift, assemble=assemble)


def _mismatch_message(source: Path, result: ScheduleCheck) -> str:
    """The one-line warning of a first frame the recording contradicts."""
    if result.supported != result.given:
        what = f"the recording supports first_frame = {result.supported}, not the given {result.given}"
    else:
        what = (f"the recording supports first_frame = {result.supported} but a sweep start at frame "
                f"{result.start:.2f}, not at {result.given}")
    return (f"{source}: {what} (sweep start fitted at frame {result.start:.2f}, confidence {result.confidence:.2f}; "
            f"{result.beams_differ} beam(s) take chirps of another state, the given timing fits worse by "
            f"{result.delta_rss:.0f} sigma^2); the beams may be shifted: check the sweep schedule's first_frame or "
            "import with --first-frame auto")


@dataclass(frozen=True)
class _BeamFrames:
    """The recorded frames a sweep uses, read in one pass.

    ``cube [M, K, V, N]``: each beam's frame, the selected channels [ADC counts]; ``background
    [K, V, N]``: the sum of the RIS-off frames read (background subtraction); the reader's lost
    packets and packet issues (plain dicts) and the beams whose frame holds zero-filled bytes.
    """

    cube: np.ndarray
    background: np.ndarray
    damaged_beams: tuple[int, ...]
    dropped: tuple[dict[str, Any], ...]
    issues: tuple[dict[str, Any], ...]


def _read_beams(info: CaptureInfo, align: SweepAlignment, off: set[int], chans: tuple[int, ...], cfg: TiChirpConfig,
                *, frames_per_block: int) -> _BeamFrames:
    """Stream the recording up to the last frame needed, keeping each beam's chirps (one frame, or the K consecutive
    chirps across two) and summing the off frames."""
    segments = align.beam_segments()
    last = max([seg[-1][0] for seg in segments] + list(off)) + 1
    M, K, N, V = len(segments), cfg.num_loops, cfg.num_samples, len(chans)
    cube4 = np.empty((M, K, V, N), np.complex128)
    background = np.zeros((K, V, N), np.complex128)
    beams_of: dict[int, list[tuple[int, int, int, int]]] = {}          # frame -> (beam, first chirp, count, offset)
    for m, seg in enumerate(segments):
        offset = 0
        for f, k0, n in seg:
            beams_of.setdefault(int(f), []).append((m, k0, n, offset))
            offset += n
    damaged_beams: list[int] = []
    dropped: list[dict[str, Any]] = []
    issues: list[dict[str, Any]] = []
    for block in iter_frames(info, frames_per_block=frames_per_block, max_frames=last):
        dropped.extend(asdict(d) for d in block.dropped)
        issues.extend(asdict(i) for i in block.issues)
        for j in range(block.cube.shape[0]):
            f = block.first_frame + j
            frame = block.cube[j][:, list(chans), :]
            for m, k0, n, offset in beams_of.get(f, ()):
                cube4[m, offset:offset + n] = frame[k0:k0 + n]
                if block.damaged[j]:
                    damaged_beams.append(m)
            if f in off:
                background += frame
    return _BeamFrames(cube=cube4, background=background, damaged_beams=tuple(damaged_beams), dropped=tuple(dropped),
                       issues=tuple(issues))


def _combined_cube(beams: _BeamFrames, radar: RadarConfig, leakage: str, gate_range: float,
                   off_count: int) -> tuple[np.ndarray, np.ndarray]:
    """``(cube [M, K, N], weights [V])``: the channels combined (one as is, several by MRC), the leakage removed."""
    cube4 = beams.cube
    if cube4.shape[2] == 1:
        weights = np.ones(1, complex)
        cube = cube4[:, :, 0, :]
    else:
        weights = mrc_weights(cube4, radar, gate_range)
        cube = combine_channels(cube4, channels=list(range(cube4.shape[2])), weights=weights)
    if leakage == "gate":
        cube = apply_range_gate(cube, range_gate_basis(radar, gate_range))
    elif leakage == "background":
        bg = np.einsum("kvn,v->kn", beams.background / off_count, weights / np.sum(np.abs(weights)))
        cube = subtract_background(cube, bg)
    return cube, weights


def _slot_schedule(schedule: str | Path | SweepSchedule | SweepSchedules, ris: int | str | None,
                   cfg: TiChirpConfig, first_frame: int | str | None,
                   leakage: str) -> tuple[SweepSchedule, dict[str, Any] | None]:
    """The schedule of the RIS imported (its slot's first frame) and the ``ris_slot`` provenance (None: one RIS)."""
    if isinstance(schedule, SweepSchedule):
        if ris is not None:
            raise MeasuredFormatError(f"ris={ris!r}: the sweep schedule describes one RIS; leave out --ris")
        return schedule, None
    several = schedule if isinstance(schedule, SweepSchedules) else read_sweep_schedules(schedule)
    frame_interval = cfg.to_radar_config().frame_interval
    sched = several.schedule(ris, frame_interval=frame_interval)
    if not several.several:
        return sched, None
    index = several.index(ris)
    if len(several.names) > 1 and first_frame == "auto":
        raise MeasuredFormatError(f"--first-frame auto: {several.source} describes {len(several.names)} RISs in "
                                  "time division, whose sweeps look alike to the aligner; give the slot's first frame")
    if len(several.names) > 1 and leakage == "background":
        raise MeasuredFormatError(f"leakage removal 'background' needs RIS-off frames; in {several.source} the other "
                                  "RISs sweep outside this RIS's slot; use --leakage gate")
    slot = {"name": several.names[index], "index": index, "names": list(several.names),
            "first_frames": list(several.first_frames(frame_interval)),
            "time_division": several.time_division(frame_interval).to_dict()}
    return sched, slot


def import_captures(raw: str | Path | Sequence[str | Path], config: str | Path | TiChirpConfig,
                    schedule: str | Path | SweepSchedules, **options: Any) -> dict[str, Capture]:
    """Import every RIS of a time-division recording: one capture per RIS (:func:`import_capture`).

    Parameters
    ----------
    raw, config
        As :func:`import_capture`.
    schedule : path or SweepSchedules
        A sweep schedule of one or several RISs (``[[ris]]`` tables, ``docs/formats.md`` "Several RISs").
    **options
        The other keywords of :func:`import_capture` (not ``ris``).

    Returns
    -------
    dict of str to Capture
        Each RIS's capture (its slot's beams, cube [ADC counts]) by its name, in file order; ``""``
        for the one-RIS form.
    """
    if "ris" in options:
        raise TypeError("import_captures imports every RIS; use import_capture(..., ris=NAME) for one")
    several = schedule if isinstance(schedule, SweepSchedules) else read_sweep_schedules(schedule)
    if not several.several:
        return {"": import_capture(raw, config, several.schedules[0], **options)}
    options.setdefault("series_cache", {})                 # the recording's RIS power per frame, computed once
    return {name: import_capture(raw, config, several, ris=name, **options) for name in several.names}


def import_capture(raw: str | Path | Sequence[str | Path], config: str | Path | TiChirpConfig,
                   schedule: str | Path | SweepSchedule | SweepSchedules, *, ris: int | str | None = None,
                   lanes: int | None = None, iq_swap: bool | None = None,
                   form: str = "auto", frames_per_block: int = 8, first_frame: int | str | None = None,
                   leakage: str = DEFAULT_LEAKAGE, gate_range: float = DEFAULT_GATE_RANGE,
                   channels: Sequence[int] | None = None, min_confidence: float = 0.5,
                   assemble: str = DEFAULT_ASSEMBLE, check_schedule: bool = True,
                   series_cache: dict[Any, Any] | None = None) -> Capture:
    """Import a recorded RIS sweep as a :class:`~risloc_rt.model.capture.Capture`.

    Parameters
    ----------
    raw : path or sequence of paths
        ``adc_data_Raw_0.bin`` (split siblings are collected) or the files in order.
    config : path or TiChirpConfig
        mmWave SDK ``.cfg`` or mmWave Studio ``.json`` (its lane count is used when ``lanes`` is None).
    schedule : path, SweepSchedule or SweepSchedules
        The sweep schedule (TOML, ``docs/formats.md``), of one RIS or several (``[[ris]]`` tables).
    ris : str, int or None
        With several RISs: the one whose slot to import (its name or index); None for one RIS.
    lanes : {2, 4}, optional
        LVDS lanes (default: the Studio JSON's, else 2).
    iq_swap : bool, optional
        The file stores Q before I; default the configuration's LVDS order
        (:func:`~risloc_rt.measured.dca1000.inspection.file_iq_swap`: a Studio ``.json``'s
        ``iqSwapSel``, else I first — an SDK ``.cfg``'s SampleSwap orders the on-chip buffer, not the file).
    form : {"auto", "raw", "packets"}
        Plain samples or packet-recorded (``"auto"`` detects it).
    frames_per_block : int
        Frames decoded at a time (sets the memory used).
    first_frame : int, "auto" or None
        Overrides the schedule's ``first_frame``: an int is the manual alignment (beam m at
        ``first_frame + m·frames_per_beam``), ``"auto"`` finds the sweep (:mod:`.alignment`).
    leakage : {"gate", "background", "none"}
        Self-interference removal (:mod:`.leakage`); ``gate_range`` [m] for the gate.
    gate_range : float
        Range gate [m]; also the nearest range the alignment and the MRC weights look at.
    channels : sequence of int, optional
        Virtual channels to use (default: the schedule's ``channel``); several are combined by
        maximal-ratio combining on the RIS return (weights ``conj(h_v)·h_0/|h_0|``, h_v its complex
        amplitude in channel v at the strongest beam and range bin; output ``Σ w_v y_v / Σ |w_v|``).
    min_confidence : float
        ``"auto"`` refuses an alignment whose confidence is below this.
    assemble : {"span", "frame"}
        A beam no frame holds wholly: its K consecutive chirps across the frame boundary, or the
        frame holding most of it (:func:`.alignment.select_chirps`).
    check_schedule : bool
        Check a given first frame against the recording (reads it twice more).
    series_cache : dict, optional
        Shared by the imports of one recording's RISs (:func:`import_captures`): the check's RIS
        power per frame is computed once for all of them.

    Returns
    -------
    Capture
        ``cube`` complex128 ``[M, K, N]`` [ADC counts]; ``radar = config.to_radar_config()`` with the
        schedule's ``frames_per_beam``; the schedule's sweep and RIS; :func:`default_processing`;
        ``frame_index`` the recorded frame of each beam; provenance ``source="measurement"`` with the
        sha256 of every file, the config text, the schedule, the alignment, the leakage removal, the
        channels and the reader's issues; ``import_warnings`` (one-line texts) and ``import_flags``
        (``[{"code": "schedule-mismatch", "message": ...}]``) when the recording contradicts a given
        first frame; ``truth`` from the schedule's ``[truth]`` or None; ``ris_slot`` (several RISs:
        the RIS's name and index, every RIS's first frame, the time division; else None).

    Raises
    ------
    MeasuredFormatError
        Bad files or options, a channel the configuration does not have, a recording with too
        few frames for the schedule, or an ``"auto"`` alignment below ``min_confidence``.
    dsp.budget.BudgetError
        The beams' frames (:func:`import_memory`) would exceed the memory limit.
    """
    if leakage not in LEAKAGE_METHODS:
        raise MeasuredFormatError(f"leakage = {leakage!r} must be one of {', '.join(LEAKAGE_METHODS)}")
    cfg, cfg_lanes, config_path, config_text = _configuration(config)
    sched, slot = _slot_schedule(schedule, ris, cfg, first_frame, leakage)
    chans = _channels(channels, sched, cfg)
    first_frame = _first_frame(first_frame, sched)
    lanes = lanes or cfg_lanes or 2
    iq_swap = file_iq_swap(config_path if config_path is not None else cfg, iq_swap=iq_swap)
    layout = RawLayout.from_config(cfg, lanes=lanes, iq_swap=iq_swap)
    info = open_raw(raw, layout, form=form, expected_frames=cfg.num_frames or None)
    radar = cfg.to_radar_config()
    program = sched.program(radar.frame_interval)
    radar = replace(radar, frames_per_beam=max(1, int(round(program.frames_per_beam))))
    align = _alignment(info, radar, sched, first_frame, chans, frames_per_block=frames_per_block,
                       gate_range=gate_range, min_confidence=min_confidence, assemble=assemble)
    wanted = align.frame_index
    off = set(int(f) for f in align.off_frames) if leakage == "background" else set()
    if leakage == "background" and not off:
        raise MeasuredFormatError(
            f"{info.files[0]}: leakage removal 'background' needs frames with the RIS off, and the alignment leaves "
            "none (record frames before or after the sweep, or describe the [sync] pattern); use --leakage gate")
    check_memory(import_memory(len(wanted), cfg.num_loops, len(chans), cfg.num_samples),
                 f"{info.files[0]}: {len(wanted)} beams (sweep schedule) x {cfg.num_loops} loops x {len(chans)} "
                 f"channel(s) x {cfg.num_samples} samples (radar configuration) as complex128",
                 fix="check the sweep's beams and the configuration's numLoops and numAdcSamples, or import fewer "
                     "channels (--channels)")
    checked = None
    if check_schedule and first_frame != "auto":
        checked = _check_schedule(info, radar, sched, int(first_frame), chans, frames_per_block=frames_per_block,
                                  gate_range=gate_range, assemble=assemble, series_cache=series_cache)
    beams = _read_beams(info, align, off, chans, cfg, frames_per_block=frames_per_block)
    cube, weights = _combined_cube(beams, radar, leakage, gate_range, len(off))
    sweep = BeamSweep(np.deg2rad(np.asarray(sched.angles_deg, float)))
    ris = _ris(sched)
    alignment = align.to_dict()
    warnings_: list[str] = []
    flags: list[dict[str, str]] = []
    if checked is not None:
        alignment["check"] = checked.to_dict()
        if checked.mismatch:
            warnings_.append(_mismatch_message(info.files[0], checked))
            flags.append({"code": "schedule-mismatch", "message": warnings_[-1]})
    prov = provenance(
        "measurement",
        device="TI DCA1000",
        raw_files=[{"path": str(p), "sha256": file_sha256(p), "bytes": p.stat().st_size} for p in info.files],
        config={"path": None if config_path is None else str(config_path),
                "sha256": None if config_path is None else file_sha256(config_path), "text": config_text},
        schedule=format_sweep_schedule(sched),
        alignment=alignment,
        import_warnings=warnings_,
        import_flags=flags,
        ris_slot=slot,
        leakage={"method": leakage, "gate_range": gate_range if leakage == "gate" else None,
                 "background_frames": len(off)},
        channels={"channels": list(chans), "combine": "single" if len(chans) == 1 else "mrc",
                  "weights": [[float(w.real), float(w.imag)] for w in weights]},
        reader={"form": info.form, "lanes": lanes, "iq_swap": bool(iq_swap), "channel": chans[0],
                "frames_recorded": info.num_frames, "truncated_bytes": info.truncated_bytes,
                "notes": list(info.notes), "dropped_packets": list(beams.dropped), "packet_issues": list(beams.issues),
                "damaged_beams": sorted(set(beams.damaged_beams))},
    )
    return Capture(cube=np.ascontiguousarray(cube, np.complex128), sweep=sweep, radar=radar, ris=ris,
                   processing=default_processing(cfg.num_samples, cfg.num_loops),
                   frame_index=np.asarray(wanted, np.int64), provenance=prov, truth=_truth(sched, ris))
