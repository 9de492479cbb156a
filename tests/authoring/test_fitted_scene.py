"""The fitted scene folder (risloc_rt.authoring.fitted_scene): the spec with fitted materials, built atomically.

Oracles: the spec loader (the rewritten spec must load, with exactly the named materials turned into custom ones of
the given values and every other material and object unchanged), the builder (a rebuild from the folder's own
spec.toml gives the same bytes) and the file system (nothing but the target appears; a user's folder is never
replaced). No ray tracing.
"""

from __future__ import annotations

import json
import math
import os

import pytest

from risloc_rt.authoring.build import build_scene
from risloc_rt.authoring.fitted_scene import (PROVENANCE_NAME, check_material_values, fitted_spec_text,
                                              write_fitted_scene)
from risloc_rt.authoring.scene_folder import SCENES_DIR
from risloc_rt.authoring.spec import load_spec, loads_spec


def _files(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_only_the_named_material_changes_and_a_rebuild_is_byte_identical(tmp_path):
    # l_hall: concrete walls/floor, a ceiling board ceiling and wooden/chipboard objects: fit the concrete only
    old = load_spec(SCENES_DIR / "l_hall" / "spec.toml")
    new = loads_spec(fitted_spec_text("l_hall", {"concrete-200mm": (6.1, 0.6)}), base_dir=SCENES_DIR / "l_hall")
    before, after = old.all_materials(), new.all_materials()
    assert list(after) == list(before)
    for name, mat in after.items():
        if name == "concrete-200mm":
            assert mat.itu is None and mat.properties(60e9) == (6.1, 0.6) and mat.thickness == before[name].thickness
        else:
            assert mat == before[name]
    assert new.object_names == old.object_names and new.radar == old.radar
    assert [r.name for r in new.ris] == [r.name for r in old.ris]

    out = write_fitted_scene("l_hall", tmp_path / "fit", {"concrete-200mm": (6.1, 0.6)},
                             {"chi2": 1.5, "sigma": math.inf})
    assert json.loads((out / PROVENANCE_NAME).read_text()) == {"chi2": 1.5, "sigma": None}   # JSON has no inf
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit"]                          # no staging folder left
    build_scene(out / "spec.toml", tmp_path / "rebuilt")
    built = {k: v for k, v in _files(out).items() if k != PROVENANCE_NAME}
    assert built == _files(tmp_path / "rebuilt")
    xml = (out / "scene.xml").read_text()
    assert 'id="mat-concrete-200mm"' in xml and 'value="6.1"' in xml


def test_existing_folders_and_force(tmp_path):
    values = {"concrete-200mm": (6.0, 0.5)}
    out = write_fitted_scene("paper_hall", tmp_path / "fit", values, {"run": 1})
    with pytest.raises(ValueError, match="exists; name a new folder, or give --force"):
        write_fitted_scene("paper_hall", out, values, {"run": 2})
    assert json.loads((out / PROVENANCE_NAME).read_text()) == {"run": 1}
    write_fitted_scene("paper_hall", out, {"concrete-200mm": (6.2, 0.4)}, {"run": 3}, force=True)
    assert json.loads((out / PROVENANCE_NAME).read_text()) == {"run": 3}
    assert "permittivity = 6.2" in (out / "spec.toml").read_text()
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep")
    with pytest.raises(ValueError, match="never replaced, even with --force"):
        write_fitted_scene("paper_hall", user, values, {}, force=True)
    assert os.listdir(user) == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit", "mine"]


@pytest.mark.parametrize("pair, what", [((0.5, 0.1), "eps_r=0.5"), ((5.0, -0.1), "sigma=-0.1"),
                                        ((math.nan, 0.1), "eps_r=nan"), ((5.0, math.inf), "sigma=inf")])
def test_values_the_tracer_cannot_express_are_one_line_naming_the_range(pair, what, tmp_path):
    with pytest.raises(ValueError, match=f"{what}.*finite eps_r >= 1 and a finite sigma >= 0 S/m") as err:
        write_fitted_scene("paper_hall", tmp_path / "fit", {"concrete-200mm": pair}, {})
    assert "\n" not in str(err.value)
    assert not (tmp_path / "fit").exists()
    assert check_material_values({"m": (1.0, 0.0)}) == {"m": (1.0, 0.0)}       # the edges are allowed


def test_a_name_that_is_not_a_material_of_the_spec(tmp_path):
    with pytest.raises(ValueError, match="'glass-6mm' is not a material of .*its materials: concrete-200mm"):
        write_fitted_scene("paper_hall", tmp_path / "fit", {"glass-6mm": (6.0, 0.1)}, {})
    assert not (tmp_path / "fit").exists()


def test_a_failure_while_staging_leaves_nothing(tmp_path):
    # the scene is built into the staging folder, then the provenance cannot be written (not JSON): no target, no
    # half scene, no staging folder left behind
    with pytest.raises(TypeError):
        write_fitted_scene("paper_hall", tmp_path / "fit", {"concrete-200mm": (6.0, 0.5)}, {"x": object()})
    assert list(tmp_path.iterdir()) == []


def test_a_fitted_scattering_coefficient_is_written_and_a_pair_keeps_the_sources(tmp_path):
    out = write_fitted_scene("paper_hall", tmp_path / "rough", {"concrete-200mm": (6.1, 0.6, 0.4)}, {})
    mat = load_spec(out / "spec.toml").all_materials()["concrete-200mm"]
    assert (mat.permittivity, mat.conductivity, mat.scattering_coefficient) == (6.1, 0.6, 0.4)
    assert '<float name="scattering_coefficient" value="0.4"/>' in (out / "scene.xml").read_text()
    build_scene(out / "spec.toml", tmp_path / "rebuilt")
    assert {k: v for k, v in _files(out).items() if k != PROVENANCE_NAME} == _files(tmp_path / "rebuilt")
    # fitting (eps_r, sigma) of a rough material keeps its S; S = 0 is a smooth surface (no key written)
    again = write_fitted_scene(out, tmp_path / "again", {"concrete-200mm": (5.9, 0.7)}, {})
    assert load_spec(again / "spec.toml").all_materials()["concrete-200mm"].scattering_coefficient == 0.4
    smooth = write_fitted_scene(out, tmp_path / "smooth", {"concrete-200mm": (5.9, 0.7, 0.0)}, {})
    assert "scattering_coefficient" not in (smooth / "spec.toml").read_text()


@pytest.mark.parametrize("value", [(6.0, 0.5, 1.2), (6.0, 0.5, -0.1), (6.0, 0.5, math.nan), (6.0,), (6.0, 0.5, 0.1, 2.0)])
def test_a_scattering_coefficient_the_tracer_cannot_take_is_one_line(value, tmp_path):
    with pytest.raises(ValueError, match="concrete-200mm") as err:
        write_fitted_scene("paper_hall", tmp_path / "fit", {"concrete-200mm": value}, {})
    assert "\n" not in str(err.value) and ("S in [0, 1]" in str(err.value) or "expected (eps_r" in str(err.value))
    assert not (tmp_path / "fit").exists()
