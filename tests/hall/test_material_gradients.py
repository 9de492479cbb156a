"""Derivatives of the traced path gains w.r.t. the materials' ε_r and σ (risloc_rt.hall.raytrace.material_gradients).

Oracles: the existing tracer (the gains at the start values), the ITU-R P.2040 single-layer slab
reflection coefficient written out by hand (normal incidence, with its derivative by the chain
rule), the identity ∂a/∂σ = −j/(ε0 ω)·∂a/∂ε_r that holds for gains holomorphic in η = ε_r − jσ/(ε0 ω),
and central finite differences of re-traced gains.

The scene: an 8 m × 6 m × 3 m hall with concrete walls (0.2 m), a glass floor (6 mm), a wood ceiling
(30 mm) and a 0.4 m chipboard crate in a corner, which no single-bounce path from the radar reaches.
"""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.authoring import build_scene, loads_spec
from risloc_rt.hall.raytrace.material_gradients import MaterialJacobian, material_jacobian
from risloc_rt.hall.raytrace.result import TraceSettings
from risloc_rt.hall.raytrace.tracer import trace_scene

SPEC = """
[scene]
name = "gradient_box"
frequency = 60e9

[hall]
size = [8.0, 6.0]
height = 3.0
wall_thickness = 0.2

[hall.materials]
walls = { itu = "concrete", thickness = 0.2 }
floor = { itu = "glass", thickness = 0.006 }
ceiling = { itu = "wood", thickness = 0.03 }

[[objects]]
kind = "box"
name = "crate"
min = [0.1, 0.1, 0.0]
max = [0.5, 0.5, 0.4]
material = { itu = "chipboard", thickness = 0.02 }
"""
CONCRETE, GLASS, WOOD, CHIPBOARD = "concrete-200mm", "glass-6mm", "wood-30mm", "chipboard-20mm"
MATERIALS = (CONCRETE, GLASS, WOOD, CHIPBOARD)
THICKNESS = {CONCRETE: 0.2, GLASS: 0.006, WOOD: 0.03}
RADAR = (3.0, 2.5, 1.2)  # 1.2 m above the floor, 1.8 m below the ceiling, 3 m from wall_3 (x = 0)
FREQUENCY = 60e9
EPSILON_0 = 8.8541878128e-12  # [F/m]
C = 299_792_458.0  # [m/s]
#: Depth 2 finds every single and double bounce of the box; 10⁴ rays suffice for a box this size.
SETTINGS = TraceSettings(max_depth=2, samples_per_src=10_000)


@pytest.fixture(scope="module")
def hall(tmp_path_factory) -> str:
    """Scene folder of the gradient test hall."""
    out = tmp_path_factory.mktemp("gradient_box")
    build_scene(loads_spec(SPEC), out)
    return str(out)


@pytest.fixture(scope="module")
def jac(hall) -> MaterialJacobian:
    """The Jacobian of every path's gain w.r.t. all four materials at their ITU values, depth 2."""
    return material_jacobian(hall, RADAR, MATERIALS, frequency=FREQUENCY, settings=SETTINGS)


def slab_normal(eps: float, sigma: float, thickness: float, frequency: float) -> tuple[complex, complex]:
    """ITU-R P.2040 eq. (43a) slab reflection coefficient R at normal incidence and d(ln R)/dη.

    η = ε_r − jσ/(ε0 ω), n = √η, r = (1 − n)/(1 + n), E = exp(−2j k d n),
    R = r (1 − E)/(1 − r² E); the derivative by the chain rule through n (dn/dη = 1/(2n)).
    (TE and TM differ only in the sign of r at normal incidence, which cancels in ln R's derivative.)
    """
    omega = 2 * np.pi * frequency
    k = omega / C
    eta = eps - 1j * sigma / (EPSILON_0 * omega)
    n = np.sqrt(eta)
    e = np.exp(-2j * k * thickness * n)
    r = (1 - n) / (1 + n)
    big_r = r * (1 - e) / (1 - r * r * e)
    dr = -2 / (1 + n) ** 2
    de = -2j * k * thickness * e
    dln_dn = dr / r - de / (1 - e) + (2 * r * dr * e + r * r * de) / (1 - r * r * e)
    return complex(big_r), complex(dln_dn / (2 * n))


def _path(j: MaterialJacobian, description: str) -> int:
    found = [i for i in range(len(j.paths)) if j.paths.describe(i) == description]
    assert len(found) == 1, f"{description!r}: {len(found)} paths"
    return found[0]


