"""Issue 20 item 3: a measured estimate's 1σ is the total of named terms, listed in result.json.

The capture is an emulated recording whose ``.cfg`` says 68.69 MHz/µs (the device runs 1896 steps,
68.6538): the budget states the correction that truncation made, by hand here. Without a calibration
the nominal τ_RB and range offset are flagged ``uncalibrated`` with the bias they may hide; with a
calibration file its σ enters the total, exactly in quadrature.
"""

from __future__ import annotations

import json
from dataclasses import replace
import math
import re

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig
from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.io.report import significant
from risloc_rt.measured import dca1000_radar, emulate_capture
from risloc_rt.measured.compare.calibration_file import Calibration, write_calibration
from risloc_rt.model.builder import analytic_scenario
from risloc_rt.model.simulate import simulate

C = 299_792_458.0
SLOPE = 1896 * 2.7e9 * 900 / 2**26 / 1e-6            # trunc(68.69 * 2^26 / (2.7e3 * 900)) steps [Hz/s]


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    offset = 6e-6 + 128 / 10e6 / 2
    nominal = RadarConfig(carrier_frequency=60e9 + SLOPE * offset, bandwidth=68.69e12 * 50e-6, chirp_duration=50e-6,
                          num_samples=128, sample_rate=10e6, num_chirps=16, tx_power_dbm=20.0)
    scenario = analytic_scenario(distance=9.3, aod=np.deg2rad([17.2, 0.0]), radar=dca1000_radar(nominal),
                                 processing=ProcessingConfig(n_dft=255, k_dft=64))
    sim = simulate(scenario, rng=np.random.default_rng(5))
    root = tmp_path_factory.mktemp("budget")
    exp = emulate_capture(sim, root / "rec")
    text = exp.config_path.read_text()
    line = next(x for x in text.splitlines() if x.startswith("profileCfg"))
    fields = line.split()
    fields[2], fields[8] = "60", "68.69"
    exp.config_path.write_text(text.replace(line, " ".join(fields)))
    npz = root / "cap.npz"
    assert main(["capture", "import", str(exp.raw_path), "--config", str(exp.config_path), "--sweep",
                 str(exp.schedule_path), "-o", str(npz)]) == 0
    return npz


def _locate(npz, out, *extra):
    assert main(["locate", str(npz), "--out", str(out), *extra]) == 0
    return json.loads((out / "result.json").read_text())["cases"][0]


def _terms(case, quantity):
    return {t["name"]: t for t in case["estimate"]["uncertainty_budget"] if t["quantity"] == quantity}


def test_budget_without_calibration_flags_the_nominal_delays(imported, tmp_path, capsys):
    case = _locate(imported, tmp_path / "a")
    est = case["estimate"]
    assert est["std"]["kind"] == "budget"
    dist = _terms(case, "distance")
    assert set(dist) >= {"noise", "slope register", "radar range offset", "loop-back delay τ_RB"}
    # the truncation's correction, by hand: the .cfg's 68.69 would have shrunk the apparent range by S_dev/S_file
    apparent = est["delay"] * C / 2
    assert dist["slope register"]["correction"] == pytest.approx(apparent * (1 - SLOPE / 68.69e12), rel=1e-9)
    assert dist["slope register"]["correction"] == pytest.approx(5.2e-3, abs=0.2e-3)          # 5 mm at 9.7 m
    # nominal delays: no σ, a bound, out of the total
    assert dist["radar range offset"]["value"] is None and dist["loop-back delay τ_RB"]["value"] is None
    tau_bound = 0.1 * 1.78e-9 * C / 2
    assert dist["loop-back delay τ_RB"]["bound"] == pytest.approx(tau_bound, rel=1e-3)
    assert est["std"]["distance"] == pytest.approx(dist["noise"]["value"], rel=1e-12)
    flags = {f["code"]: f["message"] for f in case["flags"]}
    assert "uncalibrated" in flags
    assert f"~{math.hypot(0.05, tau_bound) * 1e3:.0f} mm" in flags["uncalibrated"]
    out = capsys.readouterr().out
    assert "1σ budget, distance: noise" in out
    assert not re.search(r"± 0\.0*(?![0-9])", out)                  # a σ is never printed as all zeros


