"""Ctrl-C at random moments of each long command (issue 19).

For each long command (``risloc study sweep``, ``risloc study map``, ``risloc scene build``,
``risloc simulate``, ``risloc demo --analytic``) the command is first run uninterrupted (the
reference; twice, the shorter wall time is the window and the two must be equal, which checks
the comparison itself). Then, at N moments drawn uniformly over that wall time (a seeded
``numpy.random.Generator``), the command is started as a program in its own process group and the
group gets SIGINT at that moment, as a terminal's Ctrl-C does. Each moment checks

* **exit 130**: the exit status is 130;
* **one line**: stderr is exactly one line, ``risloc ...: interrupted; ...``, no traceback;
* **intact**: nothing is written beside the output (in the command's working folder); every file
  that existed before is byte-identical or a complete new version equal to the reference (a study's ``runs.jsonl`` keeps its previous bytes and gains only whole rows, a
  subset of the reference rows; a scene folder is the previous build or the new one, byte for
  byte; a single output is absent or equal to the reference), no temporary file is left, and no
  process of the group is left running;
* **resume equal**: the same command run again, uninterrupted, gives the reference (run rows as
  a set; JSON, Parquet and ``.npz`` contents equal; time fields such as ``seconds`` and
  ``created``, and a sitting's ``devices``, ignored; everything else bit for bit).

Moments whose process had already finished are counted as ``finished``; a SIGINT that lands in
CPython's own start-up, before any line of risloc runs (``docs/robustness.md``, "Limit"), kills the
process with Python's handler (status -2, maybe a traceback): counted as ``startup`` and checked
for intact outputs and resume, but not for exit 130 and one line.

    .venv/bin/python benchmarks/interrupts.py [--moments 50] [--seed 0] [--only simulate ...]
        [--from-commit HEAD] [--json results.json] [--notes /tmp/notes-interrupts.md]
    .venv/bin/python benchmarks/interrupts.py --merge a.json b.json     # the table of runs split over processes

``tests/fuzz/test_interrupt_moments.py`` runs the same checks at a few moments per command.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

#: The small study of the sweep (the parameters of tests/studies/conftest.py's SMALL: ~20 ms a run).
SMALL_SWEEP = ["--set", "num_chirps=32", "--set", "num_samples=64", "--set", "n_dft=128", "--set", "k_dft=128",
               "--set", "sweep_span_deg=15.0", "--set", "aod_deg=10.3"]


# ------------------------------------------------------------------------------ comparing outputs


def _is_time_key(key: str) -> bool:
    """Fields that carry wall-clock time (``seconds``, ``wall_seconds``, ``seconds_per_run``, ``created``, ``timing``)
    or a sitting's provenance (``devices``: what ran the runs, whose trace variant is null when the traces came from
    the cache, so a second sitting names another; ``tests/studies/test_device_stream.py`` holds what they must say)."""
    return key in ("created", "timing", "devices") or key.endswith("seconds") or key.startswith("seconds")


def strip_time(obj: Any) -> Any:
    """``obj`` (parsed JSON) without its time fields, recursively."""
    if isinstance(obj, dict):
        return {k: strip_time(v) for k, v in obj.items() if not _is_time_key(str(k))}
    if isinstance(obj, list):
        return [strip_time(v) for v in obj]
    return obj


def _canon(obj: Any) -> str:
    return json.dumps(strip_time(obj), sort_keys=True, default=repr)


def jsonl_rows(data: bytes) -> tuple[list[str], bytes]:
    """The canonical rows (time fields dropped) of a run log's whole lines, and its torn tail."""
    lines = data.split(b"\n")
    tail = lines.pop()
    return [_canon(json.loads(line)) for line in lines], tail


def _npz_content(data: bytes) -> dict[str, Any]:
    with np.load(io.BytesIO(data), allow_pickle=False) as f:
        out = {}
        for k in f.files:
            a = f[k]
            if a.dtype.kind == "U" and a.ndim == 0:
                try:
                    out[k] = ("json", _canon(json.loads(str(a))))
                    continue
                except ValueError:
                    pass
            out[k] = (a.dtype.str, a.shape, a.tobytes())
        return out


