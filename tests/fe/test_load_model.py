"""The journal load model (docs/design.md §3): the bearing pressure's shape and its band
along the journal, against independent figures (mm, N, MPa).

- Balance: for each shape, on the whole bearing surface and on a band, the assembled load
  vector's z-forces sum to Q/2 per journal (the input, not the code's own integral) to
  round-off, and a band's forces act at the band's middle.
- Statics: moving the band along the journal changes the critical section's moment (from
  the symmetry plane's reactions) by Q/2 × the shift, and the journal's own section moment
  (σ_xx integrated over a cross-section) is Q/2 × (centre − section position).
- The journal's nominal stress follows 32·M/(π·dj³) as dj changes: the moment from stress
  integration over the journal's section, for two journal diameters.
- Bad bands are refused with one line naming the key and the allowed range in mm.
"""
from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

import pipeline.fe.elasticity as pe
import pipeline.fe.solve as ps
from conftest import ROOT
from pipeline.errors import InputError
from pipeline.fe.loads import crosshead_loads
from pipeline.fe.meshing import make_mesh
from pipeline.inputs.case import at_formula_position, formula_bearing, read_case_file, resolve
from pipeline.post.sections import journal_nominal, ligament_resultants, sigma_xx_at, sigma_xx_field

Q = 10_000.0  # N, No. 05's load
FACTOR = 3.0  # coarse meshes: the statics below do not depend on the mesh


def load_vector(m, lc, order: int = 2):
    """The bearing traction's assembled load vector (N per DOF) and the x of its nodes (mm),
    owned DOFs of this rank."""
    V = fem.VectorFunctionSpace(m.mesh, ("Lagrange", order))
    v = ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    bearing = next(t for t in lc.tractions if t.marker == m.facet_ids["journal_bearing"])
    f = assemble_vector(fem.form(ufl.inner(bearing.value, v) * ds(bearing.marker)))
    f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n = V.dofmap.index_map.size_local
    return f.array_r.reshape(-1, 3)[:n].copy(), V.tabulate_dof_coordinates()[:n, 0]


def total(a) -> float:
    return MPI.COMM_WORLD.allreduce(float(a), op=MPI.SUM)


@pytest.fixture(scope="module")
def meshes():
    """No. 05's quarter and full model on a coarse mesh."""
    case = resolve("05", None, {"mesh_factor": FACTOR})
    return {model: make_mesh(case.dims, model, case.mesh_spec(FACTOR)) for model in ("quarter", "full")}


@pytest.mark.parametrize("model", ["quarter", "full"])
@pytest.mark.parametrize("shape", ["cosine", "uniform"])
@pytest.mark.parametrize("band", [(None, None), (5.0, 30.0), (2.2, 33.9)])
def test_each_shape_and_band_carries_q_half_per_journal_at_its_middle(meshes, model, shape, band):
    length, centre = band
    case = replace(resolve("05"), model=model, bearing_shape=shape, bearing_length_mm=length,
                   bearing_centre_mm=centre)
    m = meshes[model]
    b = case.bearing_band()
    lc = crosshead_loads(m, case.dims, Q, "bearing", shape=shape, band=b, order=2)
    f, x = load_vector(m, lc)
    # Q/2 per journal; the quarter model holds half of one journal (y >= 0): Q/4.
    per_journal = Q / 2 if model == "full" else Q / 4
    for side in ((1.0, -1.0) if model == "full" else (1.0,)):
        on = side * x > 0
        fz = total(f[on, 2].sum())
        assert fz == pytest.approx(per_journal, rel=1e-10)
        # Nothing outside the band beyond the facets that straddle its ends (< 3 mm here).
        outside = on & ((side * x < b.start_mm - 3.0) | (side * x > b.end_mm + 3.0))
        assert total(np.abs(f[outside]).sum()) < 1e-12 * Q
        if not b.whole:  # a band's resultant acts at its middle, on the mesh's own load vector
            centroid = total(np.dot(f[on, 2], side * x[on])) / fz
            assert centroid == pytest.approx(centre, abs=1e-9 * case.dims.b6)
    assert lc.support_force_z_N == pytest.approx(Q * (0.25 if model == "quarter" else 1.0), rel=1e-10)


