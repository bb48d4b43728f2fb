"""The contact model of the load-model reference (bench/contact.py, bench/load_reference.py).

Every number asserted comes from outside the code: closed-form areas and volumes of the
plate's bore, the cos θ model's integrals, CalculiX's face numbering, statics (the plate
and the contact carry the quarter's load Q/4; a frictionless cylinder takes no axial
force) and the Hertz line-contact width for a bore with clearance.
"""
import math
import shutil

import numpy as np
import pytest
from mpi4py import MPI

from bench.calculix import FIELD_MAX, LINE_MAX, read_dat_displacements
from bench.contact import (C3D10_FACES, PlateSpec, PressureSamples, _face_points, contact_model, deck,
                           force_summary, nodal_contact_forces, plate_mesh, pressure_summary, solve_contact,
                           stress_samples, surface_faces)
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import LevelTask, set_up
from pipeline.inputs.case import resolve

FACTOR = 5.0  # a coarse crosshead: the checks below hold on any mesh


@pytest.fixture(scope="module")
def coarse():
    """No. 05's quarter crosshead at mesh factor 5 and a coarse plate, zero clearance."""
    case = resolve("05", overrides={"mesh_factor": FACTOR, "solver": "mumps"})
    prob = set_up(case, LevelTask(FACTOR), RunContext(comm=MPI.COMM_SELF))
    spec = PlateSpec(clearance_mm=0.0, size_mm=3.0)
    cm = contact_model(prob.mesh.mesh, prob.mesh.facet_tags, prob.loads, case.dims, spec)
    return case, prob, spec, cm


def test_face_numbering_is_calculix():
    """S1..S4 of a C3D10 are the faces 1-2-3, 1-4-2, 2-4-3, 3-4-1 (CalculiX manual, as
    Abaqus): face k is the one opposite corner 3, 2, 0, 1; mid-side nodes 5-10 sit on
    the edges (1,2) (2,3) (3,1) (1,4) (2,4) (3,4)."""
    edges = {(0, 1): 4, (1, 2): 5, (0, 2): 6, (0, 3): 7, (1, 3): 8, (2, 3): 9}
    opposite = [3, 2, 0, 1]
    for face, opp in zip(C3D10_FACES, opposite):
        corners = face[:3]
        assert set(corners) == {0, 1, 2, 3} - {opp}
        for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0)]):
            assert face[3 + k] == edges[tuple(sorted((corners[a], corners[b])))]


def test_surface_faces_of_one_tet_are_its_four_faces():
    elems = np.arange(10)[None, :]
    on = np.ones(10, bool)
    assert sorted(surface_faces(elems, on)[:, 1].tolist()) == [1, 2, 3, 4]
    on[3] = False  # corner 4 off: only face S1 (1-2-3) has all its corners on
    assert surface_faces(elems, on).tolist() == [[0, 1]]
    on[4:] = False  # mid-side nodes do not count (one may lie off a curved surface)
    assert surface_faces(elems, on).tolist() == [[0, 1]]


def test_plate_bore_area_and_volume_are_the_closed_forms():
    """The quarter plate's bore (y ≥ 0) is half a cylinder: area π·rb·t;
    the plate's mesh volume is the block less half the bore's cross-section times t."""
    d = resolve("05").dims
    spec = PlateSpec(clearance_mm=0.117, size_mm=2.0)
    pm = plate_mesh(d, spec)
    x0, x1 = spec.x_range(d)
    assert (x0, x1) == pytest.approx((22.5 + 1.5, 35.0))  # b1/2 + rf to b6/2
    rb, t = d.dj / 2 + 0.117 / 2, x1 - x0
    X = pm.nodes[pm.elements[pm.bore_faces[:, 0]][np.arange(len(pm.bore_faces))[:, None],
                                                  C3D10_FACES[pm.bore_faces[:, 1] - 1]]]
    from bench.contact import TRI7, TRI7_W, _p2_triangle
    _, dN = _p2_triangle(TRI7)
    t1, t2 = np.einsum("qk,fkj->fqj", dN[:, 0], X), np.einsum("qk,fkj->fqj", dN[:, 1], X)
    area = (np.linalg.norm(np.cross(t1, t2), axis=2) * TRI7_W).sum()
    assert area == pytest.approx(math.pi * rb * t, rel=1e-4)
    p = pm.nodes[pm.elements[:, :4]]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
    assert vol.min() > 0  # every element turned to CalculiX's positive orientation
    h = spec.width_per_dj * d.dj / 2 * ((spec.below_per_dj + spec.above_per_dj) * d.dj + d.dj / 2)
    assert pm.volume_mm3 == pytest.approx(t * (h - math.pi * rb ** 2 / 2), rel=1e-9)


def test_plate_is_held_at_the_face_asked_for():
    """Top: the face 2·dj over the journal axis; bottom: 0.75·dj under the bore."""
    d = resolve("05").dims
    for held, z in (("top", d.h3 / 2 + 2.0 * d.dj), ("bottom", d.h3 / 2 - d.dj / 2 - 0.75 * d.dj)):
        pm = plate_mesh(d, PlateSpec(size_mm=3.0, held=held))
        assert pm.top.size > 10 and np.allclose(pm.nodes[pm.top, 2], z)
    with pytest.raises(ValueError):
        plate_mesh(d, PlateSpec(held="side"))


