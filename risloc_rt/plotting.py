"""Figures without global state: the one way risloc-rt draws and writes a figure.

Every figure is a :class:`matplotlib.figure.Figure` with its own Agg canvas. Nothing here calls
``matplotlib.use`` or touches :mod:`matplotlib.pyplot`, so a caller's backend, its open figures
and a notebook's inline plots stay as they were; a figure is freed when its last reference goes.
Files are written with :func:`risloc_rt._files.atomic_open` (a reader never sees half a PNG, a
failed write leaves the previous file). Importable from every floor (it imports matplotlib only
when called).
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

from ._files import atomic_open

__all__ = ["new_figure", "figure_bytes", "save_figure"]


def new_figure(*, figsize: tuple[float, float], dpi: float = 100, nrows: int = 0, ncols: int = 1,
               **subplots: Any) -> Any:
    """A new figure on its own Agg canvas, and its axes when ``nrows`` > 0.

    Parameters
    ----------
    figsize : (float, float)
        Width and height [inch].
    dpi : float
        Resolution [dots per inch] (also the default when saving).
    nrows, ncols : int
        With ``nrows`` >= 1, also create an ``nrows`` × ``ncols`` grid of axes
        (:meth:`Figure.subplots`, same squeezing rules); ``nrows=0`` returns the figure alone.
    **subplots
        Passed to :meth:`Figure.subplots` (``gridspec_kw``, ``sharex``, ``subplot_kw``, ...).

    Returns
    -------
    Figure, or (Figure, axes)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    if nrows <= 0:
        if subplots:
            raise TypeError(f"subplot options {sorted(subplots)} need nrows >= 1")
        return fig
    return fig, fig.subplots(nrows, ncols, **subplots)


def figure_bytes(fig: Any, *, fmt: str = "png", tight: bool = True, **savefig: Any) -> bytes:
    """The encoded figure (``fmt``: any format matplotlib writes, default PNG) as bytes.

    ``tight`` applies :meth:`Figure.tight_layout` first; ``savefig`` options (``dpi``,
    ``bbox_inches``, ...) go to :meth:`Figure.savefig`.
    """
    if tight:
        fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, **savefig)
    return buf.getvalue()


def save_figure(fig: Any, path: str | os.PathLike[str], *, tight: bool = True, **savefig: Any) -> Path:
    """Write ``fig`` to ``path`` atomically; the format is the suffix's (``.png`` when none).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        A figure from :func:`new_figure`.
    path : path-like
        The target file; its folder is created when missing.
    tight : bool
        Apply :meth:`Figure.tight_layout` first.
    **savefig
        Options of :meth:`Figure.savefig` (``dpi``, ``bbox_inches``, ...).

    Returns
    -------
    Path
        ``path``.
    """
    out = Path(path)
    fmt = out.suffix.lstrip(".").lower() or "png"
    data = figure_bytes(fig, fmt=fmt, tight=tight, **savefig)
    with atomic_open(out) as fh:
        fh.write(data)
    return out
