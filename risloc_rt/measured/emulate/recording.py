"""A whole recording as a real experiment leaves it: lead frames, a RIS sync code, a sweep on a drifting RIS clock.

:func:`emulate_recording` synthesises every recorded frame chirp by chirp from the scenario's
paths (frozen geometry): the paths that do not pass through the RIS (hall echoes, targets, the
panel's structure) in every frame; the RIS re-transmission of the beam the RIS shows at that
chirp (:func:`~risloc_rt.measured.sweep.ris_timing.chirp_states`: '1' chips of the sync code show
``sync_beam``, off time nothing; the RIS's durations in whole frames or in milliseconds of its own
clock, ``beam_dwell_ms`` and a chip code, converted with the radar's frame period); a Tx→Rx leakage tone near zero range with per-chirp phase jitter; receiver noise; then the ADC
and the DCA1000 files (:func:`~.experiment.write_frames`). A beam boundary inside a frame
switches the RIS between two of its chirps, as a free-running RIS does.

It also injects what a calibration must find (:mod:`risloc_rt.measured.compare.calibration_file`):
the radar's internal range offset (every delay longer by ``2·range_offset/c``), a receiver gain
the model does not know (``power_offset_db``), and the RIS's true τ_RB and ζ (give them in
``scenario.ris``; the schedule written states ``nominal_ris``'s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dsp import BeamSweep, db_to_linear
from dsp.radar import SPEED_OF_LIGHT
from dsp.validation import non_negative

from ...model.beat import beat_cube
from ...model.paths import PathSet, select_paths, shift_paths
from ...model.ris import RisConfig
from ...model.scenario import Scenario, analytic_paths
from ..errors import MeasuredFormatError
from ..sweep.ris_timing import SYNC, RisProgram, chirp_fractions, chirp_states
from ..sweep.schedule import write_sweep_schedule
from .experiment import (SCHEDULE_NAME, EmulatedExperiment, check_folder, dca1000_radar, schedule_fields,
                         sweep_schedule_of, write_frames)

__all__ = ["EmulatedRecording", "RecordingPlan", "emulate_recording"]


@dataclass(frozen=True)
class RecordingPlan:
    """How the experiment runs (durations in nominal frames unless said otherwise).

    Parameters
    ----------
    lead_frames : float
        Radar frames recorded before the RIS program starts (fractional: the RIS's clock phase).
    frames_per_beam : int or None
        Nominal frames per beam (default 1 when ``beam_dwell_ms`` is None too).
    beam_dwell_ms : float or None
        Instead: the RIS's own time per beam [ms] (25.0 against 20 ms frames: 1.25 frames).
    sync_on, sync_off, sync_cycles, sync_gap : int
        The on/off sync pattern before the sweep (:class:`~risloc_rt.measured.sweep.ris_timing.RisProgram`).
    sync_pattern : str
        Instead of the on/off form: the sync code ('1' on at ``sync_beam``, '0' off), chips of ``chip_ms``.
    chip_ms : float or None
        One chip of ``sync_pattern`` on the RIS's clock [ms].
    sync_gap_ms : float or None
        Instead of ``sync_gap``: RIS off between the code and the sweep [ms].
    repeat_after : bool
        The sync code is sent again after the sweep (after the gap).
    clock_drift : float
        RIS clock rate error d: every RIS duration lasts ``(1 + d)`` × nominal radar frames.
    tail_frames : int
        Radar frames recorded after the sweep (RIS off).
    sync_beam : (az, el) or None
        Beam the RIS shows in sync-on frames [rad, RIS frame]; None: its relay Rx beam (pointed at the UE).
    leakage_dbm : float or None
        Tx→Rx leakage power at the ADC [dBm]; None: no leakage.
    leakage_range : float
        Apparent range of the leakage [m].
    leakage_jitter : float
        Phase noise of the leakage, rms per chirp [rad].
    range_offset : float
        The radar's internal range offset [m] (all delays + 2·range_offset/c).
    power_offset_db : float
        Receiver gain the model does not know [dB] (ADC counts per √W raised by it).
    schedule_first_frame : {"auto", "true"}
        What the written ``sweep.toml`` says: ``"auto"``, or the true first frame (when whole).
    """

    lead_frames: float = 0.0
    frames_per_beam: int | None = None
    sync_on: int = 0
    sync_off: int = 0
    sync_cycles: int = 0
    sync_gap: int = 0
    clock_drift: float = 0.0
    tail_frames: int = 2
    sync_beam: tuple[float, float] | None = None
    leakage_dbm: float | None = None
    leakage_range: float = 0.08
    leakage_jitter: float = 0.0
    range_offset: float = 0.0
    power_offset_db: float = 0.0
    schedule_first_frame: str = "auto"
    beam_dwell_ms: float | None = None
    sync_pattern: str = ""
    chip_ms: float | None = None
    sync_gap_ms: float | None = None
    repeat_after: bool = False

    def __post_init__(self) -> None:
        if self.frames_per_beam is not None and self.beam_dwell_ms is not None:
            raise MeasuredFormatError("give frames_per_beam or beam_dwell_ms, not both")
        if bool(self.sync_pattern) != (self.chip_ms is not None):
            raise MeasuredFormatError("sync_pattern and chip_ms go together (the code and one chip's duration [ms])")
        non_negative(self.lead_frames, "lead_frames", "frames", error=MeasuredFormatError)
        if not -0.5 < self.clock_drift < 0.5:
            raise MeasuredFormatError(f"clock_drift={self.clock_drift} must lie in (-0.5, 0.5)")
        if self.schedule_first_frame not in ("auto", "true"):
            raise MeasuredFormatError(f"schedule_first_frame={self.schedule_first_frame!r} must be 'auto' or 'true'")
        if int(self.tail_frames) < 0:
            raise MeasuredFormatError(f"tail_frames={self.tail_frames} must be >= 0")

    @property
    def uses_ris_clock(self) -> bool:
        """Some RIS duration is in milliseconds of its own clock."""
        return self.beam_dwell_ms is not None or self.chip_ms is not None or self.sync_gap_ms is not None

    def program(self, num_beams: int, frame_interval: float | None = None) -> RisProgram:
        """The RIS's program for ``num_beams`` beams, in nominal frames.

        Parameters
        ----------
        num_beams : int
            M, beams of the sweep.
        frame_interval : float, optional
            The radar's frame period [s]; needed for the durations in milliseconds (``x_ms·1e-3/T_f``).

        Returns
        -------
        RisProgram
        """
        if self.uses_ris_clock and frame_interval is None:
            raise MeasuredFormatError("the plan gives RIS durations in milliseconds; give the radar's frame_interval")
        tf = 1.0 if frame_interval is None else float(frame_interval)
        fpb = (1 if self.frames_per_beam is None else self.frames_per_beam) if self.beam_dwell_ms is None \
            else self.beam_dwell_ms * 1e-3 / tf
        gap = self.sync_gap if self.sync_gap_ms is None else self.sync_gap_ms * 1e-3 / tf
        return RisProgram(num_beams=num_beams, frames_per_beam=fpb, sync_on=self.sync_on, sync_off=self.sync_off,
                          sync_cycles=self.sync_cycles, sync_gap=gap, sync_pattern=self.sync_pattern,
                          chip_frames=1.0 if self.chip_ms is None else self.chip_ms * 1e-3 / tf,
                          repeat_after=self.repeat_after)

    def start(self, program: RisProgram) -> float:
        """Radar time the first beam starts [frames]: the lead frames plus the stretched sync pattern.

        Parameters
        ----------
        program : RisProgram
            From :meth:`program`.

        Returns
        -------
        float
            [frames from the recording's first frame].
        """
        return self.lead_frames + program.sync_length * (1 + self.clock_drift)

    def dwell(self, program: RisProgram) -> float:
        """Radar frames per beam: ``frames_per_beam·(1 + clock_drift)``.

        Parameters
        ----------
        program : RisProgram
            From :meth:`program`.

        Returns
        -------
        float
            [frames].
        """
        return float(program.frames_per_beam) * (1 + self.clock_drift)


@dataclass(frozen=True)
class EmulatedRecording:
    """What :func:`emulate_recording` wrote, and the truth an aligner must find."""

    experiment: EmulatedExperiment
    start: float
    dwell: float
    true_frame_index: np.ndarray
    num_frames: int


def emulate_recording(scenario: Scenario, folder: str | Path, *, plan: RecordingPlan = RecordingPlan(),
                      rng: np.random.Generator, paths: PathSet | None = None, nominal_ris: RisConfig | None = None,
                      noise: bool = True, adc_bits: int = 16, dc_offset: complex = 0j,
                      iq_gain_db: float = 0.0, dropped_packets_rate: float = 0.0) -> EmulatedRecording:
    """Write the recording of one RIS sweep experiment into ``folder`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
        Radar (made TI-compatible with :func:`~.experiment.dca1000_radar`), RIS (its true
        τ_RB and ζ), sweep, UE (frozen at ``ue_position``).
    folder : path
        Created if missing; refused if it holds a capture already.
    plan : RecordingPlan
    rng : numpy.random.Generator
        Noise, leakage jitter, lost packets.
    paths : PathSet, optional
        Default: the analytic paths of the scenario (e.g. ``hall_paths(...).paths`` for a hall).
    nominal_ris : RisConfig, optional
        The RIS the written schedule describes (default ``scenario.ris``).
    noise : bool
        Add the receiver noise (``radar.noise_power``).
    adc_bits, dc_offset, iq_gain_db, dropped_packets_rate
        As :func:`~.experiment.emulate_capture` (dc_offset in LSB counts).

    Returns
    -------
    EmulatedRecording
        The experiment written, the true start [frames] and dwell [frames per beam], the frame that
        holds each beam and the frames recorded.
    """
    folder = check_folder(folder)
    radar = dca1000_radar(scenario.radar)
    M, K, N = scenario.sweep.num_beams, radar.num_chirps, radar.num_samples
    program = plan.program(M, radar.frame_interval)
    start, dwell = plan.start(program), plan.dwell(program)
    F = int(math.ceil(start + M * dwell + program.after_length * (1 + plan.clock_drift))) + int(plan.tail_frames)
    if F * K * N > 60_000_000:
        raise MeasuredFormatError(f"the recording would hold {F} frames x {K} x {N} samples; shorten it (fewer lead, "
                                  "sync or tail frames) or use a smaller radar")
    base = analytic_paths(replace(scenario, radar=radar)) if paths is None else paths
    if plan.range_offset:
        base = shift_paths(base, 2 * plan.range_offset / SPEED_OF_LIGHT, radar.carrier_frequency)
    via = base.via_ris
    sync_beam = scenario.ris.relay_rx_angle if plan.sync_beam is None else np.asarray(plan.sync_beam, float)
    one = BeamSweep(np.zeros((1, 2)))
    static = beat_cube(select_paths(base, ~via), radar=radar, sweep=one, ris=scenario.ris)[0]          # [K, N]
    ris_paths = select_paths(base, via)
    beams = beat_cube(ris_paths, radar=radar, sweep=scenario.sweep, ris=scenario.ris)             # [M, K, N]
    sync = beat_cube(ris_paths, radar=radar, sweep=BeamSweep(sync_beam[None]), ris=scenario.ris)  # [1, K, N]
    table = np.concatenate([beams, sync, np.zeros((1, K, N), complex)])                          # [M + 2, K, N]

    fractions = chirp_fractions(K, radar.chirp_interval, radar.frame_interval)
    times = np.arange(F)[:, None] + fractions[None, :]
    state = chirp_states(program, times, start=start, dwell=dwell)                               # [F, K]
    row = np.where(state >= 0, state, np.where(state == SYNC, M, M + 1))
    frames = table[row, np.arange(K)[None, :], :] + static[None]                                 # [F, K, N]
    if plan.leakage_dbm is not None:
        tau = 2 * plan.leakage_range / SPEED_OF_LIGHT
        amp = math.sqrt(db_to_linear(plan.leakage_dbm - 30.0))
        tone = np.exp(-2j * np.pi * radar.slope * tau * np.arange(N) * radar.sample_period)
        jitter = rng.normal(0.0, plan.leakage_jitter, (F, K)) if plan.leakage_jitter else np.zeros((F, K))
        frames += amp * np.exp(1j * jitter)[:, :, None] * tone[None, None, :]
    if noise:
        sigma = math.sqrt(radar.noise_power / 2)
        frames += sigma * (rng.standard_normal(frames.shape) + 1j * rng.standard_normal(frames.shape))
    raw, fs, counts = write_frames(frames, radar, folder, adc_bits=adc_bits, dropped_packets_rate=dropped_packets_rate,
                                   dc_offset=dc_offset, iq_gain_db=iq_gain_db, power_offset_db=plan.power_offset_db,
                                   rng=rng)
    true_index = np.ceil(start + np.arange(M) * dwell - 1e-9).astype(np.int64)
    whole = abs(start - round(start)) < 1e-9
    first: int | None = int(round(start)) if plan.schedule_first_frame == "true" and whole else None
    ris = nominal_ris or scenario.ris
    per_beam = ({"frames_per_beam": int(program.frames_per_beam)} if plan.beam_dwell_ms is None
                else {"frames_per_beam": None, "beam_dwell_ms": plan.beam_dwell_ms})
    schedule = sweep_schedule_of(
        np.rad2deg(scenario.sweep.angles), **per_beam, first_frame=first, channel=0,
        sync_on_frames=plan.sync_on, sync_off_frames=plan.sync_off, sync_cycles=plan.sync_cycles,
        sync_gap_frames=plan.sync_gap, sync_gap_ms=plan.sync_gap_ms, sync_pattern=plan.sync_pattern,
        sync_chip_ms=plan.chip_ms, sync_repeat_after=plan.repeat_after,
        max_clock_drift=max(0.02, 2 * abs(plan.clock_drift)), **schedule_fields(ris, scenario.truth))
    path = write_sweep_schedule(schedule, folder / SCHEDULE_NAME, comment=(
        f"risloc emulated recording: {F} frames, sweep of {M} beams x {program.frames_per_beam:g} frame(s) from radar "
        f"frame {start:.3f}, RIS clock drift {plan.clock_drift:+.4%}; full scale {fs:.6g} sqrt(W)"))
    exp = EmulatedExperiment(folder=folder, raw=raw, schedule_path=path, schedule=schedule, full_scale=fs,
                             counts_per_unit=counts)
    return EmulatedRecording(experiment=exp, start=start, dwell=dwell, true_frame_index=true_index, num_frames=F)
