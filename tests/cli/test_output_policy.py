"""Issue 19 item 2 at every entry point: a file risloc-rt did not write is never replaced without
``--force`` (one-line error, exit 2, the file byte-identical), a rerun over its own unchanged
output works, a failed or interrupted multi-file output leaves the previous state, and a name taken
from an input cannot put a file outside ``--out``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from risloc_rt.cli import main

USER_BYTES = b"the user's own file, not risloc-rt's\n"
TRACE = ["--depth", "1", "--samples", "2000"]
RAW = Path(__file__).resolve().parents[3] / "shared" / "captures" / "iwr6843_corner_reflector" / "adc_data_Raw_0.bin"


def _one_error_line(capsys, verb: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"risloc {verb}: error: "), err
    return err[0]


def _tree(root: Path) -> dict[str, bytes | None]:
    found: dict[str, bytes | None] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            found[os.path.relpath(os.path.join(dirpath, d), root)] = None
        for f in filenames:
            found[os.path.relpath(os.path.join(dirpath, f), root)] = Path(dirpath, f).read_bytes()
    return found


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:
    """The paper's broadside case, cut to 21 beams x 32 chirps so that a ``locate`` with plots is quick."""
    from dataclasses import replace

    import numpy as np

    from dsp.sweep import BeamSweep
    from risloc_rt.io.capture_file import save_capture
    from risloc_rt.model.scenario import paper_scenario
    from risloc_rt.model.simulate import simulate

    s = paper_scenario("broadside")
    s = replace(s, radar=replace(s.radar, num_chirps=32), sweep=BeamSweep.azimuth_grid(
        np.deg2rad(-10), np.deg2rad(10), np.deg2rad(1)))
    return save_capture(simulate(s, rng=np.random.default_rng(1)), tmp_path_factory.mktemp("cap") / "cap.npz")


def _single_file_cases(capture: Path, tmp: Path, monkeypatch) -> list[tuple[str, list[str], Path]]:
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp / "cache"))
    cases = [
        ("simulate", ["simulate", "--no-noise", "-o", str(tmp / "sim.npz")], tmp / "sim.npz"),
        ("simulate", ["simulate", "--no-noise", "-o", str(tmp / "bare")], tmp / "bare.npz"),   # .npz appended
        ("trace", ["trace", "paper_hall", "--ue", "6,9,1.2", *TRACE, "-o", str(tmp / "paths.npz")],
         tmp / "paths.npz"),
        ("trace", ["trace", "paper_hall", "--ue", "6,9,1.2", *TRACE, "--plot", str(tmp / "profile.png")],
         tmp / "profile.png"),
        ("scene show", ["scene", "show", "paper_hall", "-o", str(tmp / "plan.png")], tmp / "plan.png"),
    ]
    if RAW.is_file():
        cases.append(("capture inspect", ["capture", "inspect", str(RAW), "--layout", "256,4,3,64", "--plot",
                                  str(tmp / "inspect.png")], tmp / "inspect.png"))
    return cases


def test_single_file_outputs_refuse_a_user_file_unless_force(capture, tmp_path, capsys, monkeypatch):
    for verb, argv, target in _single_file_cases(capture, tmp_path, monkeypatch):
        target.write_bytes(USER_BYTES)
        assert main(argv) == 2, argv
        line = _one_error_line(capsys, verb)
        assert str(target) in line and "risloc-rt did not write it" in line and "--force" in line
        assert target.read_bytes() == USER_BYTES                 # untouched
        assert main([*argv, "--force"]) == 0, argv
        assert target.read_bytes() != USER_BYTES
        capsys.readouterr()
        assert main(argv) == 0, argv                             # its own file, unchanged: a rerun replaces it
        capsys.readouterr()


def test_capture_import_refuses_a_user_file(tmp_path, capsys):
    exp = tmp_path / "exp"
    assert main(["simulate", "--distance", "8", "--aod", "10,0", "--no-noise", "--format", "dca1000",
                 "-o", str(exp)]) == 0
    capsys.readouterr()
    target = tmp_path / "imported.npz"
    target.write_bytes(USER_BYTES)
    argv = ["capture", "import", str(exp / "adc_data_Raw_0.bin"), "--config", str(exp / "adc_data.cfg"),
            "--sweep", str(exp / "sweep.toml"), "-o", str(target)]
    assert main(argv) == 2
    assert "risloc-rt did not write it" in _one_error_line(capsys, "capture import")
    assert target.read_bytes() == USER_BYTES
    assert main([*argv, "--force"]) == 0 and main(argv) == 0
    # the DCA1000 folder itself: a second simulate into it is refused (a capture is never overwritten)
    before = _tree(exp)
    assert main(["simulate", "--no-noise", "--format", "dca1000", "-o", str(exp)]) == 2
    assert _tree(exp) == before


@pytest.mark.parametrize("verb", ["locate", "demo"])
def test_folder_outputs_refuse_a_user_result_json(capture, tmp_path, capsys, verb):
    out = tmp_path / "res"
    out.mkdir()
    (out / "result.json").write_bytes(USER_BYTES)
    (out / "notes.txt").write_bytes(USER_BYTES)                  # a file of the user's beside: never touched
    argv = ["locate", str(capture), "--out", str(out)] if verb == "locate" else \
        ["demo", "--analytic", "--out", str(out)]
    assert main(argv) == 2
    line = _one_error_line(capsys, verb)
    assert "result.json exists and risloc-rt did not write it" in line
    assert _tree(out) == {"result.json": USER_BYTES, "notes.txt": USER_BYTES}   # refused before any work
    if verb == "demo":
        return                                                  # the same helper as locate's, below (3 cases: slow)
    assert main([*argv, "--force"]) == 0
    capsys.readouterr()
    assert (out / "result.json").read_bytes() != USER_BYTES and (out / "notes.txt").read_bytes() == USER_BYTES
    assert main(argv) == 0                                      # its own outputs now
    assert not [p for p in out.iterdir() if p.name.startswith(".risloc-stage-")]


def test_interrupted_locate_leaves_the_previous_folder(capture, tmp_path, capsys, monkeypatch):
    import risloc_rt.cli.locate as locate

    out = tmp_path / "res"
    assert main(["locate", str(capture), "--out", str(out)]) == 0
    before = _tree(out)
    real = locate.write_result

    def write_then_interrupt(folder, cases, **kw):
        real(folder, cases, **kw)            # result.json and the plots are written (into the stage) ...
        raise KeyboardInterrupt              # ... then Ctrl-C, before the swap

    monkeypatch.setattr(locate, "write_result", write_then_interrupt)
    assert main(["locate", str(capture), "--out", str(out), "--estimator", "paper"]) == 130
    assert _tree(out) == before               # byte for byte: nothing half old, half new, no stage left
    capsys.readouterr()


def test_a_capture_name_cannot_put_outputs_outside_out(capture, tmp_path, capsys):
    odd = tmp_path / "in" / "..npz"           # stem "." would make out/./ the case folder; "..." -> ".."
    odd.parent.mkdir()
    odd.write_bytes(capture.read_bytes())
    dots = tmp_path / "in" / "...npz"
    dots.write_bytes(capture.read_bytes())
    out = tmp_path / "work" / "res"
    for path in (odd, dots):
        assert main(["locate", str(path), "--out", str(out)]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "work").iterdir()) == ["res"]        # nothing beside --out
    cases = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert cases == ["_.", "_.."] and all((out / c / "aod_sweep.png").is_file() for c in cases)
