"""FE model of No. 05: loads integrate to Q, quarter = full, coarse meshes (mm, N, MPa)."""
import math

import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from geometry.table import lookup
from pipeline.inputs.case import resolve
from pipeline.fe.loads import crosshead_loads
from pipeline.fe.meshing import make_mesh, owners

D05 = lookup("05").dims
Q = 10_000.0


def integrate(mesh, expr, measure):
    return mesh.comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)


@pytest.mark.slow
@pytest.mark.parametrize("model,share", [("quarter", 0.25)])
def test_loads_integrate_to_q_and_match_closed_form_pressures(model, share):
    case = resolve("05", overrides={"mesh_factor": 2.0})
    m = make_mesh(case.dims, model, case.mesh_spec())
    lc = crosshead_loads(m, case.dims, Q, "bearing")
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    seat, bearing = lc.tractions
    fz_seat = integrate(m.mesh, seat.value[2], ds(m.facet_ids["seat"]))
    fz_bear = integrate(m.mesh, bearing.value[2], ds(m.facet_ids["journal_bearing"]))
    assert fz_seat == pytest.approx(-share * Q, rel=1e-10)
    assert fz_bear == pytest.approx(share * Q, rel=1e-10)
    assert abs(fz_seat + fz_bear) < 1e-6 * Q
    # The mesh-scaled pressures differ from the closed forms only by the faceting error.
    p_seat_closed = Q / (math.pi / 4 * (37 ** 2 - 25 ** 2))
    p0_closed = Q / (math.pi * 10 * 11)       # p0 = Q / (π rj Lj), docs/design.md §3
    area = integrate(m.mesh, fem.Constant(m.mesh, 1.0), ds(m.facet_ids["seat"]))
    assert share * Q / area == pytest.approx(p_seat_closed, rel=2e-3)
    # p0 from the scaled load: the vertical resultant of p0·cos²θ over the faceted half-cylinder.
    zc = D05.h3 / 2
    xs = ufl.SpatialCoordinate(m.mesh)
    cos_t = (zc - xs[2]) / ufl.sqrt(xs[1] ** 2 + (xs[2] - zc) ** 2)
    unit = integrate(m.mesh, cos_t * cos_t, ds(m.facet_ids["journal_bearing"]))
    assert share * Q / unit == pytest.approx(p0_closed, rel=5e-3)


# Quarter against full model: tests/verification/test_invariance.py (tolerance from the quarter model's own error bar).


def test_meshes_are_shared_out_largest_first():
    """meshing.owners: the error bar's meshes (costs factor^-3 at x1, x1.3, x1.69) on 2 ranks:
    the finest alone on rank 0, the two coarser (together 0.66 of it) on rank 1; one rank
    takes everything; ties go to the lower rank."""
    costs = [f ** -3 for f in (1.0, 1.3, 1.69)]
    assert owners(costs, 2) == [0, 1, 1]
    assert owners(costs, 1) == [0, 0, 0]
    assert owners(costs, 4) == [0, 1, 2]
    assert owners([1.0, 1.0, 1.0, 1.0], 2) == [0, 1, 0, 1]


def test_error_bar_meshes_are_solved_one_per_rank_rank_0_least():
    """run.error_bar_ranks: the requested mesh on all ranks (None), the coarser ones shared
    out largest first, counting from the last rank (rank 0 also starts the picture)."""
    from pipeline.analysis.meshes import error_bar_ranks
    assert error_bar_ranks([1.0, 1.3, 1.69], 2) == [None, 1, 0]
    assert error_bar_ranks([0.77, 1.0, 1.3, 1.69], 2) == [None, 1, 0, 0]  # 1.0 against 0.66
    assert error_bar_ranks([1.0, 1.3, 1.69], 1) == [None, 0, 0]
    assert error_bar_ranks([1.0], 4) == [None]
