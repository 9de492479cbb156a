"""Choose and initialise the Dr.Jit/Mitsuba backend before sionna-rt is imported.

sionna-rt 2.2 runs on Dr.Jit 1.5, whose CPU backend JIT-compiles through a shared libLLVM.
Dr.Jit picks a libLLVM by itself, but LLVM 15 and 16 *abort the process* (SIGABRT, ``LLVM ERROR:
Cannot select ... fmaximum``) at the first path solve, and LLVM 14 is refused. Nothing in Python
can catch that abort, so :func:`ensure_backend` settles the choice before the first import of
``drjit``: it points ``DRJIT_LIBLLVM_PATH`` at the newest libLLVM >= 17 on the machine, refuses a
user-set library older than 17, and then sets the Mitsuba variant (CUDA when a GPU is usable,
else LLVM) before ``import sionna.rt``.

Dr.Jit can be initialised only once per process: the first call decides, later calls return the
cached variant.
"""

from __future__ import annotations

import glob
import os
import re
import sys
from typing import Literal

__all__ = [
    "BackendError", "MIN_LLVM_MAJOR", "backend_info", "ensure_backend", "find_libllvm", "llvm_major",
    "package_versions",
]

#: Oldest LLVM major version that Dr.Jit 1.5 runs sionna-rt 2.2 with (15/16 abort, 14 is refused).
MIN_LLVM_MAJOR = 17

#: Where :func:`find_libllvm` looks for shared libLLVM files (Debian/Ubuntu layouts).
LIBLLVM_GLOBS: tuple[str, ...] = (
    "/usr/lib/*-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
)

_CUDA_VARIANT = "cuda_ad_mono_polarized"
_LLVM_VARIANT = "llvm_ad_mono_polarized"
_ENV = "DRJIT_LIBLLVM_PATH"

_FIX = (
    "Fix: install a newer LLVM (`apt-get install libllvm19` on Debian 12), or set "
    f"{_ENV}=/path/to/libLLVM.so.<17 or newer>, or run ./setup.sh, which installs libllvm19."
)

# The chosen variant and what was learnt while choosing it (module-level: Dr.Jit is per process).
_state: dict[str, object] = {}


class BackendError(RuntimeError):
    """No usable Dr.Jit backend: no libLLVM >= 17 (and no CUDA), or one that would abort."""


def llvm_major(path: str) -> int | None:
    """LLVM major version read from a libLLVM file name, or None when the name does not say.

    Understands ``libLLVM.so.19.1``, ``libLLVM-19.so``, ``libLLVM-14.0.6.so.1`` and a parent
    folder ``llvm-19/``; a symbolic link is resolved first.

    Parameters
    ----------
    path : str
        Path of a shared library (it need not exist).
    """
    candidates = [os.path.realpath(path), path] if os.path.lexists(path) else [path]
    for p in candidates:
        name = os.path.basename(p)
        match = re.match(r"libLLVM(?:-(\d+)(?:\.\d+)*\.so|\.so\.(\d+))", name)
        if match:
            return int(match.group(1) or match.group(2))
    for p in candidates:
        match = re.search(r"/llvm-(\d+)/", p)
        if match:
            return int(match.group(1))
    return None


def find_libllvm(*, patterns: tuple[str, ...] = LIBLLVM_GLOBS, min_major: int = MIN_LLVM_MAJOR) -> str | None:
    """Path of the newest shared libLLVM with major version >= ``min_major``, or None.

    Parameters
    ----------
    patterns : tuple of str
        Glob patterns to search (default :data:`LIBLLVM_GLOBS`).
    min_major : int
        Oldest acceptable LLVM major version.

    Notes
    -----
    Files whose version cannot be read from the name are skipped; among equal majors the longest
    version suffix wins (``libLLVM.so.19.1`` over ``libLLVM-19.so``, which usually is a link to it).
    """
    found: dict[str, tuple[int, str]] = {}
    for pattern in patterns:
        for path in sorted(glob.glob(pattern)):
            if path.endswith(".a") or not os.path.isfile(path):
                continue
            major = llvm_major(path)
            if major is None or major < min_major:
                continue
            real = os.path.realpath(path)
            # One entry per real file, named by the path that was found.
            if real not in found or len(path) > len(found[real][1]):
                found[real] = (major, path)
    if not found:
        return None
    major, path = max(found.values(), key=lambda mp: (mp[0], os.path.basename(os.path.realpath(mp[1])), mp[1]))
    return path


