"""Factory fixtures shared by the test suite.

Each fixture returns a factory function (``def test_x(make_radar): radar = make_radar(num_samples=64)``);
every factory takes keyword overrides, so a test states only what it changes. The defaults are a
*small* radar (N = 128 samples, K = 16 chirps, N_DFT = 2N - 1, K_DFT = 4K) with Table I's RF
parameters (f_c, B, T, T_s), so the unambiguous range, slope and Doppler scale are the paper's;
tests that need Table I itself use :func:`risloc_rt.model.scenario.paper_scenario` (see ``paper_run``).
Constants come from the library: ``from dsp import SPEED_OF_LIGHT as C`` and
``from risloc_rt.model.scenario import PAPER_DISTANCE, PAPER_RCS``.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest

from dsp import BeamSweep, ProcessingConfig, RadarConfig, RisPose
from risloc_rt.model.paths import PathSet
from risloc_rt.model.beat import add_noise
from risloc_rt.model.ris import RisConfig
from risloc_rt.model.scenario import PAPER_DISTANCE, PAPER_RCS, PointTarget, Scenario, paper_scenario
from risloc_rt.model.simulate import simulate


def _make_radar(**kw: Any) -> RadarConfig:
    """Table I radar with N = 128 samples and K = 16 chirps unless overridden."""
    params: dict[str, Any] = {"num_samples": 128, "num_chirps": 16}
    params.update(kw)
    return RadarConfig(**params)


def _make_processing(radar: RadarConfig | None = None, **kw: Any) -> ProcessingConfig:
    """N_DFT = 2N - 1 (as the paper) and K_DFT = 4K for ``radar`` unless overridden."""
    radar = radar or _make_radar()
    params: dict[str, Any] = {"n_dft": 2 * radar.num_samples - 1, "k_dft": 4 * radar.num_chirps}
    params.update(kw)
    return ProcessingConfig(**params)


def _paper_sweep() -> BeamSweep:
    """-45° … 45° in 1.5° steps, elevation 0 (61 beams), as in the paper."""
    return BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 1.5]))


def _make_ris(
    *,
    mode: str = "relay",
    position: Any = (0.0, PAPER_DISTANCE, 0.0),
    facing: Any = (0.0, 0.0, 0.0),
    yaw: float = 0.0,
    rx_toward: Any = (0.0, 0.0, 0.0),
    **kw: Any,
) -> RisConfig:
    """RIS facing ``facing`` turned by ``yaw`` [rad], relay Rx beam toward ``rx_toward``."""
    pose = RisPose.facing(np.asarray(position, float), np.asarray(facing, float), yaw=yaw)
    return RisConfig(pose=pose, mode=mode, **kw).with_rx_toward(np.asarray(rx_toward, float))


def _make_scenario(
    *,
    radar: RadarConfig | None = None,
    processing: ProcessingConfig | None = None,
    mode: str = "relay",
    yaw: float = 0.0,
    ue_position: Any = (0.0, 0.0, 0.0),
    ris_position: Any = (0.0, PAPER_DISTANCE, 0.0),
    ris_facing: Any | None = None,
    structure: bool = True,
    sweep: BeamSweep | None = None,
    ris_kw: dict[str, Any] | None = None,
    **kw: Any,
) -> Scenario:
    """Paper-like scenario on the small radar: UE, RIS facing it (turned by ``yaw`` [rad]).

    ``structure`` adds the RIS panel's structural reflection (σ = 19 m² at the RIS centre), as
    :func:`paper_scenario` does.
    """
    radar = radar or _make_radar()
    processing = processing or _make_processing(radar)
    ue = np.asarray(ue_position, float)
    ris_pos = np.asarray(ris_position, float)
    ris = _make_ris(mode=mode, position=ris_pos, facing=ue if ris_facing is None else ris_facing,
                    yaw=yaw, rx_toward=ue, **(ris_kw or {}))
    targets = (PointTarget(position=ris_pos, rcs=PAPER_RCS, label="ris_structure"),) if structure else ()
    return Scenario(
        radar=radar,
        ris=ris,
        sweep=sweep or _paper_sweep(),
        processing=processing,
        ue_position=ue,
        targets=targets,
        **kw,
    )


def _tone_paths(gain: Any, delay: Any, delay_rate: Any, *, label: str = "target") -> PathSet:
    """Non-RIS paths (NaN RIS angles) with the given gains [√W], delays [s] and rates [s/s]."""
    g = np.atleast_1d(np.asarray(gain, complex))
    n = g.shape[0]
    return PathSet(
        gain=g,
        delay=np.broadcast_to(np.asarray(delay, float), (n,)).copy(),
        delay_rate=np.broadcast_to(np.asarray(delay_rate, float), (n,)).copy(),
        ris_incidence=np.full((n, 2), np.nan),
        ris_departure=np.full((n, 2), np.nan),
        labels=(label,) * n,
    )


def _delay_step(radar: RadarConfig, processing: ProcessingConfig) -> float:
    """Spacing of the delay grid, max_delay / N_DFT [s]."""
    return radar.max_delay / processing.n_dft


# Fixtures: each returns its factory (pure functions, so one per session).

def _tone(radar: RadarConfig, tau: float, nu: float) -> np.ndarray:
    f1 = (radar.slope * tau + radar.carrier_frequency * nu) * radar.sample_period
    f2 = radar.carrier_frequency * nu * radar.chirp_interval
    k, n = radar.num_chirps, radar.num_samples
    return np.exp(-2j * np.pi * ((np.arange(k)[:, None] * f2 + np.arange(n)[None, :] * f1) % 1.0))


def _grid_tone(radar: RadarConfig, processing: ProcessingConfig, p: int, q: int) -> np.ndarray:
    tau = p / (processing.n_dft * radar.slope * radar.sample_period)
    nu = (q if q < processing.k_dft // 2 else q - processing.k_dft) / (processing.k_dft * radar.carrier_frequency
                                                                        * radar.chirp_interval)
    return _tone(radar, tau - radar.carrier_frequency * nu / radar.slope, nu)  # the fast-time tone carries f_c ν too


def _multipath_cube(radar: RadarConfig, count: int, rng: np.random.Generator) -> np.ndarray:
    cube = np.zeros((count, radar.num_chirps, radar.num_samples), complex)
    for m in range(count):
        for _ in range(rng.integers(1, 7)):
            tau = rng.uniform(0.0, 0.95) * radar.max_delay
            nu = rng.uniform(-1.0, 1.0) / (2.0 * radar.carrier_frequency * radar.chirp_interval)
            cube[m] += 10 ** (-rng.uniform(0, 40) / 20) * np.exp(2j * np.pi * rng.uniform()) * _tone(radar, tau, nu)
        cube[m] = add_noise(cube[m], 10 ** (rng.uniform(-20, 30) / 10), rng)
    return cube


def _hard_table1_beams(radar: RadarConfig, processing: ProcessingConfig, rng: np.random.Generator) -> np.ndarray:
    res = radar.max_delay / radar.num_samples
    cube = np.zeros((6, radar.num_chirps, radar.num_samples), complex)
    cube[0] = _tone(radar, 300.3 * res, 1e-9) + 0.9 * _tone(radar, 301.8 * res, 1.2e-9)
    a, b = _grid_tone(radar, processing, 200, 4700), _grid_tone(radar, processing, 800, 60)  # on grid cells
    cube[1] = a + (1 + 5e-7) * b
    cube[2] = (1 + 5e-7) * a + b
    cube[3] = _tone(radar, 250.7 * res, 0.0)  # at -15 dB per sample: ≈ +30 dB after integration
    for m, snr_db in [(0, 20), (3, -15), (4, 0)]:  # beams 1, 2 noiseless: the 5e-7 decides; 4 noise only
        cube[m] = add_noise(cube[m], 10 ** (-snr_db / 10), rng)
    return cube  # beam 5 all zero


def _glitch_beams(rng: np.random.Generator) -> np.ndarray:
    burst = np.zeros((128, 600), complex)
    burst[7] = np.exp(2j * np.pi * 0.1 * np.arange(600))
    impulse = np.zeros((128, 600), complex)
    impulse[5, 100] = 1.0
    return np.stack([add_noise(burst, 1e-12, rng), add_noise(impulse, 1e-12, rng)])


@pytest.fixture(scope="session")
def tone():
    """``tone(radar, tau, nu) -> complex [K, N]``: one unit path of eq. (1), built with numpy only:
    ``exp(-j2π((Sτ + f_c ν) n T_s + f_c ν k T_c))``, delay τ [s], delay rate ν [s/s]."""
    return _tone


@pytest.fixture(scope="session")
def grid_tone():
    """``grid_tone(radar, processing, p, q) -> complex [K, N]``: a unit tone on grid cell (q, p) of the
    N_DFT × K_DFT grid: delay bin p, Doppler bin q (FFT order)."""
    return _grid_tone


@pytest.fixture(scope="session")
def multipath_cube():
    """``multipath_cube(radar, count, rng) -> complex [count, K, N]``: independent beams, each 1-6 returns of
    random delay (up to 0.95 of the unambiguous delay), Doppler (up to ±v_max), phase and amplitude (0-40 dB
    spread) plus receiver noise from -20 to +30 dB per sample relative to a unit return: from clean to noise
    only after integration (the grid searches' random test beams)."""
    return _multipath_cube


@pytest.fixture(scope="session")
def hard_table1_beams():
    """``hard_table1_beams(radar, processing, rng) -> complex [6, K, N]`` for Table I's N, K, N_DFT = 1199 and
    K_DFT = 4793: (0) two returns 1.5 resolution cells apart (they interfere between native delay samples) at
    20 dB per sample; (1, 2) two equal noiseless returns on grid cells (q, p) = (4700, 200) and (60, 800) whose
    powers differ by 1e-6, either one stronger; (3) a return at -15 dB per sample (≈ +30 dB after
    integration); (4) noise only; (5) all zeros (every cell ties at 0)."""
    return _hard_table1_beams


@pytest.fixture(scope="session")
def glitch_beams():
    """``glitch_beams(rng) -> complex [2, 128, 600]`` (Table I's K, N): a tone in one chirp (an interference
    burst: flat in Doppler near its delay) and one ADC sample (a glitch: flat over the whole grid), each with
    receiver noise of power 1e-12."""
    return _glitch_beams


@pytest.fixture(scope="session")
def make_radar():
    """``make_radar(**kw) -> RadarConfig``: Table I radar with N = 128 samples and K = 16 chirps unless overridden."""
    return _make_radar


@pytest.fixture(scope="session")
def make_processing():
    """``make_processing(radar=None, **kw) -> ProcessingConfig``: N_DFT = 2N - 1 (as the paper) and
    K_DFT = 4K for ``radar`` (default: ``make_radar()``) unless overridden."""
    return _make_processing


@pytest.fixture(scope="session")
def paper_sweep():
    """``paper_sweep() -> BeamSweep``: -45° … 45° in 1.5° steps, elevation 0 (61 beams), as in the paper."""
    return _paper_sweep


@pytest.fixture(scope="session")
def make_ris():
    """``make_ris(*, mode="relay", position=(0, PAPER_DISTANCE, 0), facing=(0, 0, 0), yaw=0.0,
    rx_toward=(0, 0, 0), **kw) -> RisConfig``: RIS at ``position`` facing ``facing`` turned by ``yaw``
    [rad], relay Rx beam toward ``rx_toward``; ``kw`` go to :class:`RisConfig`."""
    return _make_ris


@pytest.fixture(scope="session")
def make_scenario():
    """``make_scenario(*, radar=None, processing=None, mode="relay", yaw=0.0, ue_position=(0, 0, 0),
    ris_position=(0, PAPER_DISTANCE, 0), ris_facing=None, structure=True, sweep=None, ris_kw=None, **kw)
    -> Scenario``: paper-like scenario on the small radar (``make_radar()``, ``make_processing(radar)``,
    ``paper_sweep()`` by default): UE, RIS facing it (or ``ris_facing``) turned by ``yaw`` [rad], relay Rx
    beam on the UE.

    ``structure`` adds the RIS panel's structural reflection (σ = 19 m² at the RIS centre), as
    :func:`paper_scenario` does; ``kw`` go to :class:`Scenario`.
    """
    return _make_scenario


@pytest.fixture(scope="session")
def tone_paths():
    """``tone_paths(gain, delay, delay_rate, *, label="target") -> PathSet``: non-RIS paths (NaN RIS
    angles) with the given gains [√W], delays [s] and rates [s/s]."""
    return _tone_paths


@pytest.fixture(scope="session")
def delay_step():
    """``delay_step(radar, processing) -> float``: spacing of the delay grid, max_delay / N_DFT [s]."""
    return _delay_step


@functools.lru_cache(maxsize=None)
def _paper_run(case: str, mode: str) -> tuple[Scenario, Any]:
    scenario = paper_scenario(case, mode=mode)
    capture = simulate(scenario, rng=np.random.default_rng(0), noise=False)
    return scenario, capture


@pytest.fixture(scope="session")
def paper_run():
    """``paper_run(case, mode) -> (scenario, noiseless capture)`` for Table I, computed once."""
    return _paper_run


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh, seeded Generator per test."""
    return np.random.default_rng(20240607)


#: An 8 m × 6 m × 3 m concrete box with a 16×4 relay RIS and one radar: the smallest hall that traces
#: in well under a second (floor maps, the CLI's device tests).
TINY_HALL_SPEC = """
[scene]
name = "tiny_box"
description = "8 m x 6 m x 3 m concrete box with a 16x4 relay RIS"
frequency = 60e9
[hall]
size = [8.0, 6.0]
height = 3.0
wall_thickness = 0.2
[hall.materials]
walls = { itu = "concrete", thickness = 0.2 }
floor = { itu = "concrete", thickness = 0.2 }
ceiling = { itu = "concrete", thickness = 0.2 }
[[ris]]
name = "ris0"
position = [7.0, 3.0, 1.2]
facing = [1.0, 3.0, 1.2]
rows = 16
columns = 4
spacing = "half-wavelength"
amplification_db = 45.532
loopback_delay = 1.78e-9
mode = "relay"
panel = { width = 0.10, height = 0.05, material = "metal" }
[radar]
positions = [[2.0, 3.0, 1.2]]
facing = "ris0"
"""


@pytest.fixture(scope="session")
def tiny_hall_spec() -> str:
    """The TOML spec of :data:`TINY_HALL_SPEC` (write it to a ``spec.toml`` and ``risloc scene build`` it)."""
    return TINY_HALL_SPEC


def _detect_with_candidates(cubes: Any, prep: Any, backend: Any, options: dict, monkeypatch: Any) -> tuple:
    """``dsp.detect_batch`` on ``backend`` (the host cubes copied there explicitly) and the candidates it
    handed to the sweep-modulation test: (detections, candidate cells [B, 5], their statistics [B, 5])."""
    import dsp
    from dsp import detection

    seen = []
    original = detection._candidates

    def spy(*args: Any, **kwargs: Any) -> Any:
        out = original(*args, **kwargs)
        seen.append(out)
        return out

    monkeypatch.setattr(detection, "_candidates", spy)
    try:
        dets = dsp.detect_batch(backend.asarray(cubes), prep.radar, backend=backend, **options)
    finally:
        monkeypatch.setattr(detection, "_candidates", original)
    assert len(seen) == 1
    cells, stats, _values = seen[0]
    return dets, cells, stats


@pytest.fixture(scope="session")
def detect_with_candidates():
    """``detect_with_candidates(cubes, prep, backend, options, monkeypatch)``: see :func:`_detect_with_candidates`."""
    return _detect_with_candidates


def _impulse_screen_matches_host(cube: np.ndarray, noise_power: float, backend: Any) -> None:
    """Two 1e3·σ glitches (beam 7 chirp 1 sample 2, beam 50 chirp 127 sample 599) put in a copy of ``cube``
    [M ≥ 51, 128, 600]; ``dsp.impulses.screen_impulses`` on ``backend`` finds the host's samples, its largest
    excess to 1e-12 and zeroes the same samples."""
    from dsp.impulses import screen_impulses

    cube = cube.copy()
    cube[7, 1, 2] = cube[50, 127, 599] = 1e3 * np.sqrt(noise_power)
    host_out, host = screen_impulses(cube)
    dev_out, dev = screen_impulses(backend.asarray(cube))
    np.testing.assert_array_equal(dev.samples, host.samples)
    assert host.count == 2 and dev.largest_db == pytest.approx(host.largest_db, rel=1e-12)
    np.testing.assert_array_equal(backend.to_host(dev_out), host_out)


@pytest.fixture(scope="session")
def impulse_screen_matches_host():
    """``impulse_screen_matches_host(cube, noise_power, backend)``: see :func:`_impulse_screen_matches_host`."""
    return _impulse_screen_matches_host
