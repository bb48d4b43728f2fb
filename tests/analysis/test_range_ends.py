"""The ends of the sensitivity ranges (pipeline/analysis/ranges.py; docs/design.md §10),
worked out by hand: each end rounded to 0.01 mm (a drawing's precision), a high end capped
at a geometry rule rounded down, a low end raised to one rounded up, each cap said in the
range's note (mm).

No. 05's rules, with the margin m = 0.02·h3 = 0.5 mm and room = min(h3, b1)/2 − m = 12 mm:
dj/2 + rf ≤ room; rf ≤ b2 − m = 12; d2 + m = 21.5 ≤ seat_inner ≤ d14 − m = 30.5;
d14 + m = 31.5 ≤ seat_outer ≤ b1 − m = 44.5. Spreads: dj ±10 %, rf ±20 %, seats ±0.06·Dm
= ±1.86 mm.
"""
from __future__ import annotations

from dataclasses import replace

import pytest

from pipeline.analysis.ranges import _clip_high, _clip_low, default_range
from pipeline.inputs.case import resolve

NO05 = resolve("05").dims


def test_a_value_is_rounded_to_a_hundredth_of_a_millimetre():
    assert _clip_high(18.1107, 30.0, "r", "mm") == (18.11, "")
    assert _clip_high(1.096, 30.0, "r", "mm") == (1.1, "")
    assert _clip_low(26.864, 0.0, "r", "mm") == (26.86, "")
    assert _clip_low(35.136, 0.0, "r", "mm") == (35.14, "")


def test_a_cap_is_rounded_inwards_and_said():
    """A limit off the 0.01 mm grid: the high end goes down to 1.23, the low end up to 1.24,
    so both stay inside the rule."""
    high, note = _clip_high(5.0, 1.2345, "rule h", "mm")
    assert high == 1.23 and note == "high end clipped from 5 to 1.23 mm (rule h)"
    low, note = _clip_low(1.0, 1.2345, "rule l", "mm")
    assert low == 1.24 and note == "low end clipped from 1 to 1.24 mm (rule l)"
    # A limit on the grid is kept, not moved a step inwards.
    assert _clip_high(22.0, 21.0, "r", "mm")[0] == 21.0 and _clip_low(20.0, 21.5, "r", "mm")[0] == 21.5
    # At the limit exactly: no cap.
    assert _clip_high(21.0, 21.0, "r", "mm") == (21.0, "") and _clip_low(21.5, 21.5, "r", "mm") == (21.5, "")


def test_default_ranges_of_unrounded_dimensions():
    """No. 05 with dj = 20.123, rf = 1.37, seats 25.004 and 36.996 mm:
    dj 18.1107 → 18.11 and 22.1353 → 22.14, capped at 2·(12 − 1.37) = 21.26;
    rf 1.096 → 1.10 and 1.644 → 1.64 (cap min(12 − 10.0615, 12) = 1.9385 not reached);
    seat_inner 23.144 → 23.14, 26.864 → 26.86; seat_outer 35.136 → 35.14, 38.856 → 38.86."""
    d = replace(NO05, dj=20.123, rf=1.37, seat_inner=25.004, seat_outer=36.996)
    got = {name: default_range(name, d) for name in ("dj", "rf", "seat_inner", "seat_outer")}
    assert (got["dj"].low, got["dj"].high) == (18.11, 21.26)
    assert "clipped from 22.14 to 21.26" in got["dj"].note
    assert (got["rf"].low, got["rf"].high, got["rf"].note) == (1.1, 1.64, "")
    assert (got["seat_inner"].low, got["seat_inner"].high, got["seat_inner"].note) == (23.14, 26.86, "")
    assert (got["seat_outer"].low, got["seat_outer"].high, got["seat_outer"].note) == (35.14, 38.86, "")
    assert [got[k].nominal for k in got] == [20.123, 1.37, 25.004, 36.996]


def test_seat_ranges_clipped_at_their_rules():
    """seat_inner 29: 30.86 capped at d14 − m = 30.5; seat_inner 22.5: 20.64 raised to
    d2 + m = 21.5; seat_outer 32: 30.14 raised to d14 + m = 31.5; seat_outer 43.5: 45.36
    capped at b1 − m = 44.5."""
    hi = default_range("seat_inner", replace(NO05, seat_inner=29.0))
    assert (hi.low, hi.high) == (27.14, 30.5) and "clipped from 30.86 to 30.5" in hi.note
    lo = default_range("seat_inner", replace(NO05, seat_inner=22.5))
    assert (lo.low, lo.high) == (21.5, 24.36) and "clipped from 20.64 to 21.5" in lo.note
    lo = default_range("seat_outer", replace(NO05, seat_outer=32.0))
    assert (lo.low, lo.high) == (31.5, 33.86) and "clipped from 30.14 to 31.5" in lo.note
    hi = default_range("seat_outer", replace(NO05, seat_outer=43.5))
    assert (hi.low, hi.high) == (41.64, 44.5) and "clipped from 45.36 to 44.5" in hi.note


def test_the_fillet_s_range_is_capped_where_the_journal_leaves_no_room():
    """rf = 1.9 with dj = 20: the high end 2.28 meets room − dj/2 = 12 − 10 = 2 mm."""
    r = default_range("rf", replace(NO05, rf=1.9))
    assert (r.low, r.high) == (1.52, 2.0) and "clipped from 2.28 to 2" in r.note


@pytest.mark.parametrize("name", ["b1", "Q"])
def test_only_the_assumed_dimensions_have_a_default_range(name):
    with pytest.raises(ValueError):
        default_range(name, NO05)
