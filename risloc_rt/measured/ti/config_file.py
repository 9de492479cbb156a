"""A radar configuration file by its suffix: an mmWave SDK ``.cfg`` or an mmWave Studio ``.json`` export."""

from __future__ import annotations

from pathlib import Path

from ..errors import MeasuredFormatError
from .chirp_config import TiChirpConfig
from .sdk_cfg import read_sdk_cfg
from .studio_json import read_studio_json

__all__ = ["load_config"]


def load_config(path: str | Path, *, strict: bool = True) -> tuple[TiChirpConfig, int | None]:
    """A ``.cfg`` (mmWave SDK) or ``.json`` (mmWave Studio) file → (config, LVDS lanes or None).

    Parameters
    ----------
    path : path
        The configuration file; the suffix (case-insensitive) says which parser reads it.
    strict : bool, default True
        ``.cfg`` only: unknown commands raise (:func:`~.sdk_cfg.parse_sdk_cfg`).

    Returns
    -------
    (TiChirpConfig, int or None)
        The configuration in SI units, and the LVDS lanes the Studio export enables (None for a
        ``.cfg``, which does not say).

    Raises
    ------
    MeasuredFormatError
        Another suffix, or a file its parser refuses.
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        parsed = read_studio_json(path)
        return parsed.config, parsed.lanes
    if path.suffix.lower() == ".cfg":
        return read_sdk_cfg(path, strict=strict).config, None
    raise MeasuredFormatError(f"{path}: unknown config type {path.suffix!r}; give an mmWave SDK .cfg or an "
                              "mmWave Studio .json export")
