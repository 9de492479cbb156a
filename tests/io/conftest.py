"""Fixtures of the capture-file tests: a small simulated capture and a rewriter of saved files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from risloc_rt.model.capture import Capture
from risloc_rt.model.simulate import simulate


@pytest.fixture
def capture(make_scenario) -> Capture:
    """The small-radar paper-like scenario, simulated with noise (seed 1)."""
    return simulate(make_scenario(), rng=np.random.default_rng(1), seed=1)


def _rewrite(path: Path, *, drop: tuple[str, ...] = (), meta: Callable[[dict], Any] | None = None,
             arrays: dict[str, np.ndarray] | None = None) -> Path:
    with np.load(path, allow_pickle=False) as f:
        content = {k: f[k] for k in f.files if k not in drop}
    if meta is not None and "metadata" in content:
        block = json.loads(str(content["metadata"]))
        meta(block)
        content["metadata"] = np.array(json.dumps(block))
    content.update(arrays or {})
    out = path.with_name("edited.npz")
    np.savez(out, **content)
    return out


@pytest.fixture(scope="session")
def rewrite():
    """``rewrite(path, *, drop=(), meta=None, arrays=None) -> path``: the capture at ``path`` saved again as
    ``edited.npz`` beside it, without the arrays ``drop``, with ``meta`` applied to its JSON metadata and
    ``arrays`` replacing or adding arrays."""
    return _rewrite