def test_gains_at_start_values_equal_the_tracer(hall, jac):
    traced = trace_scene(f"{hall}/scene.xml", radar_position=RADAR, frequency=FREQUENCY, settings=SETTINGS).monostatic
    assert len(traced) == len(jac.paths) > 10
    np.testing.assert_array_equal(jac.delay, traced.delay)
    np.testing.assert_array_equal(jac.paths.interactions, traced.interactions)
    np.testing.assert_array_equal(jac.paths.objects, traced.objects)
    assert jac.paths.object_names == traced.object_names
    # Same float32 solver arithmetic (only the loop mode differs): measured bit-identical; the
    # tolerance allows the last float32 bit (1.2e-7 relative).
    np.testing.assert_allclose(jac.a, traced.amplitude, rtol=2.4e-7, atol=0)
    assert jac.materials == MATERIALS
    np.testing.assert_allclose(jac.relative_permittivity, [5.24, 6.31, 1.99, 2.58], rtol=1e-6)  # ITU a·f^b at 60 GHz


def test_other_values_retrace_and_the_scene_is_restored(hall, jac):
    moved = material_jacobian(hall, RADAR, [CONCRETE], values={CONCRETE: (6.1, 0.6)}, settings=SETTINGS)
    np.testing.assert_allclose([moved.relative_permittivity[0], moved.conductivity[0]], [6.1, 0.6], rtol=1e-7)
    wall = _path(moved, "specular:wall_3")
    r_new, _ = slab_normal(6.1, 0.6, 0.2, FREQUENCY)
    r_old, _ = slab_normal(jac.relative_permittivity[0], jac.conductivity[0], 0.2, FREQUENCY)
    # Only the reflection coefficient changed: float32 gains, 1e-5.
    assert abs(moved.a[wall] / jac.a[_path(jac, "specular:wall_3")]) == pytest.approx(abs(r_new / r_old), rel=1e-5)
    # A value for a material that is not differentiated moves its paths too, and only them.
    glassy = material_jacobian(hall, RADAR, [CONCRETE], values={GLASS: (7.0, 0.5)}, settings=SETTINGS)
    floor = _path(glassy, "specular:floor")
    r_new, _ = slab_normal(7.0, 0.5, THICKNESS[GLASS], FREQUENCY)
    r_old, _ = slab_normal(jac.relative_permittivity[1], jac.conductivity[1], THICKNESS[GLASS], FREQUENCY)
    assert abs(glassy.a[floor] / jac.a[floor]) == pytest.approx(abs(r_new / r_old), rel=1e-4)  # thin slab: 1e-4
    untouched = ~jac.touches[:, jac.materials.index(GLASS)]
    np.testing.assert_array_equal(glassy.a[untouched], jac.a[untouched])
    np.testing.assert_array_equal(glassy.d_eps[untouched, 0], jac.d_eps[untouched, 0])  # concrete's own terms
    again = material_jacobian(hall, RADAR, [CONCRETE], settings=SETTINGS)
    np.testing.assert_array_equal(again.a, jac.a)  # the cached scene went back to the ITU values


@pytest.mark.parametrize("surface, material, height", [
    ("floor", GLASS, RADAR[2]), ("ceiling", WOOD, 3.0 - RADAR[2]), ("wall_3", CONCRETE, RADAR[0])])
def test_single_bounce_matches_the_slab_formula(jac, surface, material, height):
    p = _path(jac, f"specular:{surface}")
    q = jac.materials.index(material)
    big_r, dln = slab_normal(jac.relative_permittivity[q], jac.conductivity[q], THICKNESS[material], jac.frequency)
    length = 2 * height
    # |a| = λ/(4π L) |R|: float32 gains, 1e-4.
    assert abs(jac.a[p]) == pytest.approx(C / jac.frequency / (4 * np.pi * length) * abs(big_r), rel=1e-4)
    # d ln a/dε_r = d ln R/dη and d ln a/dσ = d ln R/dη · (−j/(ε0 ω)). Tolerance 5e-4: float32 rounding
    # (1e-7) amplified by the slab phase k d n (up to 40 rad for the wood) and the near-cancelling
    # terms of its derivative; measured 3e-5 to 8e-5.
    np.testing.assert_allclose(jac.d_eps[p, q] / jac.a[p], dln, rtol=5e-4)
    np.testing.assert_allclose(jac.d_sigma[p, q] / jac.a[p], dln * (-1j / (EPSILON_0 * 2 * np.pi * jac.frequency)),
                               rtol=5e-4)


