"""Section results (pipeline/post/sections.py) against statics and closed forms.

- The critical section's moment from the FE reactions equals the statics of the applied
  loads (the loads' moment about the section's axis, from the assembled load vector and a
  rigid rotation: no stress involved) to solver tolerance, and the closed-form statics of
  the two pressure distributions to the mesh's faceting.
- On the cantilever (tests/helpers/verification_problems.py): N and M at the clamp equal statics
  (0 and F·L), and the linearised bending stress of a mid-span section equals M·c/I.
- The linearisation is exact for a linear profile; Peterson's fit against chart values.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

import pipeline.fe.elasticity as pe
import pipeline.fe.solve as ps
from helpers import verification_problems as vp
from helpers.verification_problems import BB, BH, BI, BL  # the cantilever's dimensions (mm)
from pipeline.inputs.case import resolve
from pipeline.fe.loads import crosshead_loads
from pipeline.fe.meshing import make_mesh
from pipeline.post.sections import (journal_nominal, ligament_resultants, linearise, linearised_line, peterson_kt_bending,

                                    plane_resultants, sigma_xx_field)


def test_linearisation_is_exact_for_a_linear_profile():
    t = np.linspace(0.0, 25.0, 81)
    a, b = 30.0, -2.4  # MPa, MPa/mm
    m, bend = linearise(a + b * t, t)
    assert m == pytest.approx(a + b * 25.0 / 2, rel=1e-12)
    assert bend == pytest.approx(-b * 25.0 / 2, rel=1e-12)  # value of the linear part at t = 0, minus m
    m2, b2 = linearise(np.full(81, 7.0), t)
    assert m2 == pytest.approx(7.0) and abs(b2) < 1e-12


@pytest.fixture(scope="module")
def no05():
    """No. 05, quarter model, P2 on a coarse mesh: the solution and its loads."""
    case = resolve("05", None, {"mesh_factor": 2.5, "solver": "mumps"})
    m = make_mesh(case.dims, case.model, case.mesh_spec(2.5))
    mat = pe.Material(case.E_MPa, case.nu)
    lc = crosshead_loads(m, case.dims, case.load_N, case.support)
    sol = ps.solve(m.mesh, m.facet_tags, mat, ps.Loads(lc.tractions, lc.constraints), ps.Method(2, "mumps"))
    return case, m, lc, sol, mat


def test_critical_section_moment_is_statics(no05):
    case, m, lc, sol, mat = no05
    d = case.dims
    sym = next(i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == m.facet_ids["symmetry_x"])
    N, M = ligament_resultants(sol, sym, d, 0.25)
    # Statics of the applied loads: the virtual work of the loads in the rigid rotation about
    # the section's axis (x = 0, z = h/2), w = (z - h/2, 0, -x): sum over the load vector.
    V = sol.u.function_space
    v = ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    f = fem.petsc.assemble_vector(fem.form(sum(ufl.inner(t.value, v) * ds(t.marker) for t in lc.tractions)))
    f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    w = fem.Function(V)
    w.interpolate(lambda x: np.vstack([x[2] - d.h3 / 2, 0 * x[0], -x[0]]))
    n_owned = V.dofmap.index_map.size_local * 3
    load_moment = MPI.COMM_WORLD.allreduce(float(np.dot(f.array[:n_owned], w.x.array[:n_owned])), op=MPI.SUM)
    # Σ R_x (z - h/2) = -(loads' moment) for the quarter; M = -Σ R_x (z - h/2), both halves.
    statics = 2 * load_moment
    assert M == pytest.approx(statics, rel=1e-7, abs=1e-6 * abs(statics))
    # The closed form from the two pressure distributions: Q/2 · (bearing centroid - seat centroid).
    ri, ro = d.seat_inner / 2, d.seat_outer / 2
    x_seat = 4 / (3 * math.pi) * (ro ** 3 - ri ** 3) / (ro ** 2 - ri ** 2)
    x_bearing = (d.b1 / 2 + d.rf + d.b6 / 2) / 2
    assert -M == pytest.approx(case.load_N / 2 * (x_bearing - x_seat), rel=3e-3)
    assert abs(N) < 1e-4 * case.load_N  # no axial load on the crosshead: the section force vanishes
    # The section's nominal stresses from its force and moment: N/(w·h) and 6|M|/(w·h²) over
    # both ligaments, w = b1 − di wide and h = h3 high (beam theory), M the statics above.
    from pipeline.post.sections import ligament_sections
    cs = ligament_sections(sol, mat, d, 0.25, sym)["critical_section"]
    w, h = d.b1 - d.d2, d.h3
    assert (cs["width_mm"], cs["height_mm"]) == (w, h)
    assert cs["M_Nmm"] == pytest.approx(statics, rel=1e-7) and cs["N_N"] == N
    assert cs["bending_MPa"] == pytest.approx(6 * abs(statics) / (w * h ** 2), rel=1e-7)
    assert cs["membrane_MPa"] == pytest.approx(N / (w * h), rel=1e-12, abs=1e-12)
    assert cs["nominal_MPa"] == pytest.approx(cs["membrane_MPa"] + 6 * abs(statics) / (w * h ** 2), rel=1e-7)


def test_linearised_ligament_stress_is_near_the_beam_value(no05):
    """Mid-ligament, the linearised bending stress is the section's beam value 6M/(w h²)
    within 10 % (3-D: the bore makes the ligament's stress uneven across its width)."""
    case, m, lc, sol, mat = no05
    d = case.dims
    sym = next(i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == m.facet_ids["symmetry_x"])
    _, M = ligament_resultants(sol, sym, d, 0.25)
    y = (d.d2 / 2 + d.b1 / 2) / 2
    line = linearised_line(sigma_xx_field(sol.u, mat), np.array([1e-6, y, 1e-6]), np.array([1e-6, y, d.h3 - 1e-6]))
    beam = 6 * abs(M) / ((d.b1 - d.d2) * d.h3 ** 2)
    assert line.bending_MPa == pytest.approx(beam, rel=0.10)


def test_cantilever_section_resultants_and_linearised_bending():
    F = 1000.0
    L, h, I = BL, BH, BI
    prob = vp.bar(L, h, BB / 2, lc=3.0, order=2)
    mesh, ids = prob.mesh, prob.ids
    x = ufl.SpatialCoordinate(mesh)
    q = F / (2 * I) * (h ** 2 / 4 - x[1] ** 2)
    mat = pe.Material(210_000.0, 0.3)
    cons = [pe.Constraint(None, marker=ids["x0"]), pe.Constraint(2, marker=ids["z0"])]
    sol = ps.solve(mesh, prob.facet_tags, mat,
                   ps.Loads([pe.Traction(ids["x1"], ufl.as_vector((0 * x[0], -q, 0 * x[0])))], cons), ps.Method(2, "mumps"))
    N, M = plane_resultants(sol, 0, lever_axis=1, centre_mm=0.0)
    # Half the width is modelled (z >= 0): the whole section carries twice this.
    assert abs(2 * N) < 1e-8 * F
    assert 2 * M == pytest.approx(F * L, rel=1e-8)  # hogging at the clamp: top (y > 0) in tension, M > 0
    xs = L / 2
    line = linearised_line(sigma_xx_field(sol.u, mat), np.array([xs, -h / 2 + 1e-9, BB / 4]),
                           np.array([xs, h / 2 - 1e-9, BB / 4]))
    expected = F * (L - xs) * (h / 2) / I  # M c / I at mid-span
    assert abs(line.bending_MPa) == pytest.approx(expected, rel=0.01)
    assert abs(line.membrane_MPa) < 1e-3 * expected


def test_peterson_fit_against_chart_values():
    """Peterson's chart 3.10 (shouldered round bar, bending): for D/d = 1.5 and r/d = 0.1
    charts read Kt ≈ 1.7 (Shigley's Fig. A-15-9 reads 1.68); for D/d = 1.1, r/d = 0.1
    about 1.5; Kt falls as the fillet grows."""
    assert peterson_kt_bending(1.5, 1.0, 0.10) == pytest.approx(1.70, abs=0.06)
    assert peterson_kt_bending(1.1, 1.0, 0.10) == pytest.approx(1.50, abs=0.08)
    assert peterson_kt_bending(1.5, 1.0, 0.05) > peterson_kt_bending(1.5, 1.0, 0.10) > peterson_kt_bending(1.5, 1.0, 0.2)


def test_journal_nominal_moment_is_statics():
    """M at the journal root = Q/2 × the lever to the bearing's middle (closed form)."""
    d = resolve("05").dims
    M, s = journal_nominal(d, 10_000.0)
    assert M == pytest.approx(5000.0 * ((22.5 + 1.5 + 35.0) / 2 - 22.5))
    assert s == pytest.approx(32 * M / (math.pi * 20.0 ** 3))


def test_a_failed_pull_back_takes_the_next_cell_and_never_raises(monkeypatch):
    """A point in the hull of a curved cell but outside the cell itself: DOLFINx's eval
    there raises (Newton's method fails). sigma_xx_at takes the value from the next cell
    holding the point, or leaves NaN; it raises nothing, since a rank that raised would
    leave the others waiting in the allgather."""
    import pipeline.post.sections as sec

    class Links:
        def __init__(self, rows):
            self.rows = rows

        def links(self, i):
            return np.array(self.rows[i], dtype=np.int32)

    class Field:  # cell 7 fails like a bad pull-back; others give 10 × cell number (MPa)
        function_space = type("V", (), {"mesh": type("M", (), {"comm": MPI.COMM_SELF})()})()

        def eval(self, x, cells):
            if int(cells[0]) == 7:
                raise RuntimeError("Newton method failed to converge for non-affine geometry")
            return np.array([10.0 * int(cells[0])])

    rows = [[3], [7, 4], [7], []]
    monkeypatch.setattr(sec.geometry, "compute_collisions", lambda tree, pts: None)
    monkeypatch.setattr(sec.geometry, "compute_colliding_cells", lambda mesh, coll, pts: Links(rows))
    got = sec.sigma_xx_at(sec.SigmaXX(Field(), tree=None), np.zeros((4, 3)))
    assert got[:2].tolist() == [30.0, 40.0]
    assert np.isnan(got[2]) and np.isnan(got[3])


def test_a_section_s_moment_is_taken_about_the_centre_it_is_given():
    """A bar pulled by F at x = L, clamped at x = 0: the clamp's section carries N = F and,
    about an axis at y = c off the bar's own (the load has no moment about y = 0), M = −c·N
    (statics: M = Σ σ_xx (y − c) dA = 0 − c·N). Half the width is modelled: F/2."""
    F, c = 1000.0, 3.0
    prob = vp.bar(40.0, 20.0, 5.0, lc=5.0, order=2)
    ids = prob.ids
    area_half = 20.0 * 5.0
    x = ufl.SpatialCoordinate(prob.mesh)
    pull = ufl.as_vector((F / 2 / area_half + 0 * x[0], 0 * x[0], 0 * x[0]))
    cons = [pe.Constraint(None, marker=ids["x0"]), pe.Constraint(2, marker=ids["z0"])]
    sol = ps.solve(prob.mesh, prob.facet_tags, pe.Material(210_000.0, 0.3), ps.Loads([pe.Traction(ids["x1"], pull)], cons),
                   ps.Method(2, "mumps"))
    N, M = plane_resultants(sol, 0, lever_axis=1, centre_mm=c)
    assert N == pytest.approx(F / 2, rel=1e-8)
    assert M == pytest.approx(-c * F / 2, rel=1e-8)
    N0, M0 = plane_resultants(sol, 0, lever_axis=1, centre_mm=0.0)
    assert N0 == N and abs(M0) <= 1e-8 * F * 20.0
