"""A simulated ``Capture`` → the folder a real experiment would leave: DCA1000 raw files, ``.cfg``, sweep schedule.

``risloc simulate --format dca1000 -o FOLDER`` writes, into FOLDER:

- ``adc_data_Raw_0.bin`` (raw form; packet form when packets are dropped): one frame per RIS beam,
  one Rx channel (RX0, TX0), complex1x, 2 LVDS lanes, the cube scaled to ADC counts;
- ``adc_data.cfg``: the mmWave SDK 3.x configuration (``format_sdk_cfg``), ``numFrames = M``;
- ``sweep.toml``: the sweep schedule (``first_frame = 0``, ``frames_per_beam = 1``, channel 0, the
  RIS, and the truth).

**Full scale.** The top ADC code 2^(b−1) (2¹⁵ for the default 16 bits) is reached by an input
amplitude of ``FULL_SCALE_OVER_NOISE = 1e4`` × the nominal noise rms √(k T B F), i.e. the
radar's ``noise_power_dbm`` (Table I: −63.64 dBm → σ = 2.08e-5 √W, full scale 0.208 √W). The
complex noise then sits at 2¹⁵/1e4 ≈ 3.3 LSB rms (2.3 LSB per I and Q rail): quantization adds
1/12 LSB² per rail, −18 dB below the noise; the RIS return and the panel's reflection stay far
below clipping (80 dB of headroom above the noise). The full scale follows the nominal noise,
not the noise actually drawn, so ``--no-noise`` gives the same scaling.

**Chirp timing.** A TI chirp must hold the ADC window in its ramp: ``adc_start_time (6 µs) +
N/f_s + 1 µs``; Table I's 600 samples at 10 Msps (60 µs) do not fit its 50 µs chirp.
:func:`dca1000_radar` keeps the slope, N and f_s (which set the beat signal and the range axis)
and lengthens ``chirp_period`` to the ramp plus ≥ 3 µs idle, rounded up to a whole µs (Table I:
70 µs; only the velocity axis changes). It also truncates the slope to the device's programmable
step (``slope_step``), as TI's firmware does, and puts the start frequency on its step so that the
centre of the ADC window is the radar's carrier (within 40 Hz): the slope and carrier the importer
reads back are the ones simulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dsp import RadarConfig, db_to_linear

from ...model.capture import Capture
from ..errors import MeasuredFormatError
from ..sweep.schedule import SweepSchedule, write_sweep_schedule
from ..ti.chirp_config import TiChirpConfig, device_steps, slope_step, start_frequency_step
from .raw_files import AdcImpairments, EmulatedCapture, Recording, write_raw_capture

__all__ = ["ADC_START_TIME", "FULL_SCALE_OVER_NOISE", "MIN_IDLE", "PREFIX", "RAMP_MARGIN", "SCHEDULE_NAME",
           "EmulatedExperiment", "check_folder", "dca1000_radar", "emulate_capture", "full_scale", "schedule_fields",
           "sweep_schedule_of", "write_frames"]

FULL_SCALE_OVER_NOISE = 1e4
"""Input amplitude of the top ADC code, in units of the nominal noise rms."""
ADC_START_TIME = 6e-6
RAMP_MARGIN = 1e-6
MIN_IDLE = 3e-6
PREFIX = "adc_data"
SCHEDULE_NAME = "sweep.toml"


@dataclass(frozen=True)
class EmulatedExperiment:
    """What :func:`emulate_capture` wrote: the raw capture, the ``.cfg``, the schedule and the scaling."""

    folder: Path
    raw: EmulatedCapture
    schedule_path: Path
    schedule: SweepSchedule
    full_scale: float
    counts_per_unit: float

    @property
    def raw_path(self) -> Path:
        """The first raw file (``adc_data_Raw_0.bin``)."""
        return self.raw.files[0]

    @property
    def config_path(self) -> Path:
        return self.raw.cfg_path


def dca1000_radar(radar: RadarConfig) -> RadarConfig:
    """The radar a TI device runs when programmed for ``radar`` (see the module doc).

    Parameters
    ----------
    radar : RadarConfig
        The radar to simulate; its slope is the one a user writes in the ``.cfg``, its carrier the
        frequency at the centre of the ADC window.

    Returns
    -------
    RadarConfig
        The slope truncated to the device's step (:func:`~risloc_rt.measured.ti.chirp_config.slope_step`,
        as TI's firmware does: Table I's 68.69 MHz/µs becomes 68.6538) [Hz/s], bandwidth adjusted;
        the carrier the centre of the ADC window of the truncated start frequency
        ``f_0 = f_c − S·(ADC_START_TIME + N/(2 f_s))`` (within one 40 Hz step of ``f_c``) [Hz]; the
        chirp period lengthened to ramp + 3 µs idle, rounded up to a whole µs [s], when the ramp does
        not fit (and the frame period with it). Reading back the ``.cfg`` the emulator writes for it
        gives this radar (``TiChirpConfig.to_radar_config``).
    """
    slope = device_steps(radar.slope, slope_step(radar.carrier_frequency)) * slope_step(radar.carrier_frequency)
    offset = ADC_START_TIME + radar.adc_window / 2
    f_step = start_frequency_step(radar.carrier_frequency)
    start = device_steps(radar.carrier_frequency - slope * offset, f_step) * f_step
    out = replace(radar, bandwidth=slope * radar.chirp_duration, carrier_frequency=start + slope * offset)
    ramp = ADC_START_TIME + radar.adc_window + RAMP_MARGIN
    if radar.chirp_interval < ramp + MIN_IDLE * (1 - 1e-9):
        period = math.ceil((ramp + MIN_IDLE) * 1e6 - 1e-6) * 1e-6
        frame = None if radar.frame_period is None else max(radar.frame_period, radar.num_chirps * period)
        out = replace(out, chirp_period=period, frame_period=frame)
    return out


def full_scale(radar: RadarConfig) -> float:
    """Input amplitude of the top ADC code: ``FULL_SCALE_OVER_NOISE`` × √(noise power) [√W].

    Parameters
    ----------
    radar : RadarConfig
        Its ``noise_power_dbm`` [dBm] sets the nominal noise.

    Returns
    -------
    float
        The full scale [√W].
    """
    return FULL_SCALE_OVER_NOISE * math.sqrt(db_to_linear(radar.noise_power_dbm - 30.0))


def sweep_schedule_of(angles_deg: np.ndarray, **fields) -> SweepSchedule:
    """The schedule, as an azimuth grid (start/stop/step) when the sweep is one, else the explicit list.

    Parameters
    ----------
    angles_deg : float array [M, 2]
        Each beam's (az, el) [deg].
    **fields
        The schedule's other attributes (``frames_per_beam``, ``first_frame``, the RIS, ...).

    Returns
    -------
    SweepSchedule
    """
    az, el = angles_deg[:, 0], angles_deg[:, 1]
    if len(az) >= 2 and np.ptp(el) < 1e-9:
        step = (az[-1] - az[0]) / (len(az) - 1)
        if step > 0 and np.allclose(np.diff(az), step, rtol=0, atol=1e-9):
            try:
                return SweepSchedule.azimuth(round(float(az[0]), 9), round(float(az[-1]), 9), round(float(step), 9),
                                             elevation_deg=round(float(el[0]), 9), **fields)
            except MeasuredFormatError:
                pass
    return SweepSchedule(angles_deg=tuple((float(a), float(e)) for a, e in angles_deg), **fields)


def schedule_fields(ris, truth) -> dict:
    """The sweep schedule's RIS and truth fields of a ``RisConfig`` and a ``Truth`` (or None).

    Parameters
    ----------
    ris : RisConfig
        Pose [m], τ_RB [s], mode, element grid and pitch [m], relay Rx beam [rad].
    truth : Truth or None
        Its ``ue_position`` [m].

    Returns
    -------
    dict
        ``SweepSchedule`` keyword arguments (positions [m], τ_RB [ns], angles [deg]).
    """
    return dict(
        ris_position=tuple(float(x) for x in ris.pose.position),
        ris_facing=tuple(float(x) for x in ris.pose.position + ris.pose.normal),
        loopback_delay_ns=float(ris.loopback_delay * 1e9), ris_mode=ris.mode, ris_rows=ris.num_rows,
        ris_columns=ris.num_columns, ris_element_spacing=float(ris.element_spacing),
        relay_rx_angle_deg=tuple(float(x) for x in np.rad2deg(ris.relay_rx_angle)),
        truth_ue_position=None if truth is None else tuple(float(x) for x in truth.ue_position))


def check_folder(folder: str | Path) -> Path:
    """``folder`` as a Path, refused when it is a file or already holds ``adc_data*`` files or ``sweep.toml``.

    Parameters
    ----------
    folder : path
        The experiment's folder (it need not exist yet).

    Returns
    -------
    Path
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise MeasuredFormatError(f"{folder} is a file; give a folder for the DCA1000 capture (-o FOLDER)")
    if folder.is_dir():
        clash = sorted(p.name for p in folder.iterdir() if p.name.startswith(PREFIX) or p.name == SCHEDULE_NAME)
        if clash:
            raise MeasuredFormatError(f"{folder} already holds {', '.join(clash[:3])}; risloc does not overwrite a "
                                      "capture: give a new or empty folder, or remove those files")
    return folder


