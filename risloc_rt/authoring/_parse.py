"""Reading TOML tables with errors that name the key path and the fix (used by :mod:`.spec`)."""

from __future__ import annotations

import difflib
import math
from typing import Any

__all__ = ["SpecError", "Table", "toml_type"]

_MISSING = object()


class SpecError(ValueError):
    """A hall spec that cannot be used; the message names the key path and says how to fix it.

    Attributes
    ----------
    key : str
        Dotted key path of the offending value, e.g. ``"objects[2].size"`` (``""`` for the file).
    problem, fix : str
        What is wrong, and how to fix it.
    code : str
        Which check failed, for :mod:`.check`: ``"spec"`` (a malformed spec, the default),
        ``"material.frequency"`` (an ITU material undefined at the carrier) or
        ``"position.outside"`` (a radar or RIS outside the hall).
    """

    def __init__(self, key: str, problem: str, fix: str = "", *, source: str | None = None,
                 code: str = "spec") -> None:
        self.key = key
        self.problem = problem
        self.fix = fix
        self.source = source
        self.code = code
        message = f"{key}: {problem}" if key else problem
        if fix:
            message += f"; {fix}"
        if source:
            message = f"{source}: {message}"
        super().__init__(message)

    def with_source(self, source: str) -> "SpecError":
        """The same error, its message prefixed with the spec file's path."""
        return SpecError(self.key, self.problem, self.fix, source=source, code=self.code)


def toml_type(value: Any) -> str:
    """TOML name of a Python value's type (for error messages)."""
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "float"
    if isinstance(value, str):
        return "string"
    if isinstance(value, list):
        return "array"
    if isinstance(value, dict):
        return "table"
    return type(value).__name__


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class Table:
    """A TOML table being read.

    Every accessor marks its key as used; :meth:`finish` then rejects the keys nobody asked for
    (typos), suggesting the closest valid key.

    Parameters
    ----------
    data : dict
        The parsed TOML table.
    path : str
        Its key path (``""`` for the document root, ``"objects[2]"`` for an array element).
    """

    def __init__(self, data: Any, path: str) -> None:
        if not isinstance(data, dict):
            raise SpecError(path, f"must be a table, got a {toml_type(data)} ({data!r})",
                            "write it as [section] or {key = value, ...}")
        self.data = data
        self.path = path
        self._valid: list[str] = []

    def key(self, name: str) -> str:
        """Key path of ``name`` in this table."""
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        """Whether the key is present (and declares it valid)."""
        self._valid.append(name)
        return name in self.data

    def raw(self, name: str, default: Any = _MISSING, *, what: str = "") -> Any:
        """The value as parsed by tomllib; missing without default raises, naming ``what``."""
        self._valid.append(name)
        if name in self.data:
            return self.data[name]
        if default is _MISSING:
            raise SpecError(self.key(name), "required key is missing",
                            f"add {name} = {what}" if what else f"add the key '{name}'")
        return default

    def number(self, name: str, *, unit: str, default: Any = _MISSING, minimum: float | None = None,
               strict: bool = False, example: str = "") -> Any:
        """A finite float; with ``minimum``, ``>= minimum`` (``> minimum`` when ``strict``)."""
        value = self.raw(name, default, what=example or f"<number> [{unit}]")
        if value is default and default is not _MISSING:
            return value
        return check_number(value, self.key(name), unit=unit, minimum=minimum, strict=strict)

    def integer(self, name: str, *, default: Any = _MISSING, minimum: int | None = None) -> Any:
        """An integer (a float such as ``16.0`` is refused: counts are written without a point)."""
        value = self.raw(name, default, what="<integer>")
        if value is default and default is not _MISSING:
            return value
        if not isinstance(value, int) or isinstance(value, bool):
            raise SpecError(self.key(name), f"must be an integer, got a {toml_type(value)} ({value!r})",
                            f"write e.g. {name} = 16")
        if minimum is not None and value < minimum:
            raise SpecError(self.key(name), f"{value} must be >= {minimum}", f"use an integer >= {minimum}")
        return value

    def string(self, name: str, *, default: Any = _MISSING, choices: tuple[str, ...] | None = None) -> Any:
        """A string, optionally one of ``choices``."""
        value = self.raw(name, default, what='"<text>"' if not choices else f'"{choices[0]}"')
        if value is default and default is not _MISSING:
            return value
        if not isinstance(value, str):
            raise SpecError(self.key(name), f"must be a string, got a {toml_type(value)} ({value!r})",
                            f'write it in quotes, e.g. {name} = "{choices[0] if choices else "text"}"')
        if choices is not None and value not in choices:
            raise SpecError(self.key(name), f"{value!r} is not one of {list(choices)}",
                            f"use one of {', '.join(repr(c) for c in choices)}" + _suggest(value, choices))
        return value

    def vector(self, name: str, length: int, *, unit: str, default: Any = _MISSING, minimum: float | None = None,
               strict: bool = False) -> Any:
        """A tuple of ``length`` finite floats."""
        example = "[" + ", ".join(["<number>"] * length) + f"] [{unit}]"
        value = self.raw(name, default, what=example)
        if value is default and default is not _MISSING:
            return value
        return check_vector(value, self.key(name), length, unit=unit, minimum=minimum, strict=strict)

    def table(self, name: str) -> "Table | None":
        """An optional sub-table, ``None`` when absent."""
        value = self.raw(name, None)
        return None if value is None else Table(value, self.key(name))

    def required_table(self, name: str) -> "Table":
        """A sub-table that must be present."""
        return Table(self.raw(name, what="{ ... }"), self.key(name))

    def tables(self, name: str) -> list["Table"]:
        """An array of tables (``[[name]]``); empty when absent."""
        value = self.raw(name, [])
        if not isinstance(value, list):
            raise SpecError(self.key(name), f"must be an array of tables, got a {toml_type(value)}",
                            f"write each entry as [[{name}]]")
        return [Table(item, f"{self.key(name)}[{i}]") for i, item in enumerate(value)]

    def finish(self) -> None:
        """Raise on the first key no accessor asked for."""
        valid = sorted(set(self._valid))
        for name in self.data:
            if name not in valid:
                raise SpecError(self.key(name), "unknown key",
                                f"valid keys here are {valid or 'none'}" + _suggest(name, valid))


