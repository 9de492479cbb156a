"""Factories for the measured-capture tests: a small TDM-MIMO TI configuration and tone cubes.

It also registers the test-side TI reference decoder, ``ti_reference.py`` next to this file, as the
module ``ti_reference`` (the tests run with ``--import-mode=importlib``: this folder is not on
``sys.path``), so that the reader tests ``import ti_reference as ref``.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from risloc_rt.measured import TiChirp, TiChirpConfig

if "ti_reference" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("ti_reference", Path(__file__).with_name("ti_reference.py"))
    sys.modules["ti_reference"] = _module = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(_module)


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


# ---------------------------------------------------------------------------------------------- emulated hall
RANGE_OFFSET, TAU_RB, ZETA_DB, GAIN_DB = 0.0123, 1.93e-9, 42.0, 7.0
"""Injected into the emulated hall recording: range offset [m], true τ_RB [s], ζ [dB], receiver gain [dB]."""
TRACE = ["--depth", "2", "--samples", "20000"]
"""The model's ray tracing (what the calibrate/compare tests run with): depth 2, 2e4 rays, specular only."""
RECORDING_TRACE = {"max_depth": 3, "samples_per_src": 100_000, "diffuse_reflection": True,
                   "scattering_coefficient": 0.3}
"""The hall the recording is synthesised from: traced more finely than the model, so the ray tracer's own error is
not zero by construction: one more bounce, 5x the rays, and diffuse reflection (every surface scatters S² = 9 % of
its reflected power with a Lambertian pattern, rough concrete at 60 GHz; its specular echoes keep 1 − S², 0.41 dB
less than the model's). About 6 s of CPU on 2 cores (the model's trace: 1 s)."""


@pytest.fixture(scope="session")
def injected_hall(tmp_path_factory):
    """The default hall (radar position 1: 13.38 m, 21°) recorded with a true RIS (τ_RB 1.93 ns, ζ 42 dB) and radar
    (range offset 12.3 mm, +7 dB gain, Tx→Rx leakage) while the sweep schedule states the nominal RIS; imported.

    The recording comes from the hall traced with :data:`RECORDING_TRACE`; ``settings`` (depth 2, 2e4 rays,
    specular) is what the tests' calibration and comparison trace with. Both traces go to ``cache`` (the tests point
    ``RISLOC_CACHE_DIR`` at it, so the CLI's traces are hits after the first)."""
    import warnings

    from dsp import RadarConfig
    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.hall.raytrace.tracer import TraceSettings
    from risloc_rt.hall.scenario import hall_paths, hall_scenario
    from risloc_rt.io.capture_file import save_capture
    from risloc_rt.measured import RecordingPlan, dca1000_radar, emulate_recording, import_capture

    root = tmp_path_factory.mktemp("hall")
    cache = TraceCache(root / "cache")
    settings = TraceSettings(max_depth=2, samples_per_src=20000)
    recording_trace = TraceSettings(**RECORDING_TRACE)
    hs = hall_scenario("paper_hall", radar_index=1, radar=dca1000_radar(RadarConfig()), trace=recording_trace)
    nominal = hs.base.ris
    true = replace(hs, base=replace(hs.base, ris=replace(nominal, loopback_delay=TAU_RB, amplification_db=ZETA_DB)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traced = hall_paths(true, cache=cache)
    plan = RecordingPlan(lead_frames=3.0, sync_on=2, sync_off=2, sync_cycles=2, sync_gap=1, tail_frames=2,
                         range_offset=RANGE_OFFSET, power_offset_db=GAIN_DB, leakage_dbm=-10.0)
    rec = emulate_recording(true.base, root / "rec", plan=plan, paths=traced.paths, nominal_ris=nominal,
                            rng=np.random.default_rng(3))
    exp = rec.experiment
    # The sweep's first frame is given (lead frames + sync code = 12), not found: these tests are about calibration
    # and comparison, the aligner has its own (tests/measured/test_align.py).
    first_frame = round(rec.start)
    capture = import_capture(exp.raw_path, exp.config_path, exp.schedule_path, first_frame=first_frame)
    path = save_capture(capture, root / "capture.npz")
    return {"capture": capture, "path": path, "cache": cache, "settings": settings, "root": root,
            "recording_trace": recording_trace, "recording_paths": traced.paths,
            "counts_db": 20 * np.log10(exp.counts_per_unit), "noise_dbm": true.base.radar.noise_power_dbm,
            "range_offset": RANGE_OFFSET, "tau_rb": TAU_RB, "zeta_db": ZETA_DB, "trace": TRACE}
