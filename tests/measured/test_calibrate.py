"""risloc calibrate: injected radar range offset, τ_RB, ζ and receiver gain recovered from an emulated hall recording.

The emulator synthesises the default hall (radar position 1: 13.38 m, 21°) with the *true* RIS (τ_RB 1.93 ns,
ζ 42.0 dB) and radar (range offset 12.3 mm, +7 dB receiver gain, Tx→Rx leakage) while the sweep schedule states
the nominal RIS (1.78 ns, 45.532 dB); the calibration fits against the hall traced with the nominal RIS.

The recording's hall is traced more finely than the model's (conftest.RECORDING_TRACE: depth 3, 1e5 rays,
diffuse reflection with S = 0.3; the model: depth 2, 2e4 rays, specular only), so the fit meets the ray tracer's
own error. What it then recovers, and the tolerances that follow (measured on this fixture, seed 3):

- τ_RB, from the RIS's paths (free-space legs, the same in both traces): 1.9181 ± 0.0020 ns, −0.012 ns; 0.02 ns.
- the RIS's absolute power, ζ + power offset (counts² per W at the RIS): −0.12 dB; 0.5 dB.
- the noise floor in ADC counts² (the chirp-to-chirp variance, no model in it): 0.5 dB.
- the range offset, from the static echoes: +1.57 ± 0.26 mm (+0.51 mm from a depth-3 specular trace without
  diffuse reflection: the rest is the diffuse speckle on the static echoes); 2 mm.
- the power offset and ζ separately: the power offset is one scale of the *model's* static sum, dominated by
  wall_1, whose recorded echo the finer trace makes 2.9 dB weaker than the model's (1 − S² = −0.41 dB of it
  specular; the rest is its own diffuse speckle folded onto it, 23.1 m → 1.29 m): power offset −2.41 dB, ζ
  +2.29 dB, opposite by construction (their sum above); 3 dB each. With the specular depth-3 trace both are
  within 0.04 dB. The noise power in dBm (counts² / power offset) inherits the power offset's error.
"""

from __future__ import annotations

import numpy as np
import pytest

from risloc_rt.cli import main
from risloc_rt.io.capture_file import load_capture
from risloc_rt.measured.compare.calibration_file import read_calibration
from risloc_rt.measured.compare.calibration_fit import calibrate_capture
from risloc_rt.measured.compare.traced_hall import hall_model

RANGE_OFFSET, TAU_RB, ZETA_DB = 0.0123, 1.93e-9, 42.0          # what conftest.injected_hall injects
TRACE = ["--depth", "2", "--samples", "20000"]


@pytest.fixture(scope="module")
def hall_capture(injected_hall):
    assert (injected_hall["range_offset"], injected_hall["tau_rb"], injected_hall["zeta_db"]) == (RANGE_OFFSET, TAU_RB,
                                                                                                ZETA_DB)
    return injected_hall


def test_calibration_recovers_the_injected_values(hall_capture):
    cap = hall_capture["capture"]
    assert cap.ris.loopback_delay == pytest.approx(1.78e-9) and cap.ris.amplification_db == pytest.approx(45.532)
    model = hall_model(cap, "paper_hall", cap.truth.ue_position, trace=hall_capture["settings"],
                       cache=hall_capture["cache"])
    cal = calibrate_capture(cap, model.traced.paths)
    print(f"calibration: range offset {cal.range_offset * 1e3:.3f} ± {cal.range_offset_std * 1e3:.3f} mm (injected "
          f"{RANGE_OFFSET * 1e3}), tau_RB {cal.loopback_delay * 1e9:.4f} ± {cal.loopback_delay_std * 1e9:.4f} ns "
          f"(injected {TAU_RB * 1e9}), zeta {cal.amplification_db:.3f} ± {cal.amplification_db_std:.3f} dB (injected "
          f"{ZETA_DB}), noise {cal.noise_power_dbm:.3f} ± {cal.noise_power_dbm_std:.3f} dBm (injected "
          f"{hall_capture['noise_dbm']:.3f}), power offset {cal.power_offset_db:.3f} ± {cal.power_offset_db_std:.3f} dB "
          f"(injected {hall_capture['counts_db']:.3f})")
    # tolerances from the trace difference (module docstring)
    assert abs(cal.loopback_delay - TAU_RB) <= 0.02e-9
    ris_power, injected_ris_power = cal.amplification_db + cal.power_offset_db, ZETA_DB + hall_capture["counts_db"]
    assert abs(ris_power - injected_ris_power) <= 0.5
    injected_noise_db = hall_capture["noise_dbm"] - 30 + hall_capture["counts_db"]           # [dB counts²]
    assert abs(10 * np.log10(cal.details["noise_counts2"]) - injected_noise_db) <= 0.5
    assert abs(cal.range_offset - RANGE_OFFSET) <= 2e-3
    assert abs(cal.power_offset_db - hall_capture["counts_db"]) <= 3.0 and abs(cal.amplification_db - ZETA_DB) <= 3.0
    assert abs(cal.noise_power_dbm - hall_capture["noise_dbm"]) <= 3.0
    assert 0 < cal.range_offset_std < 1e-3 and 0 < cal.loopback_delay_std < 0.02e-9 and 0 < cal.amplification_db_std < 0.5