def _parquet_content(data: bytes) -> str:
    import pyarrow.parquet as pq

    table = pq.read_table(io.BytesIO(data))
    return _canon({"columns": sorted(c for c in table.column_names if not _is_time_key(c)),
                   "rows": table.to_pylist()})


def equivalent(name: str, a: bytes | None, b: bytes | None) -> bool:
    """Are two versions of the file ``name`` the same result (time fields ignored; else bit for bit)?"""
    if a is None or b is None:
        return a is b
    if a == b:
        return True
    try:
        if name.endswith(".risloc-outputs.json"):  # the output ledger: the same files (their hashes vary with the zip times)
            return sorted(json.loads(a).get("files", {})) == sorted(json.loads(b).get("files", {}))
        if name.endswith(".jsonl"):
            ra, ta = jsonl_rows(a)
            rb, tb = jsonl_rows(b)
            return not ta and not tb and sorted(ra) == sorted(rb)
        if name.endswith(".json"):
            return _canon(json.loads(a)) == _canon(json.loads(b))
        if name.endswith(".npz"):
            return _npz_content(a) == _npz_content(b)
        if name.endswith(".parquet"):
            return _parquet_content(a) == _parquet_content(b)
    except Exception:  # noqa: BLE001 - an unreadable file is not the reference
        return False
    return False


def tree(path: Path) -> dict[str, bytes | None]:
    """Every entry under ``path`` (hidden ones too): file bytes, or None for a folder; {} if absent."""
    if not path.exists():
        return {}
    return {p.relative_to(path).as_posix(): (None if p.is_dir() and not p.is_symlink() else p.read_bytes())
            for p in sorted(path.rglob("*"))}


def _log_ok(before: bytes | None, after: bytes, ref: bytes) -> str:
    """'' if ``after`` is ``before`` plus whole rows of the reference; else why not."""
    if before is not None and not after.startswith(before):
        return "runs.jsonl lost its previous bytes"
    try:
        rows, tail = jsonl_rows(after)
    except ValueError as exc:
        return f"runs.jsonl has a bad line ({exc})"
    if tail:
        return f"runs.jsonl ends in a torn line ({tail[:40]!r})"
    if not set(rows) <= set(jsonl_rows(ref)[0]):
        return "runs.jsonl has rows that are not the reference's"
    if len(set(rows)) != len(rows):
        return "runs.jsonl has a row twice"
    return ""


def check_files(before: dict, after: dict, ref: dict) -> str:
    """'' if each file of ``after`` is its ``before`` bytes or a complete reference version; else why not."""
    problems = []
    for rel in sorted(set(before) | set(after)):
        b, a, r = before.get(rel), after.get(rel), ref.get(rel)
        if rel in before and rel not in after:
            problems.append(f"{rel} was deleted")
        elif rel not in ref and rel not in before:
            problems.append(f"{rel} left behind (not an output)")
        elif a is None or a == b:
            continue
        elif rel.endswith(".jsonl"):
            why = _log_ok(b, a, r or b"")
            if why:
                problems.append(why)
        elif not equivalent(rel, a, r):
            problems.append(f"{rel} is neither its previous bytes nor the reference")
    return "; ".join(problems)


def check_scene(before: dict, after: dict, ref: dict) -> str:
    """'' if the folder is the previous build or the new one, byte for byte."""
    if after == before or after == ref:
        return ""
    pending = b'"pending"' in (after.get("build-manifest.json") or b"")
    diff = sorted(k for k in set(after) | set(before) if after.get(k) != before.get(k) and after.get(k) != ref.get(k))
    if not diff and pending:
        return "a mix of the previous and the new build (stopped in the swap, manifest 'pending')"
    return f"neither the previous nor the new build: {diff[:4]}{' (manifest pending)' if pending else ''}"


def check_resume(after: dict, ref: dict) -> str:
    """'' if the resumed output equals the reference."""
    if set(after) != set(ref):
        return f"files differ: extra {sorted(set(after) - set(ref))[:3]}, missing {sorted(set(ref) - set(after))[:3]}"
    bad = [rel for rel in sorted(ref) if not equivalent(rel, after[rel], ref[rel])]
    return f"differs from the reference: {bad[:4]}" if bad else ""


