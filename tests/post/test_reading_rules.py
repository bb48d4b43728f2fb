"""The reading rule of each peak (pipeline/analysis/level.py: read_peaks; docs/design.md §5),
node by node: at a node of the shoulder fillet the reported value is the midpoint of that
node's unaveraged and averaged readings, at every other node its unaveraged reading; the
global peak is the node of the largest reported value, the critical peak that node over
|x| ≤ di/2 (MPa, mm).

The readings are planted: both readings at the nodes of a box around No. 05's quarter,
zero except at chosen nodes. Every expected number is one of the planted ones or the
midpoint of two at one node, worked out here.
"""
from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem
from dolfinx.mesh import CellType, create_box
from mpi4py import MPI

from pipeline.analysis.level import read_peaks
from pipeline.inputs.case import resolve
from pipeline.post.features import fillet_region
from pipeline.post.peaks import MIDPOINT, UNAVERAGED, NodeReadings

CASE = resolve("05")
D = CASE.dims
# Places on No. 05 (mm), each a node of the box below (spacing 2.5 × 4 × 5 mm): in the
# fillet's region (x = b1/2 = 22.5, 7.5 mm below the journal's axis: within dj/2 + rf of it),
# beside the bore (x = 0 ≤ di/2, bottom face) and on the body away from both (x = 20 < b1/2
# − 0.02·h3, top face).
FILLET = np.array([22.5, 0.0, 5.0])
FILLET_2 = np.array([22.5, 4.0, 5.0])    # another node of the fillet's region, 4 mm from FILLET
BORE = np.array([0.0, 12.0, 0.0])
BODY = np.array([20.0, 16.0, 25.0])
DIVISIONS = [14, 6, 5]  # over 35 × 24 × 25 mm


def test_the_places_are_where_the_rules_say():
    """docs/design.md §5: the fillet's region is b1/2 − 0.02·h3 ≤ |x| ≤ b1/2 + rf + 0.02·h3
    within dj/2 + rf + 0.02·h3 of the journal's axis; the critical region |x| ≤ di/2."""
    tol = 0.02 * D.h3
    def in_fillet(p):
        r = np.hypot(p[1], p[2] - D.h3 / 2)
        return D.b1 / 2 - tol <= abs(p[0]) <= D.b1 / 2 + D.rf + tol and r < D.dj / 2 + D.rf + tol
    assert in_fillet(FILLET) and not in_fillet(BODY) and not in_fillet(BORE)
    assert abs(BORE[0]) <= D.d2 / 2 and abs(BODY[0]) > D.d2 / 2 and abs(FILLET[0]) > D.d2 / 2


def planted(unaveraged: dict, averaged: dict, case=None) -> NodeReadings:
    """Both readings at the nodes of a box over the quarter: zero but at the node of each key
    (a place → MPa), the midpoint taken on the case's fillet."""
    case = case or CASE
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([35.0, 24.0, 25.0])], DIVISIONS,
                      CellType.tetrahedron)
    space = fem.FunctionSpace(mesh, ("CG", 1))
    n = space.dofmap.index_map.size_local
    xyz = space.tabulate_dof_coordinates()[:n]
    values = []
    for planted_at in (unaveraged, averaged):
        v = np.zeros(n)
        for place, value in planted_at.items():
            at = np.linalg.norm(xyz - place, axis=1) < 1e-9
            assert at.sum() == 1, place
            v[at] = value
        values.append(v)
    fillet = fillet_region(case)
    midpoint = np.zeros(n, dtype=bool) if fillet is None else fillet(xyz)
    return NodeReadings(vm=None, space=space, xyz=xyz, unaveraged=values[0], averaged=values[1], midpoint=midpoint)


def test_the_fillet_reads_its_midpoint_and_the_global_peak_is_the_larger():
    """Fillet unaveraged 120 and averaged 100 → its reading is 110; the body's unaveraged 105
    (averaged 104) is below: the global peak is the fillet's 110, half-width 10, rule midpoint."""
    readings = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0, tuple(BORE): 60.0},
                       {tuple(FILLET): 100.0, tuple(BODY): 104.0, tuple(BORE): 59.0})
    glob, crit = read_peaks(CASE, readings)
    assert glob.rule == MIDPOINT and glob.value_MPa == pytest.approx((120.0 + 100.0) / 2)
    assert glob.half_width_MPa == pytest.approx((120.0 - 100.0) / 2)
    assert np.allclose(glob.location_mm, FILLET, atol=1e-9)
    assert crit.rule == UNAVERAGED and crit.value_MPa == 60.0 and crit.averaged.value_MPa == 59.0


