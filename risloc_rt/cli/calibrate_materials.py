"""``risloc calibrate CAPTURE... --scene HALL --materials NAME,... --out DIR``: the hall's materials from captures.

Each capture (at its known radar position: ``--ue`` or its truth; with its ``--calibration`` if
given) is compared with the traced hall; its explained static peaks become the fit's observation
(captures from the same position with the same calibration are repeats: their sweep means are
averaged into one observation, :func:`repeat_groups`),
read from the complex mean over the sweep's beams (``--peak-profile sweep-mean``, the default:
:mod:`risloc_rt.measured.compare.sweep_mean_peaks`) or from the comparison's best beam
(``best-beam``: :mod:`risloc_rt.measured.compare.material_peaks`); the named materials' ε_r and σ [S/m] are fitted
by Levenberg–Marquardt through the ray tracer's exact derivatives
(:func:`risloc_rt.hall.material_fit.fit_materials`, progress per iteration on stderr). Printed: a
table per material (ε_r ± 1σ, σ ± 1σ [S/m]), the correlation matrix and the identifiability
report. A material that is not identifiable is never written as a number: the report names the
reason and no scene is written (exit 2); so is a fit that ends at the edge of what the tracer accepts
(ε_r = 1, σ at :data:`SIGMA_RANGE`'s ends), where the Fisher 1σ means nothing, and one whose 1σ the
profile check calls weak (the cost does not rise by ½ over ±1σ or by 2 over ±2σ: a local figure; on emulated
recordings such 1σ covered 12–45 % of the errors) unless ``--allow-weak``. A weak parameter, and every free one
correlated with it (|ρ| ≥ :data:`PROFILE_CORRELATION`), gets its profile-likelihood interval
(:func:`risloc_rt.hall.material_profile.profile_interval`: the parameter held at a grid of values, the others
fitted again at each), printed at 68.3 and 95.4 % and quoted in the refusal; with ``--allow-weak`` the scene gets the
lowest χ² found (a profile that finds a lower one than the fit moves it there) and ``material-fit.json`` its
intervals (``profile_intervals``, open ends null). Otherwise the fitted scene folder is written atomically
(:func:`risloc_rt.authoring.fitted_scene.write_fitted_scene`) with ``material-fit.json``.

``--scattering NAME,...`` (a subset of ``--materials``): each such material's scattering coefficient S
[unitless] is stated by its **profile likelihood over the full simulator**
(:func:`risloc_rt.cli.calibrate_scattering.scattering_profiles`): at every S of its grid a scene folder with that S is built in a temporary folder, the
captures' peaks are read against it as for the fit (the beat model of every traced path: the diffuse
returns of the scattering surfaces, range folding, the IF filter and G), and the other parameters are
fitted again; each peak's residual over S is smoothed and what the smooth curve leaves (the
simulator's own noise: its diffuse paths are sampled anew for every S) is added to the peak's σ. Why not through the material tracer's ∂a/∂S
(:func:`~risloc_rt.hall.material_fit.fit_materials` ``scattering=``, exact for the specular loss): the
diffuse returns a scattering surface sends into a peak's range cell are not in that model, and measured
on emulated recordings they moved S by more than its σ (a folded floor return masked a wall's loss
entirely; a wall's own diffuse returns near its echo added 0.17 dB; without a calibration, G absorbs
the diffuse power). The scene gets each profile's best S, material-fit.json the profile
(``profile_intervals["NAME:S"]``).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from .common import CliError, trace_cache, trace_settings, vector

__all__ = ["run_materials", "material_names", "peak_profile", "repeat_groups", "SIGMA_RANGE", "PEAK_PROFILES",
           "DEFAULT_PEAK_PROFILE", "REPEAT_TOLERANCE", "PROFILE_CORRELATION"]

#: Where the static peaks are read: the complex mean over the sweep's beams, or the comparison's best beam.
PEAK_PROFILES: tuple[str, ...] = ("sweep-mean", "best-beam")
#: The default (``docs/calibration-materials.md``, "Measured": more static peaks, each with a smaller σ).
DEFAULT_PEAK_PROFILE: str = "sweep-mean"

#: A free parameter correlated with a weak one at least this much (|ρ|) gets its profile interval too: its Fisher 1σ
#: assumes the weak one's likelihood is quadratic.
PROFILE_CORRELATION: float = 0.5


#: The conductivities the fit can reach [S/m] (ln σ within the engine's bounds, -40..20): a fitted σ at either end
#: is refused, as is ε_r at its bound 1.
SIGMA_RANGE: tuple[float, float] = (math.exp(-40.0) * 1.001, math.exp(20.0) / 1.001)


def material_names(text: str) -> list[str]:
    """The ``--materials`` list: comma-separated, non-empty, no repeats.

    Parameters
    ----------
    text : str
        The flag's value, e.g. ``concrete-200mm,glass-6mm``.

    Returns
    -------
    list of str
        The names.

    Raises
    ------
    CliError
        An empty name or a repeated one.
    """
    names = [n.strip() for n in text.split(",")]
    if not all(names):
        raise CliError(f"--materials {text!r}: give comma-separated material names, e.g. concrete-200mm,glass-6mm")
    if len(set(names)) != len(names):
        raise CliError(f"--materials {text!r} names a material twice")
    return names


def peak_profile(args: argparse.Namespace) -> str:
    """The ``--peak-profile`` asked for (``sweep-mean`` when the parser has no such flag).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line; ``peak_profile`` is read if present.

    Returns
    -------
    str
        One of :data:`PEAK_PROFILES`.

    Raises
    ------
    CliError
        Any other value.
    """
    value = getattr(args, "peak_profile", None) or DEFAULT_PEAK_PROFILE
    if value not in PEAK_PROFILES:
        raise CliError(f"--peak-profile {value!r}: give one of {', '.join(PEAK_PROFILES)}")
    return value


def _per_capture(values: list[str] | None, n: int, flag: str) -> list[str | None]:
    """``values`` of a repeated flag as one entry per capture (none, one for all, or one each)."""
    if not values:
        return [None] * n
    if len(values) == 1:
        return values * n
    if len(values) != n:
        raise CliError(f"{flag} is given {len(values)} times for {n} captures: give it once for all or once per capture")
    return list(values)


#: Captures whose radar positions lie within this of each other [m] (and share a calibration) are repeats of one
#: position: their sweep means are averaged (``docs/calibration-materials.md``, "Repeats").
REPEAT_TOLERANCE: float = 1e-3


def repeat_groups(keys: list[tuple[Any, str | None]]) -> list[list[int]]:
    """Which captures are repeats of one radar position: groups of indices, in the captures' order.

    Parameters
    ----------
    keys : list of (array [3], str or None)
        Per capture its radar position [m] and its calibration file (None: none).

    Returns
    -------
    list of list of int
        Each group's indices, the first capture of the group first; captures join the first group whose
        position is within :data:`REPEAT_TOLERANCE` of theirs and whose calibration is theirs.
    """
    groups: list[list[int]] = []
    for i, (ue, cal) in enumerate(keys):
        for g in groups:
            ue0, cal0 = keys[g[0]]
            if cal == cal0 and float(np.max(np.abs(np.asarray(ue, float) - np.asarray(ue0, float)))) <= REPEAT_TOLERANCE:
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def _observations(args: argparse.Namespace, scene: Path, names: list[str]) -> tuple[list[Any], list[dict[str, Any]]]:
    """Every radar position's observation (repeats averaged, :func:`repeat_groups`), and its provenance record
    (path, sha256, its repeats', radar position, peaks)."""
    from dataclasses import replace

    from .._files import file_sha256
    from ..io.capture_file import load_capture
    from ..measured.compare.calibration_file import read_calibration
    from ..measured.compare.material_peaks import capture_observation
    from ..measured.compare.sweep_mean_peaks import sweep_mean_observation
    from ..measured.compare.traced_hall import hall_model, ue_position_of

    if args.ue is not None and len(args.ue) not in (len(args.capture),):
        raise CliError(f"--ue is given {len(args.ue)} times for {len(args.capture)} captures: give it once per capture "
                       "(in their order) or not at all (each capture's truth)")
    ues = _per_capture(args.ue, len(args.capture), "--ue")
    cals = _per_capture(args.calibration, len(args.capture), "--calibration")
    settings = trace_settings(args)
    mean = peak_profile(args) == "sweep-mean"
    loaded = []
    for path, ue_text, cal_path in zip(args.capture, ues, cals):
        capture = load_capture(path)
        ue, source = ue_position_of(capture, None if ue_text is None else vector(ue_text, "--ue"))
        loaded.append((path, capture, ue, source, cal_path))
    observations, records = [], []
    for group in repeat_groups([(x[2], x[4]) for x in loaded]) if mean else [[i] for i in range(len(loaded))]:
        path, capture, ue, source, cal_path = loaded[group[0]]
        repeats = [loaded[i] for i in group[1:]]
        cal = None if cal_path is None else read_calibration(cal_path)
        ris = None if cal is None else replace(capture.ris, loopback_delay=cal.loopback_delay,
                                               amplification_db=cal.amplification_db)
        model = hall_model(capture, scene, ue, ue_source=source, ris=ris, trace=settings, cache=trace_cache(args))
        common = dict(calibration=cal, settings=settings, model_sigma_db=args.model_sigma,
                      prominence_db=args.peak_prominence, floor_db=args.peak_floor)
        if mean:
            peaks = sweep_mean_observation(capture, model, names, repeats=[r[1] for r in repeats], **common)
        else:
            peaks = capture_observation(capture, model, names, **common)
        res = [u["power_residual_db"] for u in peaks.used if "power_residual_db" in u]
        rms = float(np.sqrt(np.mean(np.square(res)))) if res else peaks.comparison.summary["power_residual_rms_db"]
        also = (f" and {len(repeats)} repeat(s) at the same position ({', '.join(str(r[0]) for r in repeats)}: the "
                f"sweep means of {len(group)} captures averaged)") if repeats else ""
        print(f"{path}{also}: radar at {[round(float(x), 3) for x in ue]} m ({source}); {len(peaks.used)} peak(s) used "
              f"({peak_profile(args)}), {len(peaks.left_out)} left out; power residual rms at the scene's materials "
              f"{_fmt(rms)} dB")
        for u in peaks.used:
            print(f"  used {u['distance_m']:.3f} m: {u['label']}, SNR {u['snr_db']:.1f} dB, sigma {u['sigma_db']:.2f} dB")
        for d, why in peaks.left_out:
            print(f"  left out {d:.3f} m: {why}")
        observations.append(peaks.observation)
        records.append({"capture": str(path), "sha256": file_sha256(path),
                        "repeats": [{"capture": str(r[0]), "sha256": file_sha256(r[0])} for r in repeats],
                        "radar_position_m": [float(x) for x in ue],
                        "radar_position_source": source, "calibration": cal_path,
                        "calibration_sha256": None if cal_path is None else file_sha256(cal_path),
                        "peaks": [dict(p) for p in peaks.used],
                        "left_out": [{"distance_m": d, "reason": r} for d, r in peaks.left_out]})
    return observations, records


def _fmt(x: Any) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def _print_fit(fit: Any, s_profiles: dict[str, Any] | None = None) -> None:
    """The table per material (and each fitted S), the correlation matrix and the identifiability report, on stdout."""
    flagged = fit.identifiability.not_identifiable
    print(f"{'material':24s} {'eps_r':>10s} {'1 sigma':>9s} {'sigma [S/m]':>12s} {'1 sigma':>9s}  (start eps_r, sigma)")
    for q, m in enumerate(fit.materials):
        start = fit.start[m]
        if any(p.startswith(m + ":") for p in flagged):
            print(f"{m:24s} {'not identifiable (see the report below)':>43s}  ({start[0]:.4g}, {start[1]:.4g})")
            continue
        eps, sig, d_eps, d_sig = fit.value(m)
        held = fit.identifiability.fixed
        e_txt = "     held" if f"{m}:eps_r" in held else f"{d_eps:9.4f}"
        s_txt = "     held" if f"{m}:ln_sigma" in held else f"{d_sig:9.4f}"
        print(f"{m:24s} {eps:10.4f} {e_txt} {sig:12.4f} {s_txt}  ({start[0]:.4g}, {start[1]:.4g})")
    for key, prof in (s_profiles or {}).items():
        print(f"{key.rpartition(':')[0]:24s} S {prof.best_physical:.4f} (its profile over the full simulator, conditional "
              f"on the others: {prof.span(1)} at 68.3 %, {prof.span(2)} at 95.4 %)")
    params = fit.identifiability.parameters
    print("correlation (eps_r, ln sigma per material" + ("; at the scattering coefficients above" if s_profiles else "")
          + "):")
    for i, p in enumerate(params):
        print(f"  {p:36s} " + " ".join("     nan" if not math.isfinite(c) else f"{c:+8.3f}" for c in fit.correlation[i]))
    dof = len(fit.residuals_db) - len(params) + len(fit.identifiability.fixed)
    print(f"{len(fit.residuals_db)} peak(s); power residual rms {fit.rms_start_db:.3f} dB at the start -> "
          f"{fit.rms_db:.3f} dB; chi2 {fit.chi2:.3g} for {dof} degree(s) of freedom; {fit.iterations} iteration(s), "
          f"{fit.evaluations} evaluation(s), {fit.seconds:.1f} s" + ("" if fit.converged else "; NOT converged"))
    print("identifiability: " + fit.identifiability.summary().replace("\n", "\n  "))


def _profile_intervals(scene: Path, observations: list, fit: Any, weak: dict[str, str],
                       args: argparse.Namespace) -> dict[str, Any]:
    """Profile-likelihood intervals of every weak parameter and of every free one correlated with it (|ρ| ≥
    :data:`PROFILE_CORRELATION`), progress on stderr, the 68.3 and 95.4 % intervals printed; ``{}`` when none is weak."""
    from ..hall.material_profile import profile_interval

    rep = fit.identifiability
    params = rep.parameters
    chosen = [p for p in params if p in weak]
    for p in params:
        if p in chosen or p in rep.fixed or p in rep.not_identifiable:
            continue
        i = params.index(p)
        if any(abs(fit.correlation[i, params.index(w)]) >= PROFILE_CORRELATION for w in weak):
            chosen.append(p)
    out = {}
    if chosen:
        print("the 1-sigma of " + ", ".join(_shown(p) for p in chosen) + " in the table above is a "
              "local figure (weak, or correlated with a weak parameter); their profile likelihoods follow")
    for p in chosen:
        def progress(value: float, delta: float, p: str = p) -> None:
            unit = " S/m" if p.endswith(":ln_sigma") else ""
            print(f"  profile of {_shown(p)}: {value:.4g}{unit}, chi2 - chi2(fit) = {delta:.4g}",
                  file=sys.stderr, flush=True)

        out[p] = profile_interval(scene, observations, fit, p, settings=trace_settings(args), progress=progress)
        print(f"profile likelihood: {out[p].describe(1)}; 95.4 %: {out[p].span(2)}; 99.7 %: {out[p].span(3)} "
              f"({out[p].grid.size} points, {out[p].evaluations} evaluations, {out[p].seconds:.1f} s)")
    return out


def _scattering_names(text: str | None, names: list[str]) -> list[str]:
    """The ``--scattering`` list: names among ``--materials``, no repeats (empty without the flag)."""
    if text is None:
        return []
    rough = [n.strip() for n in text.split(",")]
    if not all(rough) or len(set(rough)) != len(rough):
        raise CliError(f"--scattering {text!r}: give comma-separated material names, each once, e.g. concrete-200mm")
    unknown = [n for n in rough if n not in names]
    if unknown:
        raise CliError(f"--scattering names {', '.join(unknown)}, not among --materials ({', '.join(names)}): fit a "
                       "material's eps_r and sigma to fit its S")
    return rough


def _shown(parameter: str) -> str:
    """A parameter as the command line names it: ``m:sigma`` for ``m:ln_sigma``, ``m:S`` for ``m:scattering``."""
    m, _, kind = parameter.rpartition(":")
    return f"{m}:{ {'ln_sigma': 'sigma', 'scattering': 'S'}.get(kind, kind)}"


def _provenance(args: argparse.Namespace, scene: Path, fit: Any, records: list[dict[str, Any]],
                profiles: dict[str, Any] | None = None, written: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``material-fit.json`` document."""
    from .._version import __version__

    rep = fit.identifiability
    profiles = profiles or {}
    return {
        "format": "risloc-material-fit", "version": 1, "risloc_rt_version": __version__,
        "source_scene": str(scene), "captures": records,
        "trace": {k: getattr(trace_settings(args), k) for k in ("max_depth", "samples_per_src")},
        "peak_profile": peak_profile(args),
        "units": "eps_r unitless, sigma S/m, scattering coefficient S and share S^2 unitless, powers and residuals dB, "
                 "positions m, delays s",
        "materials": {m: {"eps_r": float(fit.relative_permittivity[q]), "eps_r_sigma": float(fit.relative_permittivity_sigma[q]),
                          "sigma_s_per_m": float(fit.conductivity[q]), "sigma_sigma_s_per_m": float(fit.conductivity_sigma[q]),
                          "ln_sigma_sigma": float(fit.log_conductivity_sigma[q]), "start": list(fit.start[m])}
                      for q, m in enumerate(fit.materials)},
        "scattering": [p.rpartition(":")[0] for p in profiles if p.endswith(":scattering")],
        "fixed": list(rep.fixed), "parameters": list(rep.parameters), "correlation": np.asarray(fit.correlation).tolist(),
        "iterations": fit.iterations, "evaluations": fit.evaluations, "converged": fit.converged,
        "chi2": fit.chi2, "degrees_of_freedom": len(fit.residuals_db) - len(rep.parameters) + len(rep.fixed),
        "power_residual_rms_start_db": fit.rms_start_db, "power_residual_rms_db": fit.rms_db, "seconds": fit.seconds,
        "identifiability": {"condition": rep.condition, "singular_values": np.asarray(rep.singular_values).tolist(),
                            "not_identifiable": dict(rep.not_identifiable), "weak": dict(rep.weak),
                            "profile_cost": {k: list(v) for k, v in rep.profile_cost.items()},
                            "profile_cost_2sigma": {k: list(v) for k, v in rep.profile_cost_2sigma.items()},
                            "peaks_per_material": {m: int(np.asarray(rep.constrains)[:, q].sum())
                                                   for q, m in enumerate(fit.materials)}},
        "profile_intervals": {
            _shown(p): {
                "unit": "S/m" if p.endswith(":ln_sigma") else "unitless", "best": prof.best_physical,
                **{f"interval_{n}sigma": [_json_number(x) for x in prof.physical(n)] for n in prof.intervals},
                "grid": [float(c) for c in prof.grid_physical],
                "delta_chi2": [float(d) for d in prof.delta_chi2], "moved": prof.moved,
                "evaluations": prof.evaluations, "seconds": prof.seconds}
            for p, prof in profiles.items()},
        "written": {m: list(v) for m, v in (written or {}).items()},
    }


def _json_number(x: float) -> float | None:
    """A float for JSON: an open interval end (inf) is null."""
    return float(x) if math.isfinite(x) else None


def run_materials(args: argparse.Namespace) -> int:
    """``risloc calibrate --materials``: fit, print the table/correlations/report, write the fitted scene folder.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (CAPTURE..., --scene, --materials, --out, --force, --ue [m] per capture,
        --calibration, --fixed, --max-iter, --model-sigma [dB], --peak-prominence/--peak-floor [dB], trace flags).

    Returns
    -------
    int
        0 when the scene folder is written; a bad input or a material that is not identifiable raises
        ``CliError`` (exit 2, nothing written).
    """
    import tempfile

    from ..authoring.fitted_scene import check_fitted_target
    from ..authoring.scene_folder import scene_directory
    from ..hall.material_fit import fit_materials
    from .calibrate_scattering import scattering_profiles

    if args.output is not None:
        raise CliError("-o writes a radar/RIS calibration file; a material fit writes a scene folder: give --out DIR "
                       "instead of -o")
    if args.out is None:
        raise CliError("--materials needs --out DIR, the new scene folder to write the fitted hall to")
    if isinstance(args.max_iter, bool) or args.max_iter < 1:
        raise CliError(f"--max-iter {args.max_iter} must be >= 1")
    if not (math.isfinite(args.model_sigma) and args.model_sigma >= 0):
        raise CliError(f"--model-sigma {args.model_sigma} must be a finite number >= 0 [dB]")
    names = material_names(args.materials)
    rough = _scattering_names(getattr(args, "scattering", None), names)
    if rough and getattr(args, "diffuse", None) is not None:
        raise CliError(f"--diffuse {args.diffuse:g} gives every material one scattering coefficient, so --scattering "
                       "cannot fit one per material: leave --diffuse out (a scene whose materials scatter is traced "
                       "with diffuse reflection anyway)")
    held = {str(f) for f in args.fixed}
    if not rough and all(f"{m}:{k}" in held for m in names for k in ("eps_r", "sigma")):
        raise CliError("every parameter is held with --fixed: nothing is left to fit (free one, or fit a scattering "
                       "coefficient with --scattering NAME)")
    scene = scene_directory(args.scene)
    out = check_fitted_target(args.out, force=args.force)
    observations, records = _observations(args, scene, names)

    def progress(iteration: int, cost: float) -> None:
        print(f"  iteration {iteration}: chi2/2 = {cost:.5g}", file=sys.stderr, flush=True)

    fit = fit_materials(scene, observations, names, settings=trace_settings(args), max_iter=args.max_iter,
                        progress=progress, fixed=args.fixed)
    with tempfile.TemporaryDirectory(prefix=".risloc-scattering-") as tmp:
        fit_scene, s_profiles, notes = scene, {}, {}
        if rough:
            fit, observations, records, fit_scene, s_profiles, notes = scattering_profiles(
                args, scene, names, rough, fit, Path(tmp), progress, _observations)
        _write_fit(args, scene, fit_scene, out, fit, observations, records, s_profiles, notes)
    return 0


def _write_fit(args: argparse.Namespace, scene: Path, fit_scene: Path, out: Path, fit: Any, observations: list,
               records: list[dict[str, Any]], s_profiles: dict[str, Any], notes: dict[str, Any]) -> None:
    """Print the fit, refuse what it cannot state (flagged, at the tracer's edge, weak without --allow-weak), write."""
    from ..authoring.fitted_scene import write_fitted_scene

    _print_fit(fit, s_profiles)
    flagged = fit.identifiability.not_identifiable
    if flagged:
        first = next(iter(flagged.values())).split(": e.g.")[0]
        raise CliError(f"no scene written: {', '.join(flagged)} not identifiable from these peaks ({first}); hold one "
                       "with --fixed NAME:eps_r, add radar positions that see the material at other angles, or fit "
                       "fewer materials")
    values: dict[str, tuple[float, ...]] = {m: fit.value(m)[:2] for m in fit.materials}
    held = fit.identifiability.fixed
    at_bound = [f"{m}:eps_r = 1" for m, (eps, _) in values.items() if eps <= 1.0 and f"{m}:eps_r" not in held]
    at_bound += [f"{m}:sigma = {sig:.3g} S/m" for m, (_, sig) in values.items()
                 if not SIGMA_RANGE[0] < sig < SIGMA_RANGE[1] and f"{m}:ln_sigma" not in held]
    if at_bound:
        raise CliError(f"no scene written: the fit ran into the edge of what the ray tracer accepts ({', '.join(at_bound)}; "
                       "eps_r >= 1, sigma within 4e-18..5e8 S/m): the peaks do not hold it there, so its 1-sigma means "
                       "nothing; hold it with --fixed NAME:eps_r (or NAME:sigma), or add radar positions")
    weak = {p: r for p, r in fit.identifiability.weak.items() if p not in held}
    profiles = _profile_intervals(fit_scene, observations, fit, weak, args)
    if weak and not getattr(args, "allow_weak", False):
        names_weak = ", ".join(_shown(p) for p in weak)
        first = profiles[next(iter(weak))]
        raise CliError(f"no scene written: {names_weak}: {next(iter(weak.values()))}; what the peaks do say is its "
                       f"profile likelihood, {first.describe(1)}; 95.4 %: {first.span(2)} "
                       "(docs/calibration-materials.md): hold one parameter with --fixed NAME:sigma or NAME:eps_r, "
                       "add radar positions that see the material at other angles, or give --allow-weak to write the "
                       "profile's best value with material-fit.json stating these intervals")
    moved = [p for p in profiles.values() if p.moved]
    if moved:  # the fit had stopped in a local valley: the scene gets the lowest chi2 any profile found
        best = min(moved, key=lambda p: p.chi2_min)
        values = dict(best.values[int(np.argmin(best.delta_chi2))])
        print(f"the profile of {_shown(best.parameter)} found chi2 {best.chi2_min:.4g} < the fit's {fit.chi2:.4g}: written "
              "are its values, " + ", ".join(f"{m} ({v[0]:.4g}, {v[1]:.4g} S/m)" for m, v in values.items()))
    for key, prof in s_profiles.items():  # the scattering coefficients: each profile's best
        m = key.rpartition(":")[0]
        values[m] = (*values[m][:2], prof.best_physical)
    document = _provenance(args, scene, fit, records, {**s_profiles, **profiles}, values)
    document["scattering_profiles"] = notes
    write_fitted_scene(scene, out, values, document, force=args.force,
                       note="captures: " + ", ".join(Path(c).name for c in args.capture))
    print(f"wrote {out} (spec.toml, scene.xml, meshes/, material-fit.json): use it as --scene {out}")
