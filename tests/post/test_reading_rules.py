"""The reading rule of each peak (pipeline/analysis/level.py: read_peaks; docs/design.md §5):
the shoulder fillet reads the midpoint of its unaveraged and averaged values, every other
place its unaveraged value; the global peak is the larger of the two, the critical peak
the unaveraged value over |x| ≤ di/2 (MPa, mm).

The stresses are planted: a von Mises field in DG1 on a box around No. 05's quarter, zero
except at chosen nodes, and averaged readings given as values at chosen points. Every
expected number is one of the planted ones or the midpoint of two, worked out here.
"""
from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem
from dolfinx.mesh import CellType, create_box
from mpi4py import MPI

from pipeline.analysis.level import read_peaks
from pipeline.inputs.case import resolve
from pipeline.post.peaks import MIDPOINT, UNAVERAGED

CASE = resolve("05")
D = CASE.dims
# Places on No. 05 (mm), each a node of the box below (spacing 2.5 × 4 × 5 mm): in the
# fillet's region (x = b1/2 = 22.5, 7.5 mm below the journal's axis: within dj/2 + rf of it),
# beside the bore (x = 0 ≤ di/2, bottom face) and on the body away from both (x = 20 < b1/2
# − 0.02·h3, top face).
FILLET = np.array([22.5, 0.0, 5.0])
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


def planted(unaveraged: dict, averaged: dict):
    """A DG1 von Mises field on a box over the quarter, zero but at the DOF nearest each key
    of ``unaveraged`` (a place → MPa), and the averaged readings: (values, points)."""
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([35.0, 24.0, 25.0])], DIVISIONS,
                      CellType.tetrahedron)
    vm = fem.Function(fem.FunctionSpace(mesh, ("DG", 1)))
    xyz = vm.function_space.tabulate_dof_coordinates()
    vm.x.array[:] = 0.0
    for place, value in unaveraged.items():
        at = np.linalg.norm(xyz - place, axis=1) < 1e-9
        assert at.any()
        vm.x.array[at] = value  # every cell's DG node at that point
    points = np.array(list(averaged))
    return vm, (np.array(list(averaged.values())), points)


def test_the_fillet_reads_its_midpoint_and_the_global_peak_is_the_larger():
    """Fillet unaveraged 120 and averaged 100 → its reading is 110; the body's unaveraged 105
    (averaged 104) is below: the global peak is the fillet's 110, half-width 10, rule midpoint."""
    vm, averaged = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0, tuple(BORE): 60.0},
                           {tuple(FILLET): 100.0, tuple(BODY): 104.0, tuple(BORE): 59.0})
    glob, crit = read_peaks(CASE, vm, averaged)
    assert glob.rule == MIDPOINT and glob.value_MPa == pytest.approx((120.0 + 100.0) / 2)
    assert glob.half_width_MPa == pytest.approx((120.0 - 100.0) / 2)
    assert np.allclose(glob.location_mm, FILLET, atol=1e-9)
    assert crit.rule == UNAVERAGED and crit.value_MPa == 60.0 and crit.averaged.value_MPa == 59.0


def test_a_place_off_the_fillet_reads_unaveraged_and_wins_when_larger():
    """Body unaveraged 112 (averaged 80: not used) against the fillet's midpoint 110: the
    global peak is the body's 112, read unaveraged (a midpoint there would be 96)."""
    vm, averaged = planted({tuple(FILLET): 120.0, tuple(BODY): 112.0, tuple(BORE): 60.0},
                           {tuple(FILLET): 100.0, tuple(BODY): 80.0, tuple(BORE): 59.0})
    glob, _ = read_peaks(CASE, vm, averaged)
    assert glob.rule == UNAVERAGED and glob.value_MPa == 112.0
    assert np.allclose(glob.location_mm, BODY, atol=1e-9)


def test_the_critical_peak_is_the_unaveraged_value_beside_the_bore_only():
    """The critical region is |x| ≤ di/2: the bore edge's 70 (averaged 50) is its peak, read
    unaveraged, though the fillet and the body hold more."""
    vm, averaged = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0, tuple(BORE): 70.0},
                           {tuple(FILLET): 100.0, tuple(BODY): 104.0, tuple(BORE): 50.0})
    _, crit = read_peaks(CASE, vm, averaged)
    assert crit.rule == UNAVERAGED and crit.value_MPa == 70.0 and crit.averaged.value_MPa == 50.0
    assert np.allclose(crit.location_mm, BORE, atol=1e-9)


def test_without_a_fillet_every_place_reads_unaveraged():
    """rf = 0: no fillet region; the largest unaveraged value anywhere is the global peak."""
    sharp = resolve("05", None, {"dims.rf": 0.0})
    vm, averaged = planted({tuple(FILLET): 120.0, tuple(BODY): 105.0}, {tuple(FILLET): 100.0, tuple(BODY): 104.0})
    glob, _ = read_peaks(sharp, vm, averaged)
    assert glob.rule == UNAVERAGED and glob.value_MPa == 120.0
