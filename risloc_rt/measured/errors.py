"""The one error type of :mod:`risloc_rt.measured`, and the small input checks that raise it."""

from __future__ import annotations

import operator
from pathlib import Path
from typing import Any

__all__ = ["MeasuredFormatError", "read_text_file"]


class MeasuredFormatError(ValueError):
    """A raw capture or radar configuration that cannot be read as given.

    The message is one line: what is wrong (file, line, field, expected and actual values) and
    how to fix it.
    """


def check_int(value: Any, name: str, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as an int in [minimum, maximum]; bools and non-integers raise."""
    if isinstance(value, bool):
        raise MeasuredFormatError(f"{name}={value!r} must be an integer, not a bool")
    try:
        out = operator.index(value)
    except TypeError:
        raise MeasuredFormatError(f"{name}={value!r} must be an integer") from None
    if minimum is not None and out < minimum:
        raise MeasuredFormatError(f"{name}={out} must be >= {minimum}")
    if maximum is not None and out > maximum:
        raise MeasuredFormatError(f"{name}={out} must be <= {maximum}")
    return int(out)


def check_float(value: Any, name: str, unit: str, *, positive: bool = False,
                non_negative: bool = False) -> float:
    """``value`` as a finite float, optionally > 0 or >= 0."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise MeasuredFormatError(f"{name}={value!r} must be a number [{unit}]") from None
    if out != out or out in (float("inf"), float("-inf")):
        raise MeasuredFormatError(f"{name}={out} must be finite [{unit}]")
    if positive and out <= 0:
        raise MeasuredFormatError(f"{name}={out:g} {unit} must be > 0")
    if non_negative and out < 0:
        raise MeasuredFormatError(f"{name}={out:g} {unit} must be >= 0")
    return out


def read_text_file(path: Path, what: str, missing: str) -> str:
    """The UTF-8 text of ``path``; a missing, unreadable or binary file is one :class:`MeasuredFormatError`.

    ``what`` names the file's role ("sweep schedule"); ``missing`` says how to get one.
    """
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise MeasuredFormatError(f"{what} {path} does not exist; {missing}") from None
    except IsADirectoryError:
        raise MeasuredFormatError(f"{what} {path} is a folder; give the file") from None
    except PermissionError:
        raise MeasuredFormatError(f"{what} {path} cannot be read (permission denied)") from None
    except UnicodeDecodeError:
        raise MeasuredFormatError(f"{path}: not a UTF-8 text file; a {what} is text") from None
