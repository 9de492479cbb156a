"""Issue 11 regressions for the trace cache and scene loading: checksummed entries, scene extents."""

from __future__ import annotations

import json

import numpy as np
import pytest

from risloc_rt.hall.raytrace.cache import TraceCache, TraceCacheWarning
from risloc_rt.hall.raytrace.result import TraceResult, TraceSettings
from risloc_rt.hall.traced import TracedPaths


def _paths(delay: float) -> TracedPaths:
    return TracedPaths.from_arrays({
        "tx_position": np.zeros(3), "rx_position": np.zeros(3), "frequency": np.array(60e9),
        "delay": np.array([delay]), "amplitude": np.array([1e-3 + 0j]), "departure": np.array([[1.0, 0, 0]]),
        "arrival": np.array([[1.0, 0, 0]]), "delay_rate": np.zeros(1), "interactions": np.ones((1, 1), int),
        "objects": np.zeros((1, 1), int), "vertices": np.zeros((1, 1, 3)), "object_names": np.array(json.dumps(["w"])),
    })


def _result() -> TraceResult:
    return TraceResult(monostatic=_paths(1e-7), legs=(_paths(5e-8),), scene_hash="ab", cache_hit=False,
                       timing={"solve": 1.0}, settings=TraceSettings(), radar_velocity=np.zeros(3))


def test_issue_11_tampered_cache_entry_is_retraced_with_a_warning(tmp_path):
    # Defect 8: a tampered cache file was trusted.
    cache = TraceCache(tmp_path)
    key = "0" * 64
    path = cache.store(key, _result())
    assert cache.load(key).monostatic.delay[0] == 1e-7
    with np.load(path) as f:
        content = {k: f[k] for k in f.files}
    content["mono/delay"] = np.array([2e-7])  # a plausible, wrong value
    np.savez(path, **content)
    with pytest.warns(TraceCacheWarning, match="checksum"):
        assert cache.load(key) is None
    path.write_bytes(path.read_bytes()[:100])  # truncated
    with pytest.warns(TraceCacheWarning):
        assert cache.load(key) is None


def test_issue_11_trace_settings_bounds():
    with pytest.raises(ValueError, match="max_depth=21 must be <= 20"):
        TraceSettings(max_depth=21)
    with pytest.raises(ValueError, match="32-bit"):
        TraceSettings(samples_per_src=2**31)
    assert TraceSettings(max_depth=12).memory_estimate() > 10e9 > TraceSettings().memory_estimate()


def test_issue_11_scene_in_millimetres_is_refused_at_load(tmp_path, box_hall):
    # Defect 8: a hall authored in millimetres was traced as a 10 km hall.
    from risloc_rt.hall.raytrace.scene import SceneError, load_scene

    hall = type(box_hall)(size=(12000.0, 8000.0, 4000.0))
    xml = hall.make(tmp_path)
    with pytest.raises(SceneError, match="spans 1.2e\\+04 m.*millimetres"):
        load_scene(xml, frequency=60e9)
