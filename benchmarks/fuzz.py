"""Fuzzing benchmark (issue 11): generated unusual and bad inputs for every reader and entry point.

Each entry point has a generator (a seeded ``numpy.random.Generator`` -> one input, mostly
mutations of a valid one) and an oracle. Every input ends in one of

* ``error``     a clear error: an expected exception type with a one-line message,
* ``correct``   the call returned and the oracle accepts the result,
* ``traceback`` any other exception (what a user would see as a Python traceback),
* ``wrong``     the call returned but the oracle rejects the result (a silent wrong answer),
* ``hang``      the input ran past the time limit.

The table also gives each entry point's peak memory (max RSS growth of its worker process) and
its peak RSS, which must stay within ``--memory-limit`` (``$RISLOC_MEMORY_LIMIT`` of the workers)
+ 200 MB: the ``declared sizes`` entry point (issue 19) feeds sizes from 0 to 10¹³ into every place
an input declares one, so a size used before it is checked shows up there. The goal is zero in
the three failure columns.

    .venv/bin/python benchmarks/fuzz.py --examples 100000 [--seed 0] [--time-limit 10]

``tests/fuzz/`` drives the same entry points with Hypothesis (fewer examples, derandomized).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import multiprocessing
import resource
import signal
import sys
import tempfile
import time
import zlib
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


class Hang(Exception):
    """Raised by the alarm when an input runs past the time limit."""


# ------------------------------------------------------------------------------------ the inputs


def _expected_errors() -> tuple[type, ...]:
    from dsp.budget import BudgetError
    from risloc_rt.authoring._parse import SpecError
    from risloc_rt.authoring.scene_folder import SceneError
    from risloc_rt.io.capture_file import CaptureFormatError

    from risloc_rt.measured import MeasuredFormatError

    return (CaptureFormatError, SpecError, SceneError, BudgetError, MeasuredFormatError, ValueError, TypeError,
            FileNotFoundError)


class Workspace:
    """Valid reference inputs, built once per worker in a temporary folder (:func:`make_workspace`)."""

    folder: Path

    def path(self, name: str) -> Path:
        return self.folder / name


def _mutate_bytes(rng: np.random.Generator, data: bytes) -> bytes:
    data = bytearray(data)
    kind = rng.integers(4)
    if kind == 0:  # flip bytes
        for pos in rng.integers(0, len(data), rng.integers(1, 4)):
            data[pos] ^= int(rng.integers(1, 256))
    elif kind == 1:  # truncate
        data = data[: int(rng.integers(0, len(data)))]
    elif kind == 2:  # insert garbage
        pos = int(rng.integers(0, len(data)))
        data[pos:pos] = rng.bytes(int(rng.integers(1, 64)))
    else:  # overwrite a run
        pos = int(rng.integers(0, len(data)))
        data[pos:pos + 16] = rng.bytes(16)
    return bytes(data)


_WEIRD = [0, -1, 1e-300, 1e300, float("nan"), float("inf"), True, False, None, "x", "60e9", [], {}, [1, 2], 1e9,
          10**12, -1e-9, 0.5, 2**31, 2**63 - 1]


def _weird(rng: np.random.Generator) -> Any:
    return _WEIRD[int(rng.integers(len(_WEIRD)))]


def gen_capture(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    """A capture file: damaged bytes, mutated metadata, or replaced arrays."""
    kind = rng.integers(3)
    if kind == 0:
        return "bytes", _mutate_bytes(rng, ws.capture_bytes)
    with np.load(io.BytesIO(ws.capture_bytes), allow_pickle=False) as f:
        content = {k: f[k] for k in f.files}
    meta = json.loads(str(content["metadata"]))
    if kind == 1:
        block = ["radar", "processing", "ris", "truth", None][int(rng.integers(5))]
        if block is None:
            meta[str(rng.choice(["extra", "proccessing", "format", "version"]))] = _weird(rng)
        else:
            target = meta[block] if isinstance(meta[block], dict) else meta
            key = str(rng.choice(sorted(target))) if target and rng.random() < 0.8 else "bogus"
            if rng.random() < 0.2:
                target.pop(key, None)
            else:
                target[key] = _weird(rng)
        content["metadata"] = np.array(json.dumps(meta))
    else:
        name = str(rng.choice(["cube", "beam_angles", "frame_index"]))
        arr = content[name]
        choice = rng.integers(5)
        if choice == 0:
            arr = arr.real.astype(rng.choice([np.float64, np.int16, np.bool_]))
        elif choice == 1:
            arr = arr.reshape(-1)
        elif choice == 2:
            arr = np.full_like(arr, np.nan) if arr.dtype.kind in "fc" else arr[:-1]
        elif choice == 3:
            arr = np.zeros((0,) + arr.shape[1:], arr.dtype)
        else:
            arr = arr.astype(np.complex64) if arr.dtype.kind == "c" else arr.astype(np.float32)
        content[name] = arr
    buf = io.BytesIO()
    np.savez(buf, **content)
    return "bytes", buf.getvalue()


def run_capture(inp: tuple[str, Any], ws: Workspace) -> str:
    from risloc_rt.io.capture_file import load_capture

    path = ws.path("fuzz.npz")
    path.write_bytes(inp[1])
    cap = load_capture(path)
    # Oracle: whatever loads must be a usable, finite complex cube consistent with its radar, and
    # an undamaged cube must be the reference's.
    ok = (np.iscomplexobj(cap.cube) and cap.cube.shape[1:] == (cap.radar.num_chirps, cap.radar.num_samples)
          and np.all(np.isfinite(cap.cube)))
    if ok and cap.cube.shape == ws.capture.cube.shape and cap.radar == ws.capture.radar:
        ok = np.allclose(cap.cube, ws.capture.cube, rtol=1e-6, atol=0) or cap.cube.dtype == np.complex64
    return "correct" if ok else "wrong"


def gen_spec(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    """A hall spec: text mutations or value replacements of a valid TOML."""
    lines = ws.spec_text.splitlines()
    kind = rng.integers(3)
    if kind == 0:
        text = _mutate_bytes(rng, ws.spec_text.encode()).decode("utf-8", "replace")
    else:
        idx = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
        i = int(rng.choice(idx))
        key = lines[i].split("=", 1)[0]
        w = _weird(rng)
        value = json.dumps(w) if not isinstance(w, float) or np.isfinite(w) else ("nan" if w != w else "inf")
        if value == "null":
            value = '""'
        lines[i] = f"{key}= {value}" if kind == 1 else f"{key.strip()}x = 1"
        text = "\n".join(lines)
    return "toml", text


def run_spec(inp: tuple[str, Any], ws: Workspace) -> str:
    from risloc_rt.authoring import loads_spec
    from risloc_rt.authoring.spec import MAX_HALL_EXTENT

    spec = loads_spec(inp[1], base_dir=ROOT / "scenes" / "l_hall")
    fp = spec.footprint_array
    ok = (0 < spec.height <= MAX_HALL_EXTENT and np.all(np.isfinite(fp)) and 1e8 <= spec.frequency <= 1e13
          and all(np.isfinite(r.position).all() for r in spec.ris))
    return "correct" if ok else "wrong"


def gen_xml(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    return "xml", _mutate_bytes(rng, ws.xml_text.encode())


def run_xml(inp: tuple[str, Any], ws: Workspace) -> str:
    from risloc_rt.authoring.scene_folder import scene_content_hash, scene_references

    xml = ws.path("scene") / "scene.xml"
    xml.write_bytes(inp[1])
    refs = scene_references(xml)
    digest = scene_content_hash(xml)
    ok = all(Path(p).is_file() and Path(p).is_relative_to(ws.folder) for _, p in refs) and len(digest) == 64
    return "correct" if ok else "wrong"


def gen_cache(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    return "bytes", _mutate_bytes(rng, ws.cache_bytes)  # type: ignore[attr-defined]


def run_cache(inp: tuple[str, Any], ws: Workspace) -> str:
    import warnings

    path = ws.cache.path_for(ws.cache_key)
    path.write_bytes(inp[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = ws.cache.load(ws.cache_key)
    if got is None:
        return "error"  # a miss with a warning: re-traced
    ok = (got.monostatic.delay.tobytes() == ws.cache_result.monostatic.delay.tobytes()  # type: ignore[attr-defined]
          and got.legs[0].amplitude.tobytes() == ws.cache_result.legs[0].amplitude.tobytes())  # type: ignore[attr-defined]
    return "correct" if ok else "wrong"


_FLAGS = ["--ue", "--ue-velocity", "--samples", "--depth", "--seed", "--tx-power-dbm", "--min-range", "--case",
          "--mode", "--radar-index", "--doppler-search", "-o", "--scene", "--limit", "--bogus"]
_VALUES = ["-6,1,2", "1,2", "nan,0,0", "1e999,0,0", "0", "-1", "1e12", "2147483648", "abc", "", "--", "-",
           "relay", "full", "x.npz", "paper_hall", "atlantis", "1,2,3,4", "-0.5,-0.25,0", "6,9,1.2"]


def gen_cli(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    verb = str(rng.choice(["simulate", "trace", "locate", "scene", "demo", "bogus"]))
    argv = [verb]
    for _ in range(int(rng.integers(0, 5))):
        argv.append(str(rng.choice(_FLAGS)))
        if rng.random() < 0.8:
            argv.append(str(rng.choice(_VALUES)))
    return "argv", argv


def run_cli(inp: tuple[str, Any], ws: Workspace) -> str:
    """Parse only (the verbs are not run: each would trace or simulate); errors must be one line, exit 2."""
    from risloc_rt.cli import build_parser, join_negative_values, value_options
    from risloc_rt.cli.common import CliError, vector

    parser = build_parser()
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            args = parser.parse_args(join_negative_values(inp[1], value_options(parser)))
        except SystemExit as exc:
            lines = err.getvalue().strip().splitlines()
            return "error" if exc.code == 2 and len(lines) == 1 else "wrong"
    for flag in ("ue", "ue_velocity"):
        text = getattr(args, flag, None)
        if text is not None:
            try:
                v = vector(text, f"--{flag}")
            except CliError:
                return "error"
            if not np.all(np.isfinite(v)) or v.shape != (3,):
                return "wrong"
    return "correct"


def gen_path_file(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    return "bytes", _mutate_bytes(rng, ws.path_file_bytes)  # type: ignore[attr-defined]


def run_path_file(inp: tuple[str, Any], ws: Workspace) -> str:
    from risloc_rt.hall.path_table import load_path_set

    path = ws.path("paths.npz")
    path.write_bytes(inp[1])
    paths, kept, meta = load_path_set(path)
    ok = np.all(np.isfinite(paths.delay)) and len(kept) == len(paths.delay)
    return "correct" if ok else "wrong"


def gen_raw(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    """A DCA1000 capture (plain or packet-recorded) with damaged bytes, and sometimes a damaged .cfg."""
    form = "raw" if rng.integers(2) == 0 else "packets"
    data = ws.raw_bytes[form]  # type: ignore[attr-defined]
    cfg = ws.raw_cfg_text  # type: ignore[attr-defined]
    if rng.integers(4) == 0:
        cfg = _mutate_text(rng, cfg)
    else:
        data = _mutate_bytes(rng, data)
    return form, (data, cfg)


def _mutate_text(rng: np.random.Generator, text: str) -> str:
    lines = text.splitlines()
    i = int(rng.integers(len(lines)))
    words = lines[i].split()
    kind = rng.integers(4)
    if kind == 0 and len(words) > 1:  # a weird value
        words[int(rng.integers(1, len(words)))] = str(_weird(rng))
    elif kind == 1:  # drop a line
        words = []
    elif kind == 2 and len(words) > 1:  # drop an argument
        words.pop(int(rng.integers(1, len(words))))
    else:  # duplicate a line, or garbage
        words = words + words if rng.integers(2) else [rng.bytes(8).decode("latin-1")]
    lines[i] = " ".join(words)
    return "\n".join(lines) + "\n"


def run_raw(inp: tuple[str, Any], ws: Workspace) -> str:
    from risloc_rt.measured import RawLayout, read_raw, read_sdk_cfg

    data, cfg_text = inp[1]
    bin_path, cfg_path = ws.path("fuzz_Raw_0.bin"), ws.path("fuzz.cfg")
    bin_path.write_bytes(data)
    cfg_path.write_text(cfg_text, encoding="latin-1")
    layout = RawLayout.from_config(read_sdk_cfg(cfg_path).config)
    raw = read_raw(bin_path, layout, form=inp[0])
    ref = ws.raw_cube  # type: ignore[attr-defined]
    # Oracle: a decoded capture has the configured shape, finite samples, and every frame that is
    # neither damaged (zero-filled) nor touched by the mutation equals the reference frame.
    if raw.cube.shape[1:] != layout.cube_shape(1)[1:] or not np.all(np.isfinite(raw.cube)):
        return "wrong"
    if layout != ws.raw_layout or data != ws.raw_bytes[inp[0]]:  # type: ignore[attr-defined]
        return "correct"  # a changed layout or changed samples decode to other, legitimate numbers
    return "correct" if raw.cube.shape == ref.shape and np.array_equal(raw.cube, ref) else "wrong"


# -------------------------------------------------------------------- sizes that inputs declare (issue 19)

#: Where an input declares a size, and the reader that must check it before allocating.
DECLARED = ("capture ris", "capture processing", "capture cube header", "spec radar grid", "spec ris",
            "cfg samples", "cfg loops and frames", "packet header", "schedule step", "schedule ris",
            "studio chirps")

_SCHEDULE = ("frames_per_beam = 1\nfirst_frame = 0\n[sweep]\nstart_deg = -45.0\nstop_deg = 45.0\nstep_deg = {step}\n"
             "[ris]\nposition = [0.0, 13.38, 0.0]\nfacing = [0.0, 12.38, 0.0]\nloopback_delay_ns = 1.78\n"
             "rows = {rows}\ncolumns = {columns}\n")


def _studio(chirp_end: int, frame_end: int, loops: int, samples: int) -> dict:
    """An mmWave Studio export (1 Tx, 4 Rx) with the given chirp range, loops and samples."""
    profile = dict(profileId=0, startFreqConst_GHz=60.25, idleTimeConst_usec=7.0, adcStartTimeConst_usec=6.0,
                   rampEndTime_usec=60.0, freqSlopeConst_MHz_usec=64.985, txStartTime_usec=1.0,
                   numAdcSamples=samples, digOutSampleRate=5000.0, rxGain_dB=30)
    chirp = dict(chirpStartIdx=0, chirpEndIdx=chirp_end, profileId=0, startFreqVar_MHz=0.0, freqSlopeVar_KHz_usec=0.0,
                 idleTimeVar_usec=0.0, adcStartTimeVar_usec=0.0, txEnable="0x1")
    frame = dict(chirpStartIdx=0, chirpEndIdx=frame_end, numLoops=loops, numFrames=8, framePeriodicity_msec=40.0)
    return {"mmWaveDevices": [{"rfConfig": {
        "rlChanCfg_t": {"rxChannelEn": "0xF", "txChannelEn": "0x1"},
        "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": 2, "b2AdcOutFmt": 1}},
        "rlProfiles": [{"rlProfileCfg_t": profile}], "rlChirps": [{"rlChirpCfg_t": chirp}], "rlFrameCfg_t": frame}}]}


def gen_declared(rng: np.random.Generator, ws: Workspace) -> tuple[str, Any]:
    """One declared size: a place (:data:`DECLARED`) and log-uniform values from 0 to 10¹³."""
    def size() -> int:
        return int(10 ** rng.uniform(0, 13)) - int(rng.integers(2))

    return str(rng.choice(DECLARED)), (size(), size(), size())


def run_declared(inp: tuple[str, Any], ws: Workspace) -> str:
    """Read the input through its public reader; the memory check must come before the allocation.

    The oracle is the memory: the worker runs under ``$RISLOC_MEMORY_LIMIT`` and its peak RSS must
    stay within that limit + 200 MB (:func:`run_entry_point`); a result is ``correct`` when it has
    the declared sizes.
    """
    kind, (a, b, c) = inp
    if kind.startswith("capture"):
        from risloc_rt.io.capture_file import load_capture
        from risloc_rt.io.report import process_capture

        with np.load(io.BytesIO(ws.capture_bytes), allow_pickle=False) as f:
            content = {k: f[k] for k in f.files}
        meta = json.loads(str(content["metadata"]))
        if kind == "capture ris":
            meta["ris"].update(num_rows=a, num_columns=b)
        elif kind == "capture processing":
            meta["processing"].update(n_dft=a, k_dft=b)
        content["metadata"] = np.array(json.dumps(meta))
        path = ws.path("declared.npz")
        path.write_bytes(_npz_bytes(content, cube_shape=(a % 10**7, b % 10**7, c % 10**7)
                                    if kind == "capture cube header" else None))
        cap = load_capture(path)
        loc, _ = process_capture(cap)
        return "correct" if cap.ris.num_rows * cap.ris.num_columns >= 1 and loc is not None else "wrong"
    if kind.startswith("spec"):
        from risloc_rt.authoring import loads_spec

        text = ws.spec_text
        if kind == "spec radar grid":
            start = text.index("positions = [", text.index("[radar]"))
            end = text.index("\n]\n", start) + 2
            text = text[:start] + f"grid = {{spacing = {1.0 / a if a else 0.0:.6g}, height = 1.2}}" + text[end:]
        else:
            text = text.replace("rows = 16", f"rows = {a}").replace("columns = 4", f"columns = {b}")
        spec = loads_spec(text, base_dir=ROOT / "scenes" / "l_hall")
        return "correct" if len(spec.radar_positions()) >= 1 else "wrong"
    if kind.startswith("cfg") or kind == "packet header":
        from risloc_rt.measured import RawLayout, read_raw, read_sdk_cfg

        cfg_text, data = ws.raw_cfg_text, ws.raw_bytes["packets" if kind == "packet header" else "raw"]  # type: ignore[attr-defined]
        lines = cfg_text.splitlines()
        for i, line in enumerate(lines):
            words = line.split()
            if kind == "cfg samples" and words[:1] == ["profileCfg"]:
                words[10] = str(a)
            elif kind == "cfg loops and frames" and words[:1] == ["frameCfg"]:
                words[3], words[4] = str(a), str(b % 70000)
            lines[i] = " ".join(words)
        if kind == "packet header":
            blob = bytearray(data)
            at = int(c % max(len(blob) // 2, 1)) & ~1
            blob[at:at + 10] = (a % 2**32).to_bytes(4, "little") + (b % 2**48).to_bytes(6, "little")
            data = bytes(blob)
        bin_path, cfg_path = ws.path("declared_Raw_0.bin"), ws.path("declared.cfg")
        bin_path.write_bytes(data)
        cfg_path.write_text("\n".join(lines) + "\n", encoding="latin-1")
        layout = RawLayout.from_config(read_sdk_cfg(cfg_path).config)
        raw = read_raw(bin_path, layout, form="packets" if kind == "packet header" else "raw")
        return "correct" if raw.cube.shape[1:] == layout.cube_shape(1)[1:] else "wrong"
    if kind.startswith("schedule"):
        from dsp import BeamSweep, RisPose
        from risloc_rt.measured import parse_sweep_schedule
        from risloc_rt.model.ris import RisConfig, ris_response

        text = _SCHEDULE.format(step=(repr(90.0 / a) if a else "0.0") if kind == "schedule step" else "1.5",
                                rows=a if kind == "schedule ris" else 16, columns=b if kind == "schedule ris" else 4)
        schedule = parse_sweep_schedule(text, source="declared.toml")
        # what simulate/compare/calibrate then do with it: the RIS response over the sweep
        ris = RisConfig(pose=RisPose.facing(schedule.ris_position, schedule.ris_facing), num_rows=schedule.ris_rows,
                        num_columns=schedule.ris_columns, loopback_delay=schedule.loopback_delay_ns * 1e-9)
        sweep = BeamSweep(np.deg2rad(np.asarray(schedule.angles_deg, float)))
        response = ris_response(ris, sweep, np.zeros((1, 2)), np.zeros((1, 2)), wavelength=5e-3)
        return "correct" if response.shape[0] == len(schedule.angles_deg) else "wrong"
    from risloc_rt.measured import parse_studio_json

    parsed = parse_studio_json(_studio(a, b % 600, c % 300, int(c % 70000)), source="declared.json")
    return "correct" if parsed.config.num_samples >= 1 else "wrong"


def _npz_bytes(content: dict[str, np.ndarray], *, cube_shape: tuple[int, ...] | None) -> bytes:
    """``content`` as an ``.npz``; with ``cube_shape``, the cube's ``.npy`` header declares that shape
    over the real cube's (too few) bytes."""
    import zipfile

    buf = io.BytesIO()
    np.savez(buf, **content)
    if cube_shape is None:
        return buf.getvalue()
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(buf.getvalue())) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "cube.npy":
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(head, {"descr": np.lib.format.dtype_to_descr(
                    content["cube"].dtype), "fortran_order": False, "shape": tuple(int(v) for v in cube_shape)})
                data = head.getvalue() + content["cube"].tobytes()
            dst.writestr(info.filename, data)
    return out.getvalue()


