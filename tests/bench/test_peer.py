"""The fair peer (bench.peer): CalculiX on the mesh a CalculiX user makes (size fields at the
raisers the dimensions name, no pilot), its nodal stresses read from the .frd.

Independent sources: the mesh sizes the spec asks for (bore edges 0.05·h3, fillet rf/4,
body 0.16·h3, all × the factor), statics (ccx's reactions balance the loads it was given;
the seat carries a quarter of the hook load) and von Mises of a uniaxial stress.
"""
import shutil
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from bench.calculix import build_model, inp_text, read_frd_stress, run_job
from bench.calculix import frd_peaks, nodal_von_mises
from bench.peer import build_points, make_parser
from geometry.places import at_journal_root
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import LevelTask, set_up
from pipeline.inputs.case import resolve

FACTOR = 2.0


@pytest.fixture(scope="module")
def user_model(tmp_path_factory):
    """No. 05 quarter on a user's graded mesh at ×2 (no pilot: no refined places), solved by
    ccx with its reactions per fixed set and its nodal stresses in the .frd."""
    assert shutil.which("ccx"), "ccx missing: tools/setup.sh installs calculix-ccx"
    case = resolve("05", overrides={"mesh_factor": FACTOR, "order": 2})
    assert case.mesh_spec(FACTOR, ()).hotspots == ()
    prob = set_up(case, LevelTask(FACTOR), RunContext(comm=MPI.COMM_SELF))
    model = build_model(prob.mesh.mesh, prob.mesh.facet_tags, prob.loads)
    wd = tmp_path_factory.mktemp("peer")
    sets = {0: "FIXX", 1: "FIXY", 2: "FIXZ"}
    lines = ["*EL FILE", "S"]
    for name in sets.values():
        lines += [f"*NODE PRINT, NSET={name}, TOTALS=ONLY", "RF"]
    (wd / "job.inp").write_text(inp_text(model, prob.material, output_lines=lines))
    run_job(wd)
    return dict(case=case, model=model, wd=wd, sets=sets)


def _edge_length(nodes: np.ndarray, elements: np.ndarray) -> np.ndarray:
    """Mean corner-to-corner edge length (mm) of each C3D10 element (1-based ids)."""
    p = nodes[elements[:, :4] - 1]
    pairs = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    return np.mean([np.linalg.norm(p[:, a] - p[:, b], axis=1) for a, b in pairs], axis=0)


@pytest.mark.calculix
@pytest.mark.slow
def test_user_mesh_is_finer_at_the_raisers_than_far_away(user_model):
    """The spec asks for 1.25 mm × 2 at the bore edges, 0.375 mm × 2 on the fillet and 4 mm
    × 2 far away (ratios 0.31 and 0.09): the elements at a raiser must be at most half the
    size of those far from every raiser, and the fillet's finer than the edges'."""
    d, m = user_model["case"].dims, user_model["model"]
    h = _edge_length(m.nodes, m.elements)
    c = m.nodes[m.elements[:, :4] - 1].mean(axis=1)
    r = np.hypot(c[:, 0], c[:, 1])
    # Distances (mm) of each centroid from the raisers' curves: the bore-edge circles
    # (r = d2/2 on z = 0 and z = h3), the seat circles on the top face, the fillet's circle.
    to_edge = np.minimum(np.hypot(r - d.d2 / 2, c[:, 2]), np.hypot(r - d.d2 / 2, c[:, 2] - d.h3))
    to_seat = np.min([np.hypot(r - rs / 2, c[:, 2] - d.h3) for rs in (d.seat_inner, d.seat_outer)], axis=0)
    to_fillet = np.hypot(np.abs(c[:, 0]) - d.b1 / 2, np.hypot(c[:, 1], c[:, 2] - d.h3 / 2) - d.dj / 2)
    near_edge = to_edge < 0.05 * d.h3 * FACTOR
    fillet = at_journal_root(d, c)
    # Beyond the sizes' growth: 0.4·h3 from the edges, 0.5·rf + (body - fillet size)/0.5 from the fillet.
    far = (np.minimum(to_edge, to_seat) > 0.4 * d.h3) & (to_fillet > 0.8 * d.h3)
    assert near_edge.sum() > 10 and fillet.sum() > 10 and far.sum() > 10
    h_far = np.median(h[far])
    assert np.median(h[near_edge]) < 0.5 * h_far
    assert np.median(h[fillet]) < 0.5 * np.median(h[near_edge])


