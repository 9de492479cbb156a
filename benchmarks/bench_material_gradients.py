"""Cost and accuracy of the material Jacobian (risloc_rt.hall.raytrace.material_gradients).

Part 1, cost: seconds per Jacobian (Q sionna-rt solves in evaluated loop mode, each with one
forward-mode derivative, ∂a/∂σ from the holomorphic identity; and 2·Q solves with ``sigma_by_identity=False``,
σ by a pass of its own, side by side) against the number of paths (ray-tracing depth) and of materials Q, on the
default hall (``scenes/paper_hall``, one material) and the L hall (``scenes/l_hall``, six), next to
the plain warm trace of :func:`risloc_rt.hall.raytrace.trace_scene` (symbolic loops, no
derivatives). Every Jacobian is timed warm (second call in the process; the first call of a
setting compiles) and its AD derivatives are checked against fourth-order central differences
of re-traced gains (ε_r ± h, ± 2h, and σ likewise, h = 0.01) for the first two materials:
``max |FD − AD| / |AD|`` over the paths that touch the material.

Part 2, mechanisms: the same check on a small hall with a glass pane (refraction through it), diffuse reflection (S = 0.3)
and diffraction on, by interaction type, and the holomorphic identity ∂a/∂σ = −j/(ε0 ω)·∂a/∂ε_r (checked on
Jacobians whose σ derivative is a pass of its own, ``sigma_by_identity=False``).

Part 3, other scenes alive: five Jacobians of the default hall alone, next to 1-4 other loaded halls, and after
releasing them; and the cost of loading the hall again for every Jacobian (why the tracer and the Jacobian keep
only their last loaded scene).

    .venv/bin/python benchmarks/bench_material_gradients.py [--quick] [--alive]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from risloc_rt.hall.raytrace.backend import backend_info
from risloc_rt.hall.raytrace.material_gradients import MaterialJacobian, material_jacobian
from risloc_rt.hall.raytrace.result import TraceSettings
from risloc_rt.hall.raytrace.tracer import trace_scene

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HALLS = {
    "paper_hall": ([6.0, 9.0, 1.2], ["concrete-200mm"]),
    "l_hall": ([4.511835789003062, 7.803140081152669, 1.2],
               ["concrete-200mm", "ceiling_board-20mm", "glass-6mm", "chipboard-20mm", "wood-30mm", "wood-50mm"]),
}
FREQUENCY = 60e9
EPSILON_0 = 8.8541878128e-12
STEP = 0.01


def _scene(name: str) -> str:
    return os.path.join(ROOT, "scenes", name)


def fd_errors(scene: str, position: list[float], jac: MaterialJacobian, material: str,
              settings: TraceSettings, h: float = STEP) -> dict[str, np.ndarray]:
    """Relative |FD − AD| / |AD| per path touching ``material``, for ε_r and σ.

    Parameters
    ----------
    scene : str
        Scene folder.
    position : list of float
        Radar position [m].
    jac : MaterialJacobian
        The AD result to check.
    material : str
        One of ``jac.materials``.
    settings : TraceSettings
        As used for ``jac``.
    h : float
        Step of the central differences (in ε_r units, and in S/m for σ).

    Returns
    -------
    dict
        ``{"eps": errors, "sigma": errors}``, float arrays over the touching paths (NaN where
        the re-traced path set differs), and ``eps_scaled``, ``sigma_scaled``: ``|FD − AD|``
        over the largest ``|AD|`` of the material's column.
    """
    q = jac.materials.index(material)
    eps, sigma = jac.relative_permittivity[q], jac.conductivity[q]
    seen = jac.touches[:, q]
    out = {}
    for kind, ad in (("eps", jac.d_eps[:, q]), ("sigma", jac.d_sigma[:, q])):
        gains = {}
        for t in (h, -h, 2 * h, -2 * h):
            value = (eps + t, sigma) if kind == "eps" else (eps, max(sigma + t, 0.0))
            moved = material_jacobian(scene, position, [material], values={material: value}, settings=settings)
            if not np.array_equal(moved.delay, jac.delay):
                out[kind] = np.full(int(seen.sum()), np.nan)
                break
            gains[t] = moved.a
        else:
            fd = (8 * (gains[h] - gains[-h]) - (gains[2 * h] - gains[-2 * h])) / (12 * h)
            out[kind] = np.abs(fd - ad)[seen] / np.abs(ad[seen])
            out[kind + "_scaled"] = np.abs(fd - ad)[seen] / np.abs(ad[seen]).max()
    return out


def _timed(fn, repeat: int = 2):
    best, value = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - t)
    return best, value


def part_cost(quick: bool) -> None:
    """Print the cost table (Part 1).

    Parameters
    ----------
    quick : bool
        Depths 1-2 only, and the FD check on the first material count only.
    """
    depths = (1, 2) if quick else (1, 2, 3, 4)
    print("\nPart 1: seconds per Jacobian (warm, best of 2) against paths P and materials Q; samples_per_src = 1e5")
    print(f"{'hall':<11}{'depth':>6}{'P':>6}{'Q':>4}{'seen':>5}{'trace [s]':>11}{'Jacobian [s]':>14}"
          f"{'per solve [s]':>15}{'2 passes [s]':>14}{'ratio':>7}{'FD/AD eps':>11}{'FD/AD sig':>11}")
    for hall, (position, materials) in HALLS.items():
        scene = _scene(hall)
        counts = sorted({1, min(3, len(materials)), len(materials)})
        for depth in depths:
            settings = TraceSettings(max_depth=depth, samples_per_src=100_000)
            material_jacobian(scene, position, materials[:1], settings=settings)  # compile
            t_trace, _ = _timed(lambda: trace_scene(os.path.join(scene, "scene.xml"), radar_position=position,
                                                    frequency=FREQUENCY, settings=settings))
            for count in counts:
                t_jac, jac = _timed(lambda: material_jacobian(scene, position, materials[:count], settings=settings))
                t_two, two = _timed(lambda: material_jacobian(scene, position, materials[:count], settings=settings,
                                                              sigma_by_identity=False))
                assert jac.sigma_by_identity and np.array_equal(jac.d_eps, two.d_eps)
                err = {"eps": [], "sigma": []}
                if count == counts[0] or count == counts[-1] and not quick:
                    for m in [m for m in jac.materials[:2] if m not in jac.unseen]:
                        for k, v in fd_errors(scene, position, jac, m, settings).items():
                            if k in err:
                                err[k].append(v)
                fmt = {k: (f"{np.max(np.concatenate(v)):.1e}" if v else "-") for k, v in err.items()}
                print(f"{hall:<11}{depth:>6}{len(jac.paths):>6}{count:>4}{int(jac.seen.sum()):>5}{t_trace:>11.3f}"
                      f"{t_jac:>14.3f}{t_jac / count:>15.3f}{t_two:>14.3f}{t_two / t_jac:>7.2f}{fmt['eps']:>11}"
                      f"{fmt['sigma']:>11}")


PANE_SPEC = """
[scene]
name = "gradient_pane"
frequency = 60e9

