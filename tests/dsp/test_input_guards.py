"""Issue 11 regressions at the dsp boundary: real cubes are refused, memory is checked before work."""

from __future__ import annotations

import numpy as np
import pytest

import dsp
from dsp import BeamSweep, ProcessingConfig, RadarConfig
from dsp.budget import BudgetError

RADAR = RadarConfig(num_samples=64, num_chirps=16)
PROCESSING = ProcessingConfig(n_dft=127, k_dft=64)
SWEEP = BeamSweep(np.zeros((3, 2)))


@pytest.mark.parametrize("dtype", [float, np.float32, int, np.int16, bool])
@pytest.mark.parametrize("entry", ["scan_beams", "self_localize", "delay_doppler_map"])
def test_real_integer_and_boolean_samples_are_refused_not_cast(entry, dtype):
    cube = np.ones((3, 16, 64), dtype)
    with pytest.raises(TypeError, match=r"real-valued .*scipy\.signal\.hilbert"):
        if entry == "scan_beams":
            dsp.scan_beams(cube, SWEEP, RADAR, PROCESSING)
        elif entry == "self_localize":
            dsp.self_localize(cube, sweep=SWEEP, radar=RADAR, processing=PROCESSING,
                              pose=dsp.RisPose.facing(np.array([0.0, 5.0, 0.0]), np.zeros(3)), loopback_delay=0.0)
        else:
            dsp.delay_doppler_map(cube[0], RADAR, PROCESSING)


def test_an_absurd_dft_size_is_refused_before_allocating(monkeypatch):
    monkeypatch.setenv("RISLOC_MEMORY_LIMIT", "1G")
    huge = ProcessingConfig(n_dft=127, k_dft=10**9)
    cube = np.ones((3, 16, 64), complex)
    with pytest.raises(BudgetError, match=r"k_dft=1000000000 needs about .* more than the limit 1 GiB"):
        dsp.scan_beams(cube, SWEEP, RADAR, huge)
    with pytest.raises(BudgetError, match="k_dft=1000000000"):
        dsp.delay_doppler_map(cube[0], RADAR, huge)
    # the Table I sizes fit comfortably in the same limit
    dsp.scan_beams(cube, SWEEP, RADAR, PROCESSING)
