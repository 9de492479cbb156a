"""Profile-likelihood intervals of a fitted material parameter (risloc_rt.hall.material_profile).

Oracles: stand-in tracers (``stand_in_tracer`` in conftest.py) whose peak powers are closed-form functions of
ε_r and ln σ, so that the profile Δχ²(c) and the interval ends are known analytically. The real tracer's
check (the L hall, concrete alone, peaks made by the tracer at ε_r 6.1, σ 0.6 S/m with 0.5 dB noise, where the
interval must hold the truth) is in test_material_fit.py's slow weak-σ test.
"""

from __future__ import annotations

import math
import numpy as np
import pytest

import risloc_rt.hall.material_fit as engine
from risloc_rt.hall.material_profile import profile_interval

S0, W, SIGMA_P = math.log(0.6), 0.5, 0.5  # the stand-in tracer's truth ln σ, its scale here, each peak's 1σ [dB]


def test_flat_beyond_one_sigma_gives_the_analytic_interval_and_open_ends(stand_in_tracer):
    """The σ-peaks move by A·tanh((ln σ − s₀)/w) with A = σ_p/(0.8√2): χ²(ln σ) = tanh²(u)/0.64, u = (ln σ − s₀)/w,
    whose supremum 1.5625 is below 4. So the 68.3 % interval is where tanh u = ±0.8, ln σ = s₀ ± w·atanh 0.8
    (σ 0.3462 to 1.0398 S/m), and the 95.4 and 99.7 % ones are open on both sides: no bound, said as such.
    ε_r (a peak linear in it, 3 dB per unit, σ_p 0.5 dB) has the parabola's interval 6.1 ± n/6 at every level."""
    amp = SIGMA_P / (0.8 * math.sqrt(2.0))
    obs = stand_in_tracer(lambda s: (amp * math.tanh((s - S0) / W), amp * (1 - math.tanh((s - S0) / W) ** 2) / W))
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.0, 0.8)})
    assert "concrete:ln_sigma" in fit.identifiability.weak
    prof = profile_interval("stand-in", obs, fit, "concrete:sigma")
    assert prof.parameter == "concrete:ln_sigma" and not prof.moved
    u = math.atanh(0.8)
    lo, hi = prof.physical(1)
    assert lo == pytest.approx(0.6 * math.exp(-W * u), rel=0.03)  # 3 % of σ is 0.06 of w in ln σ
    assert hi == pytest.approx(0.6 * math.exp(W * u), rel=0.03)
    assert np.all(prof.delta_chi2 <= 1 / 0.64 + 1e-6)  # the profile is the analytic one: never above its supremum
    c = np.asarray(prof.grid)
    assert prof.delta_chi2 == pytest.approx(np.tanh((c - S0) / W) ** 2 / 0.64, abs=1e-6)
    for n in (2, 3):
        assert prof.intervals[n] == (-math.inf, math.inf)
        assert prof.physical(n) == (0.0, math.inf)
        assert prof.covers(1e-3, n) and prof.covers(900.0, n)
        assert "not bounded within the scan (0.001..1e+03 S/m)" in prof.describe(n)
    assert prof.covers(0.6, 1) and not prof.covers(0.3, 1) and not prof.covers(1.1, 1)
    assert prof.describe(1).startswith("concrete:sigma 0.6 S/m, 68.3 % profile interval: 0.34")

    eps = profile_interval("stand-in", obs, fit, "concrete:eps_r")
    for n in (1, 2, 3):
        assert eps.physical(n) == pytest.approx((6.1 - n / 6.0, 6.1 + n / 6.0), abs=0.01 * n / 6.0)
    assert eps.best_physical == pytest.approx(6.1, abs=1e-6)


def test_a_bound_on_one_side_only(stand_in_tracer):
    """The σ-peaks fall as A·(ln σ − s₀) below s₀ and do not move above it (a wall that turns transparent when σ
    falls, with no sign of σ above): χ² = 2A²u²/σ_p² below, 0 above. With A = σ_p/√2 per unit ln σ, Δχ² = u², so
    the interval's lower ends are s₀ − n and the upper ones are open: "sigma >= ..." at every level."""
    amp = SIGMA_P / math.sqrt(2.0)
    obs = stand_in_tracer(lambda s: (amp * min(s - S0, 0.0), amp * (1.0 if s < S0 else 0.0)))
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.0, 0.5)}, profile_check=False)
    prof = profile_interval("stand-in", obs, fit, "concrete:sigma")
    for n in (1, 2, 3):
        lo, hi = prof.intervals[n]
        assert hi == math.inf
        assert lo == pytest.approx(S0 - n, abs=0.05)
        assert prof.span(n).startswith("sigma >= ") and prof.span(n) in prof.describe(n)
        assert "no upper bound up to 1e+03 S/m" in prof.describe(n)