[hall]
size = [8.0, 6.0]
height = 3.0
wall_thickness = 0.2

[hall.materials]
walls = { itu = "concrete", thickness = 0.2 }
floor = { itu = "concrete", thickness = 0.2 }
ceiling = { itu = "wood", thickness = 0.03 }

[[objects]]
kind = "box"
name = "pane"
min = [5.0, 1.0, 0.5]
max = [5.02, 5.0, 2.5]
material = { itu = "glass", thickness = 0.006 }
"""


def part_mechanisms() -> None:
    """Print the AD/FD agreement by interaction type with refraction, diffuse, diffraction (Part 2).

    The hall: 8 m × 6 m × 3 m, concrete walls and floor, a 30 mm wood ceiling and a free-standing
    4 m × 2 m glass pane (two 6 mm slabs 2 cm apart) 2 m in front of the radar, built from
    :data:`PANE_SPEC` in a temporary folder.
    """
    import tempfile

    from risloc_rt.authoring import build_scene, loads_spec

    folder = tempfile.mkdtemp(prefix="bench_material_gradients_")
    build_scene(loads_spec(PANE_SPEC), folder)
    position, materials = [3.0, 2.5, 1.2], ["concrete-200mm", "glass-6mm"]
    scene = folder
    cases = {
        "refraction, depth 3": TraceSettings(max_depth=3, samples_per_src=100_000, refraction=True),
        "diffuse S=0.3, depth 1": TraceSettings(max_depth=1, samples_per_src=100_000, diffuse_reflection=True,
                                                scattering_coefficient=0.3),
        "diffraction, depth 1": TraceSettings(max_depth=1, samples_per_src=100_000, diffraction=True),
    }
    names = {1: "specular", 2: "diffuse", 4: "refraction", 8: "diffraction"}
    print("\nPart 2: AD against FD (h = 0.01) by interaction type, pane hall; relative error over touching paths "
          "(median / 95th percentile / max; 'scaled': max |FD − AD| / max |AD| of the material); 'holo' = max |∂a/∂σ + j/(ε0 ω)·∂a/∂ε_r| / max |∂a/∂σ|")
    print(f"{'case':<24}{'material':<20}{'type':<12}{'paths':>6}{'eps med/p95/max/scaled':>32}{'sigma med/p95/max/scaled':>32}"
          f"{'holo':>9}{'J [s]':>7}")
    for label, settings in cases.items():
        material_jacobian(scene, position, materials[:2], settings=settings, sigma_by_identity=False)
        t_jac, jac = _timed(lambda: material_jacobian(scene, position, materials[:2], settings=settings,
                                                      sigma_by_identity=False), repeat=1)
        factor = -1j / (EPSILON_0 * 2 * np.pi * jac.frequency)
        for m in jac.materials:
            q = jac.materials.index(m)
            if not jac.touches[:, q].any():
                print(f"{label:<24}{m:<20}{'(unseen)':<12}")
                continue
            err = fd_errors(scene, position, jac, m, settings)
            seen = jac.touches[:, q]
            for code, name in names.items():
                has = (jac.paths.interactions == code).any(axis=1)[seen]
                if not has.any():
                    continue
                sub = np.flatnonzero(seen)[has]
                holo = np.abs(jac.d_sigma[sub, q] - factor * jac.d_eps[sub, q]).max() / np.abs(jac.d_sigma[sub, q]).max()

                def stats(kind: str) -> str:
                    v = err[kind][has]
                    return f"{np.median(v):.1e}/{np.percentile(v, 95):.1e}/{v.max():.1e}/{err[kind + '_scaled'][has].max():.0e}"

                print(f"{label:<24}{m:<20}{name:<12}{int(has.sum()):>6}{stats('eps'):>32}{stats('sigma'):>32}"
                      f"{holo:>9.1e}{t_jac:>7.2f}")


def part_alive() -> None:
    """Print the cost of other loaded scenes, and of reloading the scene (Part 3)."""
    import gc

    import risloc_rt.hall.raytrace.material_gradients as gradients
    from risloc_rt.hall.raytrace.scene import load_scene

    settings = TraceSettings(max_depth=3, samples_per_src=20_000)
    position, materials = HALLS["paper_hall"]

    reference = material_jacobian(_scene("paper_hall"), position, materials, settings=settings)

    def five() -> str:
        t, jacs = _timed(lambda: [material_jacobian(_scene("paper_hall"), position, materials, settings=settings)
                                  for _ in range(5)])
        diff = max(float(np.max(np.abs(j.d_eps - reference.d_eps))) for j in jacs) / np.abs(reference.d_eps).max()
        return f"{t:.3f} s, largest |d_eps - alone's| / max |d_eps| {diff:.1e}"

    def reloaded() -> None:
        gradients._scenes.clear()
        gc.collect()
        material_jacobian(_scene("paper_hall"), position, materials, settings=settings)

    five()
    print("\nPart 3: 5 Jacobians of paper_hall (depth 3, 2e4 rays, best of 2) next to other loaded scenes")
    print(f"alone: {five()}")
    alive = []
    for name in ("l_hall", "l_hall_2ris", "pillars_hall", "l_hall"):
        alive.append(load_scene(os.path.join(_scene(name), "scene.xml"), frequency=FREQUENCY + len(alive)))
        print(f"with {len(alive)} other scene(s) loaded (last {name}): {five()}")
    alive.clear()
    gc.collect()
    print(f"after releasing them: {five()}")
    t_reload, _ = _timed(lambda: [reloaded() for _ in range(5)])
    print(f"the scene loaded again for every Jacobian: {t_reload:.3f} s")


def main() -> None:
    """Run both parts and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="depths 1-2 only, FD check on Q = 1 only, no Part 2")
    parser.add_argument("--alive", action="store_true", help="Part 3 only")
    args = parser.parse_args()
    info = backend_info()
    print(f"sionna-rt {info['sionna-rt']}, mitsuba {info['mitsuba']}, drjit {info['drjit']}, variant {info['variant']}, "
          f"LLVM {info['llvm_version']}, {os.cpu_count()} CPUs")
    t = time.perf_counter()
    material_jacobian(_scene("paper_hall"), HALLS["paper_hall"][0], ["concrete-200mm"],
                      settings=TraceSettings(max_depth=1, samples_per_src=100_000))
    print(f"first Jacobian in this process (import, load, compile): {time.perf_counter() - t:.2f} s")
    if args.alive:
        part_alive()
        return
    part_cost(args.quick)
    if not args.quick:
        part_mechanisms()
        part_alive()


if __name__ == "__main__":
    main()
