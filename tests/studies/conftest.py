"""Small studies: a 21-beam sweep (±15°, 1.5°) of 32 chirps × 64 samples, UE at 10.3° (off the beam grid)."""

from __future__ import annotations

import pytest

from risloc_rt.studies import StudySpec

#: Fixed parameters that make a run cost ~20 ms (Table I's cube is 70× larger).
SMALL = {"num_chirps": 32, "num_samples": 64, "n_dft": 128, "k_dft": 128, "sweep_span_deg": 15.0, "aod_deg": 10.3}


@pytest.fixture
def small_spec():
    """``small_spec(runs=..., vary=..., **fixed)`` -> StudySpec over :data:`SMALL`."""

    def make(*, runs: int = 6, seed: int = 7, vary=(("tx_power_dbm", (25.0, 35.0)),), name: str = "small", **fixed):
        return StudySpec(name=name, runs=runs, seed=seed, fixed={**SMALL, **fixed}, vary=tuple(vary))

    return make


def small_cli_args() -> list[str]:
    """``--set NAME=V`` for every entry of :data:`SMALL`."""
    out = []
    for k, v in SMALL.items():
        out += ["--set", f"{k}={v}"]
    return out