# ------------------------------------------------------------------------------ the commands


@dataclass
class Command:
    """A long command: its arguments for an output location, and how its outputs are checked.

    ``target`` is the output (a file or a folder) the command writes; ``prepare(target, i)`` makes
    the state before moment ``i`` (e.g. a previous partial study); ``kind`` picks the check.
    """

    name: str
    argv: Callable[[Path], list[str]]
    kind: str  # "files" (any output: files intact or complete) or "scene" (previous or new build)
    target: Callable[[Path], Path]
    prepare: Callable[[Path, int, Command], None] = lambda target, i, cmd: None
    reference: dict[str, bytes | None] = field(default_factory=dict)
    wall: float = 0.0


def _root(target: Path) -> Path:
    """The folder whose every file is checked: the output folder, or a single file's folder."""
    return target.parent if target.suffix else target


def _out_dir(work: Path) -> Path:
    return work / "out"


def _prepare_study(target: Path, i: int, cmd: Command) -> None:
    """Even moments: a new folder. Odd moments: a previous, stopped study (its manifest and the first half of its log)."""
    if i % 2 == 0:
        return
    target.mkdir(parents=True)
    for name, data in cmd.reference.items():
        if name.endswith("study.json"):
            (target / name).write_bytes(data)  # type: ignore[arg-type]
    log = cmd.reference["runs.jsonl"] or b""
    lines = log.split(b"\n")[:-1]
    (target / "runs.jsonl").write_bytes(b"".join(line + b"\n" for line in lines[: len(lines) // 2]))


SCENE_NEW = ('name = "crates"\ncenter = [22.0, 10.5, 0.6]', 'name = "boxes"\ncenter = [21.0, 9.5, 0.6]')


def _prepare_scene(target: Path, i: int, cmd: Command) -> None:
    """The committed l_hall build, with its spec edited (an object renamed and moved): the build
    writes a new mesh and scene.xml, deletes the old mesh, and rewrites the manifest."""
    shutil.copytree(ROOT / "scenes" / "l_hall", target, symlinks=True)
    spec = target / "spec.toml"
    text = spec.read_text()
    assert SCENE_NEW[0] in text, "scenes/l_hall/spec.toml changed: update SCENE_NEW"
    spec.write_text(text.replace(*SCENE_NEW))


def commands() -> dict[str, Command]:
    """The five long commands, each small enough to run many times."""
    return {
        "simulate": Command("simulate", lambda t: ["simulate", "-o", str(t)], "files", lambda w: w / "out" / "x.npz"),
        "scene build": Command("scene build", lambda t: ["scene", "build", str(t / "spec.toml")], "scene",
                               _out_dir, _prepare_scene),
        "study sweep": Command("study sweep", lambda t: ["study", "sweep", "--vary", "tx_power_dbm=0,20", "--runs", "6",
                                                         "--workers", "1", "--quiet", "--out", str(t), *SMALL_SWEEP],
                               "files", _out_dir, _prepare_study),
        "demo": Command("demo", lambda t: ["demo", "--analytic", "--out", str(t)], "files", _out_dir),
        "study map": Command("study map", lambda t: ["study", "map", "paper_hall", "--spacing", "8", "--runs", "1",
                                                     "--depth", "1", "--samples", "1000", "--quiet", "--out", str(t)],
                             "files", _out_dir, _prepare_study),
    }


# ------------------------------------------------------------------------------ running


def risloc_argv(env: dict[str, str]) -> list[str]:
    """The program, as a user starts it: the ``risloc`` console script next to this Python."""
    return [str(Path(sys.executable).with_name("risloc"))]


def environment(pythonpath: Path | None, cache: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("RISLOC_DEBUG", "PYTHONPATH")}
    env["RISLOC_CACHE_DIR"] = str(cache)
    env["MPLBACKEND"] = "Agg"
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    return env


def _foreground_signals() -> None:
    """In the child: SIGINT as in a terminal's foreground job. A program started in the background
    by a shell (``cmd &``, ``nohup``) inherits SIGINT ignored, and Python then never raises
    KeyboardInterrupt: every moment would count as 'finished'."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@dataclass
class Outcome:
    status: int | None
    stderr: list[str]
    seconds: float
    finished_first: bool = False
    leftover_processes: bool = False


def run(argv: list[str], env: dict[str, str], cwd: Path, moment: float | None = None, timeout: float = 900) -> Outcome:
    """Run ``risloc ARGV`` in a new process group; with ``moment``, SIGINT the group after that many seconds."""
    start = time.perf_counter()
    proc = subprocess.Popen(risloc_argv(env) + argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env,
                            cwd=cwd, start_new_session=True,
                            preexec_fn=_foreground_signals)  # noqa: PLW1509 - no threads here
    finished_first = False
    if moment is not None:
        while time.perf_counter() - start < moment and proc.poll() is None:
            time.sleep(min(0.005, max(0.0, moment - (time.perf_counter() - start))))
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGINT)  # a terminal's Ctrl-C: the whole foreground group
            except ProcessLookupError:
                finished_first = True
        else:
            finished_first = True
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
    seconds = time.perf_counter() - start
    leftover = False
    for _ in range(100):  # a helper (multiprocessing's resource tracker) may take a moment to follow
        try:
            os.killpg(proc.pid, 0)
        except (ProcessLookupError, PermissionError):
            break
        time.sleep(0.05)
    else:
        leftover = True  # a process of the group (a worker) outlived the command by 5 s
        os.killpg(proc.pid, signal.SIGKILL)
    return Outcome(proc.returncode, err.decode(errors="replace").splitlines(), seconds, finished_first, leftover)


@dataclass
class Result:
    moment: float
    category: str  # "interrupted", "startup", "finished", "other"
    status: int | None
    exit_130: bool
    one_line: bool
    intact: str
    resume: str
    stderr: list[str]
    leftover: bool

    @property
    def ok(self) -> bool:
        return (self.category in ("finished", "startup") or (self.exit_130 and self.one_line)) and not self.intact \
            and not self.resume and not self.leftover


def setup_reference(cmd: Command, work: Path, env: dict[str, str], twice: bool = True) -> None:
    """Run ``cmd`` uninterrupted (twice with ``twice``: the shorter wall time is the window)."""
    outputs = []
    for n in range(2 if twice else 1):
        base = work / f"ref{n}"
        target = cmd.target(base)
        target.parent.mkdir(parents=True, exist_ok=True)
        cmd.prepare(target, 0, cmd)
        out = run(cmd.argv(target), env, base)
        if out.status != 0 or out.stderr:
            raise RuntimeError(f"{cmd.name}: the reference run failed ({out.status}): {out.stderr[-3:]}")
        root = _root(target)
        outputs.append(tree(root))
        cmd.wall = out.seconds if n == 0 else min(cmd.wall, out.seconds)
    cmd.reference = outputs[-1]
    if twice and check_resume(outputs[0], outputs[1]):
        raise RuntimeError(f"{cmd.name}: two uninterrupted runs differ: {check_resume(outputs[0], outputs[1])}")


def one_moment(cmd: Command, work: Path, env: dict[str, str], i: int, moment: float) -> Result:
    """Interrupt ``cmd`` at ``moment`` s (state ``i`` before it), check, resume, check."""
    base = work / f"m{i}"
    shutil.rmtree(base, ignore_errors=True)
    target = cmd.target(base)
    target.parent.mkdir(parents=True, exist_ok=True)
    cmd.prepare(target, i, cmd)
    root = _root(target)
    before = tree(root)
    out = run(cmd.argv(target), env, base, moment)
    after = tree(root)
    text = "\n".join(out.stderr)
    if out.finished_first or (out.status == 0 and not out.stderr):
        category = "finished"
    elif out.status != 130 and not any(line.startswith("risloc") for line in out.stderr) and (
            out.status == -signal.SIGINT or "KeyboardInterrupt" in text):
        category = "startup"  # Python's own handler: the signal came before risloc's first line ran
    elif out.status == 130:
        category = "interrupted"
    else:
        category = "other"
    one_line = len(out.stderr) == 1 and "Traceback" not in text and out.stderr[0].startswith("risloc") \
        and "interrupted" in out.stderr[0]
    beside = sorted(set(os.listdir(base)) - {root.name, target.name})  # the command's working folder
    if category == "finished":
        intact = check_resume(after, cmd.reference)
    elif cmd.kind == "scene":
        intact = check_scene(before, after, cmd.reference)
    else:
        intact = check_files(before, after, cmd.reference)
    if beside:
        intact = "; ".join(filter(None, [intact, f"wrote outside its output: {beside[:3]}"]))
    again = run(cmd.argv(target), env, base)
    resumed = tree(root)
    resume = check_resume(resumed, cmd.reference)
    beside = sorted(set(os.listdir(base)) - {root.name, target.name})
    if beside:
        resume = "; ".join(filter(None, [resume, f"the rerun wrote outside its output: {beside[:3]}"]))
    if again.status != 0 or again.stderr:
        resume = f"the resume failed ({again.status}): {again.stderr[-2:]}" + (f"; {resume}" if resume else "")
    shutil.rmtree(base, ignore_errors=True)
    return Result(moment, category, out.status, out.status == 130, one_line, intact, resume, out.stderr,
                  out.leftover_processes or again.leftover_processes)


def summarize(name: str, results: list[Result]) -> dict[str, Any]:
    """One row of the table."""
    cats = [r.category for r in results]
    interrupted = [r for r in results if r.category in ("interrupted", "other")]
    return {
        "command": name, "moments": len(results), "signalled": len(interrupted),
        "startup": cats.count("startup"), "finished": cats.count("finished"),
        "exit_130": sum(r.exit_130 for r in interrupted), "one_line": sum(r.one_line for r in interrupted),
        "intact": sum(not r.intact for r in results), "resume_equal": sum(not r.resume for r in results),
        "startup_detail": [{"moment": round(r.moment, 4), "status": r.status, "stderr": r.stderr[-8:]}
                           for r in results if r.category == "startup"],
        "failures": [{"moment": round(r.moment, 4), "category": r.category, "status": r.status,
                      "stderr": r.stderr[-3:], "intact": r.intact, "resume": r.resume, "leftover": r.leftover}
                     for r in results if not r.ok],
    }


HEADER = (f"{'command':<12} {'moments':>7} {'in risloc':>9} {'start-up':>8} {'finished':>8} {'exit 130':>8} "
          f"{'one line':>8} {'intact':>6} {'resume =':>8} {'wall [s]':>8} {'took [s]':>8}")


def table_line(row: dict[str, Any]) -> str:
    return (f"{row['command']:<12} {row['moments']:>7} {row['signalled']:>9} {row['startup']:>8} {row['finished']:>8} "
            f"{row['exit_130']:>8} {row['one_line']:>8} {row['intact']:>6} {row['resume_equal']:>8} "
            f"{row.get('wall', 0):>8.2f} {row.get('took', 0):>8.0f}")


def failure_lines(row: dict[str, Any], seed: int) -> list[str]:
    return [f"  {row['command']} (seed {seed}) at {f['moment']:.4f} s: {f['category']} status {f['status']}"
            + (f", stderr {f['stderr']}" if f["category"] != "finished" else "")
            + (f", not intact: {f['intact']}" if f["intact"] else "") + (f", resume: {f['resume']}" if f["resume"] else "")
            + (", processes left running" if f["leftover"] else "") for f in row["failures"]]


def snapshot(commit: str, into: Path) -> Path:
    """``git archive COMMIT`` of the repository under ``into`` (run from it: others may edit the work tree)."""
    into.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def run_command(cmd: Command, moments: int, seed: int, work: Path, env: dict[str, str], *, twice: bool = True,
                progress: Callable[[str], None] | None = None,
                partial: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Reference, then ``moments`` interrupted runs of ``cmd``; its table row (with the failures)."""
    import zlib

    start = time.perf_counter()
    folder = work / cmd.name.replace(" ", "-")
    folder.mkdir(parents=True, exist_ok=True)
    setup_reference(cmd, folder, env, twice=twice)
    rng = np.random.default_rng([seed, zlib.crc32(cmd.name.encode())])
    at = rng.uniform(0.0, cmd.wall, moments)
    results = []
    for i, moment in enumerate(at):
        r = one_moment(cmd, folder, env, i, float(moment))
        results.append(r)
        if progress:
            progress(f"{cmd.name} {i + 1}/{moments} at {moment:.3f} s: {r.category} status {r.status}"
                     + ("" if r.ok else f" FAILED {r.intact} {r.resume} {r.stderr[-2:]}"))
        if partial:
            partial({**summarize(cmd.name, results), "wall": cmd.wall, "took": time.perf_counter() - start})
    row = summarize(cmd.name, results)
    row["wall"] = cmd.wall
    row["took"] = time.perf_counter() - start
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--moments", type=int, default=50, help="interrupted runs per command (default 50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", action="append", choices=list(commands()), help="a command (repeatable)")
    parser.add_argument("--from-commit", metavar="REV",
                        help="run a `git archive REV` copy of the package (PYTHONPATH), not the work tree")
    parser.add_argument("--json", type=Path, help="write the rows (with every failure) here")
    parser.add_argument("--notes", type=Path, help="append the table (markdown) to this file")
    parser.add_argument("--verbose", action="store_true", help="a line per moment")
    parser.add_argument("--merge", nargs="+", type=Path, metavar="JSON",
                        help="print the table of --json files of earlier runs (commands split over processes)")
    args = parser.parse_args(argv)
    if args.merge:
        rows = [row for path in args.merge for row in json.loads(path.read_text())]
        print(HEADER)
        for row in rows:
            print(table_line(row) + ("  (partial)" if row.get("partial") else ""))
        failures = [line for row in rows for line in failure_lines(row, args.seed)]
        print("\n".join(["failures:", *failures] if failures else ["no failures"]))
        for row in rows:
            for s in row.get("startup_detail", []):
                print(f"  start-up kill, {row['command']}: {s}" if isinstance(s, str) else
                      f"  start-up kill, {row['command']} at {s['moment']:.3f} s: status {s['status']}, "
                      f"stderr {s['stderr'][:1] + s['stderr'][-2:] if s['stderr'] else 'none'}")
        return 0
    names = args.only or list(commands())
    start = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory(prefix="risloc-interrupts-") as tmp:
        work = Path(tmp)
        pythonpath = snapshot(args.from_commit, work / "src") if args.from_commit else None
        env = environment(pythonpath, work / "cache")
        print(f"risloc-rt Ctrl-C at random moments: {args.moments} per command, seed {args.seed}"
              + (f", code of {args.from_commit}" if args.from_commit else ""), flush=True)
        print(HEADER, flush=True)
        for name in names:
            cmd = commands()[name]
            def partial(row: dict[str, Any]) -> None:
                if args.json:
                    args.json.write_text(json.dumps(rows + [{**row, "partial": True}], indent=1))

            row = run_command(cmd, args.moments, args.seed, work, env, partial=partial,
                              progress=(lambda s: print("  " + s, file=sys.stderr, flush=True)) if args.verbose else None)
            rows.append(row)
            print(table_line(row), flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1))
    failures = [line for row in rows for line in failure_lines(row, args.seed)]
    if failures:
        print("failures:")
        print("\n".join(failures))
    took = time.perf_counter() - start
    print(f"took {took:.0f} s")
    if args.notes:
        with open(args.notes, "a") as fh:
            fh.write(f"\n### `benchmarks/interrupts.py --moments {args.moments} --seed {args.seed}`"
                     f"{' --only ' + ' --only '.join(names) if args.only else ''} ({took:.0f} s)\n\n```\n{HEADER}\n")
            fh.write("\n".join(table_line(r) for r in rows) + "\n```\n")
            if failures:
                fh.write("\nfailures:\n\n```\n" + "\n".join(failures) + "\n```\n")
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
