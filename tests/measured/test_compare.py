"""risloc compare: the emulated hall recording (conftest.injected_hall) against the traced hall, and its page in a
real headless browser (Debian's chromium; ./setup.sh --test installs it).

Physics as the oracle. The recording is synthesised from a finer trace of the hall than the model's
(conftest.RECORDING_TRACE: depth 3, 1e5 rays, diffuse reflection; the model: depth 2, 2e4 rays, specular), with
a range offset of 12.3 mm and the true τ_RB 0.15 ns longer than the schedule's (+22.5 mm at the RIS). Every
explained measured peak must then sit where the *recording's own* paths put it, relative to the model's
noise-free peak: residual = (offset, τ_RB error, and the shift the finer trace's extra paths give that peak)
± 3σ of the measured peak's noise (``delay_sigma_mm``, checked against a Monte Carlo below). With the
calibration the offsets vanish and only the trace's shift remains.

The wall_1 echo (folded from 23.1 m to 1.29 m, 19 dB over the floor echo 2.4 cells away) used to read 10.4 mm more
than the 12.3 mm offset. Cause, found by experiment: noise on *both* sides. The simulated side had its own noise
draw at the measured floor, and without a calibration its gain G came from the total signal power, 4 dB low for
wall_1 (the model's RIS is 3.5 dB too strong): the measured peak read +6.6 mm from its noise-free position
(σ 1.75 mm), the simulated one −3.7 mm (σ 2.8 mm), total 10.4 mm = 3.1σ of the difference. The measured minus
the noise-free prediction is white at the noise floor (no leakage, no slope or folding error: the slope is the
truncated one on both sides and the folded peak lands, noise-free, within 0.1 mm of its path's apparent
range; the floor echo pulls it by +0.26 mm, the same on both sides). The residual now takes the simulated peak
from the noise-free prediction, so only the measured noise (σ at the peak's SNR) remains.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from dsp import ProcessingConfig, RadarConfig, delay_doppler_map
from risloc_rt.cli import main
from risloc_rt.hall.path_table import apparent_distance
from risloc_rt.measured.compare.calibration_file import write_calibration
from risloc_rt.measured.compare.calibration_fit import calibrate_capture
from risloc_rt.measured.compare.comparison import _recalibrated_ris_paths, delay_sigma
from risloc_rt.measured.compare.traced_hall import hall_model
from risloc_rt.measured.sweep.leakage import apply_range_gate, range_gate_basis
from risloc_rt.model.beat import beat_cube
from risloc_rt.model.paths import shift_paths

TRACE = ["--depth", "2", "--samples", "20000"]
LOS = "ris_loopback: out LOS | back LOS"
C = 299_792_458.0


@pytest.fixture(scope="module")
def pages(injected_hall, tmp_path_factory):
    root = tmp_path_factory.mktemp("compare")
    mp = pytest.MonkeyPatch()
    mp.setenv("RISLOC_CACHE_DIR", str(injected_hall["cache"].directory))
    cap = injected_hall["capture"]
    model = hall_model(cap, "paper_hall", cap.truth.ue_position, trace=injected_hall["settings"],
                       cache=injected_hall["cache"])
    cal = write_calibration(calibrate_capture(cap, model.traced.paths), root / "cal.toml")
    base = ["compare", str(injected_hall["path"]), "--scene", "paper_hall", *TRACE]
    assert main([*base, "-o", str(root / "raw")]) == 0
    assert main([*base, "-o", str(root / "cal"), "--calibration", str(cal)]) == 0
    mp.undo()
    return root


def _doc(folder):
    return json.loads((folder / "comparison.json").read_text())


def _peak(distance, db, near):
    """Parabolic peak (in dB) of the local maximum within 3 grid bins of ``near`` [m]."""
    j = int(np.argmin(np.abs(distance - near)))
    j = j - 3 + int(np.argmax(db[j - 3:j + 4]))
    a, b, c = db[j - 1], db[j], db[j + 1]
    return float(distance[j] + 0.5 * (a - c) / (a - 2 * b + c) * (distance[1] - distance[0]))


@pytest.fixture(scope="module")
def recording_profile(injected_hall, pages):
    """Where the recording's own paths put each peak: the noise-free zero-Doppler profile [dB] at the best beam of
    the recording's trace (true RIS, the injected offset, the emulator's ADC counts per √W, the import's gate)."""
    cap = injected_hall["capture"]
    beam = _doc(pages / "raw")["best_beam"]
    paths = shift_paths(injected_hall["recording_paths"], 2 * injected_hall["range_offset"] / C,
                        cap.radar.carrier_frequency)
    frame = beat_cube(paths, radar=cap.radar, sweep=cap.sweep, ris=cap.ris)[beam] * 10 ** (injected_hall["counts_db"] / 20)
    leak = cap.provenance["leakage"]
    frame = apply_range_gate(frame[None], range_gate_basis(cap.radar, float(leak["gate_range"])))[0]
    ddm = delay_doppler_map(frame, cap.radar, cap.processing)
    return ddm.distance, 10 * np.log10(ddm.profile(0.0))


