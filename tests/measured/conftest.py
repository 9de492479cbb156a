"""Factories for the measured-capture tests: a small TDM-MIMO TI configuration and tone cubes."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from risloc_rt.measured import TiChirp, TiChirpConfig



IWR6843_3TX = """\
% IWR6843 3Tx x 4Rx TDM, 256 samples
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 7 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
lowPower 0 0
profileCfg 0 60.25 7 6 60 0 0 64.985 1 256 5000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
chirpCfg 2 2 0 0 0 0 0 2
frameCfg 0 2 64 8 40 1 0
guiMonitor -1 1 1 0 0 0 1
cfarCfg -1 0 2 8 4 3 0 15 1
sensorStart
"""


def small_config(**kw: Any) -> TiChirpConfig:
    """60 GHz, 2 Tx (TX0, TX2) x 4 Rx TDM, N = 32 complex samples at 2 Msps, K = 8 loops."""
    base = TiChirpConfig(start_frequency=60.25e9, slope=60e12, idle_time=7e-6, adc_start_time=6e-6,
                         ramp_end_time=24e-6, num_samples=32, sample_rate=2e6, rx_mask=0b1111, tx_mask=0b101,
                         chirps=(TiChirp(0b001), TiChirp(0b100)), num_loops=8, num_frames=0,
                         frame_periodicity=10e-3, rx_gain_db=30.0)
    return replace(base, **kw)


def tone_cube(config: TiChirpConfig, frames: int, *, range_bin: float, doppler_bin: float = 0.0,
              amplitude: float = 0.5, seed: int = 0) -> np.ndarray:
    """Paper-convention cube [F, K, V, N] of one target: exp(-j2π(p n/N + q k/K)) with a random phase per channel."""
    N, K, V = config.num_samples, config.num_loops, config.num_virtual
    n, k = np.arange(N), np.arange(K)
    phase = np.exp(2j * np.pi * np.random.default_rng(seed).random(V))
    tone = np.exp(-2j * np.pi * (range_bin * n[None, :] / N + doppler_bin * k[:, None] / K))   # [K, N]
    return amplitude * np.broadcast_to(tone[None, :, None, :] * phase[None, None, :, None], (frames, K, V, N)).copy()


@pytest.fixture
def cfg_text() -> str:
    """An IWR6843 3 Tx x 4 Rx SDK .cfg (chirps TX0, TX2, TX1; frameCfg on line 13)."""
    return IWR6843_3TX


@pytest.fixture
def make_config():
    return small_config


@pytest.fixture
def make_tone():
    return tone_cube
