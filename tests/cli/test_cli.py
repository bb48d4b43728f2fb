"""End-to-end: the CLI on a coarse mesh writes every key of the contract (docs/design.md §7)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


ROOT = Path(__file__).resolve().parents[2]


def cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "pipeline", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "r05"
    p = cli("run", "--size", "05", "--mesh-factor", "2.0", "--out", str(out))
    assert p.returncode == 0, p.stderr
    return out, p


@pytest.mark.slow
def test_contract_keys(coarse_run):
    out, _ = coarse_run
    res = json.loads((out / "results.json").read_text())
    assert res["units"] == {"length": "mm", "force": "N", "stress": "MPa"}
    for k in ("dims", "load_N", "E_MPa", "nu", "model", "support", "order", "assumed"):
        assert k in res["case"]
    an = res["analytic"]
    for k in ("approximate_MPa", "exact_MPa", "approximate_span_mm", "exact_span_mm"):
        assert isinstance(an[k], float)
    assert set(an["exact_terms"]) >= {"N1_N", "M1_Nmm", "N2_N", "M2_Nmm"}
    assert an["exact_MPa"] == pytest.approx(43.81, abs=0.05)   # worked by hand in docs/design.md §4 (paper: 43.75)
    fe = res["fe"]
    for k in ("peak_MPa", "critical_peak_MPa", "dofs", "cells", "order", "equilibrium_error_N"):
        assert k in fe
    assert len(fe["peak_location_mm"]) == 3 and len(fe["critical_location_mm"]) == 3
    assert fe["model"] == "quarter" and fe["support"] == "bearing" and fe["order"] == 2
    assert fe["equilibrium_error_N"] < 1e-6 * 10_000
    # Where curved-bar theory and the stress raisers put them (not where the code looks):
    # the global peak on the journal's shoulder fillet, b1/2 <= x <= b1/2 + rf; the
    # critical one at the bore edge in the section x = 0, y = d2/2, on a face z = 0 or h3.
    assert 22.5 <= fe["peak_location_mm"][0] <= 24.0
    x, y, z = fe["critical_location_mm"]
    assert abs(x) < 1e-6 and abs(y - 10.5) < 1e-6 and min(abs(z), abs(z - 25.0)) < 1e-6
    assert fe["critical"]["error_estimate"]["status"] in ("converged", "oscillatory", "settled")
    for k in ("geometry", "mesh", "import", "assemble", "solve", "post", "output", "total"):
        assert res["timings_s"][k] >= 0
    for name in ("results.json", "report.md", "mesh.msh", "fields.vtu", "von_mises.png"):
        assert (out / name).stat().st_size > 0, name


@pytest.mark.slow
def test_msh_has_physical_names(coarse_run):
    out, _ = coarse_run
    text = (out / "mesh.msh").read_text(errors="replace")
    head = text[text.index("$PhysicalNames"):text.index("$EndPhysicalNames")]
    for name in ("seat", "journal_bearing", "symmetry_x", "symmetry_y", "body"):
        assert f'"{name}"' in head


@pytest.mark.slow
def test_report_mentions_inputs_formulas_and_units(coarse_run):
    out, _ = coarse_run
    rep = (out / "report.md").read_text()
    # 43.8 and 37.76 MPa: the two formulas worked by hand (docs/design.md §4, §6)
    for s in ("mm", "MPa", "assumed", "43.8", "37.76", "safety factor", "Timings", "von_mises.png"):
        assert s in rep, s


@pytest.mark.slow
def test_the_closing_lines_are_short_and_say_each_peak_as_results_json_does(coarse_run):
    """At most 100 characters a line (the summary printed 293); one line per peak with its
    value ± band, its status, PASS/FAIL, safety factor and where it sits, each word the one
    results.json holds (fe.<peak>.status, fe.verdict, the feature)."""
    from pipeline.analysis.words import verdict_word
    out, p = coarse_run
    res = json.loads((out / "results.json").read_text())
    lines = p.stdout.splitlines()
    assert lines and max(len(ln) for ln in lines) <= 100, max(lines, key=len)
    fe = res["fe"]
    for name, key, verdict, sf in (("global peak", "peak", "global_peak", "safety_factor"),
                                   ("critical peak", "critical", "critical_peak", "critical_safety_factor")):
        line = next(ln for ln in lines if ln.startswith(name))
        block = fe[key]
        assert f"{block['value_MPa']:.2f} ± {block['error_estimate']['band']:.2f} MPa" in line
        assert f"  {block['status']} (" in line and block["status"] in ("within tolerance", "above tolerance")
        assert f"  {verdict_word(fe['verdict'][verdict]['verdict'])}  " in line
        assert f"SF {fe[sf]:.2f}" in line and line.endswith(block["feature"])
    # The notes a run carries are said in its closing lines too (once on stderr before the work).
    assert res["notes"] and all(f"note: {n}" in " ".join(p.stdout.split()) for n in res["notes"])


@pytest.mark.slow
def test_progress_lines(coarse_run):
    _, p = coarse_run
    assert p.stderr.count("] solve") == 3 and "output:" in p.stderr and "] " not in p.stdout
    # README, Known limits: meshes coarser than 1.3 misjudge the global peak; the run says so.
    assert "note: mesh factor 2 > 1.3" in p.stderr


@pytest.mark.parametrize("args,field", [
    (["run", "--size", "99"], "size"),
    (["run", "--size", "05", "--dim", "d2=50"], "d2"),
    (["run", "--size", "05", "--load", "-5"], "load_N"),
    (["run", "--size", "05", "--support", "glued"], "support"),
    (["run", "--size", "05", "--document", "writer=A. Smith"], "FIELD"),
    (["run", "--size", "05", "--document", "author=a", "--document", "author=b"], "author given twice"),
    (["run", "--size", "05", "--document", "author=a\tb"], "control character"),
])
def test_bad_input_exit_2_one_line(tmp_path, args, field):
    out = tmp_path / "never"
    p = cli(*args, "--out", str(out))
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0] and "Traceback" not in p.stderr
    assert not out.exists()


def _tet_cube(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A cube [0, n]³ of 5·n³ positively oriented tets sharing their nodes, as fields.vtu's
    whole part shares them: the 5-tet split of a unit cube, mirrored cube to cube so that
    faces match. Returns (nodes, tets)."""
    import itertools
    base = [(0, 1, 2, 4), (1, 3, 2, 7), (1, 4, 5, 7), (2, 4, 7, 6), (1, 2, 4, 7)]
    corners = np.array([(i & 1, (i >> 1) & 1, (i >> 2) & 1) for i in range(8)], float)
    pts = []
    for c in itertools.product(range(n), repeat=3):
        flip = np.array([(k % 2) for k in c])
        local = np.where(flip, 1 - corners, corners) + np.array(c)
        for tet in base:
            pts += [local[v] for v in tet]
    nodes, tets = np.unique(np.array(pts), axis=0, return_inverse=True)
    tets = tets.reshape(-1, 4)
    e = nodes[tets[:, 1:]] - nodes[tets[:, [0]]]
    negative = np.linalg.det(e) < 0
    tets[negative] = tets[negative][:, [0, 2, 1, 3]]
    return nodes, tets


