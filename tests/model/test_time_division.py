"""Time-division schedules of several RISs (risloc_rt.model.time_division): slot arithmetic and one-line errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsp import RadarConfig
from risloc_rt.model.time_division import TimeDivision, parse_time_division

NAMES = ["ris0", "ris1"]
SWEEP = 61 * RadarConfig().beam_interval  # Table I: 61 beams, one frame each [s]


def test_default_is_every_ris_back_to_back():
    s = parse_time_division(None, ris_names=NAMES, sweep_duration=SWEEP)
    assert s.order == ("ris0", "ris1") and s.idle == "off"
    assert s.starts == (0.0, pytest.approx(SWEEP)) and s.cycle == pytest.approx(2 * SWEEP)
    # slot k of cycle c starts at c * T_cycle + s_k; the RISs alternate
    assert s.slot_start(5) == pytest.approx(2 * 2 * SWEEP + SWEEP)
    assert [s.ris_of(k) for k in range(4)] == ["ris0", "ris1", "ris0", "ris1"]


def test_gap_order_and_slots_within_a_time():
    s = parse_time_division({"order": ["ris1", "ris0"], "gap_ms": 10.0, "idle": "parked", "parked_deg": [10, 0]},
                            ris_names=NAMES, sweep_duration=SWEEP)
    assert s.order == ("ris1", "ris0") and s.idle == "parked"
    assert s.parked_beam == pytest.approx((math.radians(10), 0.0))
    assert s.starts[1] == pytest.approx(SWEEP + 0.010) and s.cycle == pytest.approx(2 * (SWEEP + 0.010))
    # the slots that have ended by t: each start + T_sweep <= t
    t = 3 * (SWEEP + 0.010) + SWEEP
    assert s.slots_until(t).tolist() == [0, 1, 2, 3]
    assert s.slots_until(t - 1e-3).tolist() == [0, 1, 2]
    assert s.slots_until(SWEEP / 2).size == 0


@pytest.mark.parametrize("table", [None, {"gap_ms": 7.0}, {"start_ms": [3.0, 700.0], "cycle_ms": 1900.0}],
                         ids=["back to back", "gaps", "explicit starts"])
def test_the_slot_count_in_closed_form_is_the_slot_by_slot_count(table):
    """count_until counts without listing the slots (a 1e9 s walk has 2.6e9): it must be the number of slots
    whose start + T_sweep is at most t, counted one by one (the definition), at and around every slot's end."""
    s = parse_time_division(table, ris_names=NAMES, sweep_duration=SWEEP)

    def by_definition(t: float) -> int:
        k = 0
        while s.slot_start(k) + SWEEP <= t * (1 + 1e-12):
            k += 1
        return k

    ends = [s.slot_start(k) + SWEEP for k in range(40)]
    for t in [0.0, SWEEP / 2, *ends, *(e - 1e-9 for e in ends), *(e + 1e-9 for e in ends), 123.456]:
        assert s.count_until(t) == by_definition(t), t
        assert s.slots_until(t).tolist() == list(range(by_definition(t)))
    assert s.count_until(1e9) == pytest.approx(1e9 / s.cycle * s.num_slots, abs=s.num_slots)
    assert s.count_until(math.inf) == 0 and s.count_until(math.nan) == 0


def test_explicit_starts_round_trip():
    s = parse_time_division({"start_ms": [0.0, 500.0], "cycle_ms": 1200.0}, ris_names=NAMES, sweep_duration=SWEEP)
    assert s.starts == pytest.approx((0.0, 0.5)) and s.cycle == pytest.approx(1.2)
    again = parse_time_division({k: v for k, v in s.to_dict().items()}, ris_names=NAMES, sweep_duration=SWEEP)
    assert again == s


@pytest.mark.parametrize("table, message", [
    ({"start_ms": [0.0, 100.0]}, "overlap"),
    ({"order": ["ris0", "ris2"]}, "names RIS 'ris2', which the scene does not have; it has ris0, ris1"),
    ({"order": ["ris0", "ris0"]}, "names a RIS twice"),
    ({"gapms": 1.0}, "unknown key 'gapms'; did you mean 'gap_ms'"),
    ({"idle": "on"}, "idle = 'on' must be"),
    ({"gap_ms": -1.0}, "gap_ms = -1.0 must be a number >= 0"),
    ({"parked_deg": [100, 0]}, "parked_deg"),
    ({"start_ms": [0.0]}, "one start per RIS"),
    ({"start_ms": [0.0, 500.0], "cycle_ms": 600.0}, "ends before the last slot"),
    ({"order": []}, "non-empty list"),
    ([1, 2], "must be a table"),
])
def test_bad_schedules_are_one_line(table, message):
    with pytest.raises(ValueError, match=message) as err:
        parse_time_division(table, ris_names=NAMES, sweep_duration=SWEEP, where="sweep.toml: [schedule]")
    assert "\n" not in str(err.value)
    assert str(err.value).startswith("sweep.toml: [schedule]")


def test_the_error_type_is_the_callers():
    class FormatError(ValueError):
        pass

    with pytest.raises(FormatError, match="overlap"):
        parse_time_division({"start_ms": [0.0, 1.0]}, ris_names=NAMES, sweep_duration=SWEEP, error=FormatError)


def test_a_schedule_checks_its_own_numbers():
    with pytest.raises(ValueError, match="sweep_duration"):
        TimeDivision.consecutive(NAMES, 0.0)
    with pytest.raises(ValueError, match="gap"):
        TimeDivision.consecutive(NAMES, SWEEP, gap=-1.0)
    with pytest.raises(ValueError, match="names a RIS twice"):
        TimeDivision.consecutive(["a", "a"], SWEEP)
    s = TimeDivision.consecutive(NAMES, SWEEP)
    assert np.isclose(s.slot_start(2), s.cycle)
