"""Input checks: the one validation idiom of :mod:`dsp` and every ``risloc_rt`` package.

Every check raises :class:`ValueError` (or :class:`TypeError`) whose message names the
argument, says what was found and what is expected; the scalar checks take ``error=`` for a
package's own error type (``risloc_rt.measured`` passes ``MeasuredFormatError``), so the text
and the rule are the same everywhere.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def _describe_shape(shape: tuple[int | None, ...]) -> str:
    return "[" + ", ".join("*" if s is None else str(s) for s in shape) + "]"


def require_complex_samples(value: Any, name: str) -> None:
    """Refuse real, integer and boolean sample arrays: beat samples are complex (I/Q).

    A real-sampled ADC (TI ``adcCfg`` real) folds negative beat frequencies onto positive ones, so
    casting it to complex gives wrong ranges; the caller must form the analytic signal first.
    """
    dtype = getattr(value, "dtype", None)
    if dtype is None:
        dtype = np.asarray(value).dtype
    if np.dtype(dtype).kind in "biuf":
        raise TypeError(
            f"{name} is real-valued ({np.dtype(dtype)}); beat samples must be complex I/Q. For a real-sampled "
            "ADC form the analytic signal first (scipy.signal.hilbert(x, axis=-1)); do not cast"
        )


def as_finite_array(
    value: Any,
    name: str,
    *,
    shape: tuple[int | None, ...] | None = None,
    trailing: tuple[int, ...] | None = None,
    dtype: type = float,
    allow_empty: bool = False,
) -> np.ndarray:
    """Convert ``value`` to a finite numpy array, checking its shape.

    Parameters
    ----------
    value : array_like
        The input.
    name : str
        Argument name used in error messages.
    shape : tuple of (int or None), optional
        Required shape; ``None`` entries match any length.
    trailing : tuple of int, optional
        Required trailing dimensions (any number of leading ones).
    dtype : type
        ``float`` or ``complex``.
    allow_empty : bool
        Accept arrays with a zero-length axis.
    """
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a numeric array, got {type(value).__name__}: {exc}") from None
    if shape is not None:
        ok = arr.ndim == len(shape) and all(s is None or s == a for s, a in zip(shape, arr.shape))
        if not ok:
            raise ValueError(f"{name} has shape {list(arr.shape)}, expected {_describe_shape(shape)}")
    if trailing is not None:
        if arr.ndim < len(trailing) or tuple(arr.shape[arr.ndim - len(trailing):]) != tuple(trailing):
            raise ValueError(
                f"{name} has shape {list(arr.shape)}, expected [..., {', '.join(map(str, trailing))}]"
            )
    if arr.size == 0 and not allow_empty:
        raise ValueError(f"{name} is empty (shape {list(arr.shape)}); it needs at least one element")
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"{name} contains {bad} NaN or infinite value(s); all values must be finite")
    return arr


def _number(value: Any, name: str, unit: str, error: type[Exception] | None) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise (error or TypeError)(f"{name}={value!r} must be a number [{unit}]") from None
    if isinstance(value, bool):
        raise (error or TypeError)(f"{name}={value!r} must be a number [{unit}], not a bool")
    return v


def positive(value: Any, name: str, unit: str, *, error: type[Exception] | None = None) -> float:
    """``value`` as a float, requiring a finite number > 0 [``unit``].

    Raises ``error`` (default: :class:`TypeError` for a non-number, :class:`ValueError` for a value
    out of range); a package with its own error type (``MeasuredFormatError``) passes it here.
    """
    v = _number(value, name, unit, error)
    if not np.isfinite(v) or v <= 0:
        raise (error or ValueError)(f"{name}={value!r} must be a finite number > 0 [{unit}]")
    return v


def non_negative(value: Any, name: str, unit: str, *, error: type[Exception] | None = None) -> float:
    """``value`` as a float, requiring a finite number >= 0 [``unit``]; errors as :func:`positive`."""
    v = _number(value, name, unit, error)
    if not np.isfinite(v) or v < 0:
        raise (error or ValueError)(f"{name}={value!r} must be a finite number >= 0 [{unit}]")
    return v


def finite(value: Any, name: str, unit: str, *, error: type[Exception] | None = None) -> float:
    """``value`` as a finite float [``unit``]; errors as :func:`positive`."""
    v = _number(value, name, unit, error)
    if not np.isfinite(v):
        raise (error or ValueError)(f"{name}={value!r} must be finite [{unit}]")
    return v


def integer(value: Any, name: str, *, minimum: int | None = None, maximum: int | None = None,
            error: type[Exception] | None = None) -> int:
    """``value`` as an int in [``minimum``, ``maximum``].

    Bools and non-integral numbers are refused; an integral float (``4.0``, as JSON may give)
    is accepted. Errors as :func:`positive`.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, (float, np.floating)) and float(value).is_integer():
            value = int(value)
        else:
            raise (error or TypeError)(f"{name}={value!r} must be an integer")
    if minimum is not None and value < minimum:
        raise (error or ValueError)(f"{name}={value!r} must be an integer >= {minimum}")
    if maximum is not None and value > maximum:
        raise (error or ValueError)(f"{name}={value!r} must be an integer <= {maximum}")
    return int(value)


