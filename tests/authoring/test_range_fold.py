"""``scene check``'s ``range.walls`` warning states where a far wall's echo folds back: d mod R_max.

Oracle: the FMCW beat frequency of a return at d is sampled at 1/T_s, so it aliases to
d − k·R_max with k = floor(d / R_max) (``risloc_rt.model.power_check``); a wall 54 m away with
R_max = 21.82 m folds to 54 − 2·21.82 = 10.36 m, not to 54 − 21.82 = 32.18 m (which is itself
beyond R_max and could not be seen).
"""

from __future__ import annotations

from pathlib import Path

from dsp import RadarConfig
from risloc_rt.authoring.check import check_scene

SPEC = """[scene]
name = "long"

[hall]
size = [56.0, 8.0]
height = 4.0

[hall.materials]
walls = "concrete"
floor = "concrete"
ceiling = "concrete"

[[ris]]
name = "ris0"
position = [10.0, 4.0, 1.2]
facing = [2.0, 4.0, 1.2]

[radar]
positions = [[2.0, 4.0, 1.2]]
"""


def test_a_wall_beyond_twice_the_unambiguous_range_folds_back_modulo(tmp_path: Path):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    found = check_scene(spec).by_rule("range.walls")
    assert len(found) == 1, [i.message for i in found]
    message = found[0].message
    limit = RadarConfig().max_range
    assert 2 * limit < 54.0 < 3 * limit  # the case the old d − R_max arithmetic got wrong
    assert "(54.00 m)" in message
    assert f"to an apparent {54.0 - 2 * limit:.2f} m" in message, message
    assert f"{54.0 - limit:.2f}" not in message