def test_calibrate_cli_file_and_locate_with_it(hall_capture, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(hall_capture["cache"].directory))
    cap_path = str(hall_capture["path"])
    out = tmp_path / "cal.toml"
    assert main(["calibrate", cap_path, "--scene", "paper_hall", "-o", str(out), *TRACE]) == 0
    text = capsys.readouterr().out
    assert "range offset" in text and "tau_RB" in text
    cal = read_calibration(out)
    assert abs(cal.loopback_delay - TAU_RB) <= 0.02e-9 and abs(cal.range_offset - RANGE_OFFSET) <= 2e-3
    out.write_text(out.read_text() + "# edited by hand\n")      # now the user's file: refused without --force
    assert main(["calibrate", cap_path, "--scene", "paper_hall", "-o", str(out), *TRACE]) == 2
    assert "risloc-rt did not write it" in capsys.readouterr().err
    assert out.read_text().endswith("# edited by hand\n")
    assert main(["calibrate", cap_path, "--scene", "paper_hall", "-o", str(tmp_path / "cal.json"), *TRACE]) == 0
    assert read_calibration(tmp_path / "cal.json").amplification_db == pytest.approx(cal.amplification_db, abs=1e-9)
    capsys.readouterr()

    truth = hall_capture["capture"].truth.distance
    from risloc_rt.io.report import process_capture
    from risloc_rt.measured.compare.calibration_file import apply_to_capture

    raw, _ = process_capture(hall_capture["capture"])
    fixed, _ = process_capture(apply_to_capture(hall_capture["capture"], cal))
    print(f"distance error: nominal tau_RB {1e3 * (raw.distance - truth):+.2f} mm, calibrated "
          f"{1e3 * (fixed.distance - truth):+.2f} mm")
    # nominal: off by the range offset plus (tau_RB error) c/2 = 12.3 + 22.5 mm; calibrated: within 2 mm
    assert abs(raw.distance - truth - 0.0348) < 0.003 and abs(fixed.distance - truth) < 0.002
    assert main(["locate", cap_path, "--calibration", str(out)]) == 0


def test_simulate_with_a_calibration(hall_capture, tmp_path, capsys):
    from risloc_rt.measured.compare.calibration_file import Calibration, write_calibration

    cal = write_calibration(Calibration(range_offset=0.02, loopback_delay=2.0e-9, amplification_db=40.0,
                                        noise_power_dbm=-60.0, power_offset_db=100.0), tmp_path / "c.toml")
    out = tmp_path / "sim.npz"
    assert main(["simulate", "--distance", "8", "--aod", "10,0", "--no-noise", "--calibration", str(cal),
                 "-o", str(out)]) == 0
    sim = load_capture(out)
    assert sim.ris.loopback_delay == pytest.approx(2.0e-9) and sim.ris.amplification_db == 40.0
    assert sim.radar.noise_power_dbm == -60.0
    capsys.readouterr()
    from risloc_rt.io.report import process_capture
    loc, _ = process_capture(sim)                                       # the range offset is in the data
    assert loc.distance - 8.0 == pytest.approx(0.02, abs=1e-3)
    assert main(["locate", str(out), "--calibration", str(cal)]) == 0
    assert "8.000" in capsys.readouterr().out


@pytest.mark.parametrize("content, message", [
    ("format = 'x'\n", "expected 'risloc-calibration' version 1"),
    ("format = 'risloc-calibration'\nversion = 1\n[radar]\nrange_offset_m = 0.0\n", "radar.noise_power_dbm is missing"),
    ("format = 'risloc-calibration'\nversion = 1\n[radar\n", "not valid TOML"),
])
def test_bad_calibration_files_are_one_line_errors(tmp_path, capsys, content, message):
    bad = tmp_path / "bad.toml"
    bad.write_text(content)
    assert main(["simulate", "--no-noise", "--calibration", str(bad), "-o", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err, err
    assert main(["simulate", "--no-noise", "--calibration", str(tmp_path / "none.toml"), "-o", str(tmp_path / "x.npz")]) == 2
    assert "calibration file" in capsys.readouterr().err and not (tmp_path / "x.npz").exists()