def test_residuals_are_the_injected_offsets_and_the_finer_traces_shift(pages, injected_hall, recording_profile):
    raw, cal = _doc(pages / "raw"), _doc(pages / "cal")
    for doc in (raw, cal):
        assert doc["format"] == "risloc-comparison" and doc["ue_source"] == "truth"
        assert doc["summary"]["explained"] >= 3
        assert sorted(doc["figures"]) == ["delay_doppler", "range_profiles", "sweep"]
    dist, db = recording_profile
    for name, doc in (("uncalibrated", raw), ("calibrated", cal)):
        print(name + ":")
        for p in doc["peaks"]:
            if not p["explained"]:
                print(f"  unexplained at {p['distance_m']:.4f} m, {p['power_db']:.2f} dB")
                continue
            # what the recording's paths predict for this residual, noise-free
            predicted = 1e3 * (_peak(dist, db, p["distance_m"]) - p["simulated_distance_m"])
            print(f"  {p['label']}: residual {p['delay_residual_mm']:+.2f} mm, predicted {predicted:+.2f} mm, "
                  f"sigma {p['delay_sigma_mm']:.2f} mm, power residual {p['power_residual_db']:+.2f} dB")
            assert abs(p["delay_residual_mm"] - predicted) <= 3 * p["delay_sigma_mm"], p
    by_label = {p["label"]: p for p in raw["peaks"]}
    # the uncalibrated RIS LOS peak: the offset plus (τ_RB error)·c/2 = 12.3 + 22.48 mm, to 3σ (0.3 mm)
    los = by_label[LOS]
    assert los["delay_residual_mm"] == pytest.approx(12.3 + 22.48, abs=3 * los["delay_sigma_mm"] + 0.5)
    # wall_1, folded from 23.1 m to 1.29 m: the offset alone, to 3σ of its noise (σ ≈ 1.9 mm at 19 dB over the
    # floor) plus what the finer trace's diffuse speckle around it shifts it by (printed above)
    wall = by_label["hall: specular:wall_1"]
    predicted = 1e3 * (_peak(dist, db, wall["distance_m"]) - wall["simulated_distance_m"])
    assert wall["delay_residual_mm"] == pytest.approx(predicted, abs=3 * wall["delay_sigma_mm"])
    # calibrated, the RIS LOS peak (isolated, the same path in both traces) has nothing left but its noise
    los = {p["label"]: p for p in cal["peaks"]}[LOS]
    assert abs(los["delay_residual_mm"]) <= 3 * los["delay_sigma_mm"]
    assert cal["summary"]["delay_residual_rms_mm"] < raw["summary"]["delay_residual_rms_mm"] / 3
    assert cal["summary"]["pave_peak_beam_measured"] == cal["summary"]["pave_peak_beam_simulated"]


