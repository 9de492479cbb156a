"""A measured capture against the ray-traced hall: the hall model, calibration (file, fit), comparison (numbers, page).

Room 5 of :mod:`risloc_rt.measured` (imports :mod:`..sweep`, :mod:`..errors`, ``hall``, ``io`` and ``model``):

- :mod:`.traced_hall`: the traced hall for a capture's radar, sweep, RIS and position;
- :mod:`.calibration_file`: calibration files (range offset, τ_RB, ζ, noise, power offset) and applying them;
- :mod:`.calibration_fit`: those five fitted to a capture against the model's paths;
- :mod:`.comparison`: measured vs traced: peaks, residuals (``comparison.json``);
- :mod:`.comparison_page`: the ``risloc compare`` folder (``index.html``, PNG figures);
- :mod:`.uncertainty_budget`: every term of a measured estimate's 1σ (device registers, τ_RB, range
  offset, RIS tolerances) and the total;
- :mod:`.material_peaks`: a capture's explained static peaks as the material fit's observation
  (delays, powers with their 1σ and per-peak offsets; ``risloc calibrate --materials``);
- :mod:`.sweep_mean_peaks`: the same observation from the complex mean over the sweep's beams (the
  static echoes ~18 dB further above the noise, more with repeats; the default of ``risloc calibrate
  --materials``; its static peaks' residuals on ``risloc compare``'s page).

The names load on first use: ``import risloc_rt.measured.compare`` loads neither the hall nor ``io``.
"""

from ..._lazy import lazy_exports

_EXPORTS = {
    "HallModel": "traced_hall", "hall_model": "traced_hall", "ue_position_of": "traced_hall",
    "Calibration": "calibration_file", "adc_power_offset_db": "calibration_file",
    "apply_to_capture": "calibration_file", "apply_to_scenario": "calibration_file", "calibrated_paths": "calibration_file",
    "calibration_delay": "calibration_file", "read_calibration": "calibration_file",
    "write_calibration": "calibration_file",
    "calibrate_capture": "calibration_fit",
    "Comparison": "comparison", "compare_capture": "comparison", "parabolic_peak": "comparison",
    "FIGURES": "comparison_page", "write_comparison": "comparison_page", "BASELINE_KEYS": "comparison_page",
    "baseline_document": "comparison_page", "sweep_mean_document": "comparison_page",
    "BudgetTerm": "uncertainty_budget", "RisTolerances": "uncertainty_budget",
    "UncertaintyBudget": "uncertainty_budget", "apply_budget": "uncertainty_budget",
    "measured_budget": "uncertainty_budget", "ris_tolerances": "uncertainty_budget",
    "CapturePeaks": "material_peaks", "DEFAULT_MODEL_SIGMA_DB": "material_peaks",
    "capture_observation": "material_peaks", "peak_power_sigma_db": "material_peaks", "path_weights": "material_peaks",
    "MAX_BLEND_DB": "sweep_mean_peaks", "MIN_SNR_DB": "sweep_mean_peaks", "SweepMeanProfiles": "sweep_mean_peaks",
    "sweep_mean_observation": "sweep_mean_peaks", "sweep_mean_power_sigma_db": "sweep_mean_peaks",
    "sweep_mean_profile": "sweep_mean_peaks", "sweep_mean_profiles": "sweep_mean_peaks",
    "sweep_mean_residuals": "sweep_mean_peaks", "joint_mean_frame": "sweep_mean_peaks",
    "weighted_power_residuals": "sweep_mean_peaks",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
