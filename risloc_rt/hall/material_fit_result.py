"""The material fit's results: what the peaks can tell about each material, and the fitted values with their 1σ.

:class:`IdentifiabilityReport` and :class:`MaterialFit` are returned by
:func:`risloc_rt.hall.material_fit.fit_materials` (the engine's notes say how each number is made).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["IdentifiabilityReport", "MaterialFit"]


@dataclass(frozen=True)
class IdentifiabilityReport:
    """What the explained peaks can tell about each material.

    Attributes
    ----------
    parameters : tuple of str
        The 2Q + Q_s parameter names, ``"<material>:eps_r"`` [unitless] and ``"<material>:ln_sigma"``
        [ln(S/m)] per material, then ``"<material>:scattering"`` (the scattered share S² [unitless])
        for the Q_s materials whose S is fitted, in the order of the Jacobian's columns.
    peaks : tuple of (int, int)
        (observation index, peak index) of every explained peak, in the order of the rows.
    unexplained : tuple of (int, int)
        The observed peaks no traced path lies within the window of (left out of the fit).
    constrains : bool array [K, Q]
        Explained peak k has a path touching material q.
    jacobian_db : float array [K, 2Q + Q_s]
        ∂P_k[dB]/∂θ at the solution (unweighted) [dB per unit ε_r, ln σ or S²].
    singular_values : float array [2Q + Q_s]
        Of the weighted Jacobian with unit-norm columns, descending [unitless].
    condition : float
        Largest over smallest singular value (inf when the smallest is 0).
    threshold : float
        Relative singular value below which a direction is not identifiable.
    not_identifiable : dict
        ``{parameter name: reason}`` for every flagged parameter (empty when all are identifiable).
    profile_cost : dict
        ``{parameter name: (Δcost at −1σ, Δcost at +1σ)}``: the re-traced rise of the cost ½χ²
        when the parameter moves by its stated 1σ along its linear profile direction (the others
        following their regression on it); 0.5 on both sides for a quadratic likelihood. Empty
        when the check was not asked for.
    profile_cost_2sigma : dict
        The same at ±2σ: ``(Δcost at −2σ, Δcost at +2σ)``, 2 on both sides for a quadratic likelihood.
    weak : dict
        ``{parameter name: reason}`` for identifiable parameters whose profile check rose outside
        [``0.5/PROFILE_RATIO``, ``0.5·PROFILE_RATIO``] at ±1σ or [``2/PROFILE_RATIO``, ``2·PROFILE_RATIO``]
        at ±2σ on either side: the stated 1σ is a local figure.
    fixed : tuple of str
        Parameters held at their start value (``fit_materials(fixed=...)``): not fitted, 1σ 0,
        their correlations NaN; the others' 1σ are conditional on them.
    """

    parameters: tuple[str, ...]
    peaks: tuple[tuple[int, int], ...]
    unexplained: tuple[tuple[int, int], ...]
    constrains: np.ndarray
    jacobian_db: np.ndarray
    singular_values: np.ndarray
    condition: float
    threshold: float
    not_identifiable: dict[str, str]
    profile_cost: dict[str, tuple[float, float]] = field(default_factory=dict)
    weak: dict[str, str] = field(default_factory=dict)
    profile_cost_2sigma: dict[str, tuple[float, float]] = field(default_factory=dict)
    fixed: tuple[str, ...] = ()

    @property
    def identifiable(self) -> bool:
        """True when no parameter is flagged."""
        return not self.not_identifiable

    def summary(self) -> str:
        """One line per material: the peaks constraining it and any flag.

        Returns
        -------
        str
            Human-readable report (multi-line).
        """
        lines = [f"condition {self.condition:.3g} (limit {1 / self.threshold:.3g}); singular values "
                 + ", ".join(f"{s:.3g}" for s in self.singular_values)]
        materials = list(dict.fromkeys(p.rpartition(":")[0] for p in self.parameters))
        for q, m in enumerate(materials):
            n = int(self.constrains[:, q].sum())
            flags = [f"{p.split(':')[1]}: {r}" for p, r in self.not_identifiable.items() if p.split(":")[0] == m]
            weak = [f"{p.split(':')[1]}: {r}" for p, r in self.weak.items() if p.split(":")[0] == m]
            held = [p.split(":")[1] for p in self.fixed if p.split(":")[0] == m]
            lines.append(f"{m}: {n} peak(s)" + ("; " + "; ".join(flags) if flags else "; identifiable")
                         + ("; held at its start value (not fitted): " + ", ".join(held) if held else "")
                         + ("; weak: " + "; ".join(weak) if weak else ""))
        return "\n".join(lines)


@dataclass(frozen=True)
class MaterialFit:
    """Result of :func:`risloc_rt.hall.material_fit.fit_materials`.

    Attributes
    ----------
    materials : tuple of str
        The fitted radio materials (sionna-rt names).
    relative_permittivity : float array [Q]
        Fitted ε_r [unitless] (meaningless alone for a flagged parameter: see its σ and the report).
    conductivity : float array [Q]
        Fitted σ [S/m] (meaningless alone for a flagged parameter).
    relative_permittivity_sigma : float array [Q]
        1σ of ε_r from the Fisher information [unitless]; inf when not identifiable.
    log_conductivity_sigma : float array [Q]
        1σ of ln σ [unitless]; inf when not identifiable.
    covariance : float array [2Q, 2Q]
        (JᵀWJ)⁻¹ in the parameters (ε_r, ln σ) per material [unit ε_r², ln σ²]; inf/NaN where
        not identifiable.
    correlation : float array [2Q, 2Q]
        The correlation matrix (NaN rows/columns for flagged parameters).
    start : dict
        ``{material: (ε_r, σ [S/m])}`` the fit started from.
    residuals_start_db, residuals_db : float array [K]
        Observed − model power of every explained peak at the start and at the solution [dB].
    rms_start_db, rms_db : float
        Their root mean square [dB].
    chi2 : float
        Σ (residual/σ_dB)² at the solution [unitless].
    iterations : int
        Levenberg–Marquardt iterations (accepted or not).
    evaluations : int
        Calls of ``material_jacobian`` per radar position (traces of the whole set of positions).
    converged : bool
        The last accepted step changed the cost by less than its tolerance.
    seconds : float
        Wall-clock time of the fit [s].
    identifiability : IdentifiabilityReport
        Which peaks constrain which material, singular values, flags.
    history : tuple of float
        Cost ½χ² after each iteration.
    scattering : tuple of str
        The Q_s materials whose scattering coefficient was fitted (in the order of ``materials``).
    scattering_share : float array [Q_s]
        Their fitted scattered share S² [unitless] (``SHARE_RANGE``'s lower end: no scattering seen).
    scattering_share_sigma : float array [Q_s]
        1σ of S² from the Fisher information [unitless]; inf when not identifiable.
    search_evaluations : int
        Traces without derivatives of the start search (every radar position once each; one solve
        instead of Q + Q_s, or 2·Q + Q_s with diffuse reflection), not counted in ``evaluations``.

    The covariance and correlation matrices are [2Q + Q_s]² when S is fitted (the S² columns last).
    """

    materials: tuple[str, ...]
    relative_permittivity: np.ndarray
    conductivity: np.ndarray
    relative_permittivity_sigma: np.ndarray
    log_conductivity_sigma: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    start: dict[str, tuple[float, float]]
    residuals_start_db: np.ndarray
    residuals_db: np.ndarray
    chi2: float
    iterations: int
    evaluations: int
    converged: bool
    seconds: float
    identifiability: IdentifiabilityReport
    history: tuple[float, ...] = field(default=())
    scattering: tuple[str, ...] = ()
    scattering_share: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scattering_share_sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))
    search_evaluations: int = 0

    @property
    def scattering_coefficient(self) -> np.ndarray:
        """The fitted S = √(S²) of the ``scattering`` materials [unitless], float [Q_s]."""
        return np.sqrt(self.scattering_share)

    def values(self) -> dict[str, tuple[float, ...]]:
        """Every fitted material's values as the tracer takes them.

        Returns
        -------
        dict
            ``{material: (ε_r, σ [S/m])}``, with S [unitless] as a third entry for the
            ``scattering`` materials (meaningless alone for a flagged parameter: see ``value``).
        """
        out: dict[str, tuple[float, ...]] = {m: (float(self.relative_permittivity[q]), float(self.conductivity[q]))
                                             for q, m in enumerate(self.materials)}
        for j, m in enumerate(self.scattering):
            out[m] = (*out[m], float(self.scattering_coefficient[j]))
        return out

    @property
    def conductivity_sigma(self) -> np.ndarray:
        """1σ of σ by the delta method, σ · σ_lnσ [S/m] (inf when not identifiable)."""
        return self.conductivity * self.log_conductivity_sigma

    @property
    def rms_start_db(self) -> float:
        """RMS of the start residuals [dB]."""
        return float(np.sqrt(np.mean(self.residuals_start_db ** 2)))

    @property
    def rms_db(self) -> float:
        """RMS of the residuals at the solution [dB]."""
        return float(np.sqrt(np.mean(self.residuals_db ** 2)))

    @property
    def seconds_per_evaluation(self) -> float:
        """Wall-clock seconds per evaluation (all positions traced and differentiated once) [s]."""
        return self.seconds / max(self.evaluations, 1)

    @property
    def seconds_per_iteration(self) -> float:
        """Wall-clock seconds per Levenberg–Marquardt iteration, rejected trials and profile check included [s]."""
        return self.seconds / max(self.iterations, 1)

    def value(self, material: str) -> tuple[float, float, float, float]:
        """One material's fitted values and 1σ; refuses a flagged one.

        Parameters
        ----------
        material : str
            One of ``materials``.

        Returns
        -------
        tuple of float
            (ε_r [unitless], σ [S/m], 1σ of ε_r [unitless], 1σ of σ [S/m]).

        Raises
        ------
        ValueError
            Unknown material, or one of its parameters is not identifiable (the reason).
        """
        if material not in self.materials:
            raise ValueError(f"material {material!r} was not fitted; fitted: {', '.join(self.materials)}")
        flags = {p: r for p, r in self.identifiability.not_identifiable.items() if p.split(":")[0] == material}
        if flags:
            raise ValueError(f"material {material!r} is not identifiable from these peaks: "
                             + "; ".join(f"{p}: {r}" for p, r in flags.items()))
        q = self.materials.index(material)
        return (float(self.relative_permittivity[q]), float(self.conductivity[q]),
                float(self.relative_permittivity_sigma[q]), float(self.conductivity_sigma[q]))
