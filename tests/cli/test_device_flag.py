"""``--device cpu|cuda|auto`` on every verb that runs the DSP, and the line that says what ran where.

Oracles: ``--device cpu`` and ``$RISLOC_DEVICE=cpu`` give the numbers of the default bit for bit (the
NumPy backend is the default path, not a copy of it); a device that cannot be used (no CuPy here, a
wrong name in the flag or in ``$RISLOC_DEVICE``) is one line on stderr, exit status 2, and no output;
``result.json``'s ``"device"`` object and the console's ``device:`` line come from
``dsp.ArrayBackend.describe()``/``summary()`` of the backend that ran. The captures and scenes are the
small ones of the other tests (128 samples x 16 chirps, the tiny box hall of the floor-map tests).
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from dsp import numpy_backend, strict_backend
from dsp.xp import cuda_available
from risloc_rt.cli import build_parser, main
from risloc_rt.io.capture_file import load_capture, save_capture
from risloc_rt.io.report import format_environment, run_environment
from risloc_rt.model.beat import add_noise, beat_cube
from risloc_rt.model.motion import analytic_frame_paths
from risloc_rt.model.scenario import analytic_paths
from risloc_rt.model.simulate import simulate

#: The documented environment variable (README), written out: a rename in the code must fail these tests.
DEVICE_ENV = "RISLOC_DEVICE"

#: The fixed parameters of a ~20 ms study run (tests/studies/conftest.py's SMALL).
SMALL = {"num_chirps": 32, "num_samples": 64, "n_dft": 128, "k_dft": 128, "sweep_span_deg": 15.0, "aod_deg": 10.3}


HAS_GPU = cuda_available()[0]


@pytest.fixture(autouse=True)
def _no_device_env(monkeypatch):
    """The tests set $RISLOC_DEVICE themselves; a value from the caller's shell must not leak in."""
    monkeypatch.delenv(DEVICE_ENV, raising=False)


@pytest.fixture
def small_capture(tmp_path, make_scenario):
    """A small noisy capture file (128 samples x 16 chirps x 61 beams, UE 7.3° off broadside)."""
    capture = simulate(make_scenario(yaw=np.deg2rad(7.3), name="small"), rng=np.random.default_rng(4), seed=4)
    path = tmp_path / "small.npz"
    save_capture(capture, path)
    return path


def _result(folder):
    return json.loads((folder / "result.json").read_text())


def _device_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith("device: ")]


def _check_cpu_device(doc_device: dict) -> None:
    assert doc_device["dsp"]["device"] == "cpu"
    assert doc_device["dsp"]["library"].startswith("numpy ")
    assert doc_device["dsp"] == numpy_backend().describe()
    assert set(doc_device) == {"dsp", "trace"}


# ---- the flag on every verb -------------------------------------------------------------------------

VERBS = {
    "simulate": ["simulate", "-o", "x.npz"],
    "locate": ["locate", "x.npz"],
    "demo": ["demo"],
    "speed": ["speed"],
    "study sweep": ["study", "sweep", "--out", "o"],
    "study map": ["study", "map", "--out", "o"],
    "track": ["track", "l_hall_2ris", "--trajectory", "w.csv", "--out", "o"],
}


@pytest.mark.parametrize("verb", list(VERBS))
def test_every_verb_that_runs_the_dsp_takes_device(verb):
    parser = build_parser()
    assert parser.parse_args(VERBS[verb]).device is None  # None: $RISLOC_DEVICE, else cpu
    for name in ("cpu", "cuda", "auto"):
        assert parser.parse_args([*VERBS[verb], "--device", name]).device == name


def test_the_console_line_is_the_backends_summary():
    backend = numpy_backend()
    env = run_environment(backend)
    assert env["dsp"] == backend.describe()
    assert format_environment({"dsp": env["dsp"], "trace": None}) == f"device: dsp {backend.summary()}"
    assert (format_environment({"dsp": env["dsp"], "trace": "llvm_ad_mono_polarized"})
            == f"device: dsp {backend.summary()}; trace llvm_ad_mono_polarized")