def test_double_bounce_over_two_materials(jac):
    """floor → ceiling: ln a = ln R_glass + ln R_wood + const, so each material contributes its own term."""
    for desc in ("specular:floor > specular:ceiling", "specular:ceiling > specular:floor"):
        p = _path(jac, desc)
        assert jac.path_materials(p) == (GLASS, WOOD)
        for material in (GLASS, WOOD):
            q = jac.materials.index(material)
            _, dln = slab_normal(jac.relative_permittivity[q], jac.conductivity[q], THICKNESS[material], jac.frequency)
            np.testing.assert_allclose(jac.d_eps[p, q] / jac.a[p], dln, rtol=5e-4)  # as for single bounces
        assert jac.d_eps[p, jac.materials.index(CONCRETE)] == 0


def test_sigma_derivative_is_the_eps_derivative_times_minus_j_over_eps0_omega(hall, jac):
    """Two independent AD passes (``sigma_by_identity=False``), related by a·(η) holomorphic:
    ∂a/∂σ = ∂a/∂ε_r · ∂η/∂σ / ∂η/∂ε_r, which is how the default Jacobian (``jac``) takes d_sigma without a solve."""
    two = material_jacobian(hall, RADAR, MATERIALS, frequency=FREQUENCY, settings=SETTINGS, sigma_by_identity=False)
    assert jac.sigma_by_identity and not two.sigma_by_identity
    np.testing.assert_array_equal(two.d_eps, jac.d_eps)  # the same deterministic ε_r passes
    factor = -1j / (EPSILON_0 * 2 * np.pi * jac.frequency)
    for q in range(3):
        scale = np.abs(two.d_sigma[:, q]).max()
        assert scale > 0
        # float32: 1e-4 of the column's largest entry (measured 7e-6 to 3.4e-5).
        np.testing.assert_allclose(two.d_sigma[:, q], factor * two.d_eps[:, q], rtol=0, atol=1e-4 * scale)
        np.testing.assert_allclose(jac.d_sigma[:, q], two.d_sigma[:, q], rtol=0, atol=1e-4 * scale)


@pytest.mark.slow
def test_derivatives_equal_central_finite_differences(hall, jac):
    """Re-trace at ε_r ± h, ± 2h (and σ likewise) with h = 0.01; fourth-order central differences.

    Tolerance 5e-3 of each path's derivative: the re-traced gains are float32 (relative rounding
    ~1e-6 of |a| per solve), which the difference quotient divides by 12h = 0.12 and the slab's
    oscillation in ε_r (6 mm glass) leaves an O(h⁴) truncation; measured ≤ 1.7e-3. A wrong
    factor, sign, conjugate or a missing bounce is an O(1) error.
    """
    h = 0.01
    for material in (CONCRETE, GLASS):
        q = jac.materials.index(material)
        eps, sigma = jac.relative_permittivity[q], jac.conductivity[q]
        for kind, ad in (("eps", jac.d_eps[:, q]), ("sigma", jac.d_sigma[:, q])):
            gains = {}
            for t in (h, -h, 2 * h, -2 * h):
                value = (eps + t, sigma) if kind == "eps" else (eps, sigma + t)
                moved = material_jacobian(hall, RADAR, [material], values={material: value}, settings=SETTINGS)
                np.testing.assert_array_equal(moved.delay, jac.delay)  # same paths, same order
                gains[t] = moved.a
            fd = (8 * (gains[h] - gains[-h]) - (gains[2 * h] - gains[-2 * h])) / (12 * h)
            seen = jac.touches[:, q]
            assert seen.sum() >= 3, material  # glass: floor, floor > ceiling, ceiling > floor
            np.testing.assert_allclose(ad[seen], fd[seen], rtol=5e-3, atol=0, err_msg=f"{material} {kind}")
            # Paths that do not touch the material do not move when it changes.
            np.testing.assert_array_equal(fd[~seen], 0)