def _check_user_library(path: str) -> None:
    """Refuse a user-set DRJIT_LIBLLVM_PATH that is missing or older than LLVM 17."""
    if not os.path.isfile(path):
        raise BackendError(
            f"{_ENV}={path!r} does not name an existing file, so Dr.Jit would find no LLVM backend. "
            f"sionna-rt needs libLLVM >= {MIN_LLVM_MAJOR} (LLVM 15/16 abort the process at the first "
            f"path solve). {_FIX} Or unset {_ENV} to let risloc-rt pick a library."
        )
    major = llvm_major(path)
    if major is not None and major < MIN_LLVM_MAJOR:
        raise BackendError(
            f"{_ENV}={path!r} is LLVM {major}, but sionna-rt 2.2 (Dr.Jit 1.5) needs libLLVM >= "
            f"{MIN_LLVM_MAJOR}: LLVM 15 and 16 abort the process at the first path solve (SIGABRT, "
            f"'Cannot select ... fmaximum') and LLVM 14 is refused. {_FIX}"
        )


def _check_llvm_runtime(dr) -> tuple[int, int, int]:
    """LLVM version Dr.Jit actually loaded; BackendError when it is missing or too old."""
    version = tuple(int(v) for v in dr.detail.llvm_version())
    if not dr.has_backend(dr.JitBackend.LLVM) or version[0] < 0:
        raise BackendError(
            f"Dr.Jit found no usable libLLVM ({_ENV}={os.environ.get(_ENV)!r}). sionna-rt needs "
            f"libLLVM >= {MIN_LLVM_MAJOR} (LLVM 15/16 abort the process, 14 is refused). {_FIX}"
        )
    if version[0] < MIN_LLVM_MAJOR:
        raise BackendError(
            f"Dr.Jit loaded LLVM {'.'.join(map(str, version))} ({_ENV}={os.environ.get(_ENV)!r}), but "
            f"sionna-rt 2.2 needs libLLVM >= {MIN_LLVM_MAJOR}: LLVM 15 and 16 abort the process at "
            f"the first path solve. {_FIX}"
        )
    return version  # type: ignore[return-value]


