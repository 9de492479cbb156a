"""Sweep alignment: where in a recording the RIS sweep starts, and how long each beam lasts.

The radar does not know the RIS's beam; the recording does, through the power of the RIS's
re-transmission. :func:`ris_power_series` measures it per recorded frame and :func:`fit_alignment`
fits the RIS program (:class:`~.ris_timing.RisProgram`: on/off sync cycles, a gap, M beams of
``frames_per_beam`` nominal frames) to it, with the sweep start and the beam dwell free.

**Feature.** Each chirp (selected channels, range-gated below ``min_range``) gets a Hann-windowed
range DFT; its power, summed over channels and **averaged over the frame's chirps** (non-coherent:
a frame whose chirps see two RIS states then has exactly the chirp-weighted mean of their powers,
which a Doppler DFT would not give), is ``P_f(r)``. The range bin whose power varies most over
the recording beyond what noise explains (``var_f P − (2·mean_f P·σ² − σ⁴)/K``, σ² the median
bin power) is the RIS return; ``s_f`` is the power of its 3 range bins, one number per frame.

**Model.** For a start ``t0`` [frames] and dwell ``D`` [frames per beam] every chirp has a state
(:func:`~.ris_timing.chirp_states`), so frame f sees ``ŝ_f = Σ_j A_fj ℓ_j``: ``A_fj`` the fraction
of its chirps in state j (beam m, sync-on, off) and ``ℓ_j`` that state's power, estimated as the
``A``-weighted mean of ``s``. The misfit is ``RSS = Σ_f (√s_f − √ŝ_f)²`` (the square root makes
the noise of a power nearly level-independent). A frame straddling two beams (a dwell that is not
a whole number of frames, or a drifting RIS clock) is modelled, not discarded.

**Search.** ``D = frames_per_beam·(1 + d)`` with ``|d| ≤ max_drift`` in steps that move the
sweep's end by 1/4 frame, ``t0`` in 1/4-frame steps over the recording; the eight best distinct
alignments are refined on a 10× finer grid.

**Confidence.** With Gaussian residuals of the best fit's variance ``σ̂² = RSS_best/(F − J − 2)``
(J free levels), each refined candidate c gets the posterior weight ``w_c ∝ exp(−(RSS_c −
RSS_best)/(2σ̂²))`` (flat prior). A frame is *among beam m's best* under c when its share of
the beam's chirps is within ``MIX_TOLERANCE`` (5 %) of the largest share any frame has (1 when a
frame lies wholly inside the dwell; less with one frame per beam and a RIS not synchronised to
the radar: then every frame straddles two beams, and the beam is reported *mixed*). Each beam
gets the frame most probably among its best; the **confidence** is the posterior probability that
every selected frame is. It is 0 when the fitted program does not beat a constant level (noise
alone, no RIS modulation) in an F-test at ``NULL_P`` = 1e-3. Only the eight best coarse alignments are refined, so the far ones
(worse by many σ̂²) count as zero. Without sync frames and with one frame per beam only the
sweep's edges pin it down, and the confidence says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import numpy as np
import scipy.stats

from dsp import RadarConfig
from dsp.radar import SPEED_OF_LIGHT

from ..errors import MeasuredFormatError
from .leakage import range_gate_basis
from .ris_timing import OFF, SYNC, RisProgram, chirp_states

__all__ = ["MIX_TOLERANCE", "NULL_P", "RisPowerSeries", "SweepAlignment", "fit_alignment", "manual_alignment",
           "ris_power_series", "select_frames"]

NULL_P = 1e-3
"""The fit must beat one constant level (no RIS) at this significance (F-test), else the confidence is 0."""
_SUB_CHIRPS = 16
_TOP = 8
MIX_TOLERANCE = 0.05
"""Share of a frame's chirps [0…1]: a frame is among a beam's best when its share of the beam is within this of
the largest any frame has; a beam is *mixed* when its frame has less than 1 − this of it."""


@dataclass(frozen=True)
class SweepAlignment:
    """Which recorded frame holds each beam, and how sure that is.

    Attributes
    ----------
    method : {"auto", "manual"}
    start : float
        Radar time the first beam starts [frames from the recording's first frame].
    dwell : float
        Radar frames per beam (``frames_per_beam·(1 + drift)``; need not be whole).
    frames_per_beam : int
        The schedule's nominal frames per beam.
    frame_index : int array [M]
        Recorded frame used for each beam: the one holding most of it (manual: the first).
    mixed_beams : tuple of int
        Beams whose frame has more than ``MIX_TOLERANCE`` of its chirps in another state.
    off_frames : int array
        Frames with the RIS off for every chirp (background subtraction uses them).
    confidence : float or None
        Posterior probability that ``frame_index`` is right (module docstring); None when manual.
    runner_up : dict or None
        The best alignment selecting other frames: ``first_frame``, ``start``, ``dwell``,
        ``delta_rss`` (its misfit above the best, in units of σ̂²).
    feature : dict
        The RIS return the fit used: ``range_bin``, ``range`` [m], ``snr_db`` (its strongest
        frames over the noise), ``no_ris_probability`` (the F-test's p-value against no RIS).
    """

    method: str
    start: float
    dwell: float
    frames_per_beam: int
    frame_index: np.ndarray
    mixed_beams: tuple[int, ...] = ()
    off_frames: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    confidence: float | None = None
    runner_up: dict[str, Any] | None = None
    feature: dict[str, Any] = field(default_factory=dict)

    @property
    def first_frame(self) -> int:
        """The recorded frame of beam 0."""
        return int(self.frame_index[0])

    @property
    def drift(self) -> float:
        """RIS clock rate against the radar's, minus 1: ``dwell/frames_per_beam − 1`` [unitless]."""
        return self.dwell / self.frames_per_beam - 1.0

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON (for the capture's provenance).

        Returns
        -------
        dict
            Start and dwell [frames], drift [unitless and ppm], confidence, frames, runner-up, feature.
        """
        return {"method": self.method, "first_frame": self.first_frame, "start": float(self.start),
                "dwell": float(self.dwell), "frames_per_beam": self.frames_per_beam, "drift": float(self.drift),
                "drift_ppm": float(self.drift * 1e6), "confidence": self.confidence,
                "frame_index": [int(f) for f in self.frame_index], "mixed_beams": list(self.mixed_beams),
                "off_frames": len(self.off_frames), "runner_up": self.runner_up, "feature": dict(self.feature)}


@dataclass(frozen=True)
class RisPowerSeries:
    """Per-frame power of the RIS return: ``power [F]`` (ADC counts², 3 range cells, mean over chirps) and its bin."""

    power: np.ndarray
    range_bin: int
    range: float
    noise: float


def select_frames(program: RisProgram, start: float, dwell: float, *, frame_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Frame of each beam and whether it is mixed: ``(frame_index [M], mixed [M])``.

    Beam m lasts ``[start + m·D, start + (m+1)·D)``; a frame occupies ``[f, f + frame_width)``
    (its chirps). The frame with the largest margin ``min(f − start_m, end_m − f − frame_width)``
    is used (the earliest of equals: with a whole dwell and start, the beam's first frame); it
    lies wholly inside the beam when the margin is >= 0, else the beam is *mixed*.

    Parameters
    ----------
    program : RisProgram
        Its M beams.
    start : float
        Radar time the first beam starts [frames].
    dwell : float
        Radar frames per beam D [frames].
    frame_width : float
        Part of the frame interval the chirps occupy [frames].

    Returns
    -------
    (int array [M], bool array [M])
        Each beam's frame and whether it is mixed.
    """
    m = np.arange(program.num_beams)
    lo, hi = start + m * dwell, start + (m + 1) * dwell
    cand = np.floor(lo)[:, None] + np.arange(int(np.ceil(dwell)) + 2)[None, :]         # [M, C]
    margin = np.minimum(cand - lo[:, None], hi[:, None] - cand - frame_width)
    margin = np.where(cand >= 0, np.round(margin, 9), -np.inf)
    pick = np.argmax(margin, axis=1)
    best = margin[m, pick]
    return cand[m, pick].astype(np.int64), best < -1e-9


def _frame_times(num_frames: int, fractions: np.ndarray) -> np.ndarray:
    return np.arange(num_frames, dtype=float)[:, None] + fractions[None, :]          # [F, Kc]


def _off_frames(program: RisProgram, start: float, dwell: float, num_frames: int, fractions: np.ndarray) -> np.ndarray:
    st = chirp_states(program, _frame_times(num_frames, fractions), start=start, dwell=dwell)
    return np.flatnonzero(np.all(st == OFF, axis=1)).astype(np.int64)


def manual_alignment(program: RisProgram, first_frame: int, *, num_frames: int, fractions: np.ndarray) -> SweepAlignment:
    """The schedule's own alignment: beam m at frame ``first_frame + m·frames_per_beam``.

    Parameters
    ----------
    program : RisProgram
        The beams and frames per beam (the RIS-off frames follow from its sync pattern).
    first_frame : int
        The recorded frame of beam 0.
    num_frames : int
        Frames in the recording.
    fractions : float array [K]
        Chirp start times within a frame [frames] (:func:`~.ris_timing.chirp_fractions`).

    Returns
    -------
    SweepAlignment
        ``method="manual"``, no confidence.
    """
    idx = first_frame + program.frames_per_beam * np.arange(program.num_beams, dtype=np.int64)
    return SweepAlignment(method="manual", start=float(first_frame), dwell=float(program.frames_per_beam),
                          frames_per_beam=program.frames_per_beam, frame_index=idx,
                          off_frames=_off_frames(program, float(first_frame), float(program.frames_per_beam),
                                                 num_frames, fractions))


def ris_power_series(blocks: Callable[[], Iterable[np.ndarray]], radar: RadarConfig, *, min_range: float = 0.5,
                     gate: np.ndarray | None = None) -> RisPowerSeries:
    """The per-frame RIS-return power of a recording (module docstring, "Feature").

    Parameters
    ----------
    blocks : callable
        Returns a fresh iterator of frame blocks ``complex [B, K, V, N]`` (the selected channels);
        called twice (one pass finds the cell, one reads it).
    radar : RadarConfig
    min_range : float
        Cells nearer than this to zero beat frequency (either side: bin N−1 is just below DC) are
        not candidates (leakage, DC) [m].
    gate : array [N, T], optional
        Range-gate basis applied to each frame first; default: the gate at ``min_range``
        (:func:`.leakage.range_gate_basis`), which removes the leakage's phase-noise skirt too.

    Returns
    -------
    RisPowerSeries
        ``power [F]`` [ADC counts²], its range bin and range [m], the noise level [counts²].
    """
    N = radar.num_samples
    if gate is None:
        gate = range_gate_basis(radar, min_range)
    cell = radar.sample_rate / N * SPEED_OF_LIGHT / (2 * radar.slope)
    min_range = min_range + 2 * cell
    win = np.hanning(N + 2)[1:-1]

    def power(block: np.ndarray) -> np.ndarray:
        y = block - (block @ gate) @ gate.T
        spec = np.fft.ifft(y * win, axis=-1)                                   # [B, K, V, N] range profiles
        return np.mean(np.sum(np.abs(spec) ** 2, axis=2), axis=1)               # [B, N]: mean over chirps

    total = np.zeros(N)
    square = np.zeros(N)
    count = 0
    for block in blocks():
        p = power(block)
        total += p.sum(axis=0)
        square += (p ** 2).sum(axis=0)
        count += p.shape[0]
    if count < 2:
        raise MeasuredFormatError(f"the recording holds {count} frame(s); finding the sweep needs the whole sweep")
    mean = total / count
    var = square / count - mean ** 2
    noise = float(np.median(mean))
    score = var - (2 * mean * noise - noise ** 2) / radar.num_chirps
    bin_range = np.arange(N) * cell
    far = bin_range[-1] + cell
    score[(bin_range < min_range) | (bin_range > far - min_range)] = -np.inf   # both sides of zero beat frequency
    p = int(np.argmax(score))
    cols = np.clip(np.arange(p - 1, p + 2), 0, N - 1)
    series = [power(block)[:, cols].sum(axis=1) for block in blocks()]
    return RisPowerSeries(power=np.concatenate(series), range_bin=p, range=float(bin_range[p]), noise=noise)


def _exact(s: np.ndarray, program: RisProgram, start: float, dwell: float, times: np.ndarray) -> float:
    """RSS (square-root domain) of one candidate with the levels fitted by least squares."""
    F, Kc = times.shape
    J = program.num_beams + 2
    state = chirp_states(program, times, start=start, dwell=dwell)
    j = np.where(state >= 0, state, np.where(state == SYNC, J - 2, J - 1))
    A = np.bincount((np.arange(F)[:, None] * J + j).ravel(), minlength=F * J).reshape(F, J) / Kc
    A = A[:, A.any(axis=0)]
    gram = A.T @ A
    level = np.linalg.solve(gram + 1e-12 * np.trace(gram) * np.eye(gram.shape[0]), A.T @ s)
    pred = A @ level
    return float(np.sum((np.sqrt(np.maximum(s, 0)) - np.sqrt(np.maximum(pred, 0))) ** 2))


def _evaluate(s: np.ndarray, program: RisProgram, starts: np.ndarray, dwell: float, times: np.ndarray) -> np.ndarray:
    """RSS (square-root domain) of each start for one dwell, levels as weighted means (fast): ``[C]``."""
    F, Kc = times.shape
    J = program.num_beams + 2
    root = np.sqrt(np.maximum(s, 0))
    out = np.empty(starts.size)
    chunk = max(1, 2_000_000 // (F * Kc))
    for c0 in range(0, starts.size, chunk):
        st = starts[c0:c0 + chunk]
        C = st.size
        state = chirp_states(program, times[None], start=st[:, None, None], dwell=dwell)    # [C, F, Kc]
        j = np.where(state >= 0, state, np.where(state == SYNC, J - 2, J - 1))
        idx = (np.arange(C)[:, None, None] * J + j).ravel()
        w = np.broadcast_to(s[None, :, None], (C, F, Kc)).ravel()
        pure = np.broadcast_to(np.all(j == j[:, :, :1], axis=2)[:, :, None], j.shape).ravel()
        num = np.bincount(idx, weights=w, minlength=C * J)
        den = np.bincount(idx, minlength=C * J)
        num_p = np.bincount(idx, weights=w * pure, minlength=C * J)
        den_p = np.bincount(idx, weights=pure, minlength=C * J)
        # A state's level: the mean of its pure frames (unbiased), else the chirp-weighted mean.
        level = np.where(den_p > 0, num_p / np.maximum(den_p, 1), np.where(den > 0, num / np.maximum(den, 1), 0.0))
        level = level.reshape(C, J)
        pred = np.take_along_axis(level, j.reshape(C, -1), axis=1).reshape(C, F, Kc).mean(axis=2)
        out[c0:c0 + C] = np.sum((root[None] - np.sqrt(np.maximum(pred, 0))) ** 2, axis=1)
    return out


def _candidates(s: np.ndarray, program: RisProgram, times: np.ndarray, *, max_drift: float,
                frame_width: float) -> np.ndarray:
    """The refined alignments ``[C, 3]``: (start [frames], dwell [frames], RSS) (module docstring, "Search")."""
    F, M, P = s.size, program.num_beams, program.frames_per_beam
    step_d = 0.25 / (M * P)
    n_d = min(int(np.ceil(max_drift / step_d)), 400) if max_drift > 0 else 0
    drifts = np.linspace(-max_drift, max_drift, 2 * n_d + 1) if n_d else np.zeros(1)
    coarse: list[tuple[float, float, float]] = []                            # (rss, start, dwell)
    fine: dict[tuple[float, float], float] = {}                             # (start, dwell) -> exact rss

    def run(starts: np.ndarray, dwell: float, exact: bool = False) -> None:
        if exact:
            for t in starts:
                key = (round(float(t), 6), round(float(dwell), 9))
                if key not in fine:
                    fine[key] = _exact(s, program, float(t), dwell, times)
            return
        coarse.extend(zip(_evaluate(s, program, starts, dwell, times), starts, np.full(starts.size, dwell)))

    for d in drifts:
        dwell = P * (1 + d)
        t_hi = F - (M - 1) * dwell - frame_width
        if t_hi >= 0:
            run(np.arange(0.0, t_hi + 1e-9, 0.25), dwell)
    if not coarse:
        raise MeasuredFormatError(
            f"the recording holds {F} frame(s), too few for {M} beams x {P} frame(s); check the sweep schedule's "
            "beams and frames_per_beam, or whether the recording stopped early")
    seeds: list[tuple[float, float, float]] = []                             # the best distinct coarse fits
    for r, t, d in sorted(coarse):
        if all(abs(t - t2) >= 0.5 or abs((t + M * d) - (t2 + M * d2)) >= 0.5 for _, t2, d2 in seeds):
            seeds.append((r, t, d))
            if len(seeds) == _TOP:
                break
    fine_d = step_d / 4 if n_d else 0.0
    for _, t0, dwell in seeds:                                # the best few, finer, with least-squares levels
        for dd in np.arange(-2, 3) * fine_d if n_d else [0.0]:
            dw = dwell + P * dd
            if abs(dw / P - 1) <= max_drift + 1e-12:
                run(t0 + np.arange(-10, 11) * 0.025, dw, exact=True)
    return np.array([(t, d, r) for (t, d), r in fine.items()])                  # [C, 3]


def _beam_frames(cand: np.ndarray, weight: np.ndarray, best_i: int, num_beams: int, *, frame_width: float,
                 num_frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(frame_index [M], ok [C], mixed [M])``: each beam's frame most probably among its best, whether candidate
    c agrees on every beam, and whether the best fit leaves a beam's frame mixed (module docstring, "Confidence")."""
    t0, dwell = cand[best_i, 0], cand[best_i, 1]
    m = np.arange(num_beams)
    options = np.floor(t0 + m * dwell)[:, None] + np.arange(-1, int(np.ceil(dwell)) + 2)[None, :]     # [M, O]
    lo = cand[:, 0][:, None, None] + m[None, :, None] * cand[:, 1][:, None, None]                     # [C, M, 1]
    hi = lo + cand[:, 1][:, None, None]
    share = np.clip(np.minimum(options[None] + frame_width, hi) - np.maximum(options[None], lo), 0, None) / frame_width
    share = np.where((options[None] >= 0) & (options[None] < num_frames), share, -1.0)              # [C, M, O]
    good = share >= share.max(axis=2, keepdims=True) - MIX_TOLERANCE
    p_good = np.einsum("c,cmo->mo", weight, good)
    pick = np.argmax(p_good + 1e-9 * np.arange(options.shape[1], 0, -1)[None, :], axis=1)
    idx = options[m, pick].astype(np.int64)
    ok = good[:, m, pick].all(axis=1)                                                               # [C]
    mixed = share[best_i, m, pick] < 1 - MIX_TOLERANCE
    return idx, ok, mixed


def _no_ris_probability(s: np.ndarray, rss0: float, levels: int) -> float:
    """p-value of the F-test of the fitted program (``levels`` free levels) against one constant level."""
    F = s.size
    root = np.sqrt(np.maximum(s, 0))
    rss_null = float(np.sum((root - root.mean()) ** 2))
    dof = max(F - levels - 2, 1)
    stat = ((rss_null - rss0) / (levels - 1)) / (rss0 / dof) if rss0 > 0 else np.inf
    return float(scipy.stats.f.sf(stat, levels - 1, dof))


def fit_alignment(series: RisPowerSeries | np.ndarray, program: RisProgram, *, fractions: np.ndarray,
                  frame_width: float, max_drift: float = 0.02) -> SweepAlignment:
    """Fit the RIS program to the per-frame RIS power (module docstring).

    Parameters
    ----------
    series : RisPowerSeries or float array [F]
        The RIS return's power per recorded frame [ADC counts²].
    program : RisProgram
        The RIS's program in nominal frames (sync, gap, beams).
    fractions : float array [Kc]
        Chirp start times within a frame [frames] (:func:`~.ris_timing.chirp_fractions`).
    frame_width : float
        Part of the frame interval the chirps occupy [frames] (1 for back-to-back frames).
    max_drift : float
        Largest RIS clock rate error searched, |d| [unitless, e.g. 0.02 = 2 %].

    Returns
    -------
    SweepAlignment
        ``method="auto"``: start and dwell [frames], each beam's frame, the mixed beams, the
        RIS-off frames, the confidence, the runner-up and the feature used.
    """
    s = np.asarray(series.power if isinstance(series, RisPowerSeries) else series, float)
    F, M, P = s.size, program.num_beams, program.frames_per_beam
    if not 0 <= max_drift < 0.5:
        raise MeasuredFormatError(f"max_clock_drift = {max_drift!r} must lie in [0, 0.5), e.g. 0.02 (2 %)")
    sub = fractions if fractions.size <= _SUB_CHIRPS else fractions[np.unique(np.round(
        np.linspace(0, fractions.size - 1, _SUB_CHIRPS)).astype(int))]
    cand = _candidates(s, program, _frame_times(F, sub), max_drift=max_drift, frame_width=frame_width)
    best_i = int(np.argmin(cand[:, 2]))
    t0, dwell, rss0 = cand[best_i]
    J = M + (2 if program.has_sync else 1)
    sigma2 = max(rss0 / max(F - J - 2, 1), 1e-30)
    weight = np.exp(-0.5 * (cand[:, 2] - rss0) / sigma2)
    weight /= weight.sum()
    idx, ok, mixed = _beam_frames(cand, weight, best_i, M, frame_width=frame_width, num_frames=F)
    confidence = float(np.sum(weight[ok]))
    p_null = _no_ris_probability(s, rss0, J)         # is there a RIS at all? (F-test against noise alone)
    if p_null > NULL_P:
        confidence = 0.0
    runner = None
    if not ok.all():
        j = int(np.flatnonzero(~ok)[np.argmin(cand[~ok, 2])])
        r_idx, _ = select_frames(program, cand[j, 0], cand[j, 1], frame_width=frame_width)
        runner = {"first_frame": int(r_idx[0]), "start": float(cand[j, 0]), "dwell": float(cand[j, 1]),
                  "delta_rss": float((cand[j, 2] - rss0) / sigma2)}
    feature: dict[str, Any] = {}
    if isinstance(series, RisPowerSeries):
        top = float(np.percentile(s, 99))
        feature = {"range_bin": series.range_bin, "range": series.range,
                   "snr_db": float(10 * np.log10(max(top, 1e-300) / max(3 * series.noise, 1e-300)))}
    feature["no_ris_probability"] = p_null
    return SweepAlignment(method="auto", start=t0, dwell=dwell, frames_per_beam=P, frame_index=idx,
                          mixed_beams=tuple(int(m) for m in np.flatnonzero(mixed)),
                          off_frames=_off_frames(program, t0, dwell, F, fractions), confidence=confidence,
                          runner_up=runner, feature=feature)