def test_unseen_material_has_exactly_zero_derivatives(hall):
    j = material_jacobian(hall, RADAR, MATERIALS, settings=TraceSettings(max_depth=1, samples_per_src=10_000))
    assert len(j.paths) == 6  # the six single bounces; the corner crate is off every specular foot point
    assert j.unseen == (CHIPBOARD,)
    np.testing.assert_array_equal(j.seen, [True, True, True, False])
    q = j.materials.index(CHIPBOARD)
    assert j.material_objects[CHIPBOARD] == ("crate",)
    assert not j.touches[:, q].any()
    assert np.all(j.d_eps[:, q] == 0) and np.all(j.d_sigma[:, q] == 0)
    # Every derivative outside `touches` is exactly zero, every one inside it is not.
    assert np.all(j.d_eps[~j.touches] == 0) and np.all(j.d_sigma[~j.touches] == 0)
    assert np.all(j.d_eps[j.touches] != 0) and np.all(j.d_sigma[j.touches] != 0)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"materials": ["brick-200mm"]}, ValueError, ["'brick-200mm'", "concrete-200mm (concrete)"]),
    ({"materials": "concrete-200mm,nope"}, ValueError, ["'nope'", "not a radio material"]),
    ({"materials": []}, ValueError, ["empty"]),
    ({"materials": [CONCRETE, CONCRETE]}, ValueError, ["more than once"]),
    ({"materials": [3]}, TypeError, ["must be str"]),
    ({"values": {CONCRETE: (0.5, 1.0)}}, ValueError, [CONCRETE, "relative_permittivity=0.5", ">= 1"]),
    ({"values": {GLASS: (6.0, -0.1)}}, ValueError, [GLASS, "conductivity=-0.1", ">= 0"]),
    ({"values": {GLASS: (float("nan"), 0.1)}}, ValueError, [GLASS, "nan"]),
    ({"values": {"brick": (4.0, 0.1)}}, ValueError, ["'brick'", "not a radio material"]),
    ({"values": {GLASS: 6.0}}, TypeError, [GLASS, "pair"]),
    ({"values": [(GLASS, (6.0, 0.1))]}, TypeError, ["mapping"]),
    ({"radar_position": [1.0, 2.0]}, ValueError, ["radar_position"]),
    ({"frequency": -1.0}, ValueError, ["frequency"]),
    ({"settings": {"max_depth": 1}}, TypeError, ["TraceSettings"]),
])
def test_bad_input_is_a_one_line_error(hall, kwargs, error, words):
    args = {"radar_position": RADAR, "materials": [CONCRETE], "settings": SETTINGS, **kwargs}
    with pytest.raises(error) as info:
        material_jacobian(hall, args.pop("radar_position"), args.pop("materials"), **args)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message


@pytest.mark.slow
def test_diffuse_reflection_is_differentiated_too(hall):
    """Diffuse reflection (S = 0.3): gains as the tracer's, AD against FD, and no holomorphic shortcut.

    sionna-rt's raw order of diffuse paths changes from solve to solve; each solve is sorted as the
    tracer sorts, so the gains equal ``trace_scene``'s path for path.
    """
    settings = TraceSettings(max_depth=1, samples_per_src=10_000, diffuse_reflection=True, scattering_coefficient=0.3)
    j = material_jacobian(hall, RADAR, [CONCRETE], settings=settings)
    traced = trace_scene(f"{hall}/scene.xml", radar_position=RADAR, frequency=FREQUENCY, settings=settings).monostatic
    diffuse = (j.paths.interactions == 2).any(axis=1)
    assert diffuse.sum() > 100
    np.testing.assert_array_equal(j.delay, traced.delay)
    np.testing.assert_allclose(j.a, traced.amplitude, rtol=2.4e-7, atol=0)  # as at the start values
    h, eps, sigma = 0.01, j.relative_permittivity[0], j.conductivity[0]
    gains = {t: material_jacobian(hall, RADAR, [CONCRETE], values={CONCRETE: (eps + t, sigma)}, settings=settings).a
             for t in (h, -h, 2 * h, -2 * h)}
    fd = (8 * (gains[h] - gains[-h]) - (gains[2 * h] - gains[-2 * h])) / (12 * h)
    seen = j.touches[:, 0]
    ad = j.d_eps[:, 0]
    # Against the largest derivative (a path whose derivative nearly vanishes has a large relative
    # FD error): 5e-3, as for the specular check; measured 1.5e-4.
    assert np.abs(fd - ad)[seen].max() <= 5e-3 * np.abs(ad[seen]).max()
    assert np.median(np.abs(fd - ad)[seen] / np.abs(ad[seen])) <= 5e-3  # measured 7e-5
    # A diffuse gain is not holomorphic in η: ∂a/∂σ is not −j/(ε0 ω)·∂a/∂ε_r there (it is on specular paths).
    factor = -1j / (EPSILON_0 * 2 * np.pi * j.frequency)
    off = np.abs(j.d_sigma[:, 0] - factor * ad)
    assert off[diffuse & seen].max() > 0.1 * np.abs(j.d_sigma[diffuse & seen, 0]).max()
    assert off[~diffuse & seen].max() < 1e-4 * np.abs(j.d_sigma[~diffuse & seen, 0]).max()