# ---- a device that cannot be used: one line, exit 2, nothing written -----------------------------------

def _argv(verb: str, tmp_path, capture: str) -> tuple[list[str], list]:
    """(argv, outputs that must not appear) of ``verb`` writing under ``tmp_path``."""
    if verb == "simulate":
        return ["simulate", "-o", str(tmp_path / "new.npz")], [tmp_path / "new.npz"]
    if verb == "locate":
        return ["locate", capture, "--out", str(tmp_path / "loc")], [tmp_path / "loc"]
    if verb == "demo":
        return ["demo", "--analytic", "--out", str(tmp_path / "demo")], [tmp_path / "demo"]
    if verb == "speed":
        return (["speed", "--scene", "paper_hall", "--json", str(tmp_path / "s.json")], [tmp_path / "s.json"])
    if verb == "track":  # the device is checked before the trajectory file is read
        return (["track", "l_hall_2ris", "--trajectory", str(tmp_path / "w.csv"), "--out", str(tmp_path / "t")],
                [tmp_path / "t"])
    if verb == "study sweep":
        return (["study", "sweep", "--vary", "tx_power_dbm=30", "--runs", "1", "--workers", "1", "--quiet",
                 "--out", str(tmp_path / "sw")], [tmp_path / "sw"])
    return (["study", "map", "paper_hall", "--runs", "1", "--workers", "1", "--quiet", "--out", str(tmp_path / "m")],
            [tmp_path / "m"])


@pytest.mark.skipif(HAS_GPU, reason="this machine has CuPy and a GPU: --device cuda works here")
@pytest.mark.parametrize("verb", list(VERBS))
def test_device_cuda_without_cupy_is_one_line_exit_2_and_writes_nothing(verb, tmp_path, small_capture, capsys):
    argv, outputs = _argv(verb, tmp_path, str(small_capture))
    status = main([*argv, "--device", "cuda"])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith(f"risloc {verb}: error: --device=cuda but ")
    assert "CuPy" in captured.err and "pip install" in captured.err and "--device cpu" in captured.err
    assert not any(p.exists() for p in outputs)
    assert "speed:" not in captured.out  # refused before the work, not after it


@pytest.mark.parametrize("verb", list(VERBS))
def test_a_bad_risloc_device_is_one_line_naming_it(verb, tmp_path, small_capture, capsys, monkeypatch):
    argv, outputs = _argv(verb, tmp_path, str(small_capture))
    monkeypatch.setenv(DEVICE_ENV, "bogus")
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"${DEVICE_ENV}='bogus' is not a device; use cpu, cuda or auto" in err
    assert not any(p.exists() for p in outputs)


def test_a_bad_device_name_is_one_line(tmp_path, capsys):
    assert main(["simulate", "-o", str(tmp_path / "x.npz"), "--device", "gpu"]) == 2
    err = capsys.readouterr().err
    assert err == "risloc simulate: error: --device='gpu' is not a device; use cpu, cuda or auto\n"
    assert not (tmp_path / "x.npz").exists()


# ---- the same numbers on the CPU, however it is chosen -------------------------------------------------

def test_simulate_draws_the_same_noise_with_device_cpu(tmp_path, monkeypatch, capsys):
    argv = ["simulate", "--case", "off-broadside", "--seed", "3", "-o"]
    assert main([*argv, str(tmp_path / "default.npz")]) == 0
    assert main([*argv, str(tmp_path / "cpu.npz"), "--device", "cpu"]) == 0
    monkeypatch.setenv(DEVICE_ENV, "cpu")
    assert main([*argv, str(tmp_path / "env.npz")]) == 0
    if not HAS_GPU:  # auto without a GPU: NumPy
        monkeypatch.setenv(DEVICE_ENV, "auto")
        assert main([*argv, str(tmp_path / "auto.npz")]) == 0
    default = load_capture(tmp_path / "default.npz")
    for name in ("cpu", "env") + (() if HAS_GPU else ("auto",)):
        other = load_capture(tmp_path / f"{name}.npz")
        assert np.array_equal(other.cube, default.cube), name
        assert "noise_backend" not in other.provenance
    capsys.readouterr()


