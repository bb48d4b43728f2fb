"""CalculiX peer (bench.calculix) and the bench driver (bench.run) on a coarse mesh.

CalculiX and DOLFINx get the same second-order mesh, supports and consistent nodal loads,
so they solve the same discrete problem up to the element quadrature: C3D10 integrates
the stiffness with 4 points (degree 2, exact on straight tets), DOLFINx with degree 5
on the curved P2 geometry. With DOLFINx forced to degree 2 the two must agree to the
7 significant digits CalculiX prints displacements with; with DOLFINx's own quadrature
they differ only where elements are curved (the shoulder fillet).
"""
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx.fem.petsc import LinearProblem
from mpi4py import MPI

from bench.calculix import FIELD_MAX, LINE_MAX, fmt, read_dat_displacements, solve_ccx
from pipeline.inputs.case import resolve
from pipeline.fe.loads import crosshead_loads
from pipeline.fe.meshing import make_mesh
from pipeline.post.peaks import peak, von_mises
from pipeline.post.features import critical_region
from pipeline.fe.elasticity import Material, strain, stress
from pipeline.fe.assembly import dirichlet_bc
from pipeline.fe.solve import Loads, Method, solve


ROOT = Path(__file__).resolve().parents[2]
FACTOR = 2.0


@pytest.fixture(scope="module")
def coarse(tmp_path_factory):
    """No. 05 quarter at mesh factor 2: DOLFINx P2 (MUMPS) and CalculiX on one mesh."""
    assert shutil.which("ccx"), "ccx missing: tools/setup.sh installs calculix-ccx"
    case = resolve("05", overrides={"mesh_factor": FACTOR})
    m = make_mesh(case.dims, case.model, case.mesh_spec(FACTOR), comm=MPI.COMM_SELF)
    mat = Material(E=case.E_MPa, nu=case.nu)
    lc = crosshead_loads(m, case.dims, case.load_N, case.support)
    sol = solve(m.mesh, m.facet_tags, mat, Loads(lc.tractions, lc.constraints), Method(2, "mumps"))
    work = tmp_path_factory.mktemp("ccx")
    cx = solve_ccx(m.mesh, m.facet_tags, lc, mat, workdir=work)
    return dict(case=case, m=m, mat=mat, lc=lc, sol=sol, cx=cx, work=work)


def peaks(u, mat, case):
    vm = von_mises(u, mat)
    return peak(vm).value_MPa, peak(vm, critical_region(case)).value_MPa


def test_float_fields_fit_calculix():
    for x in (-3.21991607979353e-07, -1.234567890123456e-300, 123456789012345.6, -0.1 / 3, 1e-20, 0.0):
        s = fmt(x)
        assert len(s) <= FIELD_MAX
        assert float(s) == pytest.approx(x, rel=1e-11, abs=0)


@pytest.mark.slow
def test_inp_fields_and_lines(coarse):
    text = (coarse["work"] / "job.inp").read_text()
    lines = text.splitlines()
    assert max(len(s) for s in lines) <= LINE_MAX
    longest = max(len(f.strip()) for s in lines if not s.startswith("**") for f in s.split(","))
    assert longest <= FIELD_MAX
    # Every number written carries 12 significant digits at most.
    node_block = lines[lines.index("*NODE, NSET=NALL") + 1:lines.index("*ELEMENT, TYPE=C3D10, ELSET=EALL")]
    xyz = np.array([[float(v) for v in s.split(",")[1:]] for s in node_block])
    assert np.abs(xyz - coarse["cx"].model.nodes).max() <= 1e-11 * np.abs(xyz).max()