def test_unexplained_peaks_are_the_finer_traces_paths(pages, injected_hall):
    """A peak the model cannot label lies on a path only the recording's trace has (diffuse or a third bounce)."""
    cap = injected_hall["capture"]
    rec = injected_hall["recording_paths"]
    app = apparent_distance(rec, cap.radar) + injected_hall["range_offset"]
    model_labels = set(hall_model(cap, "paper_hall", cap.truth.ue_position, trace=injected_hall["settings"],
                                  cache=injected_hall["cache"]).traced.paths.labels)
    for doc in (_doc(pages / "raw"), _doc(pages / "cal")):
        for p in doc["peaks"]:
            if p["explained"]:
                continue
            near = np.flatnonzero(np.abs(app - p["distance_m"]) <= 1.5 * cap.radar.range_resolution)
            labels = {rec.labels[i] for i in near}
            print(f"unexplained {p['distance_m']:.4f} m: {len(near)} recording paths, e.g. {sorted(labels)[:3]}")
            assert near.size and not labels <= model_labels, (p, labels)


def test_delay_sigma_is_the_monte_carlo_spread_of_the_peak():
    """delay_sigma against the peak picking it describes: a Hann-windowed tone at 20 dB over the profile's noise floor,
    its parabolic peak's spread over 400 noise draws (a small radar: N = 64, K = 16)."""
    radar = RadarConfig(num_samples=64, num_chirps=16, sample_rate=2e6, bandwidth=1e9, chirp_duration=40e-6)
    proc = ProcessingConfig(n_dft=128, k_dft=16)
    rng = np.random.default_rng(20)
    n = np.arange(radar.num_samples)
    frac = 10.3 / radar.num_samples                                   # a tone between bins [cycles/sample]
    amp, noise = 1.0, 10 ** (-20 / 10) * radar.num_samples * radar.num_chirps / 1.5 ** 2   # peak 20 dB over the floor
    tone = amp * np.exp(-2j * np.pi * frac * n)[None, :] * np.ones((radar.num_chirps, 1))
    reads = []
    for _ in range(400):
        frame = tone + np.sqrt(noise / 2) * (rng.standard_normal(tone.shape) + 1j * rng.standard_normal(tone.shape))
        ddm = delay_doppler_map(frame, radar, proc)
        db = 10 * np.log10(ddm.profile(0.0))
        reads.append(_peak(ddm.distance, db, frac * radar.max_range))
    spread = float(np.std(reads, ddof=1))
    sigma = delay_sigma(amp ** 2, noise, radar, proc)
    print(f"delay sigma {1e3 * sigma:.3f} mm, Monte Carlo {1e3 * spread:.3f} mm")
    assert spread == pytest.approx(sigma, rel=0.15)                   # 400 draws: the std is known to 3.5 %


def test_a_calibration_moves_the_ris_paths_of_a_model_traced_with_the_nominal_ris(injected_hall):
    """The library call compare_capture(capture, nominal model, calibration=...) used to keep the model's τ_RB and ζ
    in the RIS paths' delays and gains (only `risloc compare`, which traces with the calibrated RIS, was right):
    the recalibrated paths of the nominal model are the paths traced with the calibrated RIS."""
    cap = injected_hall["capture"]
    kw = dict(trace=injected_hall["settings"], cache=injected_hall["cache"])
    nominal = hall_model(cap, "paper_hall", cap.truth.ue_position, **kw)
    from dataclasses import replace
    true_ris = replace(cap.ris, loopback_delay=injected_hall["tau_rb"], amplification_db=injected_hall["zeta_db"])
    traced = hall_model(cap, "paper_hall", cap.truth.ue_position, ris=true_ris, **kw).traced.paths
    moved = _recalibrated_ris_paths(nominal.traced.paths, cap.ris, true_ris, cap.radar.carrier_frequency)
    # the pruning keeps other weak paths at another ζ: compare the paths both sets hold
    unique = [label for label in set(moved.labels) & set(traced.labels)
              if moved.labels.count(label) == traced.labels.count(label) == 1]
    common = [(moved.labels.index(label), traced.labels.index(label)) for label in unique]
    assert len(common) >= 20 and any(moved.labels[i] == LOS for i, _ in common)
    i, j = np.array(common).T
    np.testing.assert_allclose(moved.delay[i], traced.delay[j], rtol=0, atol=1e-18)
    # gains to 0.5 %: the trace weights each path by the IF filter's magnitude at its beat frequency
    # (hall.pruning), which the 0.15 ns longer τ_RB moves by S·Δτ = 10 kHz; the shift keeps the traced weight
    np.testing.assert_allclose(moved.gain[i], traced.gain[j], rtol=5e-3, atol=0)
    assert _recalibrated_ris_paths(traced, true_ris, true_ris, cap.radar.carrier_frequency) is traced


