"""The RIS: element grid, hardware parameters and its beam response in both modes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from dsp import BeamPattern, RisPose, db_to_linear, direction_from_angles
from dsp.validation import as_finite_array, dataclass_from_dict, finite, non_negative, positive, positive_int
from dsp.sweep import BeamSweep

__all__ = ["RisConfig", "RisMode", "check_ris_memory", "ris_response", "ris_response_memory"]

RisMode = Literal["relay", "reflective"]

#: Half a wavelength at 60 GHz [m], the default element spacing.
HALF_WAVELENGTH_60GHZ = 299_792_458.0 / 60e9 / 2


@dataclass(frozen=True)
class RisConfig:
    """A RIS panel: pose, element grid and hardware parameters.

    Parameters
    ----------
    pose : RisPose
        Centre and orientation of the element grid (``docs/conventions.md``).
    num_rows : int, default 16
        Elements along the row axis **u** (azimuth), N_RIS^az.
    num_columns : int, default 4
        Elements along the column axis **w** (elevation), N_RIS^el.
    element_spacing : float, default λ/2 at 60 GHz (2.498 mm)
        Pitch of the square element grid [m].
    amplification_db : float, default 45.532
        ζ = L_loss · α_RIS, amplification-and-loss factor of the loop-back path [dB].
    loopback_delay : float, default 1.78e-9
        τ_RB, receive-to-transmit delay inside the RIS [s].
    mode : {"relay", "reflective"}, default "relay"
        ``"reflective"``: eq. (1), one array with phase profile ``exp(-2j Xᵀ g(φ_m))``.
        ``"relay"``: the paper's footnote and its experiment, separate identical Rx and Tx arrays,
        Rx beam fixed at ``relay_rx_angle``, Tx beam swept.
    relay_rx_angle : float array [2], default [0, 0]
        ``[az, el]`` of the fixed Rx beam in relay mode [rad]; the experiment points it at the UE
        (:meth:`with_rx_toward`).
    """

    pose: RisPose
    num_rows: int = 16
    num_columns: int = 4
    element_spacing: float = HALF_WAVELENGTH_60GHZ
    amplification_db: float = 45.532
    loopback_delay: float = 1.78e-9
    mode: RisMode = "relay"
    relay_rx_angle: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        if not isinstance(self.pose, RisPose):
            raise TypeError(f"pose must be a dsp.RisPose, got {type(self.pose).__name__}")
        set_("num_rows", positive_int(self.num_rows, "num_rows"))
        set_("num_columns", positive_int(self.num_columns, "num_columns"))
        set_("element_spacing", positive(self.element_spacing, "element_spacing", "m"))
        set_("amplification_db", finite(self.amplification_db, "amplification_db", "dB"))
        set_("loopback_delay", non_negative(self.loopback_delay, "loopback_delay", "s"))
        if self.mode not in ("relay", "reflective"):
            raise ValueError(f"mode={self.mode!r} must be 'relay' or 'reflective'")
        rx = as_finite_array(self.relay_rx_angle, "relay_rx_angle", shape=(2,)).copy()
        rx.setflags(write=False)
        set_("relay_rx_angle", rx)

    @property
    def num_elements(self) -> int:
        """N_RIS = num_rows · num_columns."""
        return self.num_rows * self.num_columns

    @property
    def amplification(self) -> float:
        """ζ, linear power factor [unitless]."""
        return float(db_to_linear(self.amplification_db))

    @property
    def size(self) -> tuple[float, float]:
        """Aperture (along u, along w) = (num_rows, num_columns) · spacing [m]."""
        return (self.num_rows * self.element_spacing, self.num_columns * self.element_spacing)

    @property
    def element_positions(self) -> np.ndarray:
        """Element centres in the RIS frame ``(u, w, n)``, centred on the pose [N_RIS, 3] [m].

        Row-major: element ``i·num_columns + j`` is row i (along u), column j (along w).
        """
        u = (np.arange(self.num_rows) - (self.num_rows - 1) / 2) * self.element_spacing
        w = (np.arange(self.num_columns) - (self.num_columns - 1) / 2) * self.element_spacing
        uu, ww = np.meshgrid(u, w, indexing="ij")
        return np.column_stack([uu.ravel(), ww.ravel(), np.zeros(uu.size)])

    def beam_pattern(self) -> "BeamPattern":
        """The sweep's array factor as the DSP sees it (``dsp.BeamPattern``): same grid and
        spacing, phase-gradient factor 1 (relay: only the Tx beam sweeps) or 2 (reflective, eq. (1))."""
        return BeamPattern(num_rows=self.num_rows, num_columns=self.num_columns, element_spacing=self.element_spacing,
                           gradient_factor=1 if self.mode == "relay" else 2)

    def with_rx_toward(self, point: Any) -> "RisConfig":
        """Copy whose relay Rx beam points at a world ``point`` [3] [m]."""
        from dataclasses import replace

        return replace(self, relay_rx_angle=self.pose.angles_to(point))

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary (pose as position/normal/up lists)."""
        return {
            "pose": {"position": self.pose.position.tolist(), "normal": self.pose.normal.tolist(),
                     "up": self.pose.up.tolist()},
            "num_rows": self.num_rows,
            "num_columns": self.num_columns,
            "element_spacing": self.element_spacing,
            "amplification_db": self.amplification_db,
            "loopback_delay": self.loopback_delay,
            "mode": self.mode,
            "relay_rx_angle": self.relay_rx_angle.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, require_all: bool = False) -> "RisConfig":
        """Inverse of :meth:`to_dict`; unknown (or, with ``require_all``, missing) keys raise."""
        if not isinstance(data, dict):
            raise TypeError(f"ris must be a mapping, got {type(data).__name__}")
        data = dict(data)
        if "pose" in data:
            data["pose"] = dataclass_from_dict(RisPose, data["pose"], "ris.pose", require_all=require_all)
        return dataclass_from_dict(cls, data, "ris", require_all=require_all)