@pytest.mark.calculix
@pytest.mark.slow
def test_calculix_model_balances(user_model):
    """Statics: in each direction, ccx's reaction on the fixed nodes balances the nodal loads
    it was given (measured to 1e-12 of the load); the loads on the top face carry a quarter
    of the hook load down (the quarter model)."""
    m, case, wd = user_model["model"], user_model["case"], user_model["wd"]
    applied = m.loads.copy()
    for comp, ids in m.fixed.items():  # inp_text leaves out loads on fixed DOFs
        applied[ids - 1, comp] = 0.0
    text = (wd / "job.dat").read_text().splitlines()
    quarter = case.load_N / 4
    for comp, name in user_model["sets"].items():
        k = next(i for i, s in enumerate(text) if s.strip().startswith(f"total force (fx,fy,fz) for set {name}"))
        total = [float(v) for v in next(s for s in text[k + 1:] if s.strip()).split()]
        assert abs(total[comp] + applied[:, comp].sum()) < 1e-6 * quarter, (name, total)
    top = m.nodes[:, 2] > case.dims.h3 - 1e-9
    assert m.loads[top, 2].sum() == pytest.approx(-quarter, rel=1e-6)


@pytest.mark.calculix
@pytest.mark.slow
def test_frd_stresses_read_as_a_user_reads_them(user_model):
    """Every node's stress is read; the peaks are the largest nodal von Mises, the critical
    one beside the bore (|x| <= d2/2) and no larger than the global one."""
    m, case = user_model["model"], user_model["case"]
    S = read_frd_stress(user_model["wd"] / "job.frd", m.nodes.shape[0])
    pk = frd_peaks(case, m.nodes, S)
    assert pk["critical_MPa"] <= pk["peak_MPa"]
    assert abs(pk["critical_location_mm"][0]) <= case.dims.d2 / 2
    assert pk["peak_MPa"] == pytest.approx(nodal_von_mises(S).max())


def test_frd_reader_and_von_mises(tmp_path):
    """Fixed-column .frd lines (ccx's format); uniaxial stress σ has von Mises |σ|, pure
    shear τ has √3·τ."""
    p = Path(tmp_path) / "x.frd"
    p.write_text(" -4  STRESS      6    1\n -5  SXX         1    4    1    1\n"
                 " -1         1 1.00000E+02 0.00000E+00 0.00000E+00 0.00000E+00 0.00000E+00 0.00000E+00\n"
                 " -1         2 0.00000E+00 0.00000E+00 0.00000E+00 1.00000E+01 0.00000E+00-0.00000E+00\n"
                 " -3\n")
    S = read_frd_stress(p, 2)
    np.testing.assert_allclose(nodal_von_mises(S), [100.0, np.sqrt(3) * 10.0])
    with pytest.raises(Exception):
        read_frd_stress(p, 3)


def test_points_cover_three_kinds_on_one_core():
    args = make_parser().parse_args(["--user-factors", "4,2", "--user-critical-factors", "3",
                                     "--both-factors", "2.5", "--critical-factors", "10"])
    pts = build_points(args)
    kinds = {(p["kind"], p["want"], p["pilot"]) for p in pts}
    assert kinds == {("dolfinx", "both", True), ("calculix", "both", True), ("dolfinx", "critical", True),
                     ("calculix", "critical", True), ("peer", "both", False), ("peer", "critical", False)}
    assert sum(p["kind"] == "peer" for p in pts) == 2 * 3  # two ccx solvers × three user meshes


def test_stays_within_needs_every_finer_mesh():
    """A family within 1 % at ×4, 1.5 % at ×2, within at ×1.3 and ×1: the bench's rule takes
    ×4, "stays within" takes ×1.3 (the finest, ×1, has no finer mesh to stay on)."""
    from bench.peer import cheapest
    errs = {4.0: 0.005, 2.0: 0.015, 1.3: -0.004, 1.0: 0.002}
    rows = [{"kind": "peer", "solver": "ccx-spooles", "want": "both", "factor": f, "dofs": int(1e4 / f ** 3),
             "t_wall": 10.0 / f, "peak_err": e, "critical_err": 0.0} for f, e in errs.items()]
    assert cheapest(rows, ("peak_err",), 0.01, stays=False)["factor"] == 4.0
    assert cheapest(rows, ("peak_err",), 0.01, stays=True)["factor"] == 1.3
    assert cheapest(rows[-1:], ("peak_err",), 0.01, stays=True) is None
