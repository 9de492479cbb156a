"""A study folder keeps one noise stream: the device is recorded, a sitting on another is refused, the devices are named."""

from __future__ import annotations

import json

import pytest

import dsp
from risloc_rt.studies import run_study
from risloc_rt.studies.store import StudyFolderError, study_device


def test_the_stream_of_each_device():
    assert study_device("cpu", local=True) == ("cpu", "host-boxmuller")
    assert study_device("cuda", local=False) == ("cuda", "cuda")  # a Dask cluster's workers resolve it
    assert study_device("AUTO", local=True) == ("auto", "cuda" if dsp.cuda_available()[0] else "host-boxmuller")


def test_a_study_records_its_stream_and_its_devices(small_spec, tmp_path):
    res = run_study(small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),)), tmp_path / "s", workers=1, quiet=True,
                    figures=False, device="cpu")
    manifest = json.loads((tmp_path / "s" / "study.json").read_text())
    assert manifest["noise_stream"] == "host-boxmuller"
    (dev,) = res.summary["devices"]
    assert dev["dsp"]["device"] == "cpu" and dev["dsp"]["library"].startswith("numpy ")
    assert dev["trace"] is None or dev["trace"].endswith("_ad_mono_polarized")  # an analytic study traced nothing
    on_disk = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert on_disk["devices"] == res.summary["devices"]
    assert on_disk["noise_stream"] == res.summary["noise_stream"] == "host-boxmuller"


def test_a_rerun_with_nothing_left_to_run_still_names_what_ran_the_runs(small_spec, tmp_path):
    # Regression (found by the Ctrl-C benchmark, tests/fuzz/test_interrupt_moments.py): a finished study's rerun,
    # or one resumed after a stop between its last rows and its summary, ran no batch and wrote "devices": [],
    # and a figure without the DSP's device, although every row had been run on the CPU
    spec = small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),))
    first = run_study(spec, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    assert len(first.summary["devices"]) == 1
    record = tmp_path / "s" / f"devices-{spec.key}.json"
    assert json.loads(record.read_text())["devices"] == first.summary["devices"]
    (tmp_path / "s" / "summary.json").unlink()  # as a stop right after the last rows leaves it
    again = run_study(spec, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    assert again.new_runs == 0
    assert again.summary["devices"] == first.summary["devices"]


def test_a_study_continued_on_another_device_names_both_in_order(small_spec, tmp_path, monkeypatch):
    # the second sitting's batches ran elsewhere (a stand-in environment: another BLAS, the same noise stream);
    # the summary lists every sitting's device, first seen first, and the manifest keeps them for the next one
    import risloc_rt.io.report as report

    spec = small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),))
    first = run_study(spec, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    real = report.run_environment
    other = lambda backend: {**real(backend), "dsp": {**real(backend)["dsp"], "detail": "BLAS stand-in"}}  # noqa: E731
    monkeypatch.setattr(report, "run_environment", other)
    more = spec.__class__(**{**spec.__dict__, "runs": 3})
    second = run_study(more, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    assert second.new_runs == 1
    assert second.summary["devices"] == [first.summary["devices"][0], other(dsp.backend_for("cpu"))]
    monkeypatch.setattr(report, "run_environment", real)
    third = run_study(more, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    assert third.new_runs == 0 and third.summary["devices"] == second.summary["devices"]


def test_continuing_a_folder_whose_runs_came_from_another_stream_is_refused(small_spec, tmp_path):
    spec = small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),))
    run_study(spec, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    manifest = tmp_path / "s" / "study.json"
    data = json.loads(manifest.read_text())
    data["noise_stream"] = "cuda"  # as a GPU sitting would have left it
    manifest.write_text(json.dumps(data))
    log = (tmp_path / "s" / "runs.jsonl").read_bytes()
    with pytest.raises(StudyFolderError, match=r"noise was drawn on a GPU \(--device cuda\); continue it with that device"):
        run_study(spec.__class__(**{**spec.__dict__, "runs": 3}), tmp_path / "s", workers=1, quiet=True,
                  figures=False, device="cpu")
    assert (tmp_path / "s" / "runs.jsonl").read_bytes() == log  # nothing appended


def test_a_folder_started_on_the_ziggurat_stream_continues_on_it(small_spec, tmp_path):
    # A CPU folder made before the Box–Muller stream ("host", or no noise_stream at all) keeps its stream:
    # its new runs are the ziggurat's ("fast"), bit for bit a run of that stream, and its manifest still says so
    from risloc_rt.studies.kernel import prepare_point, run_once
    from risloc_rt.studies.params import complete_point

    spec = small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),))
    for old in ("host", None):
        folder = tmp_path / f"s-{old}"
        run_study(spec, folder, workers=1, quiet=True, figures=False, device="cpu")
        manifest = folder / "study.json"
        data = json.loads(manifest.read_text())
        if old is None:
            del data["noise_stream"]  # a manifest from before devices existed
        else:
            data["noise_stream"] = old
        manifest.write_text(json.dumps(data))
        more = spec.__class__(**{**spec.__dict__, "runs": 3})
        res = run_study(more, folder, workers=1, quiet=True, figures=False, device="cpu")
        assert res.new_runs == 1
        assert json.loads(manifest.read_text())["noise_stream"] == res.summary["noise_stream"] == "host"
        new = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()][-1]
        assert new["run"] == 2
        prep = prepare_point(complete_point(spec.points()[0]))
        fast = run_once(prep, study_seed=spec.seed, point=0, run=2, noise_stream="fast")
        boxmuller = run_once(prep, study_seed=spec.seed, point=0, run=2, noise_stream="boxmuller")
        assert new["snr_db"] == fast["snr_db"] != boxmuller["snr_db"]  # the grid distance is the same at 30 dBm
        assert new["distance"] == fast["distance"] and new["aod_az"] == fast["aod_az"]