ENTRY_POINTS: dict[str, tuple[Callable, Callable]] = {
    "capture .npz": (gen_capture, run_capture),
    "scene spec (TOML)": (gen_spec, run_spec),
    "scene XML": (gen_xml, run_xml),
    "trace-cache entry": (gen_cache, run_cache),
    "path file": (gen_path_file, run_path_file),
    "CLI arguments": (gen_cli, run_cli),
    "raw DCA1000 + .cfg": (gen_raw, run_raw),
    "declared sizes": (gen_declared, run_declared),
}

#: Seconds per input before it counts as a hang, where an entry point needs more than ``--time-limit``:
#: a declared size that fits in memory (a 7408 x 794 DFT grid on 61 beams, 5e5 radar positions)
#: costs work in proportion, tens of seconds, legitimately.
TIME_LIMITS = {"declared sizes": 60.0}


def time_limit(name: str, default: float) -> float:
    """Seconds per input for entry point ``name``: ``default``, or :data:`TIME_LIMITS`'s if larger."""
    return max(default, TIME_LIMITS.get(name, 0.0))


def make_workspace(folder: Path) -> Workspace:
    """The reference inputs (a small capture, specs, a cache entry, a path file) under ``folder``."""
    ws = Workspace.__new__(Workspace)
    _init_workspace(ws, folder)
    return ws