def _chromium(page):
    out = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr",
                          "--v=0", "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=120)
    return out.stdout, out.stderr


@pytest.mark.skipif(shutil.which("chromium") is None,
                    reason="chromium is not installed (./setup.sh --test installs Debian's chromium for this test)")
def test_the_page_loads_in_a_headless_browser(pages, tmp_path):
    folder = pages / "cal"
    dom, log = _chromium(folder / "index.html")
    assert 'id="figure-status">3/3<' in dom
    assert dom.count('data-loaded="yes"') == 3 and 'data-loaded="no"' not in dom
    assert "CONSOLE" not in log, [line for line in log.splitlines() if "CONSOLE" in line]
    doc = _doc(folder)
    rows = re.findall(r'<tr class="(?:explained|unexplained)">(.*?)</tr>', dom, flags=re.S)
    assert len(rows) == len(doc["peaks"])
    for row, peak in zip(rows, doc["peaks"]):
        cells = re.findall(r"<td>(.*?)</td>", row)
        assert float(cells[1]) == pytest.approx(peak["distance_m"], abs=1e-4)
        for cell, key in ((cells[5], "delay_residual_mm"), (cells[6], "power_residual_db")):
            if peak[key] is None:                                   # an unexplained peak has no residual
                assert cell == "–" and not peak["explained"]
            else:
                assert float(cell) == pytest.approx(peak[key], abs=0.01)
    # The check can fail: a page whose figure is missing reports it.
    broken = tmp_path / "broken"
    shutil.copytree(folder, broken)
    (broken / "sweep_power.png").unlink()
    dom, _ = _chromium(broken / "index.html")
    assert 'id="figure-status">2/3<' in dom and 'data-loaded="no"' in dom


