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

**Chirps of each beam.** The cube holds K chirps per beam. A frame wholly inside the beam's
dwell is used as it is (the one with the largest margin to the beam's edges; with a whole dwell
and start, the beam's first frame). A beam that no frame holds wholly (a dwell that is not a whole
number of frames, an unsynchronised RIS) is *spread over two frames*; ``assemble`` decides:
``"span"`` takes the K consecutive chirps (in recording order, across the frame boundary) wholly
inside the dwell with the largest margin (the automatic alignment also when the best whole frame
lies within :data:`SPAN_PREFERENCE` of an edge and the K chirps lie that much further inside),
``"frame"`` the frame holding most of the
beam's chirps (then the beam is *mixed*). :data:`DEFAULT_ASSEMBLE` is the better of the two on emulated
recordings (``docs/measured-captures.md``, "RIS timing model"). A beam holding fewer than K
chirps (a RIS clock slightly fast with one frame per beam) takes the K consecutive chirps holding
most of it with ``"span"``, the frame holding most of it with ``"frame"``.

**Confidence.** With Gaussian residuals of the best fit's variance ``σ̂² = RSS_best/(F − J − 2)``
(J free levels), each refined candidate c gets the posterior weight ``w_c ∝ exp(−(RSS_c −
RSS_best)/(2σ̂²))`` (flat prior). A frame is *among beam m's best* under c when its share of
the beam's chirps is within ``MIX_TOLERANCE`` (5 %) of the largest share any frame has (1 when a
frame lies wholly inside the dwell; less with one frame per beam and a RIS not synchronised to
the radar: then every frame straddles two beams, and the beam is reported *mixed*). The same holds
for the K chirps of a ``"span"`` (the best any K consecutive chirps can have). Each beam gets the
chirps the best fit selects; the **confidence** is the posterior probability that every beam's
chirps are among its best. It is 0 when the fitted program does not beat a constant level (noise
alone, no RIS modulation) in an F-test at ``NULL_P`` = 1e-3. Only the eight best coarse alignments are refined, so the far ones
(worse by many σ̂²) count as zero. Without sync frames and with one frame per beam only the
sweep's edges pin it down, and the confidence says so.