def _init_workspace(ws: Workspace, folder: Path) -> None:
    from dataclasses import replace

    from dsp import ProcessingConfig
    from risloc_rt.hall.raytrace.cache import TraceCache
    from risloc_rt.hall.raytrace.result import TraceResult, TraceSettings
    from risloc_rt.hall.traced import TracedPaths
    from risloc_rt.io.capture_file import save_capture
    from risloc_rt.model.scenario import paper_scenario
    from risloc_rt.model.simulate import simulate

    ws.folder = folder
    sc = paper_scenario("broadside")
    sc = replace(sc, radar=replace(sc.radar, num_samples=32, num_chirps=8),
                 processing=ProcessingConfig(n_dft=63, k_dft=32))
    ws.capture = simulate(sc, rng=np.random.default_rng(0), seed=0)
    ws.capture_bytes = save_capture(ws.capture, folder / "ref.npz").read_bytes()
    ws.spec_text = (ROOT / "scenes" / "l_hall" / "spec.toml").read_text()
    ws.xml_text = (ROOT / "scenes" / "paper_hall" / "scene.xml").read_text()
    (folder / "scene" / "meshes").mkdir(parents=True, exist_ok=True)
    for p in (ROOT / "scenes" / "paper_hall" / "meshes").iterdir():
        (folder / "scene" / "meshes" / p.name).write_bytes(p.read_bytes())

    def traced(delay: float) -> TracedPaths:
        return TracedPaths.from_arrays({
            "tx_position": np.zeros(3), "rx_position": np.zeros(3), "frequency": np.array(60e9),
            "delay": np.array([delay, 2 * delay]), "amplitude": np.array([1e-3 + 1e-4j, 2e-4 + 0j]),
            "departure": np.array([[1.0, 0, 0], [0, 1.0, 0]]), "arrival": np.array([[1.0, 0, 0], [0, 1.0, 0]]),
            "delay_rate": np.zeros(2), "interactions": np.ones((2, 1), int), "objects": np.zeros((2, 1), int),
            "vertices": np.zeros((2, 1, 3)), "object_names": np.array(json.dumps(["wall_0"]))})

    ws.cache = TraceCache(folder / "cache")
    ws.cache_key = "f" * 64
    ws.cache_result = TraceResult(monostatic=traced(1e-7), legs=(traced(5e-8),), scene_hash="ab", cache_hit=False,
                                  timing={"solve": 1.0}, settings=TraceSettings(), radar_velocity=np.zeros(3))
    ws.cache_bytes = ws.cache.store(ws.cache_key, ws.cache_result).read_bytes()
    ws.path_file_bytes = _path_file_bytes(folder)
    _init_raw(ws, folder)