def write_frames(frames: np.ndarray, radar: RadarConfig, folder: Path, *, adc_bits: int = 16,
                 dropped_packets_rate: float = 0.0, dc_offset: complex = 0j, iq_gain_db: float = 0.0,
                 power_offset_db: float = 0.0,
                 rng: np.random.Generator | None = None) -> tuple[EmulatedCapture, float, float]:
    """Write ``frames: complex [F, K, N]`` [√W] as one-Rx DCA1000 raw files + ``.cfg`` into ``folder``.

    Parameters
    ----------
    frames : complex array [F, K, N]
        Beat samples at the ADC input [√W].
    radar : RadarConfig
        Must fit a TI chirp (:func:`dca1000_radar`).
    folder : Path
        Created when missing.
    adc_bits : {12, 14, 16}
    dropped_packets_rate : float
        Probability of losing each UDP packet, in [0, 1); > 0 writes the packet-recorded form.
    dc_offset : complex
        ADC DC offset [LSB counts].
    iq_gain_db : float
        Q/I gain imbalance [dB].
    power_offset_db : float
        Raises the ADC counts per √W by that many dB (a receiver gain the model does not know).
    rng : numpy.random.Generator, optional
        Needed when packets are dropped.

    Returns
    -------
    (EmulatedCapture, float, float)
        The raw capture, the full scale [√W] and the ADC counts per √W.
    """
    if adc_bits not in (12, 14, 16):
        raise MeasuredFormatError(f"adc_bits={adc_bits} must be 12, 14 or 16 (the xWR ADC's resolutions)")
    if not 0.0 <= dropped_packets_rate < 1.0:
        raise MeasuredFormatError(f"dropped_packets_rate={dropped_packets_rate} must lie in [0, 1)")
    try:
        cfg = TiChirpConfig.from_radar(radar, rx_mask=0b0001, tx_order=(0b001,), adc_start_time=ADC_START_TIME,
                                       ramp_margin=RAMP_MARGIN, num_frames=frames.shape[0],
                                       adc_bits=adc_bits, adc_format="complex1x")
    except MeasuredFormatError as exc:
        raise MeasuredFormatError(f"{exc} (simulate with risloc_rt.measured.dca1000_radar(radar))") \
            from None
    fs = full_scale(radar) / 10.0 ** (power_offset_db / 20.0)
    counts = 2.0 ** (adc_bits - 1) / fs
    impairments = AdcImpairments(full_scale=fs, dc_offset=complex(dc_offset) / counts, iq_gain_imbalance_db=iq_gain_db)
    recording = Recording(form="packets" if dropped_packets_rate > 0 else "raw", lanes=2,
                          drop_probability=dropped_packets_rate, prefix=PREFIX)
    folder.mkdir(parents=True, exist_ok=True)
    raw = write_raw_capture(frames[:, :, None, :], cfg, folder, recording=recording, impairments=impairments,
                            convention="paper", rng=rng)
    return raw, fs, counts