def ensure_backend(prefer: Literal["auto", "llvm", "cuda"] = "auto") -> str:
    """Initialise Dr.Jit and Mitsuba for sionna-rt and return the Mitsuba variant in use.

    Call before anything imports ``drjit``, ``mitsuba`` or ``sionna.rt`` (the functions of
    :mod:`risloc_rt.hall.raytrace` do). Idempotent: the first call decides for the whole process.

    Parameters
    ----------
    prefer : {"auto", "llvm", "cuda"}
        ``"auto"`` uses CUDA when Dr.Jit reports a CUDA backend, else the CPU (LLVM);
        ``"llvm"`` forces the CPU; ``"cuda"`` requires a GPU.

    Returns
    -------
    str
        ``"cuda_ad_mono_polarized"`` or ``"llvm_ad_mono_polarized"``.

    Raises
    ------
    BackendError
        No libLLVM >= 17 and no CUDA, ``DRJIT_LIBLLVM_PATH`` names a missing file or an LLVM
        older than 17, ``prefer="cuda"`` without a GPU, or a different variant was already chosen
        in this process.

    Notes
    -----
    When ``DRJIT_LIBLLVM_PATH`` is unset, it is set to :func:`find_libllvm`'s answer before the
    first import of ``drjit``, so Dr.Jit never picks LLVM 15/16 by itself.
    """
    if prefer not in ("auto", "llvm", "cuda"):
        raise ValueError(f"{prefer=} must be 'auto', 'llvm' or 'cuda'")
    cached = _state.get("variant")
    if cached is not None:
        _check_compatible(str(cached), prefer)
        return str(cached)

    drjit_loaded = "drjit" in sys.modules
    user_path = os.environ.get(_ENV)
    chosen_path: str | None = None
    if not drjit_loaded:
        if user_path:
            _check_user_library(user_path)
            chosen_path = user_path
        else:
            chosen_path = find_libllvm()
            if chosen_path is not None:
                os.environ[_ENV] = chosen_path

    import drjit as dr
    import mitsuba as mi

    has_cuda = bool(dr.has_backend(dr.JitBackend.CUDA))
    current = mi.variant()
    if current is not None:
        # Someone (sionna.rt itself, or user code) chose already; Mitsuba cannot switch safely.
        if current not in (_CUDA_VARIANT, _LLVM_VARIANT):
            raise BackendError(
                f"Mitsuba variant {current!r} is already set in this process; sionna-rt needs "
                f"{_LLVM_VARIANT!r} or {_CUDA_VARIANT!r}. Call risloc_rt.hall.raytrace.ensure_backend() "
                "before importing mitsuba or sionna.rt."
            )
        variant = current
    elif prefer == "cuda" or (prefer == "auto" and has_cuda):
        if not has_cuda:
            raise BackendError(
                "prefer='cuda' but Dr.Jit reports no CUDA backend (no GPU or driver). "
                "Use prefer='auto' or 'llvm' to run on the CPU."
            )
        variant = _CUDA_VARIANT
    else:
        if not drjit_loaded and not user_path and chosen_path is None:
            raise BackendError(
                f"No libLLVM >= {MIN_LLVM_MAJOR} found (searched {', '.join(LIBLLVM_GLOBS)}) and no "
                f"CUDA GPU. sionna-rt runs on the CPU through Dr.Jit's LLVM backend, which needs "
                f"libLLVM >= {MIN_LLVM_MAJOR}; LLVM 15 and 16 abort the process at the first path "
                f"solve and LLVM 14 is refused. {_FIX}"
            )
        variant = _LLVM_VARIANT

    llvm_version: tuple[int, int, int] | None = None
    if variant == _LLVM_VARIANT:
        llvm_version = _check_llvm_runtime(dr)
    if current is None:
        try:
            mi.set_variant(variant)
        except ImportError as exc:  # Dr.Jit refused the backend after all.
            raise BackendError(f"Mitsuba could not set {variant!r}: {exc}. {_FIX}") from exc

    _state.update(
        variant=variant,
        llvm_version=llvm_version if llvm_version is not None else tuple(int(v) for v in dr.detail.llvm_version()),
        library=os.environ.get(_ENV),
        cuda=has_cuda,
    )
    _check_compatible(variant, prefer)
    return variant


def _check_compatible(variant: str, prefer: str) -> None:
    if prefer == "cuda" and variant != _CUDA_VARIANT:
        raise BackendError(f"prefer='cuda' but this process already runs {variant!r}; Dr.Jit cannot switch.")
    if prefer == "llvm" and variant != _LLVM_VARIANT:
        raise BackendError(f"prefer='llvm' but this process already runs {variant!r}; Dr.Jit cannot switch.")


def package_versions() -> dict[str, str]:
    """Installed versions of sionna-rt, mitsuba and drjit (read from metadata, nothing imported)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("sionna-rt", "mitsuba", "drjit"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "missing"
    return out


def backend_info() -> dict[str, object]:
    """What :func:`ensure_backend` chose, for reports (initialises the backend if needed).

    Returns
    -------
    dict
        ``variant`` (str), ``llvm_version`` (str, ``"19.1.7"``; ``"none"`` without LLVM),
        ``libllvm_path`` (str or None: ``DRJIT_LIBLLVM_PATH`` when Dr.Jit started), ``cuda``
        (bool: a CUDA backend was reported), and the ``sionna-rt``, ``mitsuba`` and ``drjit``
        versions.
    """
    ensure_backend()
    version = _state["llvm_version"]
    return {
        "variant": _state["variant"],
        "llvm_version": ".".join(map(str, version)) if version and version[0] >= 0 else "none",  # type: ignore[index,arg-type]
        "libllvm_path": _state["library"],
        "cuda": _state["cuda"],
        **package_versions(),
    }