@pytest.mark.parametrize("band", [(None, None), (5.0, 30.0)])
def test_the_uniform_shape_is_p0_everywhere_on_the_projected_area(meshes, band):
    """Uniform: a normal pressure of one value p0 = (Q/2) / (dj · L) on the lower half,
    the journal's share over its projected area (docs/design.md §3): on the faceted mesh,
    its mean over the loaded surface is that closed form to the faceting error and its
    spread about the mean vanishes."""
    length, centre = band
    case = replace(resolve("05"), bearing_shape="uniform", bearing_length_mm=length, bearing_centre_mm=centre)
    d, m = case.dims, meshes["quarter"]
    b = case.bearing_band()
    lc = crosshead_loads(m, d, Q, "bearing", shape="uniform", band=b, order=2)
    t = lc.tractions[1].value
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)(m.facet_ids["journal_bearing"])
    x = ufl.SpatialCoordinate(m.mesh)
    # Away from the band's ends, where facets straddle them (a band of the whole surface has none).
    inner = ufl.conditional(ufl.And(ufl.ge(x[0], b.start_mm + (0 if b.whole else 1.5)),
                                    ufl.le(x[0], b.end_mm - (0 if b.whole else 1.5))), 1.0, 0.0)
    mag = ufl.sqrt(ufl.inner(t, t))
    area = total(fem.assemble_scalar(fem.form(inner * ds)))
    mean = total(fem.assemble_scalar(fem.form(inner * mag * ds))) / area
    spread = math.sqrt(total(fem.assemble_scalar(fem.form(inner * (mag - mean) ** 2 * ds))) / area)
    p0 = Q / 2 / (d.dj * b.length_mm)
    # Whole surface: to the faceting of the curved surface (its area within 1e-4 of the
    # cylinder's, tests/fe/test_traction_pinned.py). A band: p0·w(x) with the tilt w that
    # puts the cut facets' resultant at the band's middle (up to a few percent).
    assert mean == pytest.approx(p0, rel=1e-4 if b.whole else 0.05)
    assert spread < (1e-6 if b.whole else 0.05) * p0


def journal_section_moment(sol, mat, d, x_s: float, n_r: int = 20, n_phi: int = 120) -> float:
    """M = ∫ σ_xx (z − h/2) dA (N·mm) over the journal's whole cross-section at x = x_s,
    from σ_xx sampled on the half disc y >= 0 of the quarter model (Gauss in r, midpoints
    in φ), doubled for the other half."""
    R = d.dj / 2
    g, w = np.polynomial.legendre.leggauss(n_r)
    r, wr = R / 2 * (g + 1), R / 2 * w
    phi = (np.arange(n_phi) + 0.5) * math.pi / n_phi
    rr, pp = np.meshgrid(r, phi, indexing="ij")
    pts = np.column_stack([np.full(rr.size, x_s), (rr * np.sin(pp)).ravel(),
                           (d.h3 / 2 + rr * np.cos(pp)).ravel()])
    pts[:, 1] = np.maximum(pts[:, 1], 1e-9)  # just inside y >= 0
    s = sigma_xx_at(sigma_xx_field(sol.u, mat), pts).reshape(rr.shape)
    assert np.all(np.isfinite(s))
    half = np.sum(wr[:, None] * (math.pi / n_phi) * s * (rr * np.cos(pp)) * rr)
    return 2 * half


def solve_band(case, m, length, centre):
    case = replace(case, bearing_length_mm=length, bearing_centre_mm=centre)
    lc = crosshead_loads(m, case.dims, Q, "bearing", shape=case.bearing_shape, band=case.bearing_band(), order=2)
    mat = pe.Material(case.E_MPa, case.nu)
    sol = ps.solve(m.mesh, m.facet_tags, mat, ps.Loads(lc.tractions, lc.constraints), ps.Method(2, "mumps"))
    sym = next(i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == m.facet_ids["symmetry_x"])
    return sol, mat, sym