def test_budget_with_calibration_adds_its_sigma_in_quadrature(imported, tmp_path):
    cal = Calibration(range_offset=0.0, loopback_delay=1.78e-9, amplification_db=45.532, noise_power_dbm=-63.64,
                      power_offset_db=110.0, range_offset_std=1e-3, loopback_delay_std=2e-12)
    path = write_calibration(cal, tmp_path / "cal.toml")
    case = _locate(imported, tmp_path / "b", "--calibration", str(path))
    dist = _terms(case, "distance")
    assert dist["radar range offset"]["value"] == pytest.approx(1e-3, rel=1e-9)
    assert dist["loop-back delay τ_RB"]["value"] == pytest.approx(2e-12 * C / 2, rel=1e-9)
    noise = dist["noise"]["value"]
    total = math.sqrt(noise**2 + 1e-3**2 + (2e-12 * C / 2) ** 2)
    assert case["estimate"]["std"]["distance"] == pytest.approx(total, rel=1e-9)
    assert total > 1.2 * noise                                        # the calibration's σ matters here
    assert "uncalibrated" not in [f["code"] for f in case["flags"]]
    # the position's σ grows with the distance's (the radial axis of a radar 9.3 m away at 17°)
    assert case["estimate"]["std"]["peb"] >= total * 0.99


def test_simulated_capture_has_no_budget(tmp_path):
    out = tmp_path / "sim.npz"
    assert main(["simulate", "--distance", "9.3", "--aod", "17.2,0", "-o", str(out), "--seed", "1"]) == 0
    case = _locate(out, tmp_path / "c")
    assert case["estimate"]["uncertainty_budget"] is None and case["estimate"]["std"]["kind"] != "budget"
    assert "uncalibrated" not in [f["code"] for f in case["flags"]]


def test_tolerance_terms_default_to_not_stated(imported):
    from risloc_rt.io.report import process_capture
    from risloc_rt.measured.compare.uncertainty_budget import RisTolerances, apply_budget

    cap = load_capture(imported)
    loc, _ = process_capture(cap)
    _, budget = apply_budget(cap, loc)
    yaw = next(t for t in budget.terms if t.name == "RIS yaw")
    assert yaw.value is None and "not stated" in yaw.source
    loc2, budget2 = apply_budget(cap, loc, tolerances=RisTolerances(position=0.01, yaw=np.deg2rad(0.5),
                                                                       element_spacing=0.01))
    az = np.rad2deg(loc2.std.aod[0])
    noise_az = np.rad2deg(loc.std.aod[0])
    spacing = np.rad2deg(0.01 * abs(np.tan(loc.aod[0])))
    assert az == pytest.approx(math.sqrt(noise_az**2 + 0.5**2 + spacing**2), rel=1e-9)
    assert loc2.std.peb > loc.std.peb + 0.01                         # the RIS position tolerance on each axis


def test_sigma_prints_with_significant_digits():
    assert significant(2.03e-5) == "0.00002" and significant(0.00123) == "0.0012" and significant(0.47) == "0.47"


def test_schedule_tolerance_table_reaches_the_budget(imported, tmp_path):
    from risloc_rt.measured import format_sweep_schedule, parse_sweep_schedule
    from risloc_rt.measured.compare.uncertainty_budget import ris_tolerances
    from risloc_rt.measured.errors import MeasuredFormatError

    cap = load_capture(imported)
    text = cap.provenance["schedule"] + "\n[tolerance]\nposition_m = 0.005\nyaw_deg = 0.5\nelement_spacing = 0.01\n"
    sched = parse_sweep_schedule(text)
    assert (sched.tolerance_position_m, sched.tolerance_yaw_deg, sched.tolerance_element_spacing) == (0.005, 0.5, 0.01)
    assert parse_sweep_schedule(format_sweep_schedule(sched)) == sched                      # written back the same
    tol = ris_tolerances(replace(cap, provenance={**cap.provenance, "schedule": format_sweep_schedule(sched)}))
    assert (tol.position, tol.element_spacing) == (0.005, 0.01) and tol.yaw == pytest.approx(np.deg2rad(0.5))
    with pytest.raises(MeasuredFormatError, match=r"tolerance.yaw_deg = -1 must be a finite number >= 0"):
        parse_sweep_schedule(cap.provenance["schedule"] + "\n[tolerance]\nyaw_deg = -1\n")
    with pytest.raises(MeasuredFormatError, match="tolerance"):
        parse_sweep_schedule(cap.provenance["schedule"] + "\n[tolerance]\nyaw = 1\n")