def ris_response_memory(num_elements: int, num_beams: int, num_paths: int = 1) -> int:
    """Peak bytes of :func:`ris_response` for a RIS of ``num_elements`` elements, M beams and L paths.

    Parameters
    ----------
    num_elements : int
        N_RIS = num_rows · num_columns.
    num_beams : int
        M, the sweep's beams.
    num_paths : int
        L, the (incidence, departure) pairs.

    Notes
    -----
    ``8 N (6 + 7 L + 4 M)`` bytes: the element positions and their meshgrid (``6 N`` float64), the
    two steering matrices [N, L] complex128 and, while the second is formed, its real phase and
    complex argument (``7 N L`` float64 words),
    and the beam weights [M, N]: their phase times ``-j k`` (complex128) and its exponential
    (complex128), ``4 M N`` float64 words, alive together at the peak. Measured: 4.4 GiB for
    1500 × 1500 elements and 61 beams, where the formula gives 4.3 GiB.
    """
    n, m, paths = int(num_elements), int(num_beams), int(num_paths)
    return 8 * n * (6 + 7 * paths + 4 * m)


def check_ris_memory(ris: RisConfig, num_beams: int, num_paths: int = 1, *, where: str = "ris",
                     fix: str = "") -> int:
    """Refuse a RIS whose response to ``num_beams`` beams would not fit in the memory limit.

    Parameters
    ----------
    ris : RisConfig
    num_beams : int
        M, the sweep's beams.
    num_paths : int
        L, the paths through the RIS.
    where : str
        Where ``num_rows`` and ``num_columns`` came from, for the message (``"run.npz: metadata ris"``).
    fix : str
        How to bring the estimate down (default: fewer elements).

    Returns
    -------
    int
        :func:`ris_response_memory` [bytes].

    Raises
    ------
    dsp.budget.BudgetError
        The estimate exceeds :func:`dsp.budget.memory_limit`.
    """
    from dsp.budget import check_memory

    estimate = ris_response_memory(ris.num_elements, num_beams, num_paths)
    paths = f" x {num_paths:,} paths" if num_paths != 1 else ""
    check_memory(estimate, f"{where}: num_rows = {ris.num_rows:,} x num_columns = {ris.num_columns:,} "
                           f"({ris.num_elements:,} elements) x {num_beams:,} beams{paths}",
                 fix=fix or "give the RIS fewer elements (the paper's panel has 16 x 4), or raise the limit")
    return estimate