def test_picture_draws_the_outer_surface_only():
    """pipeline.output.picture.outer_surface on a cube of 5·n³ tets: the outer surface of a
    cube split into tets has 2 triangles per face square, 12 n² in all, whatever the split,
    each on a face of the cube and facing out of it; the triangles number the nodes they
    use, each once. (numpy only: no VTK in this process, which cannot share one with DOLFINx.)"""
    from pipeline.output.picture import outer_surface
    n = 3
    pts, tets = _tet_cube(n)
    used, tri = outer_surface(tets)
    xyz = pts[used][tri]
    on_face = [np.all(np.isclose(xyz[:, :, k], v), axis=1) for k in range(3) for v in (0, n)]
    assert len(tri) == 12 * n ** 2
    assert int(np.sum(np.any(on_face, axis=0))) == len(tri)
    assert len(np.unique(used)) == len(used) and tri.max() == len(used) - 1
    normal = np.cross(xyz[:, 1] - xyz[:, 0], xyz[:, 2] - xyz[:, 0])
    assert np.all(np.einsum("ij,ij->i", normal, xyz.mean(axis=1) - n / 2) > 0)


def test_picture_colour_map_is_kept_as_matplotlib_made_it(tmp_path):
    """pipeline.output.picture.turbo_rgba gives matplotlib's turbo at 256 points, whether it makes
    the table (no file yet, or a damaged one) or reads the copy it kept."""
    from matplotlib import colormaps

    from pipeline.output.picture import turbo_rgba
    expected = colormaps["turbo"](np.linspace(0.0, 1.0, 256))
    table = tmp_path / "colours" / "turbo-256.npy"
    assert np.array_equal(turbo_rgba(table), expected) and table.exists()
    assert np.array_equal(turbo_rgba(table), expected)  # read back
    table.write_bytes(b"not a table")
    assert np.array_equal(turbo_rgba(table), expected)
    assert np.array_equal(np.load(table), expected)