def test_scattering_coefficient_is_differentiated_and_the_specular_loss_is_exact(hall, jac):
    """S = 0.3 on the concrete walls (diffuse paths not traced, as asked): every path loses √(1 − S²) per concrete
    bounce and ∂ln a/∂S = −n·S/(1 − S²) for n concrete bounces, exactly 0 without one (sionna-rt's energy split,
    written out); central differences of re-traced gains agree; derivatives=False gives the same gains only."""
    s = 0.3
    eps, sigma = jac.relative_permittivity[0], jac.conductivity[0]
    j = material_jacobian(hall, RADAR, MATERIALS, values={CONCRETE: (eps, sigma, s)}, scattering=[CONCRETE],
                          frequency=FREQUENCY, settings=SETTINGS)
    assert j.scattering == (CONCRETE,) and j.d_scattering.shape == (len(j.paths), 1)
    assert j.scattering_coefficient[0] == pytest.approx(s, rel=1e-7) and j.scattering_coefficient[1] == 0.0
    np.testing.assert_array_equal(j.delay, jac.delay)
    ids = [list(j.paths.object_names).index(o) for o in j.material_objects[CONCRETE]]
    n = (np.isin(j.paths.objects, ids) & (j.paths.interactions != 0)).sum(axis=1)
    assert set(n.tolist()) == {0, 1, 2}                                    # floor/ceiling, one wall, two walls
    np.testing.assert_allclose(np.abs(j.a), np.abs(jac.a) * (1 - s * s) ** (n / 2), rtol=2e-6)
    ratio = j.d_scattering[:, 0] / j.a
    np.testing.assert_allclose(ratio.real, -n * s / (1 - s * s), rtol=0, atol=2e-6)
    assert np.abs(ratio.imag).max() <= 2e-6 and np.all(j.d_scattering[n == 0, 0] == 0)
    np.testing.assert_allclose(j.d_eps / j.a[:, None], jac.d_eps / jac.a[:, None], rtol=1e-4, atol=1e-9)
    h = 0.01
    gains = {t: material_jacobian(hall, RADAR, [CONCRETE], values={CONCRETE: (eps, sigma, s + t)}, settings=SETTINGS,
                                  derivatives=False) for t in (h, -h)}
    assert np.all(gains[h].d_eps == 0) and np.all(gains[h].d_sigma == 0)
    fd = (gains[h].a - gains[-h].a) / (2 * h)
    # second-order differences of (1 − S²)^(n/2): truncation h²·|∂³a/∂S³|/6 ≈ 1e-5 relative, float32 rounding / h
    np.testing.assert_allclose(fd, j.d_scattering[:, 0], rtol=0, atol=2e-3 * np.abs(j.d_scattering).max())
    again = material_jacobian(hall, RADAR, [CONCRETE], values={CONCRETE: (eps, sigma, s)}, settings=SETTINGS,
                              derivatives=False)
    np.testing.assert_array_equal(again.a, j.a)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"values": {CONCRETE: (5.0, 1.0, 1.5)}}, ValueError, [CONCRETE, "scattering_coefficient=1.5", "[0, 1]"]),
    ({"values": {CONCRETE: (5.0, 1.0, 0.1, 3.0)}}, TypeError, [CONCRETE, "pair", "triple"]),
    ({"scattering": [GLASS]}, ValueError, ["'glass-6mm'", "not among the differentiated materials"]),
    ({"scattering": [CONCRETE], "settings": TraceSettings(max_depth=1, scattering_coefficient=0.3)}, ValueError,
     ["--diffuse", "cannot be differentiated per material"]),
])
def test_bad_scattering_input_is_a_one_line_error(hall, kwargs, error, words):
    with pytest.raises(error) as info:
        material_jacobian(hall, RADAR, [CONCRETE], **{"settings": SETTINGS, **kwargs})
    assert "\n" not in str(info.value)
    for word in words:
        assert word in str(info.value), str(info.value)
