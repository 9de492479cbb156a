"""Issue 19 (item 4): ``study map --force`` on a folder of another map keeps that map's log and never reuses it.

Before, the other map's ``runs.jsonl`` stayed in place and its (cell, run) rows were taken as this
map's finished runs: a silently wrong map.
"""

from __future__ import annotations

from .test_floor_map import tiny_hall  # noqa: F401 - the module-scoped fixture


def test_force_keeps_the_other_maps_log_and_runs_this_map_afresh(tiny_hall, tmp_path, capsys):  # noqa: F811
    from risloc_rt.studies import StudyFolderError
    from risloc_rt.studies.floor_map import MapSettings, run_map

    first = MapSettings(scene=str(tiny_hall), spacing=3.0, runs=1, depth=1, samples=10_000)
    second = MapSettings(scene=str(tiny_hall), spacing=3.0, runs=1, depth=1, samples=10_000, tx_power_dbm=-25.0)
    out = tmp_path / "m"
    run_map(first, out, workers=1, quiet=True)
    first_log = (out / "runs.jsonl").read_bytes()
    try:
        run_map(second, out, workers=1, quiet=True)
    except StudyFolderError as exc:
        assert f"runs-{first.key}.jsonl" in str(exc)
    else:
        raise AssertionError("another map's folder was used without --force")
    capsys.readouterr()
    run_map(second, out, workers=1, quiet=True, force=True)
    kept = out / f"runs-{first.key}.jsonl"
    assert kept.read_bytes() == first_log
    assert str(kept) in capsys.readouterr().err
    second_log = (out / "runs.jsonl").read_bytes()
    assert second_log and not second_log.startswith(first_log[: first_log.index(b"\n")])