def _steering(positions: np.ndarray, directions: np.ndarray, wavenumber: float) -> np.ndarray:
    """Array vectors ``a = exp(j k Xᵀ d)`` [N_RIS, L] for local directions [L, 3]."""
    return np.exp(1j * wavenumber * (positions @ directions.T))


def ris_response(
    ris: RisConfig,
    sweep: BeamSweep,
    incidence: Any,
    departure: Any,
    *,
    wavelength: float,
) -> np.ndarray:
    """Complex response of the RIS for every sweep beam and every (incidence, departure) pair.

    Parameters
    ----------
    ris : RisConfig
    sweep : BeamSweep
        M steering angles φ_m [rad].
    incidence : float array [L, 2]
        ``[az, el]`` toward where each wave comes from (the UE, or the last wall hit), RIS
        frame [rad].
    departure : float array [L, 2]
        ``[az, el]`` toward where each re-transmitted wave goes, RIS frame [rad]. In the
        monostatic free-space case both equal the UE's angle θ.
    wavelength : float
        λ [m].

    Returns
    -------
    complex array [M, L]
        ``reflective``: ``a(θ_d)ᵀ diag(exp(-2j Xᵀ g(φ_m))) a(θ_i)``, peak N_RIS.
        ``relay``: ``[a(θ_i)ᵀ w_Rx] · [a(θ_d)ᵀ w_Tx,m] / N_RIS`` with
        ``w = exp(-j Xᵀ g(φ))``; divided by N_RIS so that its peak is N_RIS too and the same ζ
        gives the same peak loop-back power in both modes.

    Raises
    ------
    dsp.budget.BudgetError
        The response would exceed the memory limit (:func:`ris_response_memory`), before anything
        is allocated.

    Notes
    -----
    ``g(θ) = 2π/λ · d(θ)`` with ``d`` the unit direction of ``docs/conventions.md``. The
    elements are isotropic in the front half-space (as in the paper) and do not radiate
    backwards: a path whose incidence or departure lies behind the panel (|az| >= 90°) gets 0. With λ/2
    spacing the reflective mode has grating lobes where ``sin φ - sin θ = ±1`` in azimuth,
    inside ±45° as soon as ``|sin θ| > 1 - sin 45° ≈ 0.29`` (θ > 17°); the relay mode has none.
    """
    lam = positive(wavelength, "wavelength", "m")
    inc = as_finite_array(incidence, "incidence", shape=(None, 2), allow_empty=True)
    dep = as_finite_array(departure, "departure", shape=(None, 2), allow_empty=True)
    if inc.shape != dep.shape:
        raise ValueError(f"incidence {list(inc.shape)} and departure {list(dep.shape)} must have the same shape")
    check_ris_memory(ris, sweep.num_beams, len(inc))
    k = 2 * np.pi / lam
    x = ris.element_positions  # [N, 3]
    d_inc = direction_from_angles(inc) if inc.size else np.zeros((0, 3))  # [L, 3]
    d_dep = direction_from_angles(dep) if dep.size else np.zeros((0, 3))
    # Elements radiate into the front half-space only: nothing enters or leaves through the back.
    front = (d_inc[:, 2] > 0) & (d_dep[:, 2] > 0)  # [L]
    a_inc = _steering(x, d_inc, k)  # [N, L]
    a_dep = _steering(x, d_dep, k)  # [N, L]
    beams = direction_from_angles(sweep.angles)  # [M, 3]
    if ris.mode == "reflective":
        profile = np.exp(-2j * k * (beams @ x.T))  # ω_m, [M, N]
        return (profile @ (a_inc * a_dep)) * front[None, :]
    w_tx = np.exp(-1j * k * (beams @ x.T))  # [M, N]
    w_rx = np.exp(-1j * k * (x @ direction_from_angles(ris.relay_rx_angle)))  # [N]
    rx_gain = w_rx @ a_inc  # [L]
    return (w_tx @ a_dep) * (rx_gain * front)[None, :] / ris.num_elements