def test_a_place_off_the_fillet_reads_unaveraged_and_wins_when_larger():
    """Body unaveraged 112 (averaged 80: not used) against the fillet's midpoint 110: the
    global peak is the body's 112, read unaveraged (a midpoint there would be 96)."""
    readings = planted({tuple(FILLET): 120.0, tuple(BODY): 112.0, tuple(BORE): 60.0},
                       {tuple(FILLET): 100.0, tuple(BODY): 80.0, tuple(BORE): 59.0})
    glob, _ = read_peaks(CASE, readings)
    assert glob.rule == UNAVERAGED and glob.value_MPa == 112.0
    assert np.allclose(glob.location_mm, BODY, atol=1e-9)


def test_the_critical_peak_is_the_unaveraged_value_beside_the_bore_only():
    """The critical region is |x| ≤ di/2: the bore edge's 70 (averaged 50) is its peak, read
    unaveraged, though the fillet and the body hold more."""
    readings = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0, tuple(BORE): 70.0},
                       {tuple(FILLET): 100.0, tuple(BODY): 104.0, tuple(BORE): 50.0})
    _, crit = read_peaks(CASE, readings)
    assert crit.rule == UNAVERAGED and crit.value_MPa == 70.0 and crit.averaged.value_MPa == 50.0
    assert np.allclose(crit.location_mm, BORE, atol=1e-9)


def test_without_a_fillet_every_place_reads_unaveraged():
    """rf = 0: no fillet region; the largest unaveraged value anywhere is the global peak."""
    sharp = resolve("05", None, {"dims.rf": 0.0})
    readings = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0}, {tuple(FILLET): 100.0, tuple(BODY): 104.0}, sharp)
    glob, _ = read_peaks(sharp, readings)
    assert glob.rule == UNAVERAGED and glob.value_MPa == 120.0


def test_the_midpoint_joins_two_readings_of_one_node():
    """Two fillet nodes: FILLET with unaveraged 120 and averaged 90 (midpoint 105), FILLET_2
    with 110 and 104 (midpoint 107). Node by node the global peak is FILLET_2's 107, with
    both its readings; the midpoint of the two largest readings of different nodes,
    (120 + 104) / 2 = 112, is no node's value and is not reported."""
    assert fillet_region(CASE)(np.array([FILLET, FILLET_2])).all()
    readings = planted({tuple(FILLET): 120.0, tuple(FILLET_2): 110.0}, {tuple(FILLET): 90.0, tuple(FILLET_2): 104.0})
    glob, _ = read_peaks(CASE, readings)
    assert glob.rule == MIDPOINT and glob.value_MPa == pytest.approx((110.0 + 104.0) / 2)
    assert (glob.unaveraged.value_MPa, glob.averaged.value_MPa) == (110.0, 104.0)
    assert np.allclose(glob.location_mm, FILLET_2, atol=1e-9) and glob.averaged.location_mm == glob.location_mm


def test_each_peak_is_the_largest_reported_value_at_its_node():
    """The field file's contract: each peak's value is the reported array at its node, and
    the global peak is the largest reported value anywhere."""
    readings = planted({tuple(FILLET): 120.0, tuple(FILLET_2): 110.0, tuple(BODY): 105.0, tuple(BORE): 70.0},
                       {tuple(FILLET): 90.0, tuple(FILLET_2): 104.0, tuple(BODY): 104.0, tuple(BORE): 50.0})
    reported = readings.reported
    for p in read_peaks(CASE, readings):
        at = np.linalg.norm(readings.xyz - p.location_mm, axis=1) < 1e-9
        assert reported[at] == pytest.approx([p.value_MPa], rel=1e-15)
    assert read_peaks(CASE, readings)[0].value_MPa == reported.max()


def test_a_solution_is_read_with_the_midpoint_on_the_fillet_s_nodes_only():
    """pipeline.analysis.level.peaks_of: the readings of a displacement on the box take the
    midpoint at the nodes of the fillet's region (FILLET among them) and nowhere else."""
    from pipeline.analysis.level import peaks_of
    from pipeline.fe.elasticity import Material
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([35.0, 24.0, 25.0])], DIVISIONS,
                      CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 2)))
    u.interpolate(lambda x: 1e-3 * np.vstack([x[0] * x[1], x[2], x[0] ** 2]))
    readings, _, _ = peaks_of(CASE, u, Material(E=CASE.E_MPa, nu=CASE.nu))
    expected = fillet_region(CASE)(readings.xyz)
    assert np.array_equal(readings.midpoint, expected) and 0 < expected.sum() < len(expected)
    at = lambda p: np.linalg.norm(readings.xyz - p, axis=1) < 1e-9   # noqa: E731
    assert readings.midpoint[at(FILLET)].all() and not readings.midpoint[at(BODY) | at(BORE)].any()