def emulate_capture(capture: Capture, folder: str | Path, *, adc_bits: int = 16, dropped_packets_rate: float = 0.0,
                    dc_offset: complex = 0j, iq_gain_db: float = 0.0, power_offset_db: float = 0.0,
                    rng: np.random.Generator | None = None) -> EmulatedExperiment:
    """Write ``capture`` as a DCA1000 recording of one RIS sweep into ``folder`` (see the module doc).

    Parameters
    ----------
    capture : Capture
        One frame per beam; its radar must fit a TI chirp (:func:`dca1000_radar` before simulating).
    folder : path
        Created if missing; refused if it already holds ``adc_data*`` files or ``sweep.toml``.
    adc_bits : {12, 14, 16}
    dropped_packets_rate : float
        Probability that a UDP packet is lost (0 … 1); > 0 writes the packet-recorded form.
    dc_offset : complex
        ADC DC offset [LSB counts].
    iq_gain_db : float
        Q/I gain imbalance [dB].
    power_offset_db : float
        Receiver gain the model does not know: ADC counts per √W raised by it [dB].
    rng : numpy.random.Generator, optional
        Needed when packets are dropped.

    Returns
    -------
    EmulatedExperiment
        The folder, the raw capture, the schedule (and its path), the full scale [√W] and the ADC
        counts per √W.
    """
    if capture.radar.frames_per_beam != 1:
        raise MeasuredFormatError(f"the capture has frames_per_beam={capture.radar.frames_per_beam}; the emulator "
                                  "writes one frame per beam (frames_per_beam=1)")
    folder = check_folder(folder)
    raw, fs, counts = write_frames(np.asarray(capture.cube), capture.radar, folder, adc_bits=adc_bits,
                                   dropped_packets_rate=dropped_packets_rate, dc_offset=dc_offset,
                                   iq_gain_db=iq_gain_db, power_offset_db=power_offset_db, rng=rng)
    schedule = sweep_schedule_of(np.rad2deg(capture.sweep.angles), frames_per_beam=1, first_frame=0, channel=0,
                               **schedule_fields(capture.ris, capture.truth))
    path = write_sweep_schedule(schedule, folder / SCHEDULE_NAME, comment=(
        f"risloc simulate --format dca1000: {schedule.num_beams} beams, one frame each from frame 0; "
        f"full scale {fs:.6g} sqrt(W) = 2^{adc_bits - 1} counts"))
    return EmulatedExperiment(folder=folder, raw=raw, schedule_path=path, schedule=schedule, full_scale=fs,
                              counts_per_unit=counts)