def _suggest(name: str, options: Any) -> str:
    close = difflib.get_close_matches(name, list(options), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def check_number(value: Any, key: str, *, unit: str, minimum: float | None = None, strict: bool = False) -> float:
    """``value`` as a finite float, optionally bounded below; errors name ``key``."""
    if not _is_number(value):
        raise SpecError(key, f"must be a number [{unit}], got a {toml_type(value)} ({value!r})",
                        "write a plain number without quotes")
    v = float(value)
    if not math.isfinite(v):
        raise SpecError(key, f"{v} is not finite", "use a finite number")
    if minimum is not None and (v <= minimum if strict else v < minimum):
        bound = ">" if strict else ">="
        raise SpecError(key, f"{v:g} must be {bound} {minimum:g} [{unit}]", f"use a value {bound} {minimum:g}")
    return v


def check_vector(value: Any, key: str, length: int, *, unit: str, minimum: float | None = None,
                 strict: bool = False) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` finite floats; errors name ``key`` or ``key[i]``."""
    if not isinstance(value, list) or len(value) != length:
        got = f"{len(value)} values" if isinstance(value, list) else f"a {toml_type(value)}"
        raise SpecError(key, f"must be an array of {length} numbers [{unit}], got {got} ({value!r})",
                        "write e.g. [" + ", ".join(["1.0"] * length) + "]")
    return tuple(check_number(v, f"{key}[{i}]", unit=unit, minimum=minimum, strict=strict)
                 for i, v in enumerate(value))