def _init_raw(ws: Workspace, folder: Path) -> None:
    """A small DCA1000 capture (3 frames, 8 loops, 4 Rx, 32 samples), plain and packet-recorded."""
    import dsp
    from risloc_rt.measured import RawLayout, Recording, TiChirpConfig, read_raw, write_raw_capture

    cfg = TiChirpConfig.from_radar(dsp.RadarConfig(num_samples=32, num_chirps=8))
    rng = np.random.default_rng(7)
    cube = 0.01 * (rng.standard_normal((3, 8, cfg.num_virtual, 32)) + 1j * rng.standard_normal((3, 8, cfg.num_virtual, 32)))
    ws.raw_bytes = {}
    for form in ("raw", "packets"):
        out = folder / f"dca_{form}"
        out.mkdir(exist_ok=True)
        em = write_raw_capture(cube, cfg, out, recording=Recording(form=form), rng=np.random.default_rng(1))
        ws.raw_bytes[form] = em.files[0].read_bytes()
        ws.raw_cfg_text = em.cfg_path.read_text()
    ws.raw_layout = RawLayout.from_config(cfg.with_frames(3))
    ws.raw_cube = read_raw(folder / "dca_raw" / em.files[0].name, ws.raw_layout, form="raw").cube


def _path_file_bytes(folder: Path) -> bytes:
    from risloc_rt.hall.path_table import save_path_set
    from risloc_rt.hall.pruning import PruneReport
    from risloc_rt.model.paths import PathSet

    import inspect

    try:
        paths = PathSet.concatenate([])
    except Exception:  # noqa: BLE001
        paths = None
    fields = inspect.signature(PruneReport).parameters
    report = PruneReport(**{name: (np.zeros(0, bool) if "kept" in name else
                                   [] if p.default is inspect.Parameter.empty else p.default)
                            for name, p in fields.items()})
    out = save_path_set(folder / "paths_ref.npz", paths, report, metadata={})
    return Path(out).read_bytes()