def interval(value: Any, name: str, unit: str, *, low: float, high: float, closed: str = "neither",
             error: type[Exception] | None = None) -> float:
    """``value`` as a float inside the interval from ``low`` to ``high`` [``unit``].

    ``closed`` says which ends belong to it: ``"neither"`` (low, high), ``"low"`` [low, high),
    ``"high"`` (low, high] or ``"both"`` [low, high]. Errors as :func:`positive`.
    """
    if closed not in ("neither", "low", "high", "both"):
        raise ValueError(f"closed={closed!r} must be 'neither', 'low', 'high' or 'both'")
    v = _number(value, name, unit, error)
    above = v >= low if closed in ("low", "both") else v > low
    below = v <= high if closed in ("high", "both") else v < high
    if not (np.isfinite(v) and above and below):
        left = "[" if closed in ("low", "both") else "("
        right = "]" if closed in ("high", "both") else ")"
        raise (error or ValueError)(f"{name}={value!r} must lie in {left}{low:g}, {high:g}{right}"
                                    + (f" [{unit}]" if unit else ""))
    return v


def one_of(value: Any, name: str, choices: Any, *, error: type[Exception] | None = None) -> Any:
    """``value`` itself when it is one of ``choices``, else :class:`ValueError` (or ``error``) listing them."""
    if value not in tuple(choices):
        raise (error or ValueError)(f"{name}={value!r} must be one of {', '.join(map(str, choices))}")
    return value


def positive_int(value: Any, name: str, *, error: type[Exception] | None = None) -> int:
    """``value`` as an int >= 1 (:func:`integer` with ``minimum=1``)."""
    return integer(value, name, minimum=1, error=error)


def dataclass_from_dict(cls: type, data: Any, what: str, *, require_all: bool = False) -> Any:
    """Build the dataclass ``cls`` from a mapping, naming unknown or missing keys in the error.

    With ``require_all`` every field must be present (used when reading files, so that nothing
    is silently taken from a default).
    """
    from dataclasses import MISSING, fields

    if not isinstance(data, dict):
        raise TypeError(f"{what} must be a mapping of field names to values, got {type(data).__name__}")
    all_fields = fields(cls)
    names = {f.name for f in all_fields}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"{what}: unknown field(s) {unknown}; valid fields are {sorted(names)}")
    missing = sorted(
        f.name for f in all_fields
        if f.name not in data
        and (require_all or (f.default is MISSING and f.default_factory is MISSING))  # type: ignore[misc]
    )
    if missing:
        raise ValueError(f"{what}: missing field(s) {missing}")
    return cls(**data)


def fields_equal(a: Any, b: Any) -> bool:
    """Field-by-field equality of two dataclasses holding arrays (NaN equals NaN).

    For ``__eq__`` of frozen result dataclasses: the generated one compares arrays with ``==``
    and fails on arrays of more than one element.
    """
    from dataclasses import fields

    if type(a) is not type(b):
        return NotImplemented
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y), equal_nan=np.asarray(x).dtype.kind in "fc"):
                return False
        elif isinstance(x, float) and isinstance(y, float) and np.isnan(x) and np.isnan(y):
            continue
        elif x != y:
            return False
    return True
