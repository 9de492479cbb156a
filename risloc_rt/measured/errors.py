"""The one error type of :mod:`risloc_rt.measured` and the text-file reader that raises it.

Input checks are :mod:`dsp.validation`'s, called with ``error=MeasuredFormatError``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["MeasuredFormatError", "read_text_file"]


class MeasuredFormatError(ValueError):
    """A raw capture or radar configuration that cannot be read as given.

    The message is one line: what is wrong (file, line, field, expected and actual values) and
    how to fix it.
    """


def read_text_file(path: Path, what: str, missing: str) -> str:
    """The UTF-8 text of ``path``; a missing, unreadable or binary file is one :class:`MeasuredFormatError`.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        The file's role in messages ("sweep schedule").
    missing : str
        How to get one, appended to the message for a missing file.

    Returns
    -------
    str
        The file's text.
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
