"""Named warnings attached to a localization (``docs/flags.md`` gives cause and remedy of each)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Flag", "FLAG_CODES", "flag_codes"]

#: Every code a :class:`Flag` may carry, with a one-line meaning (``docs/flags.md``).
FLAG_CODES: dict[str, str] = {
    "no-detection": "nothing beam-dependent above the detection threshold: no position",
    "no-beam-dependence": "a strong return does not follow the sweep: it is not the RIS",
    "grating-lobe": "another lobe of the sweep is within a few dB: the AoD is ambiguous",
    "beam-edge": "the best beam is the first or last of the sweep: the UE may lie outside it",
    "aliased": "the return may lie beyond the unambiguous range or velocity",
    "unresolved-peaks": "two returns within one resolution cell: delay and AoD are biased",
    "before-ris-delay": "the delay is shorter than the RIS loop-back delay: negative distance",
    "elevation-assumed": "a 1-D sweep cannot see elevation: the position assumes the sweep plane",
}


@dataclass(frozen=True)
class Flag:
    """One named warning about an estimate.

    Attributes
    ----------
    code : str
        One of :data:`FLAG_CODES`.
    message : str
        What was found, with numbers, and what to do.
    """

    code: str
    message: str

    def __post_init__(self) -> None:
        if self.code not in FLAG_CODES:
            raise ValueError(f"code={self.code!r} is not a flag code; valid codes are {sorted(FLAG_CODES)}")

    def to_dict(self) -> dict[str, Any]:
        """``{"code", "message"}``."""
        return {"code": self.code, "message": self.message}

    def __str__(self) -> str:
        return f"{self.code}: {self.message}"


def flag_codes(flags: Any) -> tuple[str, ...]:
    """The codes of a sequence of flags, in order."""
    return tuple(f.code for f in flags)


def _deg(x: float) -> str:
    return f"{np.rad2deg(x):+.2f}°"
