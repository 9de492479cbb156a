"""The array seam: the DSP's whole-cube steps written once, run on NumPy, CuPy or any array-API namespace.

The heavy, whole-cube steps of a run — the receiver noise of a batch of realizations
(:func:`risloc_rt.model.beat.add_noise_batch`), the detector's half-bin transform, window statistics and
threshold (:func:`dsp.detection.detect_batch`), and every read of the cube by the estimators and the
flags (:func:`dsp.dtft_subspace.contract_samples` and its siblings) — are written against the Python
array API standard (``array_api_compat``), so the same lines run on:

- ``numpy`` (the default; transforms through ``scipy.fft`` with the DSP's thread budget),
- ``cupy`` on an NVIDIA GPU (``pip install .[gpu]``; transforms through ``cupy.fft``, cuFFT),
- ``array_api_strict`` (tests and CI: a namespace that rejects everything outside the standard
  and, on its virtual ``device1``, every implicit host copy).

An :class:`ArrayBackend` names the namespace and its device; :func:`backend_for` resolves the
user's choice (``--device cpu|cuda|auto``, else ``$RISLOC_DEVICE``, else ``cpu``). The only
places where data crosses between host and device are :meth:`ArrayBackend.asarray` (host →
device, explicit) and :meth:`ArrayBackend.to_host` (device → host, explicit); the
``docs/architecture.md`` section "Host and device" lists where the DSP calls them.

Library-specific primitives live here and nowhere else: the transform (``scipy.fft`` on NumPy for
its threads, the namespace's ``fft`` extension otherwise), the median and the k-th smallest value
(NumPy's and CuPy's selection; a sort where a namespace has none — the same value) and the random
normals of the receiver noise (the array API has no random numbers: NumPy and array_api_strict draw on the host
from the run's ``numpy.random.Generator``, CuPy on the GPU from cuRAND seeded by it).
"""

from __future__ import annotations

import functools
import os
import platform
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ArrayBackend", "DeviceError", "DEVICE_ENV", "DEVICES", "GPU_ENV", "backend_for", "backend_of",
           "describe_line", "device_choice", "is_host_array", "numpy_backend", "strict_backend",
           "cuda_available"]

#: Environment variable with the default device of every command (``cpu``, ``cuda`` or ``auto``).
DEVICE_ENV = "RISLOC_DEVICE"
#: Environment variable naming the GPU (an index) of a process that should not use the current one, e.g.
#: one Dask worker per GPU; ``$CUDA_VISIBLE_DEVICES`` (one GPU per worker, as dask-cuda sets it) does the same.
GPU_ENV = "RISLOC_GPU"
#: The device choices a user can name.
DEVICES = ("cpu", "cuda", "auto")


class DeviceError(ValueError):
    """The device asked for cannot be used (no CuPy, no GPU, an unknown name); the message says how to fix it."""