@pytest.mark.slow
def test_c3d10_node_order_and_orientation(coarse):
    model = coarse["cx"].model
    x = model.nodes[model.elements - 1]                          # (E, 10, 3)
    edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]      # C3D10 nodes 5..10
    mids = np.stack([0.5 * (x[:, a] + x[:, b]) for a, b in edges], axis=1)  # (E, 6, 3)
    # dist[e, i, j]: mid-side node i of element e to the midpoint of edge j.
    dist = np.linalg.norm(x[:, 4:, None, :] - mids[:, None, :, :], axis=3)
    length = np.stack([np.linalg.norm(x[:, a] - x[:, b], axis=1) for a, b in edges], axis=1)
    own = dist[:, np.arange(6), np.arange(6)]
    # Mid-side nodes sit at or near their own edge's midpoint: curved boundary edges bow
    # out by a fraction of their length (measured with gmsh's high-order optimiser: 92 %
    # within 2 % of it, all within 32 %); a wrong order would put them about half an edge
    # away from it and onto another edge's midpoint (the argmin check below).
    assert np.all(own < 0.4 * length)
    assert np.mean(own < 0.02 * length) > 0.8
    assert np.mean(dist.argmin(axis=2) == np.arange(6)) > 0.99  # measured 0.9988
    v = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    assert np.all(v > 0)


@pytest.mark.slow
def test_supports_and_loads_match_the_pipeline(coarse):
    model, d, lc = coarse["cx"].model, coarse["case"].dims, coarse["lc"]
    X = model.nodes
    assert np.all(np.abs(X[model.fixed[0] - 1, 0]) < 1e-9)
    assert np.all(np.abs(X[model.fixed[1] - 1, 1]) < 1e-9)
    np.testing.assert_allclose(X[model.fixed[2] - 1], [[0.0, d.b1 / 2, 0.0]], atol=1e-9)
    # Consistent nodal forces carry the mesh-scaled resultants: Q/4 down on the seat, up on the journal.
    fz = model.loads[:, 2]
    top = X[:, 2] > d.h3 - 1e-9
    assert fz[top].sum() == pytest.approx(lc.seat_force_z_N, rel=1e-9)
    assert fz[~top].sum() == pytest.approx(lc.support_force_z_N, rel=1e-9)
    assert abs(fz.sum()) < 1e-9 * coarse["case"].load_N


