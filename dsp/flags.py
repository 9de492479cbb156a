"""Named warnings attached to a localization or a capture inspection (``docs/flags.md``: cause and remedy of each).

One :class:`Flag` type serves both: a localization's flags (``dsp.Localization.flags``) and a raw
capture's inspection (``risloc_rt.measured.inspect_capture``, codes in :data:`INSPECTION_CODES`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Flag", "FLAG_CODES", "INSPECTION_CODES", "flag_codes"]

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
    # capture inspection (risloc_rt.measured.inspect_capture): the raw recording itself
    "dropped-packets": "the DCA1000 lost packets: frames hold zeros in their place",
    "truncated-frame": "the recording ends inside a frame: the incomplete frame is dropped",
    "clipping": "ADC words at a rail: the receiver saturated",
    "dc-offset": "the ADC samples have a DC offset above 1 % of full scale",
    "iq-imbalance": "I and Q differ in gain or phase: images of strong targets appear mirrored in range",
    "iq-order": "more power at negative beat frequencies: I and Q swapped or the lane order wrong",
    "peak-at-dc": "the strongest return is at range bin 0-1: DC offset or Tx-Rx leakage",
    "device-timing": "the radar configuration breaks a device timing rule",
}

#: The codes an inspection of a raw capture (not a localization) may carry.
INSPECTION_CODES: frozenset[str] = frozenset({
    "dropped-packets", "truncated-frame", "clipping", "dc-offset", "iq-imbalance", "iq-order", "peak-at-dc",
    "device-timing"})


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