@dataclass(frozen=True, eq=False)
class ArrayBackend:
    """An array namespace and the device its arrays live on.

    Attributes
    ----------
    name : {"numpy", "cupy", "array_api_strict"}
        The array library.
    xp : module
        Its array-API namespace (``array_api_compat``'s wrapper for NumPy and CuPy).
    device : object or None
        The device new arrays are made on (None: the library's default).
    """

    name: str
    xp: Any
    device: Any = None

    @property
    def is_numpy(self) -> bool:
        """Arrays are NumPy arrays in host memory (no copy needed either way)."""
        return self.name == "numpy"

    def asarray(self, x: Any, dtype: Any = None) -> Any:
        """Host data -> an array of this backend on its device (an explicit copy unless NumPy).

        Parameters
        ----------
        x : array_like
            Host data (NumPy array, scalar, sequence).
        dtype : dtype of ``xp``, optional
        """
        if self.is_numpy:
            return np.asarray(x, dtype=dtype)
        return self.xp.asarray(np.asarray(x), dtype=dtype, device=self.device)

    def to_host(self, x: Any) -> np.ndarray:
        """An array of this backend -> a NumPy array (an explicit device -> host copy unless NumPy)."""
        if self.is_numpy:
            return np.asarray(x)
        if self.name == "cupy":
            return x.get()
        cpu = self.xp.Device("CPU_DEVICE")  # array_api_strict
        return np.asarray(x.to_device(cpu))

    def ifft(self, x: Any, *, n: int, axis: int) -> Any:
        """``Σ_k x_k e^{+j2π q k / n}`` along ``axis``, zero padded to ``n`` (``norm="forward"``), same precision.

        NumPy: ``scipy.fft.ifft`` on the DSP's thread budget (:func:`dsp.threads.thread_count`);
        otherwise the namespace's ``fft`` extension (cuFFT on CuPy).
        """
        if self.is_numpy:
            import scipy.fft

            from .threads import thread_count

            return scipy.fft.ifft(x, n=n, axis=axis, norm="forward", workers=thread_count())
        return self.xp.fft.ifft(x, n=n, axis=axis, norm="forward")

    def padded_ifft2(self, x: Any, shape: tuple[int, int], *, dtype: Any, out: Any = None) -> Any:
        """``Σ_k Σ_n x[..., k, n] e^{+j2π(q k/Q + p n/P)}`` over the last two axes, zero padded to ``(Q, P)``.

        Parameters
        ----------
        x : complex array [..., K, N] of this backend
        shape : (int, int)
            (Q, P) >= (K, N): the padded sizes (``norm="forward"``: no 1/(QP)).
        dtype : complex dtype of ``xp``
            The transform's precision (x is cast to it).
        out : complex array [..., Q, P] of ``dtype``, optional
            NumPy only: written and returned (a study reuses it; the result is the same bit for bit).

        Returns
        -------
        complex array [..., Q, P] of ``dtype``

        Notes
        -----
        Along axis -2 first, then -1, without transforming the zero-padded rows. NumPy writes x,
        cast, into the padded array and transforms it in place (``scipy.fft``, ``overwrite_x``): no
        cast copy and none of ``scipy.fft``'s padded copies, the same numbers as two padded
        :meth:`ifft` calls (pocketfft transforms each line alike wherever it lies). Other namespaces:
        the two :meth:`ifft` calls.
        """
        q, p = (int(v) for v in shape)
        k, n = (int(v) for v in x.shape[-2:])
        if not self.is_numpy:
            return self.ifft(self.ifft(self.xp.astype(x, dtype, copy=False), n=q, axis=-2), n=p, axis=-1)
        import scipy.fft

        from .threads import thread_count

        full = tuple(x.shape[:-2]) + (q, p)
        if out is None:
            out = np.empty(full, dtype=dtype)
        elif out.shape != full or out.dtype != np.dtype(dtype) or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous {np.dtype(dtype)} array of shape {list(full)}, "
                             f"got {out.dtype} {list(out.shape)}")
        out[..., :k, :n] = x
        out[..., k:, :n] = 0
        out[..., n:] = 0
        workers = thread_count()
        for part, axis in ((out[..., :n], -2), (out, -1)):
            done = scipy.fft.ifft(part, axis=axis, norm="forward", workers=workers, overwrite_x=True)
            if not np.may_share_memory(done, part):  # a scipy that copied instead: the result, written back
                part[...] = done
        return out

    def kth_smallest(self, x: Any, k: int, axis: int) -> Any:
        """The k-th smallest value along ``axis`` (0-based; ``size // 2``: the upper median), that axis removed.

        NumPy and CuPy by a partial sort (``partition``: 5× faster than ``median`` on NumPy); other
        namespaces by a sort (the same value).
        """
        xp, k = self.xp, int(k)
        if self.name == "numpy":
            return np.take(np.partition(x, k, axis=axis), k, axis=axis)
        index = xp.asarray([k], device=self.device)
        if self.name == "cupy":
            import cupy

            return xp.squeeze(xp.take(cupy.partition(x, k, axis=axis), index, axis=axis), axis=axis)
        return xp.squeeze(xp.take(xp.sort(x, axis=axis), index, axis=axis), axis=axis)

    def median(self, x: Any, axis: int) -> Any:
        """The median along ``axis`` (the mean of the two middle values for an even count)."""
        xp = self.xp
        if self.name in ("numpy", "cupy"):
            return xp.median(x, axis=axis)
        s = xp.sort(x, axis=axis)
        size = s.shape[axis]
        lo = xp.take(s, xp.asarray([(size - 1) // 2], device=self.device), axis=axis)
        hi = xp.take(s, xp.asarray([size // 2], device=self.device), axis=axis)
        return xp.squeeze((lo + hi) / 2, axis=axis)

    def device_normals(self, rng: np.random.Generator, shape: tuple[int, ...]) -> Any:
        """``shape`` complex64 samples with independent N(0, 1) real and imaginary parts, drawn on the GPU.

        CuPy only: cuRAND's Philox4x32-10 (``cupy.random.RandomState``: its host API generates a whole
        array per call and seeds in microseconds) seeded from ``rng`` (one 63-bit integer drawn from
        it), float32 normals. The host backends draw the receiver noise with NumPy
        (:func:`risloc_rt.model.beat.add_noise`); the array API has no random numbers.
        """
        if self.name != "cupy":
            raise ValueError(f"device_normals draws on a GPU; the {self.name} backend draws its noise on the host")
        import cupy

        seed = int(rng.integers(0, 2**63 - 1))
        gen = cupy.random.RandomState(seed, method=cupy.cuda.curand.CURAND_RNG_PSEUDO_PHILOX4_32_10)
        pair = gen.standard_normal(shape + (2,), dtype=cupy.float32)  # an even count, as cuRAND's normals need
        return pair[..., 0] + 1j * pair[..., 1]

    def free_memory(self) -> int | None:
        """Free memory of the device [bytes]; None on the host (the DSP's memory limit applies there)."""
        if self.name != "cupy":
            return None
        import cupy

        free, _total = cupy.cuda.runtime.memGetInfo()
        pool = cupy.get_default_memory_pool()
        return int(free + pool.free_bytes())

    def describe(self) -> dict[str, str]:
        """What runs the DSP: ``device`` (``cpu`` / ``cuda:0``), ``library`` (with its version),
        ``hardware`` (GPU model or CPU) and ``detail`` (BLAS, or the CUDA runtime and driver)."""
        if self.name == "cupy":
            import cupy

            dev = cupy.cuda.Device()
            props = cupy.cuda.runtime.getDeviceProperties(dev.id)
            model = props["name"].decode() if isinstance(props["name"], bytes) else str(props["name"])
            runtime = cupy.cuda.runtime.runtimeGetVersion()
            driver = cupy.cuda.runtime.driverGetVersion()
            return {"device": f"cuda:{dev.id}", "library": f"cupy {cupy.__version__}",
                    "hardware": f"{model}, {props['totalGlobalMem'] / 2**30:.0f} GiB",
                    "detail": f"CUDA runtime {runtime // 1000}.{runtime % 1000 // 10}, "
                              f"driver {driver // 1000}.{driver % 1000 // 10}"}
        cpu = _cpu_model()
        lib = f"numpy {np.__version__}" if self.is_numpy else f"{self.name} {getattr(self.xp, '__version__', '')}".strip()
        return {"device": "cpu", "library": lib, "hardware": cpu, "detail": _blas()}

    def summary(self) -> str:
        """One line for a console: ``cpu (numpy 2.4.6, AMD EPYC ..., BLAS openblas 0.3.30)``."""
        return describe_line(self.describe())


def describe_line(description: dict[str, str]) -> str:
    """:meth:`ArrayBackend.describe`'s dict (from this process or a worker's JSON) as one line.

    Parameters
    ----------
    description : dict
        ``device``, ``library``, ``hardware``, ``detail``.

    Returns
    -------
    str
        ``cpu (numpy 2.4.6, AMD EPYC ..., BLAS openblas 0.3.30)``.
    """
    d = description
    return f"{d['device']} ({d['library']}, {d['hardware']}, {d['detail']})"


@functools.lru_cache(maxsize=1)
def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("model name"):
                    name = line.split(":", 1)[1].strip()
                    return f"{name}, {os.cpu_count()} cores"
    except OSError:
        pass
    return f"{platform.machine() or 'CPU'}, {os.cpu_count()} cores"


@functools.lru_cache(maxsize=1)
def _blas() -> str:
    try:
        cfg = np.show_config(mode="dicts")  # type: ignore[call-arg]
        blas = cfg["Build Dependencies"]["blas"]
        return f"BLAS {blas.get('name', '?')} {blas.get('version', '')}".strip()
    except Exception:  # noqa: BLE001 - a description only
        return "BLAS unknown"


def is_host_array(x: Any) -> bool:
    """Whether ``x`` is host data (a NumPy array, a scalar, a sequence), not an array of a device library.

    A CuPy array is a device array although it has no ``__array_namespace__`` (CuPy 14 leaves that to
    ``array_api_compat``): the array libraries are recognised by ``array_api_compat.is_array_api_obj``.
    """
    if isinstance(x, (np.ndarray, np.generic, list, tuple, int, float, complex)):
        return True
    import array_api_compat

    return not array_api_compat.is_array_api_obj(x)


def backend_of(x: Any) -> ArrayBackend:
    """The backend an array lives on: NumPy for host data, else its library's namespace and device.

    Parameters
    ----------
    x : array
        A NumPy, CuPy or array_api_strict array (or host data).

    Returns
    -------
    ArrayBackend
    """
    if is_host_array(x):
        return numpy_backend()
    import array_api_compat

    xp = array_api_compat.array_namespace(x)
    if array_api_compat.is_cupy_namespace(xp):
        return ArrayBackend("cupy", xp, x.device)
    if array_api_compat.is_array_api_strict_namespace(xp):
        return ArrayBackend("array_api_strict", xp, x.device)
    raise DeviceError(f"arrays of {xp.__name__} are not supported; pass a NumPy or CuPy array")


def numpy_backend() -> ArrayBackend:
    """NumPy on the host (the default)."""
    import array_api_compat.numpy as xp

    return ArrayBackend("numpy", xp, None)


def strict_backend(device: str = "device1") -> ArrayBackend:
    """``array_api_strict`` on one of its virtual devices (tests: ``device1`` refuses implicit host copies).

    Parameters
    ----------
    device : str
        ``"CPU_DEVICE"``, ``"device1"`` or ``"device2"``.
    """
    try:
        import array_api_strict as xp
    except ImportError:
        raise DeviceError("array_api_strict is not installed; pip install array-api-strict "
                          "(./setup.sh --test installs it)") from None
    return ArrayBackend("array_api_strict", xp, xp.Device(device))


def cuda_available() -> tuple[bool, str]:
    """Whether CuPy finds a GPU, and if not, why (one line)."""
    try:
        import cupy
    except ImportError:
        return False, "CuPy is not installed (pip install '.[gpu]' or ./setup.sh --gpu)"
    except Exception as exc:  # noqa: BLE001 - a broken CUDA install raises anything
        return False, f"CuPy does not load ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
    try:
        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as exc:  # noqa: BLE001
        return False, f"CuPy finds no CUDA device ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
    if count < 1:
        return False, "CuPy finds no CUDA device"
    return True, f"{count} CUDA device(s)"


def device_choice(device: str | None = None) -> str:
    """The device a user chose, checked but not resolved: ``cpu``, ``cuda`` or ``auto``.

    Parameters
    ----------
    device : str, optional
        ``--device``'s value; None: ``$RISLOC_DEVICE``, else ``cpu``.

    Returns
    -------
    str
        The name in lower case (a study passes it to its workers, which resolve it on their machine).
    """
    source = "--device"
    if device is None:
        device = os.environ.get(DEVICE_ENV, "").strip() or "cpu"
        source = f"${DEVICE_ENV}"
    if not isinstance(device, str) or device.strip().lower() not in DEVICES:
        raise DeviceError(f"{source}={device!r} is not a device; use cpu, cuda or auto")
    return device.strip().lower()


def backend_for(device: str | None = None) -> ArrayBackend:
    """The backend of a device choice.

    Parameters
    ----------
    device : {"cpu", "cuda", "auto"}, optional
        ``cpu``: NumPy. ``cuda``: CuPy on the current GPU — the one ``$RISLOC_GPU`` names when set
        (it is then made current for the process) — with a one-line :class:`DeviceError` when CuPy or
        a GPU is missing. ``auto``: CuPy when it finds a GPU, else NumPy. Default: ``$RISLOC_DEVICE``,
        else ``cpu``.

    Returns
    -------
    ArrayBackend
    """
    source = "--device" if device is not None else f"${DEVICE_ENV}"
    device = device_choice(device)
    if device == "cpu":
        return numpy_backend()
    ok, why = cuda_available()
    if not ok:
        if device == "auto":
            return numpy_backend()
        raise DeviceError(f"{source}=cuda but {why}; use --device cpu (or auto) on this machine")
    import array_api_compat.cupy as xp
    import cupy

    gpu = os.environ.get(GPU_ENV, "").strip()
    if gpu:
        count = cupy.cuda.runtime.getDeviceCount()
        if not gpu.isdigit() or int(gpu) >= count:
            raise DeviceError(f"${GPU_ENV}={gpu!r} is not a GPU of this machine (it has {count}: 0 to {count - 1})")
        cupy.cuda.Device(int(gpu)).use()  # this process's (this Dask worker's) GPU from now on
    return ArrayBackend("cupy", xp, cupy.cuda.Device())