def test_picture_marks_a_peak_only_where_the_camera_sees_it():
    """pipeline.output.picture.seen_from / mark_places on the cube [-1.5, 1.5]³: from an eye on the
    −x side a node of the −x face is seen, one of the +x face is not (the cube is in the
    way); mirrored (a quarter drawn whole), the +x peak's image in x on the −x face is
    marked instead, and an eye on the +x side marks the peak itself."""
    from pipeline.output.picture import mark_places, outer_surface, seen_from
    pts, tets = _tet_cube(3)
    used, tri = outer_surface(tets)
    surf = (pts - 1.5)[used]
    left, right = np.array([-10.0, 0.3, 0.2]), np.array([10.0, 0.3, 0.2])
    assert seen_from(surf, tri, np.array([-1.5, 0.5, 0.5]), left, 1e-3)
    assert not seen_from(surf, tri, np.array([1.5, 0.5, 0.5]), left, 1e-3)
    peak = (1.5, 0.5, 0.5)
    plain = mark_places(surf, surf, tri, peak, False, [left, right], 1e-3)
    assert plain[0] is None and np.allclose(plain[1], peak)
    whole = mark_places(surf, surf, tri, peak, True, [left, right], 1e-3)
    assert np.allclose(whole[0], (-1.5, 0.5, 0.5)) and np.allclose(whole[1], peak)


@pytest.mark.slow
def test_picture_shows_the_field(coarse_run):
    """von_mises.png is a drawn field, not an empty window: 2240 x 950 pixels, a white
    background, and the turbo colours of the stress field (a few hundred distinct colours);
    the colour scale in a column of its own, right of the panels."""
    from matplotlib.image import imread
    out, _ = coarse_run
    img = imread(out / "von_mises.png")[:, :, :3]
    assert img.shape[:2] == (950, 2240)
    assert np.allclose(img[5, 1000], 1.0)                       # background between panels
    column = img[:, 2000:]
    ink = ~np.all(np.isclose(column, 1.0), axis=2)
    rows, cols = np.nonzero(ink)
    assert 0.6 * 950 < rows.ptp() < 0.85 * 950                  # the bar, its title and labels
    assert cols.min() > 10 and cols.max() < 230                 # none of it cut off at the sides
    colours = np.unique((img.reshape(-1, 3) * 255).round().astype(np.int64) @ [65536, 256, 1])
    assert len(colours) > 300


