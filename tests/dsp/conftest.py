"""Fixtures of the dsp tests: the beat tone of eq. (1), built with numpy only."""

from __future__ import annotations

import numpy as np
import pytest


def _tone(radar, tau, nu):
    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
    f2 = radar.carrier_frequency * nu * radar.chirp_interval
    k, n = radar.num_chirps, radar.num_samples
    return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))


@pytest.fixture(scope="session")
def tone():
    """``tone(radar, tau, nu) -> complex [K, N]``: one unit path of eq. (1),
    ``exp(-j2π((Sτ + f_c ν) n T_s + f_c ν k T_c))``, delay τ [s], delay rate ν [s/s]."""
    return _tone
