"""Several RISs in one traced hall (issue 22): the sweeping RIS's model is untouched by the others,
an idle RIS is a static echo where geometry puts it, and a parked relay's loop-back has the paper's
link budget with its array gain.

Oracles: free-space geometry (delays 2d/c, + τ_RB for a re-transmission), the paper's loop-back
power ``P G_trx ζ (λ/4πd)⁴`` written out here, a relay's array gain N at its steered beam, and the
radar antenna's cos² pattern; not the functions under test.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from risloc_rt.hall.scenario import facing_radar, hall_paths, hall_scenario, hall_slots, ris_index
from risloc_rt.authoring.spec import load_spec
from risloc_rt.authoring.scene_folder import scene_directory

C = 299_792_458.0
UE = np.array([12.0, 2.0, 1.2])  # seen by both RISs of paper_hall_2ris


@pytest.fixture(scope="module")
def two():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the far wall folds back (an AliasWarning the hall tests check elsewhere)
        one = hall_paths(hall_scenario("paper_hall", ue_position=UE))
        off = hall_slots("paper_hall_2ris", ue_position=UE)
        parked_beam = off[1].base.ris.pose.angles_to(UE)  # ris1 holds the beam that points at the radar
        parked = hall_scenario("paper_hall_2ris", ue_position=UE, ris=0, idle="parked", parked_beam=parked_beam)
        return {"one": one, "off": [hall_paths(s) for s in off], "slots": off, "parked": parked,
                "parked_paths": hall_paths(parked)}


def _kind(paths, prefix):
    keep = np.array([lab.startswith(prefix) for lab in paths.labels])
    return keep


def test_the_sweeping_ris_is_modelled_as_in_a_one_ris_hall(two):
    """Adding ris1 (not a mesh of the scene) changes nothing of ris0's slot but the idle RIS's own echoes."""
    one, slot = two["one"].candidates, two["off"][0].candidates
    mine = ~_kind(slot, "ris_structure[") & ~_kind(slot, "ris_parked[")
    assert mine.sum() == len(one)
    np.testing.assert_array_equal(slot.delay[mine], one.delay)
    np.testing.assert_array_equal(slot.gain[mine], one.gain)
    assert list(np.array(slot.labels)[mine]) == list(one.labels)


def test_an_idle_ris_that_is_off_leaves_its_panel_as_a_static_echo(two):
    paths = two["off"][0].candidates
    ris1 = two["slots"][1].base.ris.pose.position
    idle = _kind(paths, "ris_structure[ris1]")
    assert idle.sum() > 0 and not _kind(paths, "ris_parked[").any()
    assert not paths.via_ris[idle].any()  # not modulated by ris0's sweep
    d1 = float(np.linalg.norm(UE - ris1))
    assert np.min(paths.delay[idle]) == pytest.approx(2 * d1 / C, abs=1e-12)  # the direct pair, no τ_RB


def test_a_parked_relay_is_a_static_echo_with_the_paper_link_budget(two):
    hs, paths = two["parked"], two["parked_paths"].candidates
    idle = hs.idle[0]
    parked = _kind(paths, "ris_parked[ris1]")
    assert parked.sum() > 0 and not paths.via_ris[parked].any()
    d1 = float(np.linalg.norm(UE - idle.ris.pose.position))
    first = np.flatnonzero(parked)[np.argmin(paths.delay[parked])]
    assert paths.delay[first] == pytest.approx(2 * d1 / C + idle.ris.loopback_delay, abs=1e-12)
    radar = hs.base.radar
    lam = C / radar.carrier_frequency
    # the radar faces ris0; its cos² one-way pattern toward ris1, on the way out and back
    to_ris0 = hs.base.ris.pose.position - UE
    to_ris1 = idle.ris.pose.position - UE
    cos = to_ris0 @ to_ris1 / np.linalg.norm(to_ris0) / np.linalg.norm(to_ris1)
    paper = np.sqrt(radar.tx_power * radar.antenna_gain * idle.ris.amplification) * (lam / (4 * np.pi * d1)) ** 2
    expected = paper * cos**2 * idle.ris.num_elements  # the relay's array gain N at its steered beam
    assert abs(paths.gain[first]) == pytest.approx(expected, rel=1e-3)


def test_hall_slots_gives_none_behind_a_ris():
    behind = np.array([25.0, 12.0, 1.2])  # behind ris0 (it faces -x from x = 19.38), in front of ris1
    slots = hall_slots("paper_hall_2ris", ue_position=behind)
    assert slots[0] is None and slots[1] is not None and slots[1].ris_name == "ris1"
    spec = load_spec(scene_directory("paper_hall_2ris") / "spec.toml")
    configs = spec.ris_configs()
    assert not facing_radar(configs[0], behind) and facing_radar(configs[1], behind)


def test_slot_order_and_names():
    slots = hall_slots("paper_hall_2ris", ue_position=UE, order=["ris1", 0])
    assert [s.ris_name for s in slots] == ["ris1", "ris0"]
    assert [o.name for o in slots[0].idle] == ["ris0"]
    assert slots[0].base.name.endswith("/ris1")


@pytest.mark.parametrize("bad, message", [
    ("ris7", "has no such RIS; it has ris0, ris1"),
    (2, "has no such RIS"),
    ("", "has no such RIS"),
])
def test_a_ris_the_spec_does_not_have_is_one_line(bad, message):
    spec = load_spec(scene_directory("paper_hall_2ris") / "spec.toml")
    with pytest.raises(ValueError, match=message) as err:
        ris_index(spec, bad)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match=message):
        hall_scenario("paper_hall_2ris", ris=bad)


def test_bad_idle_state_and_order():
    with pytest.raises(ValueError, match="idle='on' must be one of"):
        hall_scenario("paper_hall_2ris", idle="on")
    with pytest.raises(ValueError, match="names a RIS twice"):
        hall_slots("paper_hall_2ris", order=["ris0", 0])
