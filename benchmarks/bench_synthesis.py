"""Beat-cube synthesis: time per Table I cube, new against the original implementation.

Table I (M = 61 beams, K = 128 chirps, N = 600 samples) for the paper's analytic scenario and for
48 paths like the ray-traced paper hall's (33 RIS loop-backs and 15 echoes at 3-20 m; built
without ray tracing), with the radar at rest (every ν = 0) and moving (every path its own ν, as
a frozen ``PathSet``, and per frame as a ``PathFrames``, ``docs/moving-radar.md``). It reports
the best of ``--repeat`` timings of :func:`risloc_rt.model.beat.beat_cube` (fresh output, and
into a reused ``out=``) and of the original ``beat_reference.beat_cube_reference``, their
ratio, and the largest difference between the two cubes relative to Σ_l |γ_l r_{m,l}|; then the
receiver noise (``add_noise``, 2·M·K·N normals), which the new code only rearranges.

    .venv/bin/python benchmarks/bench_synthesis.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from dsp import SPEED_OF_LIGHT
from risloc_rt.model.beat import add_noise, beat_cube
from risloc_rt.model.beat_reference import beat_cube_reference
from risloc_rt.model.motion import advance_paths
from risloc_rt.model.paths import PathFrames, PathSet
from risloc_rt.model.ris import ris_response
from risloc_rt.model.scenario import analytic_paths, paper_scenario


def hall_like_paths(rng: np.random.Generator, *, moving: bool) -> PathSet:
    """48 paths with the paper hall's make-up and realistic delays and gains."""
    n, n_ris = 48, 33
    tau = 2 * np.r_[rng.uniform(13.3, 16.0, n_ris), rng.uniform(3.0, 20.0, n - n_ris)] / SPEED_OF_LIGHT
    gain = np.exp(2j * np.pi * rng.random(n)) * 10 ** rng.uniform(-7.5, -4.5, n)
    angles = np.full((n, 2), np.nan)
    angles[:n_ris] = np.deg2rad(np.c_[rng.normal(21.0, 8.0, n_ris), rng.normal(0.0, 5.0, n_ris)])
    nu = rng.uniform(-2, 2, n) * 2 * 1.0 / SPEED_OF_LIGHT if moving else np.zeros(n)  # up to ±2 m/s
    return PathSet(gain=gain, delay=tau, delay_rate=nu, ris_incidence=angles, ris_departure=angles,
                   labels=("hall",) * n)


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def rel_error(new, old, paths: PathSet, scenario) -> float:
    amp = np.tile(np.abs(paths.gain), (scenario.sweep.num_beams, 1))
    via = paths.via_ris
    if via.any():
        amp[:, via] *= np.abs(ris_response(scenario.ris, scenario.sweep, paths.ris_incidence[via],
                                           paths.ris_departure[via], wavelength=scenario.radar.wavelength))
    return float((np.abs(new - old) / amp.sum(axis=1)[:, None, None]).max())


def run(repeat: int) -> None:
    scenario = paper_scenario("off-broadside")
    radar, sweep, ris = scenario.radar, scenario.sweep, scenario.ris
    rng = np.random.default_rng(0)
    cases = [("analytic, at rest", analytic_paths(scenario)),
             ("48 hall paths, at rest", hall_like_paths(rng, moving=False)),
             ("48 hall paths, moving (frozen)", hall_like_paths(rng, moving=True))]
    print(f"risloc-rt synthesis benchmark: Table I cube [{sweep.num_beams}, {radar.num_chirps}, {radar.num_samples}], "
          f"best of {repeat}; {platform.processor() or platform.machine()}, numpy {np.__version__}")
    header = (f"{'paths':<32} {'L':>3} {'old [s]':>8} {'new [s]':>8} {'new, out= [s]':>13} {'speed-up':>8} "
              f"{'max |ΔY|/Σ|γr|':>15}")
    print(header)
    print("-" * len(header))
    out = np.empty((sweep.num_beams, radar.num_chirps, radar.num_samples), complex)
    for name, paths in cases:
        old = beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris)
        new = beat_cube(paths, radar=radar, sweep=sweep, ris=ris)
        t_old = best(lambda: beat_cube_reference(paths, radar=radar, sweep=sweep, ris=ris), repeat)
        t_new = best(lambda: beat_cube(paths, radar=radar, sweep=sweep, ris=ris), repeat)
        t_out = best(lambda: beat_cube(paths, radar=radar, sweep=sweep, ris=ris, out=out), repeat)
        print(f"{name:<32} {len(paths):>3} {t_old:>8.3f} {t_new:>8.3f} {t_out:>13.3f} {t_old / t_new:>7.1f}x "
              f"{rel_error(new, old, paths, scenario):>15.1e}")
    moving = advance_paths(cases[2][1], radar=radar, num_beams=sweep.num_beams)
    assert isinstance(moving, PathFrames)
    t_fr = best(lambda: beat_cube(moving, radar=radar, sweep=sweep, ris=ris), repeat)
    print(f"{'48 hall paths, moving per frame':<32} {len(moving):>3} {'-':>8} {t_fr:>8.3f} {'':>13} {'':>8} "
          f"{'(no reference)':>15}")
    cube = np.zeros_like(out)

    def old_noise() -> np.ndarray:
        n = np.random.default_rng(1).standard_normal(cube.shape + (2,))
        return cube + np.sqrt(radar.noise_power / 2) * (n[..., 0] + 1j * n[..., 1])

    t_old = best(old_noise, repeat)
    t_new = best(lambda: add_noise(cube, radar.noise_power, np.random.default_rng(1)), repeat)
    t_in = best(lambda: add_noise(out, radar.noise_power, np.random.default_rng(1), out=out), repeat)
    same = np.array_equal(old_noise(), add_noise(cube, radar.noise_power, np.random.default_rng(1)))
    print(f"{'receiver noise (add_noise)':<32} {'':>3} {t_old:>8.3f} {t_new:>8.3f} {t_in:>13.3f} "
          f"{t_old / t_new:>7.1f}x {'same: ' + str(same):>15}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    run(args.repeat)


if __name__ == "__main__":
    main()