def test_the_model_keeps_numpys_noise_and_draws_on_another_backend(make_scenario):
    scenario = make_scenario(yaw=np.deg2rad(7.3))
    plain = simulate(scenario, rng=np.random.default_rng(9))
    on_numpy = simulate(scenario, rng=np.random.default_rng(9), backend=numpy_backend())
    assert np.array_equal(plain.cube, on_numpy.cube) and "noise_backend" not in on_numpy.provenance
    # array_api_strict on its virtual device: add_noise_batch's host draw (the fast stream), moved there and back
    strict = simulate(scenario, rng=np.random.default_rng(9), backend=strict_backend("device1"))
    clean = beat_cube(analytic_frame_paths(scenario), radar=scenario.radar, sweep=scenario.sweep, ris=scenario.ris)
    expect = add_noise(clean, scenario.radar.noise_power, np.random.default_rng(9), stream="fast")
    assert isinstance(strict.cube, np.ndarray) and strict.cube.dtype == np.complex128
    assert np.array_equal(strict.cube, expect)
    assert strict.provenance["noise_backend"] == "array_api_strict"
    noiseless = simulate(scenario, rng=np.random.default_rng(9), noise=False, backend=strict_backend("device1"))
    assert np.array_equal(noiseless.cube, clean) and "noise_backend" not in noiseless.provenance


def test_locate_gives_the_same_estimate_with_device_cpu_and_says_so(small_capture, tmp_path, monkeypatch, capsys):
    assert main(["locate", str(small_capture), "--out", str(tmp_path / "default")]) == 0
    out_default = capsys.readouterr().out
    assert main(["locate", str(small_capture), "--out", str(tmp_path / "cpu"), "--device", "cpu"]) == 0
    out_cpu = capsys.readouterr().out
    monkeypatch.setenv(DEVICE_ENV, "cpu")
    assert main(["locate", str(small_capture), "--out", str(tmp_path / "env")]) == 0
    capsys.readouterr()
    docs = {name: _result(tmp_path / name) for name in ("default", "cpu", "env")}
    for name, doc in docs.items():
        case, ref = doc["cases"][0], docs["default"]["cases"][0]
        for key in ("estimate", "detection", "flags", "error", "sweep"):
            assert case[key] == ref[key], (name, key)
        _check_cpu_device(doc["device"])
        assert doc["device"]["dsp"] == docs["default"]["device"]["dsp"]
    for text in (out_default, out_cpu):
        lines = _device_lines(text)
        assert lines == [format_environment(docs["default"]["device"])]
        assert lines[0].startswith(f"device: dsp {numpy_backend().summary()}")
    # without --out: the same line after the table
    assert main(["locate", str(small_capture), "--device", "cpu"]) == 0
    assert _device_lines(capsys.readouterr().out)[0].startswith("device: dsp cpu (numpy ")


def test_demo_gives_the_same_estimates_with_device_cpu_and_says_so(tmp_path, monkeypatch, capsys, make_scenario):
    import risloc_rt.cli.demo as demo

    def small(case, mode="relay"):  # the analytic demo on the small radar (two cases, distinct names)
        yaw = 0.0 if case == "broadside" else np.deg2rad(21.0)
        return make_scenario(mode=mode, yaw=yaw, name=f"small-{case}")

    monkeypatch.setattr(demo, "paper_scenario", small)
    assert main(["demo", "--analytic", "--seed", "2", "--out", str(tmp_path / "default")]) == 0
    out_default = capsys.readouterr().out
    assert main(["demo", "--analytic", "--seed", "2", "--out", str(tmp_path / "cpu"), "--device", "cpu"]) == 0
    out_cpu = capsys.readouterr().out
    default, cpu = _result(tmp_path / "default"), _result(tmp_path / "cpu")
    assert [c["name"] for c in cpu["cases"]] == ["small-broadside", "small-off-broadside"]
    for a, b in zip(default["cases"], cpu["cases"]):
        for key in ("estimate", "detection", "flags", "error", "sweep"):
            assert a[key] == b[key], key
    _check_cpu_device(cpu["device"])
    for text in (out_default, out_cpu):
        assert _device_lines(text) == [format_environment(cpu["device"])]