@pytest.mark.slow
def test_same_discrete_problem_with_calculix_quadrature(coarse):
    """DOLFINx with CalculiX's 4-point rule (degree 2) reproduces CalculiX: measured 3e-7 in
    u (the .dat's 7 significant digits) and ~1e-5 in the peaks; asserted 2e-6 and 2e-4."""
    m, mat, lc, case, cx = coarse["m"], coarse["mat"], coarse["lc"], coarse["case"], coarse["cx"]
    V = cx.u.function_space
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    a = ufl.inner(stress(u, mat), strain(v)) * ufl.dx(metadata={"quadrature_degree": 2})
    L = sum(ufl.inner(t.value, v) * ds(t.marker) for t in lc.tractions)
    bcs = [bc for c in lc.constraints for bc in dirichlet_bc(V, m.facet_tags, c)[0]]
    u2 = LinearProblem(a, L, bcs=bcs, petsc_options={
        "ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}).solve()
    ua, ub = u2.x.array.reshape(-1, 3), cx.u.x.array.reshape(-1, 3)
    du = np.linalg.norm(ua - ub, axis=1).max() / np.linalg.norm(ua, axis=1).max()
    assert du < 2e-6
    p_d, c_d = peaks(u2, mat, case)
    p_c, c_c = peaks(cx.u, mat, case)
    assert p_c == pytest.approx(p_d, rel=2e-4)
    assert c_c == pytest.approx(c_d, rel=2e-4)


@pytest.mark.slow
def test_peaks_agree_with_pipeline(coarse):
    """Against the pipeline's own solve (degree-5 quadrature): the critical (ligament) peak
    sits on straight elements and agrees to ~1e-4 (asserted 1e-3); the global peak sits on
    the curved fillet, where 4- against degree-5 quadrature changes it by 2-3 % on this
    coarse mesh (0.2 % at mesh factor 0.9; asserted 5 %). Displacements: ~1e-4."""
    mat, case, cx, sol = coarse["mat"], coarse["case"], coarse["cx"], coarse["sol"]
    p_d, c_d = peaks(sol.u, mat, case)
    p_c, c_c = peaks(cx.u, mat, case)
    assert c_c == pytest.approx(c_d, rel=1e-3)
    assert p_c == pytest.approx(p_d, rel=0.05)
    ua, ub = sol.u.x.array.reshape(-1, 3), cx.u.x.array.reshape(-1, 3)
    assert np.linalg.norm(ua - ub, axis=1).max() / np.linalg.norm(ua, axis=1).max() < 1e-3


def test_dat_reader_rejects_missing_nodes(tmp_path):
    p = tmp_path / "x.dat"
    p.write_text("\n displacements (vx,vy,vz) for set NALL and time  0.1000000E+01\n\n"
                 "         1  1.000000E-03  0.000000E+00 -2.000000E-03\n")
    with pytest.raises(Exception):
        read_dat_displacements(p, 2)
    np.testing.assert_allclose(read_dat_displacements(p, 1), [[1e-3, 0.0, -2e-3]])


@pytest.mark.slow
def test_bench_quick(tmp_path):
    """--quick: 2 levels, P2 pmg + mumps + CalculiX, one repeat; every output written. Run
    with the run cache on, as `make bench` is: every point still meshes (points at the same
    factor share a mesh, so a cache hit would time ~1 ms)."""
    ref = tmp_path / "ref.json"
    ref.write_text(json.dumps({"case": {"size": "05", "model": "quarter", "support": "bearing"},
                               "convergence": {"peak": {"extrapolated": 110.0, "status": "converged"},
                                               "critical": {"extrapolated": 66.5, "status": "converged"}}}))
    out = tmp_path / "bench"
    p = subprocess.run([sys.executable, "-m", "bench.run", "--quick", "--no-warmup",
                        "--reference", str(ref), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=1800,
                       env=dict(os.environ, CROSSHEAD_NO_CACHE="0"))
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    data = json.loads((out / "bench.json").read_text())
    rows = data["rows"]
    assert {(r["kind"], r["solver"]) for r in rows} == {("dolfinx", "pmg"), ("dolfinx", "mumps"),
                                                        ("calculix", "ccx-spooles")}
    assert len(rows) == 6 and all("error" not in r for r in rows)
    for r in rows:
        assert r["t_total"] > 0 and r["mem_MiB"] > 0 and r["dofs"] > 0
        assert r["t_mesh"] > 0.02, r  # meshed, not taken from the run cache
        assert math.isfinite(r["peak_err"]) and math.isfinite(r["critical_err"])
    by = {(r["kind"], r["solver"], r["factor"]): r for r in rows}
    for f in (2.0, 1.5):  # same mesh, same problem: MUMPS and p-multigrid agree, CalculiX is close
        g, mu, c = by["dolfinx", "pmg", f], by["dolfinx", "mumps", f], by["calculix", "ccx-spooles", f]
        assert g["dofs"] == mu["dofs"] == c["dofs"]
        assert g["critical_MPa"] == pytest.approx(mu["critical_MPa"], rel=1e-6)
        assert c["critical_MPa"] == pytest.approx(mu["critical_MPa"], rel=1e-3)
    assert set(data["summary"]) >= {"both", "critical", "scaling"}
    assert (out / "bench.png").stat().st_size > 10_000
    assert (out / "bench.csv").read_text().count("\n") == 7
    assert "time to 1 %" in p.stdout


def test_bench_ranks_at_all_repeats_every_point_on_more_cores():
    """--ranks-at all: every 1-core point once more on 2 cores, the pipeline as 2 MPI ranks
    and CalculiX as one process with 2 threads; the default keeps 2 ranks on the finest P2
    mesh only. (Matrix only; nothing is solved.)"""
    from bench import run as bench
    argv = ["--orders", "2,3", "--solvers", "mumps", "--factors", "4.0,1.3", "--p3-factors", "2.5",
            "--ccx-solvers", "iterative", "--ranks", "1,2", "--pilot", "on"]
    every = bench.build_matrix(bench.make_parser().parse_args(argv + ["--ranks-at", "all"]))
    one = [(s, r, t) for s, r, t in every if s.get("threads", 1) * r * t == 1]
    two = [(s, r, t) for s, r, t in every if (s, r, t) not in one]
    assert len(one) == len(two) == 5   # P2 x2 factors, P3 x1, CalculiX x2 factors
    for (s1, _, _), (s2, r2, t2) in zip(one, two):
        if s1["kind"] == "calculix":
            assert (r2, t2, s2["threads"]) == (1, 2, 2) and dict(s2, threads=1) == s1
        else:
            assert (r2, t2) == (2, 1) and s2 == s1
    finest = bench.build_matrix(bench.make_parser().parse_args(argv))
    multi = [(s, r) for s, r, _ in finest if r > 1 or s.get("threads", 1) > 1]
    assert {(s["kind"], s["factor"]) for s, _ in multi} == {("dolfinx", 1.3), ("calculix", 1.3)}


def test_bench_ranks_at_targets_adds_the_default_solver_and_calculix_on_every_level():
    """--ranks-at targets: on 2 cores the finest P2 mesh with every solver (the scaling
    check), and P2 pmg and CalculiX at every factor (the time to 1 % on both cores); no P3,
    no other solver on the coarser meshes. (Matrix only; nothing is solved.)"""
    from bench import run as bench
    argv = ["--orders", "2,3", "--solvers", "pmg,mumps", "--factors", "4.0,2.5,1.3", "--p3-factors", "2.5",
            "--ccx-solvers", "iterative,spooles", "--ranks", "1,2", "--pilot", "on", "--ranks-at", "targets"]
    pts = bench.build_matrix(bench.make_parser().parse_args(argv))
    two = {(s["kind"], s.get("solver") or s["ccx_solver"], s["order"], s["factor"])
           for s, r, t in pts if r * t == 2}
    expected = {("dolfinx", "pmg", 2, f) for f in (4.0, 2.5, 1.3)} | {("dolfinx", "mumps", 2, 1.3)} | \
        {("calculix", c, 2, f) for c in ("iterative", "spooles") for f in (4.0, 2.5, 1.3)}
    assert two == expected
    assert all(s["threads"] == 2 for s, r, t in pts if s["kind"] == "calculix" and t == 2)


def test_bench_want_critical_gives_both_kinds_the_known_places():
    """--want critical: every point, the pipeline's and CalculiX's, is made for the critical
    peak alone, so both mesh the known bore edges instead of a pilot's places (the run's
    scene); the places are those of pipeline.post.features for No. 05. (Matrix and places only.)"""
    from bench import run as bench
    from bench.point import _pilot_hotspots
    from pipeline.inputs.case import resolve
    argv = ["--orders", "2", "--solvers", "pmg", "--factors", "4.0", "--ccx-solvers", "iterative",
            "--pilot", "on", "--want", "critical"]
    pts = bench.build_matrix(bench.make_parser().parse_args(argv))
    assert {(s["kind"], s["want"]) for s, _, _ in pts} == {("dolfinx", "critical"), ("calculix", "critical")}
    spots, t = _pilot_hotspots(pts[0][0], resolve("05", overrides={"want": "critical"}), None, None)
    assert sorted(spots) == [(0.0, 10.5, 0.0), (0.0, 10.5, 25.0)] and t == 0.0


def test_reference_staleness_watches_files_that_exist():
    """bench.run warns when a reference study is older than the code that made its numbers;
    a renamed module would silence that warning, so every watched file must exist."""
    from bench.run import REFERENCE_INPUTS
    missing = [name for name in REFERENCE_INPUTS if not (ROOT / name).is_file()]
    assert not missing, f"bench.run.REFERENCE_INPUTS names files that do not exist: {missing}"