def test_a_folder_of_an_unknown_stream_is_refused(small_spec, tmp_path):
    spec = small_spec(runs=2, vary=(("tx_power_dbm", (30.0,)),))
    run_study(spec, tmp_path / "s", workers=1, quiet=True, figures=False, device="cpu")
    manifest = tmp_path / "s" / "study.json"
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), "noise_stream": "host-sobol"}))
    with pytest.raises(StudyFolderError, match=r"noise stream 'host-sobol', which this version of risloc-rt does "
                                                r"not draw"):
        run_study(spec.__class__(**{**spec.__dict__, "runs": 3}), tmp_path / "s", workers=1, quiet=True,
                  figures=False, device="cpu")


def test_a_bad_device_name_is_one_line_before_any_work(small_spec, tmp_path, monkeypatch):
    with pytest.raises(dsp.DeviceError, match=r"--device='gpu' is not a device; use cpu, cuda or auto"):
        run_study(small_spec(runs=1), tmp_path / "s", workers=1, quiet=True, figures=False, device="gpu")
    assert not (tmp_path / "s").exists()
    monkeypatch.setenv("RISLOC_DEVICE", "tpu")
    with pytest.raises(dsp.DeviceError, match=r"\$RISLOC_DEVICE='tpu' is not a device"):
        run_study(small_spec(runs=1), tmp_path / "s", workers=1, quiet=True, figures=False)


@pytest.mark.skipif(dsp.cuda_available()[0], reason="this machine has a GPU: --device cuda works here")
def test_device_cuda_without_a_gpu_is_one_line_and_makes_no_folder(small_spec, tmp_path):
    with pytest.raises(dsp.DeviceError, match=r"--device=cuda but .*; use --device cpu \(or auto\) on this machine"):
        run_study(small_spec(runs=1), tmp_path / "s", workers=1, quiet=True, figures=False, device="cuda")
    assert not (tmp_path / "s").exists()


def test_workers_sharing_a_gpu_size_their_batches_from_their_share(monkeypatch):
    """Local workers on one GPU: each sizes B from free memory / workers (helper report: each claimed it all)."""
    import dataclasses

    import dsp.budget
    from risloc_rt.studies.kernel import prepare_point, run_runs
    from risloc_rt.studies.params import complete_point

    from .conftest import SMALL

    class PretendGpu(dsp.ArrayBackend):
        def free_memory(self) -> int:
            return 8 << 30

    seen = []
    real = dsp.budget.detect_batch_size

    def spy(shape, *, free_bytes=None, runs=None):
        seen.append(free_bytes)
        return real(shape, free_bytes=free_bytes, runs=runs)

    monkeypatch.setattr(dsp.budget, "detect_batch_size", spy)
    backend = PretendGpu(**{f.name: getattr(dsp.numpy_backend(), f.name) for f in dataclasses.fields(dsp.ArrayBackend)})
    prep = prepare_point(complete_point({**SMALL, "tx_power_dbm": 30.0}))
    one = run_runs(prep, study_seed=1, point=0, runs=range(2), backend=backend)
    four = run_runs(prep, study_seed=1, point=0, runs=range(2), backend=backend, share=4)
    assert seen == [8 << 30, 2 << 30]
    assert [r["distance"] for r in one] == [r["distance"] for r in four]  # B changes nothing in the rows
