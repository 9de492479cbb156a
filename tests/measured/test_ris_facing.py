"""Issue 19 item 5 without a truth: a RIS that faces away from the radar is caught by the hall.

A sweep schedule whose ``[ris] facing`` is reversed gives a capture whose every estimate is the
mirror image of the radar through the panel, with a millimetre σ: nothing in the capture alone can
tell. Against the hall (``risloc compare``/``calibrate``), the scene's RIS faces the other way, and a
radar position given with ``--ue`` behind the panel cannot be reached by it: both are refused, in
one line, before anything is traced.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dsp import RisPose
from risloc_rt.cli import main
from risloc_rt.measured.compare.traced_hall import MAX_NORMAL_MISMATCH, hall_model
from risloc_rt.measured.errors import MeasuredFormatError


def _turned(capture, degrees: float):
    """The capture with its RIS normal turned by ``degrees`` about the vertical."""
    pose = capture.ris.pose
    c, s = np.cos(np.deg2rad(degrees)), np.sin(np.deg2rad(degrees))
    normal = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ pose.normal
    return replace(capture, ris=replace(capture.ris, pose=RisPose(position=pose.position, normal=normal)))


def test_a_reversed_facing_is_refused_before_tracing(injected_hall):
    cap = injected_hall["capture"]
    reversed_ris = _turned(cap, 180.0)
    with pytest.raises(MeasuredFormatError, match=r"the capture's RIS faces .* but the scene's faces .*180° apart"):
        hall_model(reversed_ris, "paper_hall", cap.truth.ue_position, trace=injected_hall["settings"])
    # a small mounting error is still the same panel; 10° is the limit
    assert np.rad2deg(MAX_NORMAL_MISMATCH) == pytest.approx(10.0)
    with pytest.raises(MeasuredFormatError, match="12° apart"):
        hall_model(_turned(cap, 12.0), "paper_hall", cap.truth.ue_position, trace=injected_hall["settings"])


def test_a_radar_behind_the_panel_is_refused(injected_hall, capsys):
    cap = injected_hall["capture"]
    pose = cap.ris.pose
    behind = pose.position - 2.0 * pose.normal + np.array([0.0, 0.0, 0.1])
    with pytest.raises(ValueError, match=r"is behind the RIS panel \(azimuth 180\.0°"):
        hall_model(cap, "paper_hall", behind, ue_source="given", trace=injected_hall["settings"])
    ue = ",".join(f"{v:.4f}" for v in behind)
    assert main(["compare", str(injected_hall["path"]), "--scene", "paper_hall", f"--ue={ue}",
                 *injected_hall["trace"], "-o", str(injected_hall["root"] / "never")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is behind the RIS panel" in err[0]
    assert not (injected_hall["root"] / "never").exists()
