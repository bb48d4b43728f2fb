"""The load model's default ranges and its measured effect on the peaks come from the
CalculiX contact study (docs/load-reference.md), checked here against that document's
figures worked by hand, not against the code's output."""
from __future__ import annotations

import pytest

from pipeline.analysis.ranges import ranges_of
from pipeline.inputs.case import resolve
from pipeline.analysis.verdicts import contact_study_effect

from helpers.answers import run_verdicts


def _load_ranges(case):
    return {r.input: r for r in ranges_of(case)[0] if r.kind == "load model"}


def test_no05_centre_and_length_ranges_are_the_contact_studys():
    r = _load_ranges(resolve("05"))
    # No. 05: bearing surface from b1/2 + rf = 22.5 + 1.5 = 24 mm to b6/2 = 35 mm, Lj = 11 mm.
    # docs/load-reference.md: the contact force's centre at x = 27.05 mm (standing plate, zero
    # clearance), the nearest of every solve; the middle 29.5 mm is the cos θ model's.
    assert (r["bearing_centre_mm"].low, r["bearing_centre_mm"].high) == pytest.approx((27.05, 29.5))
    # the largest line load 2.5 × its mean (standing plate): a uniform band 11 / 2.5 = 4.4 mm long
    assert (r["bearing_length_mm"].low, r["bearing_length_mm"].high) == pytest.approx((4.4, 11.0))
    assert (r["bearing_shape"].low, r["bearing_shape"].high) == ("cosine", "uniform")
    assert "0.277" in r["bearing_centre_mm"].reason and "2.5×" in r["bearing_length_mm"].reason
    assert "no contact study" not in " ".join(x.reason for x in r.values())


def test_another_size_takes_the_study_as_fractions_and_says_so():
    case = resolve("2.5")
    d = case.dims
    start, end = d.b1 / 2 + d.rf, d.b6 / 2
    r = _load_ranges(case)
    assert r["bearing_centre_mm"].low == pytest.approx(start + 0.277 * (end - start), abs=0.006)
    assert r["bearing_length_mm"].low == pytest.approx((end - start) / 2.5, abs=0.006)
    assert all("measured on No. 05" in x.reason for k, x in r.items() if k != "bearing_shape")


def test_the_measured_effect_on_the_global_peak_is_the_studys_applied_to_the_run():
    case = resolve("05")
    eff = contact_study_effect(case, run_verdicts(case, 113.77, 0.73, 66.22, 0.07, nominal=None))
    # docs/load-reference.md: the fillet's peak −10.7 % (H7/g6, standing plate) to +6.9 %
    # (H9/d9, standing); the critical peak −13.2 % to −4.3 %.
    assert eff["global_peak"]["pct"] == [-10.7, 6.9]
    assert eff["global_peak"]["MPa"] == pytest.approx([113.77 * 0.893, 113.77 * 1.069])
    assert eff["critical_peak"]["MPa"] == pytest.approx([66.22 * 0.868, 66.22 * 0.957])
    assert eff["edge_of_contact_pct"] == [28.0, 49.0]
    assert eff["applied_as"] == "measured on No. 05, this size"
    # No. 05's allowable is 80 MPa (paper): the global peak fails at both ends, the critical passes
    assert eff["global_peak"]["verdicts"] == ["fail", "fail"]
    assert eff["critical_peak"]["verdicts"] == ["pass", "pass"]


def test_no_effect_is_claimed_for_another_load_model():
    for over in ({"bearing_shape": "uniform"}, {"bearing_centre_mm": 27.0}, {"support": "rigid"}):
        case = resolve("05", None, over)
        assert contact_study_effect(case, run_verdicts(case)) is None, over
    other = contact_study_effect(resolve("2.5"), run_verdicts(resolve("2.5")))
    assert "not on this size" in other["applied_as"]


@pytest.mark.slow
def test_the_formula_positions_are_solved_on_the_first_error_bar_mesh_and_are_statics():
    """The like-with-like rows come from the first error-bar mesh (×1.3 the requested), not
    the requested one, and their section moment is still the statics of each formula's
    load position: M = −Q/2 · (position − seat centroid), the seat a uniform annulus 25 to
    37 mm (docs/design.md §5), the approximate formula's load at (b1 + b2)/2 = 28.75 mm."""
    import math

    from mpi4py import MPI

    from pipeline.analysis.context import RunContext
    from pipeline.analysis.meshes import MeshPlan, solve_meshes
    from pipeline.analysis.pilot import known_places
    case = resolve("05", None, {"mesh_factor": 3.0})
    plan = MeshPlan(factors=(3.0, 3.0 * 1.3), formula_loads=True)
    lv, _ = solve_meshes(case, plan, known_places(case), RunContext(comm=MPI.COMM_SELF))
    rows = lv[0].sections["formula_load"]
    ri, ro = 12.5, 18.5
    x_seat = 4 / (3 * math.pi) * (ro ** 3 - ri ** 3) / (ro ** 2 - ri ** 2)
    r = rows["approximate"]
    assert r["mesh_factor"] == pytest.approx(3.0 * 1.3)
    assert r["critical_section"]["M_Nmm"] == pytest.approx(-case.load_N / 2 * (28.75 - x_seat), rel=1e-3)
    assert lv[1].sections["formula_load"] is rows  # the requested level carries the error-bar mesh's rows