def _fake_trace(make_scenario):
    """``studies.speed._trace`` without a ray tracer: the small analytic scenario's paths for every setting."""

    def trace(scene, position, overrides):
        sc = make_scenario(yaw=np.deg2rad(7.3), name=f"{scene}-{position}")
        paths = analytic_paths(sc)
        return SimpleNamespace(base=sc), SimpleNamespace(paths=paths, candidates=paths.labels), 0.0

    return trace


def test_speed_gives_the_same_rows_with_device_cpu_and_reports_it(tmp_path, monkeypatch, capsys, make_scenario):
    import risloc_rt.studies.speed as speed

    monkeypatch.setattr(speed, "_trace", _fake_trace(make_scenario))
    argv = ["speed", "--scene", "paper_hall", "--realizations", "1", "--positions", "1", "--full", "1", "--json"]
    assert main([*argv, str(tmp_path / "default.json")]) == 0
    out_default = capsys.readouterr().out
    assert main([*argv, str(tmp_path / "cpu.json"), "--device", "cpu"]) == 0
    out_cpu = capsys.readouterr().out
    default = json.loads((tmp_path / "default.json").read_text())
    cpu = json.loads((tmp_path / "cpu.json").read_text())
    assert set(cpu) == {"device", "rows"} and len(cpu["rows"]) == len(default["rows"]) > 0
    numbers = ("scene", "setting", "estimator", "n", "paths", "rmse_m", "peb_m", "max_shift_m")
    for a, b in zip(default["rows"], cpu["rows"]):
        assert json.dumps([a[k] for k in numbers]) == json.dumps([b[k] for k in numbers])  # NaN as NaN: equal too
    _check_cpu_device(cpu["device"])
    for text in (out_default, out_cpu):
        assert _device_lines(text) == [format_environment(cpu["device"])]


def test_speed_passes_the_backend_to_the_detector(monkeypatch, capsys, make_scenario):
    import risloc_rt.io.report as report
    import risloc_rt.studies.speed as speed

    seen = []
    real = report.process_capture

    def spy(capture, **kw):
        seen.append(kw.get("backend"))
        return real(capture, **kw)

    monkeypatch.setattr(speed, "_trace", _fake_trace(make_scenario))
    monkeypatch.setattr(report, "process_capture", spy)
    backend = numpy_backend()
    speed.run_speed_study(["paper_hall"], realizations=1, full=0, seed=0, positions=1, grid=speed.TRACE_GRID[:1],
                          log=lambda *_: None, backend=backend)
    assert seen and all(b is backend for b in seen)


def _parquet_rows(path):
    import pyarrow.parquet as pq

    table = pq.read_table(path).to_pylist()
    return [{k: v for k, v in row.items() if "second" not in k and "time" not in k} for row in table]


def test_study_sweep_gives_the_same_runs_with_device_cpu_and_prints_the_device(tmp_path, capsys):
    fixed = [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]
    argv = ["study", "sweep", "--vary", "tx_power_dbm=25,35", *fixed, "--runs", "2", "--workers", "1", "--out"]
    assert main([*argv, str(tmp_path / "default")]) == 0
    out_default = capsys.readouterr().out
    assert main([*argv, str(tmp_path / "cpu"), "--device", "cpu"]) == 0
    out_cpu = capsys.readouterr().out
    assert _parquet_rows(tmp_path / "default" / "runs.parquet") == _parquet_rows(tmp_path / "cpu" / "runs.parquet")
    summary = json.loads((tmp_path / "cpu" / "summary.json").read_text())
    assert len(summary["devices"]) == 1
    _check_cpu_device(summary["devices"][0])
    for text in (out_default, out_cpu):
        assert _device_lines(text) == [format_environment(summary["devices"][0])]
        assert "noise stream: host-boxmuller (study.json; docs/studies.md)" in text.splitlines()
    # continued with nothing left to run: it says so, and still names what computed the runs (the folder's record)
    assert main([*argv, str(tmp_path / "cpu"), "--device", "cpu"]) == 0
    assert _device_lines(capsys.readouterr().out) == [
        "device: no runs computed now (every run was already in the log); they were computed by:",
        format_environment(summary["devices"][0])]