def test_moving_the_band_changes_the_section_moments_as_statics_says(meshes):
    case = resolve("05", None, {"mesh_factor": FACTOR})
    d, m = case.dims, meshes["quarter"]
    x_s = 26.0  # a journal section between the fillet's end (24 mm) and both bands
    moments = {}
    for centre in (29.0, 32.0):
        sol, mat, sym = solve_band(case, m, 4.0, centre)
        _, M0 = ligament_resultants(sol, sym, d, 0.25)
        moments[centre] = M0, journal_section_moment(sol, mat, d, x_s)
    # The critical section x = 0: the seat's moment is the same, the journal load's grows
    # by Q/2 × the shift (sagging: M < 0). The reactions carry the statics of the discrete
    # load exactly; that differs from Q/2 × the shift only by the x-forces of the facets'
    # tilted normals (1.6e-4 of it on this coarse mesh; measured: 2.4 N·mm of 15 000).
    assert moments[32.0][0] - moments[29.0][0] == pytest.approx(-Q / 2 * 3.0, rel=1e-3)
    # The journal's section: an upward load beyond it bends it with the bottom in tension
    # (M < 0), |M| = Q/2 × (centre − x_s); from sampled stresses, to the mesh's accuracy.
    for centre, (_, Mj) in moments.items():
        assert Mj == pytest.approx(-Q / 2 * (centre - x_s), rel=0.02)
    assert moments[32.0][1] - moments[29.0][1] == pytest.approx(-Q / 2 * 3.0, rel=0.02)


def test_journal_nominal_stress_follows_the_cube_of_its_diameter():
    """For dj = 16 and 20 mm the FE journal section moment gives the nominal stress
    32·M/(π·dj³) of the statics moment, and the code's journal-root figure is that
    closed form at the band's middle."""
    x_s, centre, length = 26.0, 31.0, 6.0
    M_statics = Q / 2 * (centre - x_s)
    nominal = {}
    for dj in (16.0, 20.0):
        case = resolve("05", None, {"mesh_factor": FACTOR, "dims.dj": dj})
        d = case.dims
        m = make_mesh(d, "quarter", case.mesh_spec(FACTOR))
        sol, mat, _ = solve_band(case, m, length, centre)
        Mj = journal_section_moment(sol, mat, d, x_s)
        nominal[dj] = 32 * abs(Mj) / (math.pi * dj ** 3)
        assert nominal[dj] == pytest.approx(32 * M_statics / (math.pi * dj ** 3), rel=0.02)
        M_root, s_root = journal_nominal(d, Q, bearing_centre_mm=centre)
        assert M_root == pytest.approx(Q / 2 * (centre - d.b1 / 2), rel=1e-12)
        assert s_root == pytest.approx(32 * Q / 2 * (centre - 22.5) / (math.pi * dj ** 3), rel=1e-12)
    assert nominal[16.0] / nominal[20.0] == pytest.approx((20 / 16) ** 3, rel=0.02)


def test_formula_positions_are_the_papers_spans():
    """The approximate formula's load at (b1 + b2)/2 = 28.75 mm (span 57.5 mm); the exact
    one's at b6/2 = 35 mm, the tip, which a band of length L approaches to L/2."""
    d = resolve("05").dims
    assert formula_bearing(d, "approximate") == pytest.approx((28.75, 2.2))
    assert formula_bearing(d, "exact") == pytest.approx((35.0 - 1.1, 2.2))
    assert formula_bearing(d, "exact", 4.0) == pytest.approx((33.0, 4.0))


@pytest.mark.parametrize("overrides, key, allowed", [
    ({"bearing_length_mm": 12.0}, "bearing_length_mm", "(0, 11] mm"),
    ({"bearing_centre_mm": 23.0}, "bearing_centre_mm", "between 24 and 35 mm"),
    ({"bearing_centre_mm": 35.0}, "bearing_centre_mm", "between 24 and 35 mm"),
    ({"bearing_length_mm": 4.0, "bearing_centre_mm": 33.5}, "bearing_centre_mm", "[26, 33] mm"),
    ({"bearing_length_mm": -1.0}, "bearing_length_mm", "> 0"),
    ({"bearing_shape": "parabolic"}, "bearing_shape", "cosine, uniform"),
    ({"support": "rigid", "bearing_centre_mm": 30.0}, "bearing_centre_mm", "support = bearing only"),
])
def test_a_band_off_the_journal_is_refused_naming_key_and_range(overrides, key, allowed):
    with pytest.raises(InputError) as exc:
        resolve("05", None, overrides)
    line = str(exc.value)
    assert line.startswith(f"{key}:") and allowed in line and "\n" not in line


def test_a_band_equal_to_the_whole_surface_is_the_default_model():
    case = resolve("05", None, {"bearing_length_mm": 11.0, "bearing_centre_mm": 29.5})
    assert case.bearing_band() == resolve("05").bearing_band() and case.bearing_band().whole


