"""One position from the captures of several RISs: ``risloc locate a.npz b.npz`` (issue 22).

Each capture holds one RIS's sweep (time division: one RIS sweeps while the others are idle,
``docs/ray-tracing.md`` "Several RISs"), its pose and its localization; the detected ones become
:class:`dsp.fusion.RisFix` and are fused by :func:`dsp.fusion.fuse_fixes` (3-D position, covariance
from the summed Fisher information, χ² consistency with exclusions). A capture is named by its
file's stem (``ris0.npz`` → ``ris0``), as ``risloc capture import`` writes them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dsp.fusion import KNOWN_HEIGHT_STD, FusedFix, RisFix, fuse_fixes

from .report import CaseResult, significant

__all__ = ["check_distinct_ris", "fuse_cases", "fused_dict", "format_fused", "common_truth"]

#: Two captures whose RIS centres are closer than this are the same RIS [m].
SAME_RIS = 1e-3
#: Truth positions within this of each other are one (static) radar position [m].
SAME_POSITION = 1e-3


def check_distinct_ris(names: list[str], captures: list[Any]) -> None:
    """Refuse two captures of one RIS (their RIS centres within 1 mm), before any is localized.

    Parameters
    ----------
    names : list of str
        The captures' names (file stems).
    captures : list of risloc_rt.model.Capture
        The captures, in the same order.

    Raises
    ------
    ValueError
        One line naming both captures.
    """
    for i, a in enumerate(captures):
        for j in range(i):
            b = captures[j]
            if float(np.linalg.norm(a.ris.pose.position - b.ris.pose.position)) < SAME_RIS:
                raise ValueError(f"captures {names[j]!r} and {names[i]!r} are of the same RIS (at "
                                 f"{np.round(a.ris.pose.position, 3).tolist()} m): a fused fix takes one "
                                 "sweep per RIS; locate them separately, or track a moving radar with 'risloc track'")


def fuse_cases(cases: list[CaseResult], *, height: float | None = None) -> FusedFix | None:
    """Fuse the detected captures of several RISs; None when none was detected.

    Parameters
    ----------
    cases : list of CaseResult
        One per capture, each of a different RIS.
    height : float, optional
        The radar's known height z [m] (``--ue-height``): one more measurement of the fusion, with
        the 1σ ``dsp.fusion.KNOWN_HEIGHT_STD`` (``dsp.fuse_fixes(height=...)``), and part of its χ² test.

    Returns
    -------
    FusedFix or None

    Raises
    ------
    ValueError
        Two captures of one RIS (:func:`check_distinct_ris`).
    """
    check_distinct_ris([c.name for c in cases], [c.capture for c in cases])
    fixes = [RisFix.from_localization(c.name, c.capture.ris.pose, c.localization)
             for c in cases if c.localization.detected and c.localization.std is not None]
    known = None if height is None else (float(height), KNOWN_HEIGHT_STD)
    return fuse_fixes(fixes, height=known) if fixes else None


def common_truth(cases: list[CaseResult]) -> np.ndarray | None:
    """The radar's true position when every capture has a truth and they agree within 1 mm.

    Parameters
    ----------
    cases : list of CaseResult
        The located captures.

    Returns
    -------
    float array [3] or None
        The position [m]; None without a truth, or when the truths differ (the radar moved).
    """
    truths = [c.truth for c in cases]
    if not truths or any(t is None for t in truths):
        return None
    points = np.array([t.ue_position for t in truths])
    if float(np.max(np.linalg.norm(points - points[0], axis=1))) > SAME_POSITION:
        return None
    return points[0]


def fused_dict(fused: FusedFix | None, truth: Any = None) -> dict[str, Any]:
    """The fused fix as plain JSON (``result.json``'s ``"fused"``); its error when ``truth`` [3] [m] is given.

    Parameters
    ----------
    fused : FusedFix or None
        None: no RIS was detected.
    truth : float array [3], optional
        The radar's true position [m].

    Returns
    -------
    dict
        ``detected``, ``position`` [m], ``std`` [m] (``inf``: unobservable), ``covariance`` [m²],
        ``peb`` [m], ``used``, ``excluded`` (name, why), ``statistic``, ``threshold``, ``dof``,
        ``flags``; with a truth ``truth`` and ``error`` (the Euclidean distance [m]).
    """
    if fused is None:
        return {"detected": False}
    out: dict[str, Any] = {
        "detected": True, "position": fused.position, "std": fused.std, "covariance": fused.covariance,
        "peb": fused.peb, "used": list(fused.used), "excluded": [list(e) for e in fused.excluded],
        "statistic": fused.statistic, "threshold": fused.threshold, "dof": fused.dof,
        "flags": [f.to_dict() for f in fused.flags]}
    if truth is not None:
        truth = np.asarray(truth, dtype=float)
        out["truth"] = truth
        seen = np.isfinite(fused.std)
        out["error"] = float(np.linalg.norm((fused.position - truth)[seen]))
    return out


def format_fused(fused: FusedFix | None, truth: Any = None, *, moved: bool = False) -> str:
    """The fused fix as console lines: position ± 1σ per axis, PEB, the RISs used and left out, flags.

    Parameters
    ----------
    fused : FusedFix or None
        None: no RIS was detected.
    truth : float array [3], optional
        The radar's true position [m]: the error is printed (over the axes the fixes see).
    moved : bool
        The captures' truths differ (the radar moved between the sweeps): said, no error printed.

    Returns
    -------
    str
    """
    if fused is None:
        return "== fused: NOTHING DETECTED by any RIS: no position"
    axes = []
    for name, x, s in zip("xyz", fused.position, fused.std):
        axes.append(f"{name} {x:+.4f}" + (" ± unobservable" if np.isinf(s) else f" ± {significant(s)}"))
    peb = "unobservable" if not np.isfinite(fused.peb) else f"{significant(fused.peb)} m"
    lines = [f"== fused ({len(fused.used)} RIS: {', '.join(fused.used)}): position [m] " + ", ".join(axes)
             + f"; PEB {peb}"]
    if fused.dof > 0:
        lines.append(f"  consistency: χ² {fused.statistic:.2f} against {fused.threshold:.2f} at {fused.dof} degrees "
                     "of freedom")
    for name, why in fused.excluded:
        lines.append(f"  left out {name}: {why}")
    if truth is not None:
        seen = np.isfinite(fused.std)
        err = float(np.linalg.norm((fused.position - np.asarray(truth, dtype=float))[seen]))
        over = "" if seen.all() else " (over the observable axes)"
        lines.append(f"  truth {np.round(np.asarray(truth, dtype=float), 4).tolist()} m: error {err:.4f} m{over}")
    elif moved:
        lines.append("  the captures' truths differ: the radar moved between the sweeps, so the fused position mixes "
                     "them (no error printed; 'risloc track' follows a moving radar)")
    lines += [f"  flag {f.code}: {f.message}" for f in fused.flags]
    return "\n".join(lines)