**Checking a given first frame** (:func:`check_first_frame`). A first frame given in the schedule
(or ``--first-frame``) is checked against the same fit: the data *clearly contradicts it* when the
fit is confident (>= :data:`CHECK_CONFIDENCE`), the posterior probability that every beam's given
chirps are among its best is at most 1 − :data:`CHECK_CONFIDENCE` (whole frames judged against
the best whole frames), and the given timing fits worse by at least :data:`CHECK_DELTA_RSS` σ̂²
(with the fitted dwell; for a whole ``frames_per_beam`` the best start that makes the given frame
beam 0's first, ``(first_frame − 1 + w, first_frame]``, w the chirps' share of the frame
interval; else the manual alignment's start ``first_frame``).
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

__all__ = ["ASSEMBLE_MODES", "CHECK_CONFIDENCE", "CHECK_DELTA_RSS", "DEFAULT_ASSEMBLE", "MIX_TOLERANCE", "NULL_P",
           "SPAN_PREFERENCE",
           "RisPowerSeries", "ScheduleCheck", "SweepAlignment", "check_first_frame", "fit_alignment",
           "manual_alignment", "ris_power_series", "select_chirps"]

NULL_P = 1e-3
"""The fit must beat one constant level (no RIS) at this significance (F-test), else the confidence is 0."""
_SUB_CHIRPS = 16
_TOP = 8
_REFINE_STEPS = 6
_CHECK_STARTS = 10
MIX_TOLERANCE = 0.05
"""Share of a frame's chirps [0…1]: a frame is among a beam's best when its share of the beam is within this of
the largest any frame has; a beam is *mixed* when its frame has less than 1 − this of it."""
ASSEMBLE_MODES = ("span", "frame")
"""A beam spread over two frames: its K consecutive chirps across the boundary, or the frame holding most of it."""
DEFAULT_ASSEMBLE = "span"
"""Chosen by the measurement in docs/measured-captures.md ("RIS timing model")."""
SPAN_PREFERENCE = 0.05
"""``"span"``, automatic alignment: a whole frame closer than this to the beam's edge [frames] gives way to K
consecutive chirps across two frames lying this much further inside (robustness to the fitted start)."""
CHECK_CONFIDENCE = 0.9
"""A given first frame is contradicted only by a fit at least this confident."""
CHECK_DELTA_RSS = 25.0
"""... whose misfit is at least this many σ̂² below the given alignment's (5 σ)."""


@dataclass(frozen=True)
class SweepAlignment:
    """Which recorded chirps hold each beam, and how sure that is.

    Attributes
    ----------
    method : {"auto", "manual"}
    start : float
        Radar time the first beam starts [frames from the recording's first frame].
    dwell : float
        Radar frames per beam (``frames_per_beam·(1 + drift)``; need not be whole).
    frames_per_beam : float
        The program's nominal frames per beam (the schedule's ``frames_per_beam``, or
        ``beam_dwell_ms`` over the radar's frame period).
    frame_index : int array [M]
        The recorded frame of each beam: the one holding most of its chirps.
    chirp_start : int array [M]
        Each beam's first chirp in recording order (``frame·K + k``); the beam uses the K
        consecutive chirps from it (across a frame boundary for a ``"span"``).
    num_chirps : int
        K, chirps per frame.
    assemble : {"span", "frame"}
        How a beam spread over two frames was taken (module docstring).
    mixed_beams : tuple of int
        Beams whose chirps have more than ``MIX_TOLERANCE`` in another state.
    off_frames : int array
        Frames with the RIS off for every chirp (background subtraction uses them).
    confidence : float or None
        Posterior probability that every beam's chirps are right (module docstring); None when manual.
    runner_up : dict or None
        The best alignment selecting other chirps: ``first_frame``, ``start``, ``dwell``,
        ``delta_rss`` (its misfit above the best, in units of σ̂²).
    feature : dict
        The RIS return the fit used: ``range_bin``, ``range`` [m], ``snr_db`` (its strongest
        frames over the noise), ``no_ris_probability`` (the F-test's p-value against no RIS).
    """

    method: str
    start: float
    dwell: float
    frames_per_beam: float
    frame_index: np.ndarray
    chirp_start: np.ndarray
    num_chirps: int
    assemble: str = DEFAULT_ASSEMBLE
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

    def beam_segments(self) -> list[list[list[int]]]:
        """Per beam, the recorded chirps it uses.

        Returns
        -------
        list [M] of lists
            ``[[frame, first chirp, count], ...]``: one segment (a whole frame) or two (a span).
        """
        return [_segments(int(g0), self.num_chirps) for g0 in self.chirp_start]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON (for the capture's provenance).

        Returns
        -------
        dict
            Start and dwell [frames], drift [unitless and ppm], confidence, frames, each beam's chirps
            (``beam_chirps``: ``[[frame, first chirp, count], ...]`` per beam), runner-up, feature.
        """
        return {"method": self.method, "first_frame": self.first_frame, "start": float(self.start),
                "dwell": float(self.dwell), "frames_per_beam": float(self.frames_per_beam),
                "drift": float(self.drift), "drift_ppm": float(self.drift * 1e6), "confidence": self.confidence,
                "frame_index": [int(f) for f in self.frame_index], "assemble": self.assemble,
                "beam_chirps": self.beam_segments(), "mixed_beams": list(self.mixed_beams),
                "off_frames": len(self.off_frames), "runner_up": self.runner_up, "feature": dict(self.feature)}


def _segments(g0: int, K: int) -> list[list[int]]:
    f, k = divmod(g0, K)
    return [[f, k, K]] if k == 0 else [[f, k, K - k], [f + 1, 0, k]]


@dataclass(frozen=True)
class RisPowerSeries:
    """Per-frame power of the RIS return: ``power [F]`` (ADC counts², 3 range cells, mean over chirps) and its bin."""

    power: np.ndarray
    range_bin: int
    range: float
    noise: float


@dataclass(frozen=True)
class ScheduleCheck:
    """A given first frame checked against the recording (:func:`check_first_frame`).

    Attributes
    ----------
    given : int
        The schedule's (or the command line's) first frame.
    supported : int
        The first frame the fit selects.
    start : float
        The fitted start [frames].
    confidence : float
        The fit's confidence.
    delta_rss : float
        The given start's misfit above the fit's (with the fitted dwell) [σ̂²].
    given_probability : float
        Posterior probability that every beam's given chirps are among its best (as the confidence).
    beams_differ : int
        Beams whose given chirps are not among the best under the fitted timing.
    mismatch : bool
        The data clearly contradicts the given frames (module docstring).
    """

    given: int
    supported: int
    start: float
    confidence: float
    delta_rss: float
    given_probability: float
    beams_differ: int
    mismatch: bool

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON (for the provenance).

        Returns
        -------
        dict
            The attributes; ``start`` [frames], ``delta_rss`` [σ̂²].
        """
        return {"given": self.given, "supported": self.supported, "start": float(self.start),
                "confidence": float(self.confidence), "delta_rss": float(self.delta_rss),
                "given_probability": float(self.given_probability), "beams_differ": self.beams_differ,
                "mismatch": self.mismatch}


def _check_assemble(assemble: str) -> None:
    if assemble not in ASSEMBLE_MODES:
        raise MeasuredFormatError(f"assemble = {assemble!r} must be one of {', '.join(ASSEMBLE_MODES)}")


def select_chirps(program: RisProgram, start: float, dwell: float, *, num_chirps: int, frame_width: float,
                  num_frames: int | None = None, assemble: str = DEFAULT_ASSEMBLE,
                  span_preference: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Each beam's K chirps and whether they are mixed: ``(chirp_start [M], mixed [M])``.

    Beam m lasts ``[start + m·D, start + (m+1)·D)``; frame f's chirp k starts at ``f + k·w/K``
    (w = ``frame_width``) and lasts ``w/K``. A frame wholly inside the beam (margin
    ``min(f − start_m, end_m − f − w) >= 0``) is used, the largest margin first (the earliest of
    equals: with a whole dwell and start, the beam's first frame). ``"span"`` takes instead the K
    consecutive chirps (across a frame boundary) with the largest margin when no frame is wholly
    inside, or when the best frame's margin is below ``span_preference`` and theirs exceeds it by
    more than that (the automatic alignment uses :data:`SPAN_PREFERENCE`; 0: never). When
    neither fits (the beam is shorter than K chirps), ``"span"`` takes the K consecutive chirps
    holding most of the beam's chirp time, ``"frame"`` the frame holding most of it; the beam is
    *mixed*.

    Parameters
    ----------
    program : RisProgram
        Its M beams.
    start : float
        Radar time the first beam starts [frames].
    dwell : float
        Radar frames per beam D [frames].
    num_chirps : int
        K, chirps per frame.
    frame_width : float
        Part of the frame interval the chirps occupy, K·T_c/T_f [frames].
    num_frames : int, optional
        Frames recorded (chirps beyond are not used).
    assemble : {"span", "frame"}
    span_preference : float
        [frames]; see above.

    Returns
    -------
    (int array [M], bool array [M])
        Each beam's first chirp (``frame·K + k``) and whether its chirps are mixed.
    """
    _check_assemble(assemble)
    K, w = int(num_chirps), float(frame_width)
    c = w / K
    F = np.inf if num_frames is None else num_frames
    m = np.arange(program.num_beams)
    lo, hi = start + m * dwell, start + (m + 1) * dwell
    cand = np.floor(lo)[:, None] + np.arange(-1, int(np.ceil(dwell)) + 2)[None, :]          # [M, C] frames
    ok = (cand >= 0) & (cand < F)
    margin = np.where(ok, np.round(np.minimum(cand - lo[:, None], hi[:, None] - cand - w), 9), -np.inf)
    pick = np.argmax(margin, axis=1)
    chirp_start = (cand[m, pick] * K).astype(np.int64)
    mixed = margin[m, pick] < -1e-9
    share = np.where(ok, _share(cand, lo[:, None], hi[:, None], w), -1.0)                    # frame holding most
    most = (cand[m, np.argmax(share, axis=1)] * K).astype(np.int64)
    chirp_start[mixed] = most[mixed]
    if assemble == "span":
        g0 = (cand[:, :1] * K).astype(np.int64) + np.arange(cand.shape[1] * K)[None, :]       # [M, G] window starts
        t_first = g0 // K + (g0 % K) * c
        g1 = g0 + K - 1
        t_end = g1 // K + (g1 % K) * c + c
        mg = np.round(np.minimum(t_first - lo[:, None], hi[:, None] - t_end), 9)
        mg = np.where((g0 >= 0) & (g1 // K < F), mg, -np.inf)
        i = np.argmax(mg, axis=1)
        span_margin = mg[m, i]
        whole = margin[m, pick]
        loose = (whole < span_preference) & (span_margin > whole + span_preference) if span_preference else False
        take = (span_margin >= -1e-9) & (mixed | loose)
        chirp_start = np.where(take, g0[m, i], chirp_start)
        mixed = mixed & ~take
        # a beam shorter than K chirps: the K consecutive chirps holding most of it (the fewest of another state)
        share = np.where(np.isfinite(mg), _share(t_first, lo[:, None], hi[:, None], w), -1.0)
        j = np.argmax(np.round(share, 9), axis=1)
        chirp_start = np.where(mixed, g0[m, j], chirp_start)
        mixed = mixed & (share[m, j] < 1 - MIX_TOLERANCE)
    return chirp_start, mixed


def _chirp_time(x: np.ndarray, w: float) -> np.ndarray:
    """Chirp time in ``[0, x)``: ``⌊x⌋·w + min(x − ⌊x⌋, w)`` [frames] (frames of K chirps spanning w each)."""
    f = np.floor(x)
    return f * w + np.minimum(x - f, w)


def _share(a: np.ndarray, lo: np.ndarray, hi: np.ndarray, w: float) -> np.ndarray:
    """Share of the K chirps from radar time ``a`` (a chirp's start) that lies in ``[lo, hi)``: their chirp time,
    ``[a, a + 1)`` of the recording's chirp time, inside the beam, over w [0…1]."""
    top, bottom = np.minimum(hi, a + 1.0), np.maximum(lo, a)
    return np.maximum(_chirp_time(top, w) - _chirp_time(bottom, w), 0.0) * (top > bottom) / w


def _frame_of(chirp_start: np.ndarray, K: int) -> np.ndarray:
    """The frame holding most of each beam's K chirps (the first of two equal halves)."""
    f, k = np.divmod(np.asarray(chirp_start, np.int64), K)
    return np.where(K - k >= k, f, f + 1).astype(np.int64)


def _frame_times(num_frames: int, fractions: np.ndarray) -> np.ndarray:
    return np.arange(num_frames, dtype=float)[:, None] + fractions[None, :]          # [F, Kc]


def _off_frames(program: RisProgram, start: float, dwell: float, num_frames: int, fractions: np.ndarray) -> np.ndarray:
    st = chirp_states(program, _frame_times(num_frames, fractions), start=start, dwell=dwell)
    return np.flatnonzero(np.all(st == OFF, axis=1)).astype(np.int64)


def _whole(frames: float) -> bool:
    return abs(frames - round(frames)) < 1e-9


def _width(fractions: np.ndarray, frame_width: float | None) -> float:
    if frame_width is not None:
        return float(frame_width)
    return float(fractions.size * (fractions[1] - fractions[0])) if fractions.size > 1 else 1.0


def manual_alignment(program: RisProgram, first_frame: int, *, num_frames: int, fractions: np.ndarray,
                     frame_width: float | None = None, assemble: str = DEFAULT_ASSEMBLE) -> SweepAlignment:
    """The schedule's own alignment: beam 0 starts with frame ``first_frame``, beams last the nominal dwell.

    With a whole ``frames_per_beam`` beam m is frame ``first_frame + m·frames_per_beam`` (its
    first frame); with a dwell that is not whole, beam m starts at radar time ``first_frame +
    m·frames_per_beam`` and its chirps follow :func:`select_chirps` (no span preference).

    Parameters
    ----------
    program : RisProgram
        The beams and their nominal dwell (the RIS-off frames follow from its sync code).
    first_frame : int
        The recorded frame of beam 0 (its start: ``start = first_frame``).
    num_frames : int
        Frames in the recording.
    fractions : float array [K]
        Chirp start times within a frame [frames] (:func:`~.ris_timing.chirp_fractions`, all K).
    frame_width : float, optional
        K·T_c/T_f [frames]; default ``K·fractions[1]``.
    assemble : {"span", "frame"}

    Returns
    -------
    SweepAlignment
        ``method="manual"``, no confidence.
    """
    w = _width(fractions, frame_width)
    K = fractions.size
    dwell = float(program.frames_per_beam)
    if _whole(dwell):                                         # the first frame of each beam, as the schedule says
        g0 = (first_frame + int(round(dwell)) * np.arange(program.num_beams, dtype=np.int64)) * K
        mixed = np.zeros(program.num_beams, bool)
    else:
        g0, mixed = select_chirps(program, float(first_frame), dwell, num_chirps=K, frame_width=w, assemble=assemble)
    return SweepAlignment(method="manual", start=float(first_frame), dwell=dwell,
                          frames_per_beam=float(program.frames_per_beam), frame_index=_frame_of(g0, K),
                          chirp_start=g0, num_chirps=K, assemble=assemble,
                          mixed_beams=tuple(int(b) for b in np.flatnonzero(mixed)),
                          off_frames=_off_frames(program, float(first_frame), dwell, num_frames, fractions))


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
    # einsum, not BLAS: these products are tiny, and a threaded BLAS on a busy machine makes them 10x slower
    gram = np.einsum("fi,fj->ij", A, A)
    level = np.linalg.solve(gram + 1e-12 * np.trace(gram) * np.eye(gram.shape[0]), np.einsum("fj,f->j", A, s))
    pred = np.einsum("fj,j->f", A, level)
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

    def run(starts: np.ndarray, dwell: float, exact: bool = False) -> tuple[float, tuple[float, float]] | None:
        if exact:
            best: tuple[float, tuple[float, float]] | None = None
            for t in starts:
                key = (round(float(t), 6), round(float(dwell), 9))
                if key not in fine:
                    fine[key] = _exact(s, program, float(t), dwell, times)
                if best is None or fine[key] < best[0]:
                    best = (fine[key], key)
            return best
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
    for _, t0, dwell in seeds:          # the best few, finer, with least-squares levels, moved to the local best
        for _ in range(_REFINE_STEPS):
            found = []
            for dd in np.arange(-2, 3) * fine_d if n_d else [0.0]:
                dw = dwell + P * dd
                if abs(dw / P - 1) <= max_drift + 1e-12:
                    found.append(run(t0 + np.arange(-10, 11) * 0.025, dw, exact=True))
            _, (t1, d1) = min(f for f in found if f is not None)
            if abs(t1 - t0) < 0.2 and abs(d1 - dwell) < 1.5 * P * fine_d:
                break                                           # the local best is inside the searched patch
            t0, dwell = t1, d1
    return np.array([(t, d, r) for (t, d), r in fine.items()])                  # [C, 3]


def _agreement(cand: np.ndarray, chirp_start: np.ndarray, best_i: int, *, num_chirps: int, frame_width: float,
               num_frames: int, assemble: str, per_beam: bool = False) -> Any:
    """``(ok [C], mixed [M])``: whether each candidate c finds every beam's chirps among its best (share within
    ``MIX_TOLERANCE`` of the best any K consecutive chirps, or any frame, can have), and whether the best fit leaves
    a beam's chirps mixed (module docstring, "Confidence")."""
    K, w = int(num_chirps), float(frame_width)
    M = chirp_start.size
    m = np.arange(M)
    lo = cand[:, 0][:, None] + m[None, :] * cand[:, 1][:, None]                               # [C, M]
    hi = lo + cand[:, 1][:, None]
    f0, r = np.divmod(chirp_start, K)
    start = (f0 + r * (w / K))[None, :]                                                       # first chirp's time
    share = _share(start, lo, hi, w)                                                          # [C, M]
    if assemble == "span":
        best = np.minimum((_chirp_time(hi, w) - _chirp_time(lo, w)) / w, 1.0)
    else:
        dwell = float(np.max(cand[:, 1]))
        f = np.floor(lo)[:, :, None] + np.arange(-1, int(np.ceil(dwell)) + 2)[None, None, :]  # [C, M, O] frames near
        opt = np.where((f >= 0) & (f < num_frames), _share(f, lo[:, :, None], hi[:, :, None], w), 0.0)
        best = np.maximum(opt.max(axis=2), share)
    good = share >= best - MIX_TOLERANCE
    if per_beam:
        return good[best_i]                                                                   # [M]
    return good.all(axis=1), share[best_i] < 1 - MIX_TOLERANCE


def _no_ris_probability(s: np.ndarray, rss0: float, levels: int) -> float:
    """p-value of the F-test of the fitted program (``levels`` free levels) against one constant level."""
    F = s.size
    root = np.sqrt(np.maximum(s, 0))
    rss_null = float(np.sum((root - root.mean()) ** 2))
    dof = max(F - levels - 2, 1)
    stat = ((rss_null - rss0) / (levels - 1)) / (rss0 / dof) if rss0 > 0 else np.inf
    return float(scipy.stats.f.sf(stat, levels - 1, dof))


def _fit(series: RisPowerSeries | np.ndarray, program: RisProgram, *, fractions: np.ndarray, frame_width: float,
         max_drift: float, assemble: str) -> tuple[SweepAlignment, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`fit_alignment`, with σ̂², what :func:`_exact` needs and the posterior: ``(alignment, sigma2, s [F],
    times [F, Kc], candidates [C, 3], weights [C])``."""
    _check_assemble(assemble)
    s = np.asarray(series.power if isinstance(series, RisPowerSeries) else series, float)
    F, M, P = s.size, program.num_beams, program.frames_per_beam
    K = fractions.size
    if not 0 <= max_drift < 0.5:
        raise MeasuredFormatError(f"max_clock_drift = {max_drift!r} must lie in [0, 0.5), e.g. 0.02 (2 %)")
    sub = fractions if fractions.size <= _SUB_CHIRPS else fractions[np.unique(np.round(
        np.linspace(0, fractions.size - 1, _SUB_CHIRPS)).astype(int))]
    times = _frame_times(F, sub)
    cand = _candidates(s, program, times, max_drift=max_drift, frame_width=frame_width)
    best_i = int(np.argmin(cand[:, 2]))
    t0, dwell, rss0 = cand[best_i]
    J = M + (2 if program.has_sync else 1)
    sigma2 = max(rss0 / max(F - J - 2, 1), 1e-30)
    weight = np.exp(-0.5 * (cand[:, 2] - rss0) / sigma2)
    weight /= weight.sum()
    g0, _ = select_chirps(program, t0, dwell, num_chirps=K, frame_width=frame_width, num_frames=F, assemble=assemble,
                          span_preference=SPAN_PREFERENCE)
    ok, mixed = _agreement(cand, g0, best_i, num_chirps=K, frame_width=frame_width, num_frames=F, assemble=assemble)
    confidence = float(np.sum(weight[ok]))
    p_null = _no_ris_probability(s, rss0, J)         # is there a RIS at all? (F-test against noise alone)
    if p_null > NULL_P:
        confidence = 0.0
    runner = None
    if not ok.all():
        j = int(np.flatnonzero(~ok)[np.argmin(cand[~ok, 2])])
        r_g0, _ = select_chirps(program, cand[j, 0], cand[j, 1], num_chirps=K, frame_width=frame_width,
                                num_frames=F, assemble=assemble, span_preference=SPAN_PREFERENCE)
        runner = {"first_frame": int(_frame_of(r_g0, K)[0]), "start": float(cand[j, 0]), "dwell": float(cand[j, 1]),
                  "delta_rss": float((cand[j, 2] - rss0) / sigma2)}
    feature: dict[str, Any] = {}
    if isinstance(series, RisPowerSeries):
        top = float(np.percentile(s, 99))
        feature = {"range_bin": series.range_bin, "range": series.range,
                   "snr_db": float(10 * np.log10(max(top, 1e-300) / max(3 * series.noise, 1e-300)))}
    feature["no_ris_probability"] = p_null
    align = SweepAlignment(method="auto", start=t0, dwell=dwell, frames_per_beam=float(P),
                           frame_index=_frame_of(g0, K), chirp_start=g0, num_chirps=K, assemble=assemble,
                           mixed_beams=tuple(int(m) for m in np.flatnonzero(mixed)),
                           off_frames=_off_frames(program, t0, dwell, F, fractions), confidence=confidence,
                           runner_up=runner, feature=feature)
    return align, sigma2, s, times, cand, weight


def fit_alignment(series: RisPowerSeries | np.ndarray, program: RisProgram, *, fractions: np.ndarray,
                  frame_width: float, max_drift: float = 0.02, assemble: str = DEFAULT_ASSEMBLE) -> SweepAlignment:
    """Fit the RIS program to the per-frame RIS power (module docstring).

    Parameters
    ----------
    series : RisPowerSeries or float array [F]
        The RIS return's power per recorded frame [ADC counts²].
    program : RisProgram
        The RIS's program in nominal frames (sync code, gap, beams).
    fractions : float array [K]
        Chirp start times within a frame, all K [frames] (:func:`~.ris_timing.chirp_fractions`).
    frame_width : float
        Part of the frame interval the chirps occupy, K·T_c/T_f [frames] (1 for back-to-back frames).
    max_drift : float
        Largest RIS clock rate error searched, |d| [unitless, e.g. 0.02 = 2 %].
    assemble : {"span", "frame"}
        A beam spread over two frames: its K consecutive chirps, or the frame holding most of it.

    Returns
    -------
    SweepAlignment
        ``method="auto"``: start and dwell [frames], each beam's chirps and frame, the mixed beams,
        the RIS-off frames, the confidence, the runner-up and the feature used.
    """
    return _fit(series, program, fractions=fractions, frame_width=frame_width, max_drift=max_drift,
                assemble=assemble)[0]


def check_first_frame(series: RisPowerSeries | np.ndarray, program: RisProgram, first_frame: int, *,
                      fractions: np.ndarray, frame_width: float, max_drift: float = 0.02,
                      assemble: str = DEFAULT_ASSEMBLE, min_confidence: float = CHECK_CONFIDENCE,
                      min_delta_rss: float = CHECK_DELTA_RSS) -> ScheduleCheck:
    """Check a given first frame against the recording (module docstring, "Checking a given first frame").

    Parameters
    ----------
    series : RisPowerSeries or float array [F]
        The RIS return's power per recorded frame [ADC counts²].
    program : RisProgram
    first_frame : int
        The given first frame (beam 0 starts with it).
    fractions, frame_width, max_drift, assemble
        As :func:`fit_alignment`.
    min_confidence : float
        The fit must be at least this confident to contradict the given frame.
    min_delta_rss : float
        ... and fit at least this many σ̂² better than the given start.

    Returns
    -------
    ScheduleCheck
        ``mismatch`` True when the data clearly contradicts the given frames; ``supported`` the fitted
        first frame, ``beams_differ`` the beams whose given chirps the fit does not support.
    """
    align, sigma2, s, times, cand, weight = _fit(series, program, fractions=fractions, frame_width=frame_width,
                                                 max_drift=max_drift, assemble=assemble)
    F, K = s.size, fractions.size
    given = manual_alignment(program, int(first_frame), num_frames=F, fractions=fractions, frame_width=frame_width,
                             assemble=assemble)
    whole = _whole(float(program.frames_per_beam))
    best_i = int(np.argmin(cand[:, 2]))
    # judged as what it is: whole frames against the best whole frames, else in the import's mode
    ok, _ = _agreement(cand, given.chirp_start, best_i, num_chirps=K, frame_width=frame_width, num_frames=F,
                       assemble="frame" if whole else assemble)
    good_best = _agreement(cand[best_i:best_i + 1], given.chirp_start, 0, num_chirps=K, frame_width=frame_width,
                           num_frames=F, assemble="frame" if whole else assemble, per_beam=True)
    p_given = float(np.sum(weight[ok]))
    rss_best = _exact(s, program, align.start, align.dwell, times)
    if whole:       # every start that makes first_frame the first frame inside beam 0: (first_frame - 1 + w, first_frame]
        starts = first_frame - (1.0 - min(frame_width, 1.0)) * np.arange(_CHECK_STARTS) / _CHECK_STARTS
    else:           # the manual alignment's own start
        starts = np.array([float(first_frame)])
    rss_given = min(_exact(s, program, float(t), align.dwell, times) for t in starts)
    delta = (rss_given - rss_best) / sigma2
    mismatch = bool(align.confidence >= min_confidence and p_given <= 1.0 - min_confidence
                    and delta >= min_delta_rss)
    return ScheduleCheck(given=int(first_frame), supported=align.first_frame, start=float(align.start),
                         confidence=float(align.confidence), delta_rss=float(delta), given_probability=p_given,
                         beams_differ=int(np.sum(~good_best)), mismatch=mismatch)