@pytest.mark.parametrize("args, key", [
    (["--bearing-centre", "40"], "bearing_centre_mm"),
    (["--bearing-length", "20"], "bearing_length_mm"),
    (["--bearing-at", "exact", "--bearing-centre", "30"], "bearing_at"),
    (["--bearing-at", "exact", "--bearing-length", "12"], "bearing_length_mm"),
    (["--bearing-shape", "uniform", "--support", "rigid"], "bearing_shape"),
])
def test_the_command_line_refuses_a_bad_band_with_exit_2_and_one_line(tmp_path, args, key):
    out = tmp_path / "never"
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--out", str(out), *args],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith(f"error: {key}:"), p.stderr
    assert not out.exists()


def test_the_case_file_and_bearing_at_set_the_band(tmp_path):
    """Case-file keys under [model]; --bearing-at puts the band at a formula's position."""
    f = tmp_path / "c.toml"
    f.write_text('size = "05"\n[model]\nbearing_shape = "uniform"\nbearing_length_mm = 6\nbearing_centre_mm = 30.5\n')
    assert read_case_file(f) == {"size": "05", "bearing_shape": "uniform", "bearing_length_mm": 6,
                                 "bearing_centre_mm": 30.5}
    case = resolve(None, f)
    assert (case.bearing_band().start_mm, case.bearing_band().end_mm) == (27.5, 33.5)
    exact = at_formula_position(replace(case, bearing_centre_mm=None), "exact")
    assert (exact.bearing_centre_mm, exact.bearing_length_mm) == (32.0, 6)  # the band ends at the tip, 35 mm
    assert at_formula_position(resolve("05"), "approximate").bearing_centre_mm == 28.75
    g = tmp_path / "at.toml"
    g.write_text('size = "05"\n[model]\nbearing_at = "approximate"\n')
    assert resolve(None, g) == at_formula_position(resolve("05"), "approximate")


def test_more_load_sets_on_one_operator_equal_separate_solves(meshes):
    """A load-model variant changes only the right-hand side: solved on the first solve's
    matrix (solve's ``more``) it gives the displacement of a solve of its own."""
    case = resolve("05", None, {"mesh_factor": FACTOR})
    d, m = case.dims, meshes["quarter"]
    mat = pe.Material(case.E_MPa, case.nu)
    lc0 = crosshead_loads(m, d, Q, "bearing", band=case.bearing_band(), order=2)
    band = replace(case, bearing_length_mm=3.0, bearing_centre_mm=33.0).bearing_band()
    lc1 = crosshead_loads(m, d, Q, "bearing", shape="uniform", band=band, order=2)
    both = ps.solve(m.mesh, m.facet_tags, mat, ps.Loads(lc0.tractions, lc0.constraints, [lc1.tractions]), ps.Method(2, "mumps"))
    alone = ps.solve(m.mesh, m.facet_tags, mat, ps.Loads(lc1.tractions, lc1.constraints), ps.Method(2, "mumps"))
    u1, u = both.more[0].u.x.array, alone.u.x.array
    assert np.max(np.abs(u1 - u)) <= 1e-10 * np.max(np.abs(u))
    assert np.allclose(both.more[0].reactions, alone.reactions, rtol=1e-8, atol=1e-8 * Q)
    assert np.max(np.abs(both.u.x.array - u)) > 1e-3 * np.max(np.abs(u))  # another load, another answer


def test_each_formulas_row_is_the_section_under_its_own_load_position():
    """The like-with-like rows (fe.sections.formula_load): the FE section moment with the
    journal load at the approximate formula's (b1 + b2)/2 = 28.75 mm and at the band ending
    at the exact formula's tip (middle 33.9 mm) is the statics of those loads,
    M = −Q/2 · (position − seat centroid), the seat a uniform annulus 25 to 37 mm
    (centroid 4/(3π)·(ro³ − ri³)/(ro² − ri²)); the formula beside it is the paper's."""
    from pipeline.analysis.level import LevelTask, solve_level
    case = resolve("05", None, {"mesh_factor": FACTOR, "solver": "mumps"})
    lv = solve_level(case, LevelTask(FACTOR, sections=True, reuse=False, formula_loads=True))
    rows = lv.sections["formula_load"]
    root = lv.sections["journal_root"]  # the case's own load: the middle of 24 to 35 mm
    assert root["load_at_mm"] == 29.5 and root["M_Nmm"] == pytest.approx(Q / 2 * (29.5 - 22.5), rel=1e-12)
    ri, ro = 12.5, 18.5
    x_seat = 4 / (3 * math.pi) * (ro ** 3 - ri ** 3) / (ro ** 2 - ri ** 2)
    for which, at, formula in (("approximate", 28.75, 37.76), ("exact", 33.9, 43.81)):
        r = rows[which]
        assert r["fe_load_at_mm"] == pytest.approx(at, abs=1e-12)
        # The faceted seat's and journal's centroids: within 1e-3 (see the shift test).
        assert r["critical_section"]["M_Nmm"] == pytest.approx(-Q / 2 * (at - x_seat), rel=1e-3)
        assert r["fe_MPa"] == pytest.approx(6 * Q / 2 * (at - x_seat) / (24 * 25 ** 2), rel=1e-3)
        assert r["formula_MPa"] == pytest.approx(formula, abs=0.05)  # docs/design.md §6
    # The approximate formula's own position is on the journal: it and the FE share it.
    assert rows["approximate"]["formula_at_fe_load_MPa"] == rows["approximate"]["formula_MPa"]
    # The exact formula at the FE load's middle: span 2 × 33.9 mm, between the paper's
    # 43.81 MPa (70 mm) and its 32.6 MPa at 57.5 mm (docs/design.md §6).
    assert 32.6 < rows["exact"]["formula_at_fe_load_MPa"] < 43.81


