"""A raw DCA1000 recording of a RIS sweep + its radar configuration + a sweep schedule → a ``Capture``.

The one bridge from measured data to the DSP: ``risloc capture import`` writes the result with
``save_capture`` and ``risloc locate`` processes it like a simulated capture.

Frame selection: beam m is recorded frame ``first_frame + m·frames_per_beam``, the **first**
frame of each beam (a RIS that holds a beam for several frames has settled by the first one it
shows the radar in full; the others are skipped). One virtual channel (``schedule.channel``) is
kept, giving a cube ``[M, K, N]`` complex128 in ADC counts with the project's sign convention
(``I − jQ``, ``docs/measured-captures.md``).
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.fft

from dsp import BeamSweep, ProcessingConfig, RisPose

from ..model.capture import Capture, provenance
from ..model.ris import RisConfig
from ..model.scenario import Truth
from .dca1000 import iter_frames, open_raw
from .errors import MeasuredFormatError
from .inspect import load_config
from .layout import RawLayout
from .sweep_schedule import SweepSchedule, format_sweep_schedule, read_sweep_schedule
from .ti_config import TiChirpConfig

__all__ = ["import_capture", "default_processing"]


def default_processing(num_samples: int, num_chirps: int) -> ProcessingConfig:
    """The processing an imported capture recommends: ``n_dft = 2N − 1`` (the paper's), ``k_dft =
    next_fast_len(4K)`` (4× Doppler zero padding rounded up to a fast FFT length), other fields default."""
    return ProcessingConfig(n_dft=2 * int(num_samples) - 1, k_dft=scipy.fft.next_fast_len(4 * int(num_chirps)))


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 22), b""):
            h.update(chunk)
    return h.hexdigest()


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


def import_capture(raw: str | Path | Sequence[str | Path], config: str | Path | TiChirpConfig,
                   schedule: str | Path | SweepSchedule, *, lanes: int | None = None, iq_swap: bool = False,
                   form: str = "auto", frames_per_block: int = 8) -> Capture:
    """Import a recorded RIS sweep as a :class:`~risloc_rt.model.capture.Capture`.

    Parameters
    ----------
    raw : path or sequence of paths
        ``adc_data_Raw_0.bin`` (split siblings are collected) or the files in order.
    config : path or TiChirpConfig
        mmWave SDK ``.cfg`` or mmWave Studio ``.json`` (its lane count is used when ``lanes`` is None).
    schedule : path or SweepSchedule
        The sweep schedule (TOML, ``docs/formats.md``).
    lanes : {2, 4}, optional
        LVDS lanes (default: the Studio JSON's, else 2).
    iq_swap : bool
        The file stores Q before I.

    Returns
    -------
    Capture
        ``cube`` complex128 ``[M, K, N]`` [ADC counts]; ``radar = config.to_radar_config()`` with the
        schedule's ``frames_per_beam``; the schedule's sweep and RIS; :func:`default_processing`;
        ``frame_index`` the recorded frame of each beam; provenance ``source="measurement"`` with the
        sha256 of every file, the config text, the schedule and the reader's issues; ``truth`` from
        the schedule's ``[truth]`` or None.

    Raises
    ------
    MeasuredFormatError
        Bad files, ``first_frame = "auto"``, a channel the configuration does not have, or a
        recording with too few frames for the schedule (the message gives both counts).
    """
    config_text, config_path, cfg_lanes = None, None, None
    if isinstance(config, TiChirpConfig):
        cfg = config
    else:
        config_path = Path(config)
        if not config_path.is_file():
            raise MeasuredFormatError(f"radar configuration {config_path} does not exist; give the mmWave SDK .cfg "
                                      "or mmWave Studio .json the capture was recorded with")
        cfg, cfg_lanes = load_config(config_path)
        config_text = config_path.read_text(encoding="utf-8", errors="replace")
    sched = schedule if isinstance(schedule, SweepSchedule) else read_sweep_schedule(schedule)
    wanted = sched.frame_indices()          # raises for first_frame = "auto"
    if sched.channel >= cfg.num_virtual:
        raise MeasuredFormatError(
            f"sweep schedule channel = {sched.channel} but the configuration has {cfg.num_virtual} virtual "
            f"channel(s) ({cfg.chirps_per_loop} chirp(s) per loop x {cfg.num_rx} rx); give channel = 0 … "
            f"{cfg.num_virtual - 1}")
    lanes = lanes or cfg_lanes or 2
    layout = RawLayout.from_config(cfg, lanes=lanes, iq_swap=iq_swap)
    info = open_raw(raw, layout, form=form, expected_frames=cfg.num_frames or None)
    needed = sched.frames_needed
    if info.num_frames < needed:
        raise MeasuredFormatError(
            f"{info.files[0]}: the recording holds {info.num_frames} whole frame(s) but the sweep schedule needs "
            f"{needed} (first_frame {sched.first_frame} + ({sched.num_beams} beams - 1) x frames_per_beam "
            f"{sched.frames_per_beam} + 1); check first_frame, frames_per_beam and the sweep's beam count, or "
            "whether the recording stopped early")

    M, K, N = sched.num_beams, cfg.num_loops, cfg.num_samples
    cube = np.empty((M, K, N), np.complex128)
    beam_of = {int(f): m for m, f in enumerate(wanted)}
    damaged_beams: list[int] = []
    dropped: list[dict[str, Any]] = []
    issues: list[dict[str, Any]] = []
    for block in iter_frames(info, frames_per_block=frames_per_block, max_frames=needed):
        dropped.extend(asdict(d) for d in block.dropped)
        issues.extend(asdict(i) for i in block.issues)
        for j in range(block.cube.shape[0]):
            m = beam_of.get(block.first_frame + j)
            if m is not None:
                cube[m] = block.cube[j, :, sched.channel, :]
                if block.damaged[j]:
                    damaged_beams.append(m)

    radar = replace(cfg.to_radar_config(), frames_per_beam=sched.frames_per_beam)
    sweep = BeamSweep(np.deg2rad(np.asarray(sched.angles_deg, float)))
    ris = _ris(sched)
    prov = provenance(
        "measurement",
        device="TI DCA1000",
        raw_files=[{"path": str(p), "sha256": _sha256(p), "bytes": p.stat().st_size} for p in info.files],
        config={"path": None if config_path is None else str(config_path),
                "sha256": None if config_path is None else _sha256(config_path), "text": config_text},
        schedule=format_sweep_schedule(sched),
        reader={"form": info.form, "lanes": lanes, "iq_swap": bool(iq_swap), "channel": sched.channel,
                "frames_recorded": info.num_frames, "truncated_bytes": info.truncated_bytes,
                "notes": list(info.notes), "dropped_packets": dropped, "packet_issues": issues,
                "damaged_beams": damaged_beams},
    )
    return Capture(cube=cube, sweep=sweep, radar=radar, ris=ris, processing=default_processing(N, K),
                   frame_index=np.asarray(wanted, np.int64), provenance=prov, truth=_truth(sched, ris))