@pytest.mark.slow
def test_study_map_gives_the_same_cells_with_device_cpu_and_prints_the_device(tmp_path, capsys, monkeypatch,
                                                                            tiny_hall_spec):
    monkeypatch.setenv("RISLOC_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "spec.toml").write_text(tiny_hall_spec)
    assert main(["scene", "build", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "hall")]) == 0
    argv = ["study", "map", str(tmp_path / "hall"), "--spacing", "3", "--runs", "1", "--depth", "1",
            "--samples", "10000", "--workers", "1", "--out"]
    capsys.readouterr()
    assert main([*argv, str(tmp_path / "default")]) == 0
    out_default = capsys.readouterr().out
    assert main([*argv, str(tmp_path / "cpu"), "--device", "cpu"]) == 0
    out_cpu = capsys.readouterr().out
    default = json.loads((tmp_path / "default" / "map.json").read_text())
    cpu = json.loads((tmp_path / "cpu" / "map.json").read_text())
    assert cpu["cells"] == default["cells"] and len(cpu["cells"]) >= 2
    assert len(cpu["devices"]) == 1
    _check_cpu_device(cpu["devices"][0])
    assert cpu["devices"][0]["trace"] in ("llvm_ad_mono_polarized", "cuda_ad_mono_polarized")
    assert cpu["noise_stream"] == default["noise_stream"] == "host-boxmuller"
    for text in (out_default, out_cpu):
        assert _device_lines(text) == [format_environment(cpu["devices"][0])]
        assert "; trace " in _device_lines(text)[0]


def test_result_json_has_the_device_object_only_when_given(tmp_path):
    """``write_result`` without a device (library callers) writes no ``"device"`` key: the format is additive."""
    from risloc_rt.io.report import write_result

    doc = json.loads(write_result(tmp_path, []).read_text())
    assert "device" not in doc
    doc = json.loads(write_result(tmp_path, [], device=run_environment(numpy_backend())).read_text())
    _check_cpu_device(doc["device"])
    assert list(doc)[:4] == ["format", "version", "units", "device"]



@pytest.mark.parametrize("verb, target", [("sweep", "run_study"), ("map", "run_map")])
def test_a_studys_device_goes_to_the_study_as_given(verb, target, tmp_path, monkeypatch, capsys):
    """``study sweep|map`` hand ``--device`` as given (None without it) to run_study / run_map, which check it and
    read $RISLOC_DEVICE (risloc_rt.studies.store.study_device, tests/studies/test_device_stream.py)."""
    import risloc_rt.studies as studies
    import risloc_rt.studies.floor_map as floor_map

    seen = {}

    def stop(*args, **kw):
        seen["device"] = kw.get("device")
        return 0  # as the CLI's guard returns an exit status

    monkeypatch.setattr(studies if verb == "sweep" else floor_map, target, stop)
    fixed = [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]
    argv = (["study", "sweep", "--vary", "tx_power_dbm=30", *fixed] if verb == "sweep" else ["study", "map"])
    for given, expect in ((["--device", "AUTO"], "AUTO"), ([], None), (["--device", "cpu"], "cpu")):
        assert main([*argv, "--runs", "1", "--out", str(tmp_path / "o"), *given]) == 0
        assert seen.pop("device") == expect
    capsys.readouterr()
