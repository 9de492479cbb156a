"""Hypothesis fuzzing of every reader and user-facing entry point (issue 11).

The entry points, generators and oracles are those of ``benchmarks/fuzz.py`` (which runs 100,000
inputs); here Hypothesis drives them with a small, derandomized budget so CI stays fast and
reproducible, plus free-form inputs (arbitrary bytes, text, argument lists). Every input must end
in a clear error or a correct result: never a traceback, a silent wrong answer or a hang.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_spec = importlib.util.spec_from_file_location("risloc_fuzz", Path(__file__).parents[2] / "benchmarks" / "fuzz.py")
fuzz = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fuzz)

SETTINGS = settings(max_examples=100, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
GOOD = {"error", "correct"}


@pytest.fixture(scope="module", autouse=True)
def _memory_limit():
    """The fuzzed inputs run under a 512 MiB memory limit (``declared sizes`` declares up to 10¹³)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RISLOC_MEMORY_LIMIT", "512M")
        yield


@pytest.fixture(scope="module")
def ws(tmp_path_factory):
    return fuzz.make_workspace(tmp_path_factory.mktemp("fuzz"))


def _outcome(name, inp, ws):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fuzz._classify(fuzz.ENTRY_POINTS[name][1], inp, ws, fuzz._expected_errors(),
                              fuzz.time_limit(name, 10.0))


@pytest.mark.parametrize("name", list(fuzz.ENTRY_POINTS))
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_generated_inputs_never_traceback_or_mislead(ws, name, seed):
    inp = fuzz.ENTRY_POINTS[name][0](np.random.default_rng(seed), ws)
    assert _outcome(name, inp, ws) in GOOD, repr(inp)[:300]


@SETTINGS
@given(data=st.binary(max_size=2000))
def test_arbitrary_bytes_as_capture_path_file_and_cache_entry(ws, data):
    for name in ("capture .npz", "path file", "trace-cache entry"):
        assert _outcome(name, ("bytes", data), ws) in GOOD


@SETTINGS
@given(data=st.binary(max_size=4000), form=st.sampled_from(["raw", "packets"]))
def test_arbitrary_bytes_as_a_dca1000_capture(ws, data, form):
    assert _outcome("raw DCA1000 + .cfg", (form, (data, ws.raw_cfg_text)), ws) in GOOD


@SETTINGS
@given(text=st.text(max_size=400))
def test_arbitrary_text_as_an_sdk_cfg(ws, text):
    assert _outcome("raw DCA1000 + .cfg", ("raw", (ws.raw_bytes["raw"], text)), ws) in GOOD


@SETTINGS
@given(text=st.text(max_size=400))
def test_arbitrary_text_as_spec(ws, text):
    assert _outcome("scene spec (TOML)", ("toml", text), ws) in GOOD


@SETTINGS
@given(argv=st.lists(st.one_of(st.sampled_from(fuzz._FLAGS + fuzz._VALUES + ["simulate", "trace", "locate"]),
                               st.text(max_size=12)), max_size=8))
def test_arbitrary_argument_lists(ws, argv):
    assert _outcome("CLI arguments", ("argv", argv), ws) in GOOD


@SETTINGS
@given(key=st.sampled_from(["radar", "processing", "ris"]),
       value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**70, 2**70), st.booleans(),
                       st.text(max_size=5), st.none()))
def test_capture_metadata_values(ws, key, value):
    import io
    import json

    with np.load(io.BytesIO(ws.capture_bytes), allow_pickle=False) as f:
        content = {k: f[k] for k in f.files}
    meta = json.loads(str(content["metadata"]))
    for field in sorted(meta[key]):
        meta[key][field] = value
        content["metadata"] = np.array(json.dumps(meta))
        buf = io.BytesIO()
        np.savez(buf, **content)
        assert _outcome("capture .npz", ("bytes", buf.getvalue()), ws) in GOOD, (key, field, value)
        meta = json.loads(str(np.load(io.BytesIO(ws.capture_bytes))["metadata"]))


@pytest.mark.slow
def test_declared_sizes_keep_peak_memory_within_the_limit(tmp_path):
    """Issue 19's goal: 300 declared sizes (0 … 10¹³, every place an input declares one) in a fresh
    process under a 512 MiB limit: no traceback, nothing wrong, and a peak RSS within the limit + 200 MB."""
    import json
    import subprocess
    import sys

    script = (f"import importlib.util, json, sys; s = importlib.util.spec_from_file_location('f', {str(_spec.origin)!r}); "
              "f = importlib.util.module_from_spec(s); s.loader.exec_module(f); "
              "print(json.dumps(f.run_entry_point('declared sizes', 300, 19, 10.0)))")
    env = {**__import__("os").environ, "RISLOC_MEMORY_LIMIT": "512M"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=900,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    r = json.loads(done.stdout.strip().splitlines()[-1])
    assert r["traceback"] == r["wrong"] == r["hang"] == 0, r["samples"]
    assert r["error"] > 0 and r["correct"] > 0                     # both sides of the limit were reached
    assert r["peak_rss"] <= 512 * 2**20 + 200e6, f"peak RSS {r['peak_rss'] / 2**20:.0f} MiB ({r['peak_input']})"
