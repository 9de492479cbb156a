"""Model only what a scene needs: the IF filter, aliasing, and paths below the noise floor."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from dsp import SPEED_OF_LIGHT, ProcessingConfig, RadarConfig, window_vector
from dsp.validation import finite, non_negative, positive_int
from dsp.sweep import BeamSweep

from ..model.paths import PathSet
from ..model.ris import RisConfig, ris_response

__all__ = ["ModelSettings", "PruneReport", "AliasWarning", "prune_paths", "processed_noise_floor", "if_filter_gain"]

IfFilter = Literal["butterworth", "ideal", "none"]


class AliasWarning(UserWarning):
    """A strong return beyond the unambiguous range folds back into the sampled band."""


@dataclass(frozen=True)
class ModelSettings:
    """How much of the traced multipath the beat model keeps.

    Parameters
    ----------
    prune_margin_db : float, default 20
        A path whose largest power over the sweep (after the IF filter) is more than this far
        below the processed noise floor is dropped [dB]. It then changes no cell of the
        delay-Doppler map by more than 10·log10(1 + 10^(-margin/10)) dB relative to noise
        (0.04 dB at 20 dB).
    if_filter : {"butterworth", "ideal", "none"}, default "butterworth"
        The analogue IF low-pass before the ADC. ``"butterworth"``: magnitude
        ``1/sqrt(1 + (f_b/B_IF)^(2n))`` of order ``if_filter_order`` at the radar's
        ``if_bandwidth``; ``"ideal"``: drop every beat frequency above B_IF; ``"none"``: no
        filter (everything beyond the sample rate folds back).
    if_filter_order : int, default 4
        n of the Butterworth response.
    alias_warning_db : float, default 10
        Warn (:class:`AliasWarning`) when a return whose beat frequency is at or above the
        sample rate reaches this far above the processed noise floor after the filter [dB].
    """

    prune_margin_db: float = 20.0
    if_filter: IfFilter = "butterworth"
    if_filter_order: int = 4
    alias_warning_db: float = 10.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "prune_margin_db", non_negative(self.prune_margin_db, "prune_margin_db", "dB"))
        if self.if_filter not in ("butterworth", "ideal", "none"):
            raise ValueError(f"if_filter={self.if_filter!r} must be 'butterworth', 'ideal' or 'none'")
        object.__setattr__(self, "if_filter_order", positive_int(self.if_filter_order, "if_filter_order"))
        object.__setattr__(self, "alias_warning_db", finite(self.alias_warning_db, "alias_warning_db", "dB"))

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary."""
        from dataclasses import asdict

        return asdict(self)


@dataclass(frozen=True)
class PruneReport:
    """What :func:`prune_paths` kept and dropped.

    Attributes
    ----------
    total, kept : int
        Paths in and out.
    below_floor : int
        Dropped: weaker than the noise floor minus the margin.
    beyond_if : int
        Dropped by the ideal IF filter.
    aliased : int
        Kept paths whose beat frequency is at or above the sample rate (they fold back).
    noise_floor : float
        Processed noise floor per delay-Doppler cell [W].
    peak_power : float array [total]
        Largest power of each input path over the sweep, after the IF filter [W].
    keep : bool array [total]
        Mask of the kept paths.
    warnings : tuple of str
        Messages of the alias warnings raised.
    """

    total: int
    kept: int
    below_floor: int
    beyond_if: int
    aliased: int
    noise_floor: float
    peak_power: np.ndarray
    keep: np.ndarray
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def summary(self) -> str:
        """One line: ``kept 57 of 2704 paths (2630 below the noise floor - 20 dB, ...)``."""
        return (f"kept {self.kept} of {self.total} paths ({self.below_floor} below the noise floor "
                f"margin, {self.beyond_if} beyond the IF bandwidth, {self.aliased} kept aliased)")


def processed_noise_floor(radar: RadarConfig, processing: ProcessingConfig) -> float:
    """Noise power per cell of the normalised delay-Doppler map [W].

    ``σ² · (Σw_N²/(Σw_N)²) · (Σw_K²/(Σw_K)²)``: for the Hann window ``σ² · 1.5²/(N K)``.
    """
    w_n = window_vector(processing.window, radar.num_samples)
    w_k = window_vector(processing.window, radar.num_chirps)
    return radar.noise_power * float((w_n**2).sum() / w_n.sum() ** 2) * float((w_k**2).sum() / w_k.sum() ** 2)