# ------------------------------------------------------------------------------------ the runner


_LAST_EXCEPTION: list[str] = [""]


def _classify(run: Callable, inp: Any, ws: Workspace, errors: tuple[type, ...], limit: float) -> str:
    def alarm(signum: int, frame: Any) -> None:
        raise Hang()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        return run(inp, ws)
    except Hang:
        return "hang"
    except errors as exc:
        message = str(exc)
        _LAST_EXCEPTION[0] = f"{type(exc).__name__}: {message[:150]}"
        return "error" if message and "\n" not in message.strip() else "traceback"
    except Exception as exc:  # noqa: BLE001 - what a user would see as a traceback
        _LAST_EXCEPTION[0] = f"{type(exc).__name__}: {str(exc)[:150]}"
        return "traceback"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _peak_rss() -> int:
    """This process image's peak RSS [bytes]: ``VmHWM`` on Linux (``ru_maxrss`` also counts the RSS a
    vfork'ed child inherits from its parent, e.g. a large pytest process), else ``ru_maxrss``."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            return 1024 * int(next(line for line in fh if line.startswith("VmHWM:")).split()[1])
    except (OSError, StopIteration, ValueError, IndexError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def run_entry_point(name: str, examples: int, seed: int, limit: float, queue: Any = None) -> dict[str, Any]:
    """Run ``examples`` generated inputs of entry point ``name``; returns its counts and peak memory."""
    import warnings

    warnings.simplefilter("ignore")
    gen, run = ENTRY_POINTS[name]
    counts = dict.fromkeys(("error", "correct", "traceback", "wrong", "hang"), 0)
    examples_wrong: list[str] = []
    with tempfile.TemporaryDirectory(prefix="risloc-fuzz-") as tmp:
        ws = make_workspace(Path(tmp))
        errors = _expected_errors()
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        rng = np.random.default_rng([seed, zlib.crc32(name.encode())])  # stable across processes
        start = time.perf_counter()
        biggest = (0, "")  # the input that raised the peak RSS most, and by how much [bytes]
        for _ in range(examples):
            inp = gen(rng, ws)
            before = _peak_rss()
            outcome = _classify(run, inp, ws, errors, time_limit(name, limit))
            rise = _peak_rss() - before
            if rise > biggest[0]:
                biggest = (rise, f"{outcome}: {repr(inp)[:150]}")
            counts[outcome] += 1
            if outcome in ("traceback", "wrong", "hang") and len(examples_wrong) < 3:
                examples_wrong.append(f"{_LAST_EXCEPTION[0]} <- {repr(inp)[:150]}")
        peak = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) * 1024
    out = {"name": name, "examples": examples, **counts, "peak_memory": peak,
           "peak_rss": _peak_rss(),
           "seconds": time.perf_counter() - start, "samples": examples_wrong,
           "peak_input": f"+{biggest[0] / 2**20:.0f} MiB at {biggest[1]}"}
    if queue is not None:
        queue.put(out)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=100_000, help="inputs in total over all entry points")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--time-limit", type=float, default=10.0, help="seconds per input before it counts as a hang")
    parser.add_argument("--only", choices=list(ENTRY_POINTS), help="one entry point")
    parser.add_argument("--memory-limit", default="512M",
                        help="$RISLOC_MEMORY_LIMIT of the workers (default %(default)s); the peak RSS of each "
                             "must stay within it + 200 MB")
    args = parser.parse_args(argv)
    import os

    from dsp.budget import MEMORY_LIMIT_ENV, parse_bytes

    os.environ[MEMORY_LIMIT_ENV] = args.memory_limit
    allowed = parse_bytes(args.memory_limit) + 200 * 2**20
    names = [args.only] if args.only else list(ENTRY_POINTS)
    per = max(args.examples // len(names), 1)
    ctx = multiprocessing.get_context("fork")
    print(f"risloc-rt fuzzing: {per} inputs per entry point, seed {args.seed}, {args.time_limit:g} s per input, "
          f"memory limit {args.memory_limit}")
    print(f"{'entry point':<20} {'inputs':>7} {'clear errors':>12} {'correct':>8} {'tracebacks':>10} "
          f"{'silent wrong':>12} {'hangs':>6} {'peak memory':>12} {'peak RSS':>9} {'time [s]':>9}")
    total = dict.fromkeys(("examples", "error", "correct", "traceback", "wrong", "hang"), 0)
    bad = []
    for name in names:
        queue = ctx.Queue()
        proc = ctx.Process(target=run_entry_point, args=(name, per, args.seed, args.time_limit, queue))
        proc.start()
        r = queue.get()
        proc.join()
        for k in total:
            total[k] += r[k]
        mem, rss = f"{r['peak_memory'] / 2**20:.0f} MiB", f"{r['peak_rss'] / 2**20:.0f} MiB"
        print(f"{name:<20} {r['examples']:>7} {r['error']:>12} {r['correct']:>8} {r['traceback']:>10} "
              f"{r['wrong']:>12} {r['hang']:>6} {mem:>12} {rss:>9} {r['seconds']:>9.1f}", flush=True)
        bad += [f"  {name}: {s}" for s in r["samples"]]
        if r["peak_rss"] > allowed:
            bad.append(f"  {name}: peak RSS {rss} above the limit + 200 MB; the largest rise: {r['peak_input']}")
            total["wrong"] += 1
    print(f"{'total':<20} {total['examples']:>7} {total['error']:>12} {total['correct']:>8} {total['traceback']:>10} "
          f"{total['wrong']:>12} {total['hang']:>6}")
    if bad:
        print("first failing inputs:")
        print("\n".join(bad))
    return 0 if total["traceback"] + total["wrong"] + total["hang"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