def test_a_fit_in_the_shallower_of_two_valleys_is_moved(stand_in_tracer):
    """Two valleys in ln σ: the σ-peaks move by f(u) = 0.8 sin²(πu/2) + 0.1 u² [dB], u = (ln σ − s₀)/w, so
    χ² = 8 f² has its minimum 0 at u = 0 (the truth) and a local one of χ² ≈ 1.17 at u ≈ 1.9, behind a barrier
    of χ² ≈ 6.5 at u = 1. A fit that stopped in the local valley (here: placed there, ``max_iter=0``; Levenberg–
    Marquardt from u = 2.1 happened to jump the barrier) must be moved by its profile: cross the barrier, find the
    truth's lower χ², say so (``moved``) and measure Δχ² from there."""
    from scipy.optimize import brentq

    def f(s):
        u = (s - S0) / W
        return (0.8 * math.sin(math.pi * u / 2.0) ** 2 + 0.1 * u * u,
                (0.4 * math.pi * math.sin(math.pi * u) + 0.2 * u) / W)

    obs = stand_in_tracer(f)
    u_local = brentq(lambda u: f(S0 + W * u)[1], 1.5, 1.99)
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.1, 0.6 * math.exp(u_local * W))},
                               profile_check=False, max_iter=0)
    assert 1.8 < u_local < 2.0 and fit.chi2 == pytest.approx(8 * f(S0 + W * u_local)[0] ** 2, rel=1e-9) and fit.chi2 > 1
    prof = profile_interval("stand-in", obs, fit, "concrete:sigma")
    assert prof.moved and prof.chi2_min < 0.05
    assert abs(prof.best - S0) <= 0.3 * W
    assert prof.covers(0.6, 1) and not prof.covers(float(fit.conductivity[0]), 1)
    assert "found a lower chi2 than the fit" in prof.describe(1)
    at_best = prof.values[int(np.argmin(prof.delta_chi2))]["concrete"]
    assert at_best[1] == pytest.approx(math.exp(prof.best), rel=1e-9) and at_best[0] == pytest.approx(6.1, abs=1e-3)


@pytest.mark.parametrize("parameter, kwargs, words", [
    ("concrete:mu", {}, "must be MATERIAL:eps_r or MATERIAL:sigma"),
    ("glass:sigma", {}, "must be MATERIAL:eps_r or MATERIAL:sigma"),
    ("concrete:sigma", {"limits": (1.0, 0.1)}, "lo < hi"),
    ("concrete:sigma", {"limits": (0.0, 10.0)}, "must be > 0 S/m"),
    ("concrete:eps_r", {"limits": (0.5, 10.0)}, "eps_r below 1"),
    ("concrete:sigma", {"max_iter": 0}, "max_iter=0"),
])
def test_bad_input_is_a_one_line_error(stand_in_tracer, parameter, kwargs, words):
    obs = stand_in_tracer(lambda s: (0.3 * s, 0.3))
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.0, 0.8)}, profile_check=False)
    with pytest.raises(ValueError, match=words) as err:
        profile_interval("stand-in", obs, fit, parameter, **kwargs)
    assert "\n" not in str(err.value)


def test_a_held_parameter_has_no_profile(stand_in_tracer):
    obs = stand_in_tracer(lambda s: (0.3 * s, 0.3))
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.0, 0.8)}, fixed=["concrete:eps_r"],
                               profile_check=False)
    with pytest.raises(ValueError, match="was held in the fit"):
        profile_interval("stand-in", obs, fit, "concrete:eps_r")
    # σ alone free: the profile is the cost itself (no conditional fit), a parabola in ln σ (0.3 dB per unit on two
    # peaks of σ_p 0.5 dB: Fisher 1σ = 0.5 / (0.3 √2) in ln σ).
    prof = profile_interval("stand-in", obs, fit, "concrete:sigma")
    sd = SIGMA_P / (0.3 * math.sqrt(2.0))
    lo, hi = prof.intervals[1]
    assert (hi - lo) / 2 == pytest.approx(sd, rel=0.02)


def test_a_scattering_coefficient_gets_the_analytic_interval_in_s(stand_in_tracer):
    """Peaks losing n_k·10 log10(1 − S²) dB (n = 1, 0, 2 bounces on the material; S 0.4 true, ε_r and σ held):
    χ²(S) = Σ n_k² (10 log10((1 − S²)/(1 − 0.16)))² / 0.5², so the level-n ends are where
    |10 log10((1 − S²)/0.84)| = n·0.5/√5 dB, and the fit's S is the truth. The same engine with every parameter
    held returns χ² at the start values."""
    obs = stand_in_tracer(lambda s: (0.0, 0.0), scattering=(0.4, (1, 0, 2)))
    held = ["concrete:eps_r", "concrete:sigma"]
    fit = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.1, 0.6, 0.2)}, fixed=held,
                               scattering=["concrete"])
    assert fit.scattering_coefficient[0] == pytest.approx(0.4, abs=1e-4) and fit.chi2 < 1e-6
    prof = profile_interval("stand-in", obs, fit, "concrete:S")
    assert prof.parameter == "concrete:scattering" and prof.kind == "scattering"
    for n in (1, 2):
        d = n * 0.5 / math.sqrt(5.0) / 10.0
        expected = (math.sqrt(1 - 0.84 * 10 ** d), math.sqrt(1 - 0.84 * 10 ** -d))
        assert prof.physical(n) == pytest.approx(expected, abs=2e-3), n
    assert prof.best_physical == pytest.approx(0.4, abs=1e-3)
    np.testing.assert_allclose(prof.grid_physical, np.sqrt(prof.grid))
    assert prof.describe(1).startswith("concrete:S 0.4, 68.3 % profile interval: 0.3")
    # every parameter held: the cost at the start (here S 0.3: 1 + 4 bounce-units of the same loss)
    at = engine.fit_materials("stand-in", obs, ["concrete"], start={"concrete": (6.1, 0.6, 0.3)},
                              fixed=[*held, "concrete:scattering"], scattering=["concrete"])
    loss = 10 * math.log10((1 - 0.09) / 0.84)
    assert at.chi2 == pytest.approx(5 * loss ** 2 / 0.25, rel=1e-6) and at.iterations <= 1
    assert at.values()["concrete"] == pytest.approx((6.1, 0.6, 0.3))