def beat_frequency(paths: PathSet, radar: RadarConfig) -> np.ndarray:
    """|S τ + f_c ν| of each path [L] [Hz]."""
    return np.abs(radar.slope * paths.delay + radar.carrier_frequency * paths.delay_rate)


def if_filter_gain(frequency: Any, radar: RadarConfig, settings: ModelSettings) -> np.ndarray:
    """Amplitude response of the IF filter at beat frequencies [L] [Hz] -> [L] [unitless]."""
    f = np.asarray(frequency, dtype=float)
    if settings.if_filter == "none":
        return np.ones_like(f)
    if settings.if_filter == "ideal":
        return (f <= radar.if_bandwidth).astype(float)
    return 1.0 / np.sqrt(1.0 + (f / radar.if_bandwidth) ** (2 * settings.if_filter_order))


def prune_paths(
    paths: PathSet,
    *,
    radar: RadarConfig,
    processing: ProcessingConfig,
    sweep: BeamSweep,
    ris: RisConfig | None,
    settings: ModelSettings,
) -> tuple[PathSet, PruneReport]:
    """Apply the IF filter to the path gains and drop the paths that cannot matter.

    Parameters
    ----------
    paths : PathSet
    radar, processing, sweep, ris
        RIS paths are judged by their strongest beam, ``|γ|² max_m |r_m|²``.
    settings : ModelSettings

    Returns
    -------
    (PathSet, PruneReport)
        The kept paths, their gains multiplied by the IF filter's amplitude, and the report.

    Warns
    -----
    AliasWarning
        For each kept return beyond the unambiguous range whose power exceeds the noise floor
        by ``alias_warning_db``: it appears as a ghost at ``τ - 1/(S T_s)``.
    """
    n = len(paths)
    f_b = beat_frequency(paths, radar)
    h = if_filter_gain(f_b, radar, settings)
    peak = paths.power * h**2
    via = paths.via_ris
    if via.any():
        if ris is None:
            raise ValueError("the path set has RIS loop-back paths but no RisConfig was given")
        r = ris_response(ris, sweep, paths.ris_incidence[via], paths.ris_departure[via], wavelength=radar.wavelength)
        peak[via] *= (np.abs(r) ** 2).max(axis=0)
    floor = processed_noise_floor(radar, processing)
    threshold = floor * 10 ** (-settings.prune_margin_db / 10)
    beyond_if = h == 0
    weak = (peak < threshold) & ~beyond_if
    keep = ~(weak | beyond_if)
    aliased = keep & (f_b >= radar.sample_rate)

    messages = []
    loud = aliased & (peak > floor * 10 ** (settings.alias_warning_db / 10))
    for i in np.flatnonzero(loud):
        true_d = paths.delay[i] * SPEED_OF_LIGHT / 2
        ghost = (paths.delay[i] % radar.max_delay) * SPEED_OF_LIGHT / 2
        msg = (f"{paths.labels[i]}: return at {true_d:.2f} m (beat {f_b[i] / 1e6:.2f} MHz) lies beyond the "
               f"unambiguous range {radar.max_range:.2f} m and folds back to {ghost:.2f} m at "
               f"{10 * np.log10(peak[i] / floor):.1f} dB above the noise floor after the IF filter")
        messages.append(msg)
        warnings.warn(msg, AliasWarning, stacklevel=2)

    kept = PathSet(
        gain=paths.gain[keep] * h[keep], delay=paths.delay[keep], delay_rate=paths.delay_rate[keep],
        ris_incidence=paths.ris_incidence[keep], ris_departure=paths.ris_departure[keep],
        labels=tuple(lab for lab, k in zip(paths.labels, keep) if k),
    )
    report = PruneReport(
        total=n, kept=int(keep.sum()), below_floor=int(weak.sum()), beyond_if=int(beyond_if.sum()),
        aliased=int(aliased.sum()), noise_floor=floor, peak_power=peak, keep=keep, warnings=tuple(messages),
    )
    return kept, report
