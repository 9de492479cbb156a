"""Memory budgets: estimate what a computation allocates and refuse it before it starts.

A size read from a file or a flag (``processing.k_dft = 1e9``, a cube header claiming
10¹² samples, ``--samples 1e12``) must end in an error that names the parameter, the estimate and
the limit, not in a ``MemoryError`` traceback, a swapping machine or a killed process. The limit
is :func:`memory_limit`: ``$RISLOC_MEMORY_LIMIT`` when set (bytes, or with a suffix: ``8G``,
``512M``), else half the memory the machine has available when asked (``MemAvailable`` in
``/proc/meminfo``, else half the physical memory), so the default follows the machine.

Pure Python and numpy; used by the capture reader, the ray tracer's settings and the CLI.
"""

from __future__ import annotations

import os
import re
from typing import Any

__all__ = ["BudgetError", "MEMORY_LIMIT_ENV", "check_memory", "detect_batch_size", "detect_memory", "dsp_memory",
           "format_bytes", "memory_limit",
           "parse_bytes"]

#: Environment variable that overrides the memory limit (bytes, or ``8G``, ``512M``, ``2.5GiB``).
MEMORY_LIMIT_ENV = "RISLOC_MEMORY_LIMIT"
#: Fraction of the available memory one computation may plan to use by default.
DEFAULT_FRACTION = 0.5
_UNITS = {"": 1, "b": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


class BudgetError(ValueError):
    """A computation would need more memory than the limit; the message names the parameter,
    the estimate, the limit and how to change either."""


def parse_bytes(text: str) -> int:
    """``"8G"`` -> 8 GiB, ``"512M"``, ``"1e9"``, ``"2.5GiB"`` -> bytes (binary units)."""
    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([kKmMgGtT]?)(i?[bB])?\s*", str(text))
    if not m:
        raise ValueError(f"{MEMORY_LIMIT_ENV}={text!r} is not a size; write bytes or e.g. 8G, 512M")
    try:
        value = float(m.group(1)) * _UNITS[m.group(2).lower()]
    except ValueError:
        raise ValueError(f"{MEMORY_LIMIT_ENV}={text!r} is not a size; write bytes or e.g. 8G, 512M") from None
    if not value > 0 or value != value or value == float("inf"):
        raise ValueError(f"{MEMORY_LIMIT_ENV}={text!r} must be a positive size, e.g. 8G")
    return int(value)


def _available_memory() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def memory_limit() -> tuple[int, str]:
    """The memory limit [bytes] and where it comes from (for messages).

    ``$RISLOC_MEMORY_LIMIT`` when set, else :data:`DEFAULT_FRACTION` of the available memory.
    """
    env = os.environ.get(MEMORY_LIMIT_ENV)
    if env:
        return parse_bytes(env), f"${MEMORY_LIMIT_ENV}"
    return int(DEFAULT_FRACTION * _available_memory()), \
        f"half the available memory; set ${MEMORY_LIMIT_ENV} (e.g. 32G) to change it"


def format_bytes(n: float) -> str:
    """``1.5 GiB``, ``92 MiB``, ``512 B``."""
    n = float(n)
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def check_memory(estimate: float, what: str, *, fix: str = "", limit: int | None = None) -> float:
    """Raise :class:`BudgetError` when ``estimate`` [bytes] exceeds the memory limit.

    Parameters
    ----------
    estimate : float
        Bytes the computation would allocate at its peak.
    what : str
        The parameter(s) responsible, as the user wrote them (``"processing.k_dft=1000000000"``).
    fix : str
        How to bring the estimate down.
    limit : int, optional
        Override :func:`memory_limit`.

    Returns
    -------
    float
        ``estimate``.
    """
    if limit is None:
        limit, source = memory_limit()
    else:
        source = "the given limit"
    if not estimate <= limit:  # also catches NaN
        raise BudgetError(f"{what} needs about {format_bytes(estimate)} of memory, more than the limit "
                          f"{format_bytes(limit)} ({source})" + (f"; {fix}" if fix else ""))
    return estimate


def dsp_memory(shape: Any, *, n_dft: int, k_dft: int, itemsize: int = 16) -> int:
    """Peak bytes of :func:`dsp.scan_beams` and one delay-Doppler map on a cube of ``shape``.

    Parameters
    ----------
    shape : (M, K, N)
        Beams, chirps, samples.
    n_dft, k_dft : int
        Fast- and slow-time DFT lengths.
    itemsize : int
        Bytes per complex sample of the cube (16 for complex128).

    Notes
    -----
    The cube (``M·K·N·itemsize``), its windowed copy and the fast-time transform
    ``[M, K, N_DFT]`` complex128, and the full slow-time transform of one beam
    ``[K_DFT, N_DFT]`` complex128 plus its power (float64): the delay-Doppler map of the chosen
    beam that the report draws, and the per-beam block of ``doppler_search="full"``. A 2× margin
    covers FFT work buffers.
    """
    m, k, n = (int(v) for v in shape)
    cube = m * k * n * (itemsize + 16)
    fast = m * k * int(n_dft) * 16
    beam = int(k_dft) * int(n_dft) * (16 + 8)
    return int(cube + 2 * (fast + beam))


#: Realizations per detector call on the host. A whole Table I run (noise, detector, estimate; one core)
#: measured 0.253-0.257 s at B = 1 and 1-6 % more at B = 2 and 4 (the refined estimator; 2-17 % more for the
#: paper's: benchmarks/bench_device.py, docs/benchmarks.md, "Devices and batches"): batching buys nothing on a
#: CPU, whose transforms are not launch-bound, and costs B cubes of memory. A GPU batches (DEVICE_BATCH).
HOST_BATCH = 1
#: Largest batch on a GPU: measured on an H200 (CuPy 14.2, Table I, refined estimator, one process), B = 8
#: ran 19-20 % under B = 1 and B = 64 13-19 % over it (docs/benchmarks.md, "Devices and batches");
#: a B of 0.98 GB realizations beyond 8 only adds memory traffic.
DEVICE_BATCH = 8


def detect_memory(shape: Any, *, whole_cells: bool) -> int:
    """Peak bytes of one realization in :func:`dsp.detect_batch` (half-bin, windowed) with its noise.

    Parameters
    ----------
    shape : (M, K, N)
        Beams, chirps, samples.
    whole_cells : bool
        The window statistics over all cells at once (a GPU: M + 1 float64 running sums of every
        cell) rather than in cache-sized blocks (the host).

    Notes
    -----
    The noisy cube (complex128, 16 B) and its complex64 copy (8 B) per sample; the slow-time
    transform (2K × N) and the half-bin transform (2K × 2N) in complex64 (NumPy casts the cube
    into the half-bin array and transforms it in place, ``ArrayBackend.padded_ifft2``: the copy
    and the slow-time array are the other backends'); the statistics (D, the
    window maximum, the statistic and its masks: 6 float64 arrays of 4KN cells), and with
    ``whole_cells`` the M + 1 running sums (8 B × 4KN each). A 1.5× margin covers FFT work buffers.
    """
    m, k, n = (int(v) for v in shape)
    cells = 4 * k * n
    total = m * k * n * (16 + 8) + m * (2 * k * n + cells) * 8 + 6 * cells * 8
    if whole_cells:
        total += (m + 1) * cells * 8 + m * cells * 8  # running sums and the deviations' energies
    return int(1.5 * total)


def detect_batch_size(shape: Any, *, free_bytes: int | None = None, runs: int | None = None) -> int:
    """Realizations per :func:`dsp.detect_batch` call: as many as the memory allows, within the caps.

    Parameters
    ----------
    shape : (M, K, N)
    free_bytes : int, optional
        Free memory of a GPU [bytes] (``ArrayBackend.free_memory()``); None on the host, where the
        memory limit (:func:`memory_limit`) bounds it and :data:`HOST_BATCH` caps it.
    runs : int, optional
        Runs to do (no batch larger than that).

    Returns
    -------
    int
        B >= 1.
    """
    if free_bytes is None:
        limit, _ = memory_limit()
        b = min(HOST_BATCH, limit // max(1, detect_memory(shape, whole_cells=False)))
    else:
        b = min(DEVICE_BATCH, int(0.8 * free_bytes) // max(1, detect_memory(shape, whole_cells=True)))
    if runs is not None:
        b = min(b, int(runs))
    return max(1, int(b))