def test_a_band_narrower_than_the_mesh_resolves_is_a_numerical_failure(meshes):
    """A band that holds no quadrature point of the coarse mesh cannot carry a load: one
    line asking for a longer band or a finer mesh, never a division by zero."""
    from pipeline.errors import NumericalError
    case = resolve("05", None, {"bearing_length_mm": 1e-4, "bearing_centre_mm": 30.0})
    with pytest.raises(NumericalError, match="longer --bearing-length or a finer mesh"):
        crosshead_loads(meshes["quarter"], case.dims, Q, "bearing", band=case.bearing_band(), order=2)


@pytest.mark.slow
def test_the_run_cache_keeps_load_models_apart_and_scaled_runs_keep_their_table(tmp_path, monkeypatch):
    """A cached solution is never taken for another load model (the shape and band shape
    the field, not only its size); a run scaled from a cached solve at another load still
    solves its formulas' rows, equal to those of a run at that load solved anew."""
    import pipeline.cache.runs as rc
    from pipeline.api import Outputs, RunOptions, write_run

    def execute_run(case, out):
        return write_run(case, RunOptions(levels=1, to_tolerance=False, sensitivity=False,
                                          outputs=Outputs(fields=False)), out)
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path / "runs")
    case = resolve("05", None, {"mesh_factor": FACTOR})
    execute_run(case, tmp_path / "a")
    for other in (replace(case, bearing_shape="uniform"), replace(case, bearing_length_mm=4.0, bearing_centre_mm=30.0)):
        res = execute_run(other, tmp_path / f"b{len(list(tmp_path.iterdir()))}")
        assert res["fe"]["scaled_from"] is None
    scaled = execute_run(replace(case, load_N=2 * Q), tmp_path / "s")
    assert scaled["fe"]["scaled_from"] == {"load_N": Q, "E_MPa": case.E_MPa}
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "1")
    fresh = execute_run(replace(case, load_N=2 * Q), tmp_path / "f")
    for which in ("approximate", "exact"):
        a, b = (r["fe"]["sections"]["formula_load"][which] for r in (scaled, fresh))
        assert a["fe_MPa"] == pytest.approx(b["fe_MPa"], rel=1e-7)


def test_the_report_compares_each_formula_at_the_fe_loads_position():
    """The report's row: FE against the formula with its load where the FE's is (41.84
    MPa at 33.9 mm), not at the tip: (47.81 − 41.84)/41.84 = +14.3 %."""
    from pipeline.output.report import formula_load_lines
    line = {"membrane_plus_bending_MPa": 1.0}
    row = {"formula_MPa": 43.81, "formula_load_at_mm": 35.0, "fe_load_band_mm": [32.8, 35.0], "fe_load_at_mm": 33.9,
           "formula_at_fe_load_MPa": 41.84, "fe_MPa": 47.81, "fe_quantity": "q",
           "lines": {"mid_ligament_height": line, "bore_edge_height": line}}
    text = "\n".join(formula_load_lines({"exact": row}))
    assert "| exact | 35.00 | 32.80 to 35.00, 33.90 | 43.81 | 41.84 | **47.81** | +14.3 % |" in text
    assert formula_load_lines(None) == [] and formula_load_lines({}) == []