def test_compare_refuses_to_overwrite_and_bad_scenes(injected_hall, pages, tmp_path, capsys):
    base = ["compare", str(injected_hall["path"]), *TRACE]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "index.html").write_text("<p>my own page</p>")     # a file risloc-rt did not write
    assert main([*base, "--scene", "paper_hall", "-o", str(mine)]) == 2
    err = capsys.readouterr().err
    assert "index.html exists and risloc-rt did not write it" in err and err.count("\n") == 1
    assert sorted(p.name for p in mine.iterdir()) == ["index.html"]            # nothing staged is left
    assert (mine / "index.html").read_text() == "<p>my own page</p>"
    assert main([*base, "--scene", "no_such_hall", "-o", str(pages / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no_such_hall" in err


def _slab_reflection(eps_r, sigma, frequency, thickness):
    """ITU-R P.2040 single-layer slab at normal incidence: R = r(1 - E) / (1 - r² E), r = (1 - √η)/(1 + √η),
    E = exp(-2j k d √η), η = ε_r - jσ/(ε0 ω) (written out here, independent of the tracer)."""
    eps0 = 8.8541878128e-12
    omega = 2 * np.pi * frequency
    eta = eps_r - 1j * sigma / (eps0 * omega)
    root = np.sqrt(eta)
    r = (1 - root) / (1 + root)
    e = np.exp(-2j * (omega / C) * thickness * root)
    return r * (1 - e) / (1 - r * r * e)


def test_baseline_scene_sets_the_residuals_before_and_after(injected_hall, pages, tmp_path, monkeypatch):
    """``--baseline-scene``: the capture against a hall with its concrete changed (after) and against the hall it came
    from (before). Oracles: the "before" numbers are those of a plain ``compare`` against that hall (the ``cal`` page,
    an independent run), the "after" ones those of a plain ``compare`` against the changed hall, and the wall_1 echo's
    power residual moves by minus the change of its one bounce off 0.2 m of concrete, |R|² of the P.2040 slab at normal
    incidence (the calibration's power offset holds the simulated gain fixed, so nothing else moves it)."""
    from risloc_rt.authoring.fitted_scene import write_fitted_scene

    monkeypatch.setenv("RISLOC_CACHE_DIR", str(injected_hall["cache"].directory))
    new = (9.0, 0.3)  # ITU concrete at 60 GHz: 5.24 and 0.0462·60^0.7822 = 1.136 S/m
    changed = write_fitted_scene("paper_hall", tmp_path / "changed", {"concrete-200mm": new}, {"test": "baseline"})
    base = ["compare", str(injected_hall["path"]), "--calibration", str(pages / "cal.toml"), *TRACE]
    assert main([*base, "--scene", str(changed), "--baseline-scene", "paper_hall", "-o", str(tmp_path / "both")]) == 0
    assert main([*base, "--scene", str(changed), "-o", str(tmp_path / "after")]) == 0
    both, before, after = _doc(tmp_path / "both"), _doc(pages / "cal"), _doc(tmp_path / "after")

    from risloc_rt.measured.compare.comparison_page import BASELINE_KEYS

    assert both["baseline"]["summary"] == {k: before["summary"][k] for k in BASELINE_KEYS}
    assert [p["power_residual_db"] for p in both["baseline"]["peaks"]] == [p["power_residual_db"] for p in before["peaks"]]
    assert both["summary"] == after["summary"] and both["peaks"] == after["peaks"]
    for k in BASELINE_KEYS:
        if both["summary"][k] is not None and before["summary"][k] is not None:
            assert both["baseline"]["change"][k] == pytest.approx(both["summary"][k] - before["summary"][k], abs=1e-12)

    f = injected_hall["capture"].radar.carrier_frequency
    gain_db = 20 * np.log10(abs(_slab_reflection(*new, f, 0.2)) / abs(_slab_reflection(5.24, 0.0462 * 60 ** 0.7822, f, 0.2)))
    assert abs(gain_db) > 1.0  # the change is large against the tolerance below
    k = next(i for i, p in enumerate(both["peaks"]) if p["explained"] and "wall_1" in p["label"]
             and both["baseline"]["peaks"][i]["explained"] and "wall_1" in both["baseline"]["peaks"][i]["label"])
    moved = both["peaks"][k]["power_residual_db"] - both["baseline"]["peaks"][k]["power_residual_db"]
    assert moved == pytest.approx(-gain_db, abs=0.1), (moved, gain_db)

    page = (tmp_path / "both" / "index.html").read_text()
    assert "Before and after" in page and "power residual, baseline [dB]" in page
    assert f"{before['summary']['power_residual_rms_db']:.3f}" in page

    # the sweep mean's static peaks (the material fit's): the same oracles, on the complex mean over the beams
    sm, sm_before, sm_after = both["sweep_mean"], before["sweep_mean"], after["sweep_mean"]
    assert sm["beams"] == injected_hall["capture"].cube.shape[0]
    assert {k: sm[k] for k in ("peaks", "power_residual_rms_db")} == {k: sm_after[k] for k in ("peaks",
                                                                                              "power_residual_rms_db")}
    assert sm["baseline"]["power_residual_rms_db"] == sm_before["power_residual_rms_db"]
    i = next(i for i, p in enumerate(sm["peaks"]) if "wall_1" in p["label"]
             and sm["baseline"]["peaks"][i]["power_residual_db"] is not None)
    moved = sm["peaks"][i]["power_residual_db"] - sm["baseline"]["peaks"][i]["power_residual_db"]
    assert moved == pytest.approx(-gain_db, abs=0.1), (moved, gain_db)
    assert sm["peaks"][i]["sigma_db"] < 0.5 * abs(gain_db)  # the mean reads it well inside the change
    assert 'id="sweep-mean"' in page and "Static peaks of the sweep mean" in page
    # each residual judged by its own σ: recomputed here from the table, before and after
    for doc in (sm, sm_before):
        r = np.array([p["power_residual_db"] for p in doc["peaks"]])
        w = 1.0 / np.array([p["sigma_db"] for p in doc["peaks"]]) ** 2
        assert doc["power_chi2"] == pytest.approx(float(np.sum(w * r * r)), rel=1e-12)
        assert doc["power_residual_weighted_rms_db"] == pytest.approx(float(np.sqrt(np.sum(w * r * r) / np.sum(w))),
                                                                      rel=1e-12)
    assert sm["baseline"]["power_chi2"] == sm_before["power_chi2"]
    assert sm["baseline"]["peaks_explained"] == len(sm_before["peaks"])
    assert f"χ² {sm['power_chi2']:.3f} for {len(sm['peaks'])} peak(s)" in page
    assert f"χ² {sm_before['power_chi2']:.3f} for {len(sm_before['peaks'])} peak(s)" in page


def test_weighted_power_residuals_follow_chi2():
    """Residuals drawn with their stated σ: χ² has mean K and variance 2K (χ²_K), the weighted rms equals the plain
    one when every σ is equal; bad input is one line."""
    from risloc_rt.measured.compare.sweep_mean_peaks import weighted_power_residuals

    rng = np.random.default_rng(5)
    sd = np.array([0.3, 0.3, 0.5, 0.8, 1.0])
    chi2 = np.array([weighted_power_residuals(rng.normal(0.0, sd), sd)[1] for _ in range(4000)])
    assert chi2.mean() == pytest.approx(5.0, abs=4 * np.sqrt(10 / 4000))
    assert chi2.var() == pytest.approx(10.0, rel=0.15)
    r = np.array([0.2, -0.4, 0.1])
    assert weighted_power_residuals(r, [0.5] * 3)[0] == pytest.approx(float(np.sqrt(np.mean(r ** 2))), rel=1e-12)
    assert weighted_power_residuals([], []) == (None, None)
    for bad, words in ((([0.1], [0.0]), "sigma_db finite and > 0"), (([0.1, 0.2], [0.5]), "one entry per peak")):
        with pytest.raises(ValueError, match=words) as err:
            weighted_power_residuals(*bad)
        assert "\n" not in str(err.value)


@pytest.mark.slow
def test_a_capture_of_the_second_ris_is_compared_in_its_slot(tmp_path, monkeypatch):
    """Regression: in a hall with two RISs, ``compare`` traced the first RIS's slot whatever the capture, so a
    capture of ``ris1``'s slot was refused ("the capture's RIS is at ... but the scene's is at ..."). The scene's
    RIS at the capture's RIS position now sweeps. Oracle: the capture is the hall's own simulation, so every
    measured peak is explained and its delay residual is the measured peak's noise (within 4 of its σ)."""
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp_path / "cache"))
    cap = tmp_path / "ris1.npz"
    assert main(["simulate", "-o", str(cap), "--scene", "paper_hall_2ris", "--ris", "ris1", "--ue", "15.5,3.5,1.2",
                 "--seed", "3", *TRACE]) == 0
    assert main(["compare", str(cap), "--scene", "paper_hall_2ris", "-o", str(tmp_path / "cmp"), *TRACE]) == 0
    doc = _doc(tmp_path / "cmp")
    assert doc["summary"]["peaks"] >= 1 and doc["summary"]["unexplained"] == 0
    assert any(p["label"] == LOS for p in doc["peaks"])
    for p in doc["peaks"]:
        assert abs(p["delay_residual_mm"]) <= 4 * p["delay_sigma_mm"], p