def test_cos_model_summary_of_the_cos_pressure_is_the_model():
    """Samples of p0·cos θ on a fine grid of the quarter journal's lower surface carry
    Q/4 up, centred mid-length (lever 7.0 mm for No. 05), with the cos θ shares."""
    d = resolve("05").dims
    spec = PlateSpec()
    load = 10_000.0
    rj, x0, x1 = d.dj / 2, d.b1 / 2 + d.rf, d.b6 / 2
    p0 = load / (math.pi * rj * (x1 - x0))
    th = (np.arange(900) + 0.5) * (90 / 900)
    xs = x0 + (np.arange(110) + 0.5) * ((x1 - x0) / 110)
    T, X = np.meshgrid(th, xs)
    r = np.radians(T.ravel())
    xyz = np.column_stack([X.ravel(), rj * np.sin(r), d.h3 / 2 - rj * np.cos(r)])
    area = np.full(r.size, rj * math.radians(90 / 900) * (x1 - x0) / 110)
    s = PressureSamples(xyz=xyz, theta_deg=T.ravel(), p_MPa=p0 * np.cos(r), area_mm2=area)
    out = pressure_summary(s, d, spec, load)
    assert out["force_z_N"] == pytest.approx(load / 4, rel=1e-5)
    assert out["lever_mm"] == pytest.approx(7.0, rel=1e-9)
    for row in out["theta"]:
        assert row["force_share"] == pytest.approx(row["cos_model_force_share"], abs=1e-5)
        assert row["p_mean_MPa"] == pytest.approx(row["cos_model_p_mean_MPa"], rel=1e-4)
    assert sum(r["cos_model_force_share"] for r in out["theta"]) == pytest.approx(1.0, abs=1e-12)
    # The cos θ model's amplitude: Q/2 per journal = p0·R·L·π/2 over its lower half, so
    # p0 = 2Q/(π·dj·L) (docs/design.md §3); No. 05, L = 35 − 24 = 11 mm: 28.937 MPa.
    assert out["p0_MPa"] == pytest.approx(2 * load / (math.pi * d.dj * (d.b6 / 2 - d.b1 / 2 - d.rf)), rel=1e-12)


def test_dat_reader_takes_the_last_increment(tmp_path):
    """A nonlinear step prints U once per increment; the end of the step is the last."""
    block = " displacements (vx,vy,vz) for set NALL and time  {t}\n\n" \
            "         1  {u:.6E}  0.000000E+00  0.000000E+00\n" \
            "         2  0.000000E+00  {u:.6E}  0.000000E+00\n\n"
    (tmp_path / "job.dat").write_text(block.format(t=0.5, u=1.0) + block.format(t=1.0, u=2.0))
    U = read_dat_displacements(tmp_path / "job.dat", 2)
    assert U[0, 0] == 2.0 and U[1, 1] == 2.0


def test_deck_fits_calculix_and_names_its_surfaces(coarse):
    case, prob, spec, cm = coarse
    text = deck(cm, prob.material)
    lines = text.splitlines()
    assert max(len(s) for s in lines) < LINE_MAX
    for s in lines[2:]:  # after the heading's title line
        if s and not s.startswith("*"):
            assert all(len(f.strip()) <= FIELD_MAX for f in s.split(","))
    for key in ("*SURFACE, NAME=SJOURNAL, TYPE=ELEMENT", "*SURFACE, NAME=SBORE, TYPE=ELEMENT",
                "*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE", "SJOURNAL,SBORE",
                "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR"):
        assert key in lines
    # The journal faces lie on the journal's lower half (radius dj/2 about y = 0, z = h3/2)
    # from the fillet's run-out to the tip; the bore faces on the bore of dj + clearance.
    d = case.dims
    pts, area, _, _ = _face_points(cm)
    r = np.hypot(pts[..., 1], pts[..., 2] - d.h3 / 2)
    assert np.abs(r - d.dj / 2).max() < 2e-3 * d.dj  # quadratic faces of a cylinder
    assert pts[..., 0].min() >= d.b1 / 2 + d.rf - 1e-6 and pts[..., 0].max() <= d.b6 / 2 + 1e-6
    assert area.sum() == pytest.approx(math.pi / 2 * d.dj / 2 * (d.b6 / 2 - d.b1 / 2 - d.rf), rel=1e-3)


@pytest.mark.slow  # a CalculiX contact solve: 3.7 s
@pytest.mark.skipif(shutil.which("ccx") is None, reason="ccx missing: tools/setup.sh installs calculix-ccx")
def test_tiny_contact_case_balances_the_load(coarse):
    """The plate's held face carries the quarter's load Q/4, and so do the contact's nodal
    forces on the journal; a frictionless cylinder takes no axial force; the contact's
    centre lies on the plate."""
    case, prob, spec, cm = coarse
    sol = solve_contact(cm, prob.material, increments=1)
    q4 = case.load_N / 4
    assert abs(sol.spring_force_N) < 1e-5 * q4
    assert sol.attempts >= 1 and sol.iterations >= sol.attempts
    assert sol.plate_reaction_N[2] + sol.spring_force_N == pytest.approx(q4, rel=1e-4)
    xyz, F = nodal_contact_forces(cm, sol.u, prob.loads, prob.material)
    f = force_summary(xyz, F, case.dims, case.load_N)
    assert f["force_z_N"] + sol.spring_force_N == pytest.approx(q4, rel=1e-4)
    assert abs(f["force_x_N"]) < 1e-3 * q4
    x0, x1 = spec.x_range(case.dims)
    assert x0 < f["centre_x_mm"] < x1
    # The journal's own stress at its surface carries the load too, to the accuracy of a
    # coarse mesh's surface stress.
    p = pressure_summary(stress_samples(cm, sol.u, prob.material, case.dims), case.dims, spec, case.load_N)
    assert p["force_z_N"] == pytest.approx(q4, rel=0.1)
