"""RIS array factors of both modes (risloc_rt/ris.py: ris_response).

Oracle: a uniform linear array of N_az elements with spacing d has its first null where the
inter-element phase step reaches 2π/N_az. In the relay Tx sweep that step is k d (sin φ - sin θ),
so the null is at Δ(sin φ) = λ/(N_az d) = 2/16 for d = λ/2; the reflective profile
exp(-2j Xᵀg(φ)) doubles the step, so its null is at half that, 1/16, and its grating lobe is at
Δ(sin φ) = λ/(2d) = 1.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp import BeamSweep, RadarConfig
from risloc_rt.model.ris import ris_response

WAVELENGTH = RadarConfig().wavelength
# Fine azimuth scan for the null search [rad]; its step in sin φ bounds the null location error.
FINE_STEP = np.deg2rad(0.005)


def response(make_ris, mode: str, steer_deg: np.ndarray, ue_deg) -> np.ndarray:
    """|r| [M] for beams ``steer_deg`` [M, 2] and a monostatic UE at ``ue_deg`` [2] (degrees)."""
    ue = np.deg2rad(np.asarray(ue_deg, float))[None, :]
    ris = make_ris(mode=mode)
    ris = dataclasses.replace(ris, relay_rx_angle=ue[0])  # Rx beam on the UE
    return np.abs(ris_response(ris, BeamSweep(np.deg2rad(steer_deg)), ue, ue, wavelength=WAVELENGTH)[:, 0])


def azimuth_scan(center_deg: float, half_span_deg: float) -> np.ndarray:
    """[M, 2] azimuth scan that contains ``center_deg`` exactly (elevation 0) [deg]."""
    offsets = np.arange(-round(half_span_deg / np.rad2deg(FINE_STEP)), round(half_span_deg / np.rad2deg(FINE_STEP)) + 1)
    az = center_deg + offsets * np.rad2deg(FINE_STEP)
    az[offsets == 0] = center_deg
    return np.column_stack([az, np.zeros_like(az)])


@pytest.mark.parametrize("mode", ["relay", "reflective"])
@pytest.mark.parametrize("ue_deg", [(0.0, 0.0), (10.0, 0.0), (-25.0, 8.0), (17.0, -12.0)])
def test_response_peaks_at_the_steered_angle_with_gain_n_ris(mode, ue_deg, make_ris):
    # 2-D grid of beams around the UE direction, containing it exactly.
    az = ue_deg[0] + np.arange(-20, 21) * 0.5
    el = ue_deg[1] + np.arange(-20, 21) * 0.5
    grid = np.stack(np.meshgrid(az, el, indexing="ij"), axis=-1).reshape(-1, 2)
    r = response(make_ris, mode, grid, ue_deg)
    best = int(np.argmax(r))
    np.testing.assert_allclose(grid[best], ue_deg, atol=1e-12)
    # Both modes are normalised to a peak of N_RIS = 64 (docstring of ris_response); all
    # 64 terms are unit phasors in phase there, so the sum is exact to rounding.
    assert r[best] == pytest.approx(64.0, rel=1e-12)
    assert np.all(r <= 64.0 * (1 + 1e-12))


@pytest.mark.parametrize("mode, expected_null", [("relay", 2 / 16), ("reflective", 1 / 16)])
@pytest.mark.parametrize("ue_az_deg", [0.0, 10.0, -20.0])
def test_first_null_of_the_azimuth_sweep(mode, expected_null, ue_az_deg, make_ris):
    scan = azimuth_scan(ue_az_deg, 20.0)
    r = response(make_ris, mode, scan, (ue_az_deg, 0.0))
    centre = int(np.flatnonzero(scan[:, 0] == ue_az_deg)[0])
    ds = np.sin(np.deg2rad(scan[:, 0])) - np.sin(np.deg2rad(ue_az_deg))
    # Walk outward from the peak to the first local minimum on each side.
    right = centre + int(np.argmax(np.diff(r[centre:]) > 0))
    left = centre - int(np.argmax(np.diff(r[centre::-1]) > 0))
    # The scan step in sin φ (at most cos(φ)·FINE_STEP) bounds how far the sampled minimum is
    # from the true null.
    tol = FINE_STEP
    assert ds[right] == pytest.approx(expected_null, abs=tol)
    assert ds[left] == pytest.approx(-expected_null, abs=tol)
    # It is a real null (the response vanishes there, not a shallow dip): within one scan step
    # of the zero, |r| <= slope · step, and the main-lobe slope is < N·π·N_az per unit sin φ.
    assert r[right] < 64 * np.pi * 16 * 2 * tol
    assert r[left] < 64 * np.pi * 16 * 2 * tol


def test_reflective_grating_lobe_is_as_strong_as_the_main_lobe_relay_has_none(make_ris):
    beams = np.array([[30.0, 0.0], [-30.0, 0.0]])
    refl = response(make_ris, "reflective", beams, (30.0, 0.0))
    relay = response(make_ris, "relay", beams, (30.0, 0.0))
    # sin(30°) - sin(-30°) = 1 = λ/(2d): the doubled phase step is exactly 2π, so every element
    # adds in phase again (equal to the main lobe to rounding).
    assert refl[1] == pytest.approx(refl[0], rel=1e-9)
    # Relay: a single phase step of π per element over 16 rows: a null; at least 20 dB below.
    assert relay[1] ** 2 < relay[0] ** 2 * 10 ** (-20 / 10)


def test_reflective_sweep_within_45deg_has_a_grating_lobe_only_off_broadside(make_ris):
    # ris_response's Notes: grating lobes enter ±45° when |sin θ| > 1 - sin 45° (θ > 17°).
    sweep_deg = np.column_stack([np.arange(-45.0, 45.01, 0.25), np.zeros(361)])
    for ue_az, expect_lobe in [(10.0, False), (30.0, True)]:
        r = response(make_ris, "reflective", sweep_deg, (ue_az, 0.0))
        far = np.abs(np.sin(np.deg2rad(sweep_deg[:, 0])) - np.sin(np.deg2rad(ue_az))) > 0.5
        # Far from the main lobe the reflective array factor is below its first sidelobe
        # (-13 dB) unless a grating lobe is there.
        assert bool(r[far].max() > 0.9 * 64) is expect_lobe


def test_relay_response_factorises_into_rx_and_tx_beams(make_ris):
    # Relay: [a(θ_i)ᵀ w_Rx] · [a(θ_d)ᵀ w_Tx] / N_RIS; with the Rx beam 1/16 off in sin az the Rx
    # factor is the 16-element Dirichlet kernel D(x) = sin(16 π x/2)/sin(π x/2)·4 (4 columns in phase).
    ue = np.array([[0.0, 0.0]])
    off = np.arcsin(1 / 16)
    ris = make_ris(mode="relay")
    ris = dataclasses.replace(ris, relay_rx_angle=np.array([off, 0.0]))
    r = ris_response(ris, BeamSweep(np.zeros((1, 2))), ue, ue, wavelength=WAVELENGTH)[0, 0]
    x = 1 / 16  # Δ(sin) times 2d/λ = 1 for λ/2 spacing
    rx_gain = 4 * np.sin(16 * np.pi * x / 2) / np.sin(np.pi * x / 2)
    tx_gain = 64.0  # Tx beam on the UE: all elements in phase
    assert abs(r) == pytest.approx(tx_gain * abs(rx_gain) / 64, rel=1e-9)
