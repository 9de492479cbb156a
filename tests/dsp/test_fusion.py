"""Fused fixes of several RISs (dsp.fusion): geometry as the oracle, the stated covariance checked by its coverage."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from dsp import RisPose
from dsp.fusion import FusedFix, RisFix, fuse_fixes

TRUTH = np.array([6.0, 4.0, 1.2])
SIGMA_D, SIGMA_AZ, SIGMA_EL = 2e-3, np.deg2rad(0.2), np.deg2rad(0.5)


def _pose(position, target=(6.0, 4.0, 1.0)) -> RisPose:
    return RisPose.facing(np.asarray(position, float), np.asarray(target, float))


def _fix(name, pose, x, *, rng=None, sees_elevation=True, sd=SIGMA_D, saz=SIGMA_AZ, sel=SIGMA_EL, offset=(0, 0, 0)):
    """The fix a RIS at ``pose`` would give of a radar at ``x``: exact, or with N(0, σ²) errors from ``rng``."""
    rel = np.asarray(x, float) - pose.position
    d = float(np.linalg.norm(rel))
    az, el = pose.angles_to(np.asarray(x, float))
    z = np.array([d, az, el]) + np.asarray(offset, float)
    if rng is not None:
        z = z + rng.standard_normal(3) * np.array([sd, saz, sel])
    return RisFix(name=name, pose=pose, distance=z[0], std_distance=sd, aod=z[1:],
                  std_aod=np.array([saz, sel if sees_elevation else np.nan]))


POSES = {"ris-a": _pose([0.0, 4.0, 2.5]), "ris-b": _pose([12.0, 0.0, 0.8]), "ris-c": _pose([6.0, 12.0, 3.5])}


def test_exact_fixes_give_the_truth_and_the_summed_information():
    fixes = [_fix(n, p, TRUTH) for n, p in POSES.items()]
    fused = fuse_fixes(fixes)
    assert isinstance(fused, FusedFix)
    np.testing.assert_allclose(fused.position, TRUTH, atol=1e-9)  # [m]
    assert fused.statistic == pytest.approx(0.0, abs=1e-12) and fused.dof == 9 - 3
    assert set(fused.used) == set(POSES)
    assert not fused.excluded and not fused.flags
    # the covariance is the inverse of the summed Fisher information: adding a RIS never widens it
    two = fuse_fixes(fixes[:2])
    assert np.all(np.linalg.eigvalsh(two.covariance - fused.covariance) > -1e-15)
    assert fused.peb < two.peb < min(fuse_fixes([f]).peb for f in fixes[:2])


def test_two_rises_at_different_heights_see_the_height_without_elevation():
    """1-D sweeps (no elevation) at 2.5 m and 0.8 m: distances and azimuths fix the height."""
    fixes = [_fix(n, POSES[n], TRUTH, sees_elevation=False) for n in ("ris-a", "ris-b")]
    fused = fuse_fixes(fixes)
    np.testing.assert_allclose(fused.position, TRUTH, atol=1e-6)
    assert np.all(np.isfinite(fused.std)) and not fused.unobservable


def test_two_rises_at_one_height_cannot_see_it_and_say_so():
    """The mirror image in the sweep plane gives the same distances and azimuths: z is not seen there."""
    a, b = _pose([0.0, 4.0, 1.2], (6, 4, 1.2)), _pose([12.0, 0.0, 1.2], (6, 4, 1.2))
    fixes = [_fix("ris-a", a, TRUTH, sees_elevation=False), _fix("ris-b", b, TRUTH, sees_elevation=False)]
    fused = fuse_fixes(fixes)
    assert len(fused.unobservable) == 1 and abs(fused.unobservable[0][2]) > 0.999
    assert fused.std[2] == np.inf and np.isfinite(fused.std[0]) and np.isfinite(fused.std[1])
    assert fused.peb == np.inf
    (flag,) = [f for f in fused.flags if f.code == "unobservable"]
    assert "the height (z)" in flag.message and "ris-a" in flag.message
    np.testing.assert_allclose(fused.position[:2], TRUTH[:2], atol=1e-6)


def test_the_stated_covariance_covers_the_errors():
    """2000 noisy fusions of three RISs: the NEES εᵀ C⁻¹ ε is χ²(3); its mean within the 99.9 % band of
    the mean of 2000 χ²(3), and 1σ/2σ/3σ coverage of each axis within binomial 99.9 % intervals."""
    rng = np.random.default_rng(7)
    n = 2000
    nees, errs, stds = [], [], []
    for _ in range(n):
        fused = fuse_fixes([_fix(k, p, TRUTH, rng=rng) for k, p in POSES.items()])
        e = fused.position - TRUTH
        nees.append(float(e @ np.linalg.solve(fused.covariance, e)))
        errs.append(e)
        stds.append(fused.std)
    lo, hi = scipy.stats.chi2.ppf([5e-4, 1 - 5e-4], 3 * n) / n
    assert lo <= np.mean(nees) <= hi
    z = np.abs(np.array(errs)) / np.array(stds)
    for k, p in ((1, 0.6827), (2, 0.9545), (3, 0.9973)):
        a, b = scipy.stats.binom.ppf([5e-4, 1 - 5e-4], n, p) / n
        share = (z <= k).mean(axis=0)
        assert np.all((a - 1e-9 <= share) & (share <= b + 1e-9)), (k, share, (a, b))


def test_a_grating_twin_is_left_out_and_named():
    """ris-c reports the AoD of its grating lobe (25° off): the other two agree, ris-c is excluded."""
    rng = np.random.default_rng(3)
    fixes = [_fix("ris-a", POSES["ris-a"], TRUTH, rng=rng), _fix("ris-b", POSES["ris-b"], TRUTH, rng=rng),
             _fix("ris-c", POSES["ris-c"], TRUTH, rng=rng, offset=(0.0, np.deg2rad(25.0), 0.0))]
    fused = fuse_fixes(fixes)
    assert [n for n, _ in fused.excluded] == ["ris-c"] and set(fused.used) == {"ris-a", "ris-b"}
    (flag,) = [f for f in fused.flags if f.code == "inconsistent-ris"]
    assert "ris-c" in flag.message and "left out" in flag.message
    np.testing.assert_allclose(fused.position, fuse_fixes(fixes[:2]).position, atol=1e-9)
    assert np.linalg.norm(fused.position - TRUTH) < 5 * fused.peb
    assert fused.statistic <= fused.threshold


def test_consistent_fixes_are_all_kept_at_the_stated_false_alarm_rate():
    """200 consistent triples at pfa 1e-2: exclusions are binomial(200, ≤ 1e-2), 99.9 % level."""
    rng = np.random.default_rng(11)
    left_out = sum(bool(fuse_fixes([_fix(k, p, TRUTH, rng=rng) for k, p in POSES.items()], pfa=1e-2).excluded)
                   for _ in range(200))
    assert left_out <= scipy.stats.binom.ppf(1 - 1e-3, 200, 1e-2)


def test_two_disagreeing_fixes_are_kept_and_flagged():
    """Two RISs, 3 measurements each, 1 m apart in distance: either may be wrong; both kept, flagged."""
    fixes = [_fix("ris-a", POSES["ris-a"], TRUTH), _fix("ris-b", POSES["ris-b"], TRUTH, offset=(1.0, 0, 0))]
    fused = fuse_fixes(fixes)
    assert not fused.excluded and set(fused.used) == {"ris-a", "ris-b"}
    (flag,) = [f for f in fused.flags if f.code == "inconsistent-ris"]
    assert "no one of them explains it" in flag.message
    assert fused.statistic > fused.threshold


def test_one_fix_is_its_own_position():
    f = _fix("ris-a", POSES["ris-a"], TRUTH)
    fused = fuse_fixes([f])
    np.testing.assert_allclose(fused.position, TRUTH, atol=1e-9)
    assert fused.dof == 0 and np.isnan(fused.statistic)


@pytest.mark.parametrize("bad, match", [
    ([], "at least one RisFix"),
    ("twice", "distinct"),
    ("pfa", r"pfa=.* must lie in \(0, 1\)"),
])
def test_bad_input_is_one_line(bad, match):
    f = _fix("ris-a", POSES["ris-a"], TRUTH)
    with pytest.raises(ValueError, match=match):
        if bad == "twice":
            fuse_fixes([f, f])
        elif bad == "pfa":
            fuse_fixes([f], pfa=1.5)
        else:
            fuse_fixes(bad)


def test_a_fix_checks_its_numbers():
    pose = POSES["ris-a"]
    with pytest.raises(ValueError, match="std_distance"):
        RisFix("r", pose, 5.0, 0.0, np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match=r"std_aod=.* must be > 0"):
        RisFix("r", pose, 5.0, 0.01, np.zeros(2), np.array([-1.0, np.nan]))
    with pytest.raises(ValueError, match="aod"):
        RisFix("r", pose, 5.0, 0.01, np.array([np.nan, 0.0]), np.ones(2))
    with pytest.raises(TypeError, match="RisPose"):
        RisFix("r", "pose", 5.0, 0.01, np.zeros(2), np.ones(2))


def _with_flags(fix: RisFix, *codes: str) -> RisFix:
    return RisFix(name=fix.name, pose=fix.pose, distance=fix.distance, std_distance=fix.std_distance, aod=fix.aod,
                  std_aod=fix.std_aod, flags=tuple(codes))


def test_a_fix_aliased_by_the_range_is_left_out_not_run_after():
    """Regression (issue 22): two RISs at one height, 1-D sweeps, one fix folded back by 21.8 m.

    Plain Gauss–Newton ran 30 km away between two range circles that do not meet. Each fix alone
    sees the 2-D position, so the χ² test cannot say which is wrong; the one flagged ``aliased`` is
    left out, named, and the other gives the position.
    """
    a, b = _pose([0.0, 4.0, 1.2], (6, 4, 1.2)), _pose([12.0, 0.0, 1.2], (6, 4, 1.2))
    good = _fix("ris-a", a, TRUTH, sees_elevation=False)
    folded = _with_flags(_fix("ris-b", b, TRUTH, sees_elevation=False, offset=(21.82, 0, 0)), "aliased")
    fused = fuse_fixes([folded, good])
    assert fused.used == ("ris-a",)
    assert [name for name, _ in fused.excluded] == ["ris-b"] and "aliased" in fused.excluded[0][1]
    np.testing.assert_allclose(fused.position[:2], TRUTH[:2], atol=1e-6)  # [m]
    assert "inconsistent-ris" in {f.code for f in fused.flags}


def test_disagreeing_fixes_without_a_doubt_of_their_own_stay_a_bounded_compromise():
    """The same two fixes with no flags: both kept and flagged; the compromise lies between them, not 30 km away."""
    a, b = _pose([0.0, 4.0, 1.2], (6, 4, 1.2)), _pose([12.0, 0.0, 1.2], (6, 4, 1.2))
    fixes = [_fix("ris-a", a, TRUTH, sees_elevation=False),
             _fix("ris-b", b, TRUTH, sees_elevation=False, offset=(21.82, 0, 0))]
    fused = fuse_fixes(fixes)
    assert set(fused.used) == {"ris-a", "ris-b"} and not fused.excluded
    assert "no one of them explains it" in next(f.message for f in fused.flags if f.code == "inconsistent-ris")
    assert np.linalg.norm(fused.position[:2] - TRUTH[:2]) < 25.0  # [m]: within the two fixes' spread


def test_degrees_of_freedom_count_what_the_fixes_see():
    """Two 1-D fixes at one height: 4 measurements of a 2-D position, 2 degrees of freedom (not 4 − 3 = 1)."""
    a, b = _pose([0.0, 4.0, 1.2], (6, 4, 1.2)), _pose([12.0, 0.0, 1.2], (6, 4, 1.2))
    fused = fuse_fixes([_fix("ris-a", a, TRUTH, sees_elevation=False), _fix("ris-b", b, TRUTH, sees_elevation=False)])
    assert fused.dof == 2
    assert fused.threshold == pytest.approx(scipy.stats.chi2.isf(1e-3, 2))


def test_a_known_height_is_one_more_measurement():
    """Two 1-D fixes at one height cannot see z; with z known to 1 mm the position is 3-D, z's 1σ that 1 mm
    (the fixes add nothing along z), and the χ² has 4 + 1 − 3 = 2 degrees of freedom."""
    a, b = _pose([0.0, 4.0, 1.2], (6, 4, 1.2)), _pose([12.0, 0.0, 1.2], (6, 4, 1.2))
    fixes = [_fix("ris-a", a, TRUTH, sees_elevation=False), _fix("ris-b", b, TRUTH, sees_elevation=False)]
    fused = fuse_fixes(fixes, height=(TRUTH[2], 1e-3))
    assert not fused.unobservable and np.isfinite(fused.peb)
    np.testing.assert_allclose(fused.position, TRUTH, atol=1e-6)  # [m]
    assert fused.std[2] == pytest.approx(1e-3, rel=1e-3) and fused.dof == 2
    with pytest.raises(ValueError, match="height"):
        fuse_fixes(fixes, height=(1.2, 0.0))


@pytest.mark.parametrize("biased", ["ris-a", "ris-b"])
def test_a_compromise_states_a_covariance_that_spans_the_fixes(biased):
    """Two RISs that each fix the position alone (elevation seen), one of them 0.1 m off in distance (50σ; no
    flag of its own): the test cannot say which is wrong, so the position is their compromise. Its covariance
    must span both fixes' own positions: over 200 noisy pairs the truth's NEES against it stays within the
    99 % level of χ²(3) in ≥ 95 % of the runs whichever RIS is wrong, where the inverse information (what
    agreeing fixes would have) puts the truth at NEES > 100 (checked on the same runs)."""
    rng = np.random.default_rng(21)
    level = scipy.stats.chi2.ppf(0.99, 3)
    within, info_nees = 0, []
    for _ in range(200):
        fixes = [_fix(k, POSES[k], TRUTH, rng=rng, offset=(0.1 if k == biased else 0.0, 0.0, 0.0))
                 for k in ("ris-a", "ris-b")]
        fused = fuse_fixes(fixes)
        (flag,) = [f for f in fused.flags if f.code == "inconsistent-ris"]
        assert "compromise" in flag.message and "widened" in flag.message and not fused.excluded
        e = fused.position - TRUTH
        within += float(e @ np.linalg.solve(fused.covariance, e)) <= level
        agreeing = fuse_fixes(fixes, pfa=1e-300)  # the same fixes, no test: the inverse information
        np.testing.assert_allclose(agreeing.position, fused.position, atol=1e-9)
        info_nees.append(float(e @ np.linalg.solve(agreeing.covariance, e)))
    assert within >= 0.95 * 200
    assert np.median(info_nees) > 100


def test_a_compromise_of_fixes_that_cannot_stand_alone_is_scaled_by_its_chi2():
    """1-D sweeps at two heights (no elevation, no known height): a fix alone cannot place the radar, so the
    compromise's covariance is the inverse information times T/(n − r), the Birge ratio squared (ris-a's azimuth
    2° off: 10σ; a distance error the free height absorbs would not be seen)."""
    fixes = [_fix("ris-a", POSES["ris-a"], TRUTH, sees_elevation=False, offset=(0.0, np.deg2rad(2.0), 0.0)),
             _fix("ris-b", POSES["ris-b"], TRUTH, sees_elevation=False)]
    fused = fuse_fixes(fixes)
    assert any(f.code == "inconsistent-ris" for f in fused.flags) and fused.statistic > fused.threshold
    agreeing = fuse_fixes(fixes, pfa=1e-300)
    np.testing.assert_allclose(fused.covariance, agreeing.covariance * fused.statistic / fused.dof, rtol=1e-9)