@pytest.mark.slow
def test_a_load_sweep_matches_a_direct_solve_and_scales_its_error_bars(tmp_path):
    """`run --load 5000,10000` solves at 5 kN and scales (linear elasticity, traction loads
    only). Independent check: a run of its own at 10 kN (run cache off, so nothing is
    scaled there) gives the same peaks and bands; the report and the terminal show each
    load's peaks with its ± (they showed the values alone)."""
    import os
    env = dict(os.environ, CROSSHEAD_NO_CACHE="1")
    coarse = ["--size", "05", "--mesh-factor", "3"]
    swept = subprocess.run([sys.executable, "-m", "pipeline", "run", *coarse, "--load", "5000,10000",
                            "--out", str(tmp_path / "swept")], cwd=ROOT, capture_output=True, text=True,
                           timeout=600, env=env)
    direct = subprocess.run([sys.executable, "-m", "pipeline", "run", *coarse, "--load", "10000", "--no-fields",
                             "--out", str(tmp_path / "direct")], cwd=ROOT, capture_output=True, text=True,
                            timeout=600, env=env)
    assert swept.returncode == 0 and direct.returncode == 0, swept.stderr + direct.stderr
    at10 = json.loads((tmp_path / "swept" / "results.json").read_text())["load_sweep"][1]
    fe = json.loads((tmp_path / "direct" / "results.json").read_text())["fe"]
    assert at10["load_N"] == 10_000
    for key, block in (("peak", "peak"), ("critical_peak", "critical")):
        assert at10[f"{key}_MPa"] == pytest.approx(fe[f"{key}_MPa"], rel=1e-6)
        band = fe[block]["error_estimate"]["band"]
        assert at10[f"{'peak' if key == 'peak' else 'critical'}_band_MPa"] == pytest.approx(band, rel=1e-6)
    row = next(ln for ln in (tmp_path / "swept" / "report.md").read_text().splitlines() if ln.startswith("| 10 000 |"))
    assert f"{at10['peak_MPa']:.2f} ± {at10['peak_band_MPa']:.2f}" in row
    assert f"10000 N {at10['peak_MPa']:.2f} ± {at10['peak_band_MPa']:.2f}" in " ".join(swept.stdout.split())


@pytest.mark.slow
def test_a_long_load_sweep_keeps_the_terminal_line_readable(tmp_path):
    """200 loads printed a 5 200-character line. Beyond six loads the line shows the first
    and last three and counts the rest, which results.json holds: 20 loads, 14 counted."""
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--mesh-factor", "3", "--levels", "1",
                        "--no-fields", "--load", "1000:20000:20", "--out", str(tmp_path / "many")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert max(len(ln) for ln in p.stdout.splitlines()) <= 100
    lines = p.stdout.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("the lines above"))
    end = next(i for i in range(start + 1, len(lines) + 1) if i == len(lines) or not lines[i].startswith("  "))
    line = " ".join(" ".join(lines[start:end]).split())  # its lines wrapped at 100 characters, joined
    assert "20 loads" in line and "… 14 more in results.json …" in line and line.count(" N ") == 6, line
    assert "MPa): 1000 N " in line and line.split("; ")[-1].startswith("20000 N ")  # the ends
    assert len(json.loads((tmp_path / "many" / "results.json").read_text())["load_sweep"]) == 20


@pytest.mark.slow
def test_the_title_block_can_be_given_on_the_command_line(tmp_path):
    """--document FIELD=TEXT fills the report's title block like the case file's [document],
    and overrides the case file's field; the fields neither gives stay blank."""
    case = tmp_path / "c.toml"
    case.write_text('size = "05"\n[document]\nauthor = "From the file"\nchecker = "B. Checker"\n')
    out = tmp_path / "r"
    p = cli("run", "--case", str(case), "--levels", "1", "--mesh-factor", "3", "--no-sensitivity", "--quiet",
            "--document", "author=A. Smith", "--document", "number=CH-05-001", "--out", str(out))
    assert p.returncode == 0, p.stderr
    doc = json.loads((out / "results.json").read_text())["about"]["document"]
    assert doc == {"part": None, "number": "CH-05-001", "revision": None, "author": "A. Smith",
                   "checker": "B. Checker"}
    assert "CH-05-001" in (out / "report.html").read_text(encoding="utf-8")
