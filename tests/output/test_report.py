"""What a person reads: report.md and the self-contained report.html, the whole-part
fields, the sections plot (docs/design.md §7)."""
from __future__ import annotations

import datetime
import json
import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from pipeline.output.mirror import mirror_quarter


ROOT = Path(__file__).resolve().parents[2]


def test_mirror_makes_four_positive_tets_with_mirrored_displacement():
    pts = np.array([[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [1.0, 1.0, 1.0]])
    cells = np.array([[0, 1, 2, 3]])
    disp = np.array([[0.1, 0.2, 0.3]] * 4)
    P, C, data, _ = mirror_quarter(pts, cells, {"v": np.arange(4.0), "displacement_mm": disp})
    V, D = data["v"], data["displacement_mm"]
    assert P.shape == (16, 3) and C.shape == (4, 4) and len(V) == 16
    vols = [np.linalg.det(np.array([P[c[1]] - P[c[0]], P[c[2]] - P[c[0]], P[c[3]] - P[c[0]]])) for c in C]
    assert all(v > 0 for v in vols)  # orientation kept: the same sign as the original tet
    assert np.allclose(D[4], [-0.1, 0.2, 0.3]) and np.allclose(D[8], [0.1, -0.2, 0.3])
    assert np.allclose(P[12], [-1.0, -1.0, 0.0])


def test_mirror_shares_the_plane_nodes_and_reflects_a_tensor():
    """A tet with a face on x = 0 (its nodes ~1e-13 off the plane, as gmsh places them) and an
    edge on y = 0: the copies share those nodes, placed on the planes exactly; a stress
    tensor's shear components change sign with the reflection (σ' = R σ R, R = diag(±1))."""
    pts = np.array([[1e-13, 0.0, 0.0], [1.0, -2e-13, 0.0], [-1e-13, 1.0, 0.0], [0.0, 0.5, 1.0]])
    sigma = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]])
    P, C, data, ids = mirror_quarter(pts, np.array([[0, 1, 2, 3]]), {"stress_MPa": np.tile(sigma.ravel(), (4, 1))})
    # Node 0 is on both planes (one node), 2 and 3 on x = 0, 1 on y = 0: 16 − 3 − 2·2 − 2·1 = 7 nodes.
    assert len(P) == 7 and len(np.unique(P, axis=0)) == 7
    assert P[ids[0][0]].tolist() == [0.0, 0.0, 0.0] and P[ids[0][2], 0] == 0.0
    assert ids[1][2] == ids[0][2] and ids[2][1] == ids[0][1] and ids[3][0] == ids[0][0]
    R = np.diag([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(data["stress_MPa"][ids[1][1]].reshape(3, 3), R @ sigma @ R)


def _tet10(pts4: np.ndarray) -> np.ndarray:
    """A straight 10-node tet in VTK order: vertices, then mid-edges (0,1), (1,2), (2,0), (0,3), (1,3), (2,3)."""
    edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    return np.vstack([pts4] + [0.5 * (pts4[a] + pts4[b]) for a, b in edges])


def test_mirror_keeps_ten_node_tets_positive_with_their_mid_edge_nodes():
    pts = _tet10(np.array([[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [1.0, 1.0, 1.0]]))
    P, C, _, _ = mirror_quarter(pts, np.arange(10)[None, :], {"displacement_mm": np.zeros((10, 3))})
    assert C.shape == (4, 10)
    for c in C:
        x = P[c]
        assert np.linalg.det(np.array([x[1] - x[0], x[2] - x[0], x[3] - x[0]])) > 0
        np.testing.assert_allclose(x, _tet10(x[:4]), atol=1e-12)   # each mid node on its VTK edge


class _Html(HTMLParser):
    def __init__(self):
        super().__init__()
        self.headings, self.images, self._in_h = [], [], False

    def handle_starttag(self, tag, attrs):
        if tag in ("h1", "h2"):
            self._in_h = True
            self.headings.append("")
        if tag == "img":
            self.images.append(dict(attrs).get("src", ""))

    def handle_endtag(self, tag):
        if tag in ("h1", "h2"):
            self._in_h = False

    def handle_data(self, data):
        if self._in_h:
            self.headings[-1] += data


# The title block a case file gives (the checker left out: a blank field to sign by hand).
DOCUMENT = {"part": "Crosshead DIN 15412 No. 05 | type A <b>", "number": "CN-0815", "revision": "B",
            "author": "A. Engineer"}


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    base = tmp_path_factory.mktemp("report")
    case = base / "05.toml"
    case.write_text('size = "05"\n\n[document]\n' + "".join(f'{k} = "{v}"\n' for k, v in DOCUMENT.items()))
    out = base / "05"
    day = datetime.datetime.now(datetime.timezone.utc).date().isoformat()
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--case", str(case), "--mesh-factor", "3",
                        "--out", str(out), "--quiet"], cwd=ROOT, capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, CROSSHEAD_NO_PDF=""))  # the run prints its report.pdf
    assert p.returncode == 0, p.stderr
    out.joinpath(".day").write_text(day)  # the UTC day the run started (the date in the title block)
    return out


@pytest.mark.slow
def test_html_report_has_every_section_and_embeds_every_picture(run_folder):
    md = (run_folder / "report.md").read_text()
    doc = _Html()
    doc.feed((run_folder / "report.html").read_text())
    sections = [ln.lstrip("# ").strip().replace("`", "") for ln in md.splitlines() if re.match(r"^#{1,2} ", ln)]
    assert sections and [h.strip() for h in doc.headings] == sections
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(doc.images) == len(pictures) >= 3  # the von Mises picture, the mesh close-ups, the sections plot
    assert "mesh_closeup.png" in pictures
    assert all(src.startswith("data:image/png;base64,") for src in doc.images)


@pytest.mark.slow
def test_fields_show_the_whole_part(run_folder):
    """fields.vtu covers x and y of both signs: the quarter mirrored (bounds ± b6/2, ± b1/2)."""
    import meshio
    m = meshio.read(run_folder / "fields.vtu")
    d = json.loads((run_folder / "results.json").read_text())["case"]["dims"]
    assert m.points[:, 0].min() == pytest.approx(-d["b6"] / 2, rel=1e-6)
    assert m.points[:, 1].min() == pytest.approx(-d["b1"] / 2, rel=1e-6)
    assert m.points[:, 0].max() == pytest.approx(d["b6"] / 2, rel=1e-6)


@pytest.mark.slow
def test_published_values_only_for_their_row(run_folder, tmp_path):
    """No. 05 at the paper's load and spans shows the published values; another load does not."""
    res = json.loads((run_folder / "results.json").read_text())
    assert res["analytic"]["published"]["exact_MPa"] == 43.75
    out = tmp_path / "other"
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--load", "12000",
                        "--mesh-factor", "3", "--levels", "1", "--out", str(out), "--quiet"],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert json.loads((out / "results.json").read_text())["analytic"]["published"] is None
    assert "published" not in (out / "report.md").read_text()


def test_load_arrows_point_where_the_loads_act():
    """Seat arrows point down onto the top face on the seat's mean radius; support arrows
    point up at the journals' underside; the quarter shows its own share of them."""
    from pipeline.inputs.case import resolve
    from pipeline.output.picture import load_arrows
    d = resolve("05").as_dict()["dims"]
    whole, quarter = load_arrows(d, 10_000.0, True), load_arrows(d, 10_000.0, False)
    assert [c for *_, c in whole].count("red") == 8 and [c for *_, c in whole].count("green") == 2
    assert [c for *_, c in quarter].count("red") == 2 and [c for *_, c in quarter].count("green") == 1
    for tail, vec, colour in whole:
        tip = tail + vec
        if colour == "red":
            assert vec[2] < 0 and tip[2] == pytest.approx(d["h3"])
            assert np.hypot(tip[0], tip[1]) == pytest.approx((d["seat_inner"] + d["seat_outer"]) / 4)
        else:
            assert vec[2] > 0 and tip[2] == pytest.approx(d["h3"] / 2 - d["dj"] / 2)
            assert d["b1"] / 2 < abs(tip[0]) < d["b6"] / 2


@pytest.mark.slow
def test_verdict_capacities_follow_linearity_and_the_lowest_is_named(run_folder):
    """Each row's capacity is the hook load at which that stress reaches the allowable:
    Q·allowable/σ (linear elasticity, loads only); the report names the row with the lowest."""
    from pipeline.output.report import VERDICT_NAMES
    res = json.loads((run_folder / "results.json").read_text())
    q, allow = res["case"]["load_N"], res["case"]["allowable_MPa"]
    rows = {k: r for k, r in res["fe"]["verdict"].items() if r["verdict"] != "none"}
    assert len(rows) >= 3
    for r in rows.values():
        assert r["capacity_N"] == pytest.approx(q * allow / r["value_MPa"], rel=1e-9)
    lowest = min(rows, key=lambda k: q * allow / rows[k]["value_MPa"])
    assert f"Lowest capacity: **{VERDICT_NAMES[lowest]}**" in (run_folder / "report.md").read_text()


@pytest.mark.slow
def test_report_flags_scaled_rows_and_singular_peaks(run_folder):
    """A scaled row of the size table is said to be no DIN value at the top; a singular global
    peak gets no Kt and names its singular feature where the peak is listed."""
    from pipeline.output.report import render_markdown
    res = json.loads((run_folder / "results.json").read_text())
    plain = render_markdown(res)
    assert "not DIN 15412 values" not in plain and "singular:" not in plain
    res["case"]["source"] = "scaled from No. 05 by geometric similarity; NOT a DIN 15412 value"
    res["fe"]["peak"]["singular_feature"] = "edge of the rigid support patch"
    md = render_markdown(res)
    assert "not DIN 15412 values" in md.split("## Summary")[0]
    assert "(singular: edge of the rigid support patch)" in md
    assert "none: the peak is singular" in md


@pytest.mark.slow
def test_the_inputs_name_the_bearing_pressure_the_run_used(run_folder):
    """The Inputs section names the journals' pressure shape of results.json's case: a run with
    `bearing_shape = uniform` was described as cos θ."""
    from pipeline.output.report import render_markdown
    res = json.loads((run_folder / "results.json").read_text())
    inputs = render_markdown(res).split("## Inputs")[1]
    assert "(cos θ bearing pressure on the lower half" in inputs and "uniform bearing pressure" not in inputs
    res["case"]["bearing_shape"] = "uniform"
    inputs = render_markdown(res).split("## Inputs")[1]
    assert "(uniform bearing pressure on the lower half" in inputs and "cos θ bearing pressure" not in inputs


def _study(status: str, values: list[float], extrapolated: float | None, band: float) -> dict:
    """A convergence block as execute_converge writes it: three meshes, finest first."""
    h = [0.01, 0.013, 0.017]
    levels = [{"peak_unaveraged_MPa": v + 1, "peak_averaged_MPa": v - 1, "critical_unaveraged_MPa": v,
               "critical_averaged_MPa": v - 0.1} for v in values]
    est = {"h": h, "values": values, "status": status, "extrapolated": extrapolated, "band": band}
    return {"levels": levels, "peak": est, "critical": dict(est, status="settled", extrapolated=values[0])}


@pytest.mark.parametrize("status,limit_label", [("converged", "Richardson limit 99.00 MPa"),
                                                ("scattered", "least-squares limit 99.00 MPa"),
                                                ("unsettled", None), ("exact", None), ("oscillatory", None)])
def test_convergence_plot_shows_both_readings_the_error_bar_and_only_a_real_limit(status, limit_label):
    """The plot drew an extrapolated limit and band only for 'converged': a study whose
    fillet peak was 'scattered' (a fitted limit, a band) showed a bare line. Now every
    status has both readings and the error bar; a limit only where one was extrapolated,
    and none for a settled peak (its 'limit' is the finest value itself)."""
    import matplotlib.pyplot as plt

    from pipeline.output.plots import convergence_figure
    fig = convergence_figure(_study(status, [100.0, 101.0, 102.0], None if status == "unsettled" else 99.0, 0.5),
                             "05")
    glob, crit = ([t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes)
    plt.close(fig)
    for labels in (glob, crit):
        assert {"unaveraged (largest element-node value)", "averaged (nodal-averaged stress)",
                "reported value", "error bar ±0.5 MPa"} <= set(labels)
    assert (limit_label in glob) if limit_label else not any("limit" in t for t in glob)
    assert not any("limit" in t for t in crit)


def test_a_peak_not_asked_for_gets_no_band_or_limit_in_the_convergence_study():
    """converge --want critical: the fillet's meshes were not refined, so its 'scattered'
    fit (a limit at 92 MPa, a ±12 MPa band at No. 05 ×3) was drawn and tabled as if it were
    a result. Its plot now shows the values only, titled as not asked for, and the report's
    line says it is not resolved; the critical peak keeps its band and limit."""
    import matplotlib.pyplot as plt

    from pipeline.output.plots import convergence_figure
    from pipeline.output.report import convergence_table
    conv = _study("scattered", [100.0, 101.0, 102.0], 99.0, 0.5)
    conv["not_wanted"] = {"peak": "want = critical: the run did not refine for the global peak"}
    conv["critical"]["gci_fine"] = 1e-3
    fig = convergence_figure(conv, "05")
    (glob, crit), titles = ([[t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes],
                            [ax.get_title() for ax in fig.axes])
    plt.close(fig)
    assert not any("limit" in t or "error bar" in t for t in glob) and "not asked for" in titles[0]
    assert "error bar ±0.5 MPa" in crit and "not asked for" not in titles[1]
    table = convergence_table(dict(conv, levels=[{"mesh_factor": 1.0, "dofs": 1, "peak_MPa": 100.0,
                                                  "critical_peak_MPa": 60.0, "time_s": 1.0}]))
    assert "- global peak: not resolved (want = critical" in table and "status `scattered`" not in table.split("- critical")[0]


def _title_block(md: str) -> dict[str, str]:
    """The title block's rows of report.md (label → cell text), from its first table (two
    label-cell pairs a row)."""
    table = md.split("| Calculation note |", 1)[1].split("\n\n", 1)[0]
    rows = {}
    for ln in table.strip().splitlines()[2:]:
        cells = [c.strip() for c in ln.strip().strip("|").split(" | ")]
        rows.update({cells[i]: cells[i + 1] for i in range(0, len(cells) - 1, 2) if cells[i]})
    return rows


@pytest.mark.slow
def test_title_block_comes_from_the_case_file_and_leaves_missing_fields_blank(run_folder):
    """Part, number, revision and author as the case file wrote them (escaped for Markdown and
    HTML), the checker it left out blank, the run's UTC day and the package's version; the
    same document fields in results.json's about block."""
    from pipeline import __version__
    md = (run_folder / "report.md").read_text()
    block = _title_block(md)
    assert block["Part"] == "Crosshead DIN 15412 No. 05 \\| type A &lt;b&gt;"
    assert (block["Document number"], block["Revision"], block["Author"]) == ("CN-0815", "B", "A. Engineer")
    assert block["Checked by"] == ""
    day = (run_folder / ".day").read_text()
    assert block["Date (UTC)"] in (day, datetime.datetime.now(datetime.timezone.utc).date().isoformat())
    assert block["Tool"].startswith(f"crosshead {__version__} (DOLFINx ")
    about = json.loads((run_folder / "results.json").read_text())["about"]
    assert about["document"] == {**DOCUMENT, "checker": None}
    html = (run_folder / "report.html").read_text()
    assert "<b>" not in html.split("</h1>", 1)[1].split("</table>", 1)[0]  # the case file's text is text


@pytest.mark.slow
def test_the_report_stands_alone_with_its_method_in_an_appendix(run_folder):
    """No link into docs/ (a reviewer outside the repository cannot open it); the appendix
    carries the load model, the error-bar method, the formulas and the sensitivity method,
    the error bar's texts quoted from their one home once each."""
    from pipeline.post.errorbar import STATUS_TEXT, TREND_TEXT
    md, html = (run_folder / "report.md").read_text(), (run_folder / "report.html").read_text()
    assert "docs/" not in md and "docs/" not in html
    appendix = md.split("## Appendix", 1)[1]
    for heading in ("### A.1 Load model", "### A.2 Peaks and their error bar", "### A.3 The two hand formulas",
                    "### A.4 Sensitivity"):
        assert heading in appendix
    assert md.count(TREND_TEXT) == 1 and md.count(STATUS_TEXT) == 1 and TREND_TEXT in appendix
    assert "M2 = 2·N1·R − (l/(4R) + 1/π)·Q·R − M1" in appendix  # the paper's eq. for the exact method


def _pdf_pages(pdf: bytes) -> int:
    """Pages of a PDF, by its page objects (/Type /Page, not /Pages)."""
    return len(re.findall(rb"/Type\s*/Page(?![s\w])", pdf))


def page_fills(pdf: Path, top_mm: float = 14.0, bottom_mm: float = 16.0, dpi: int = 30) -> list[float]:
    """Each page's share of its printable height (A4 less the print style's margins) down to
    its lowest printed pixel, the footer left out (poppler's pdftoppm, grey levels)."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["pdftoppm", "-gray", "-r", str(dpi), str(pdf), f"{tmp}/p"], check=True)
        fills = []
        for f in sorted(Path(tmp).glob("p-*.pgm"), key=lambda q: int(q.stem.rsplit("-", 1)[1])):
            head, dims, _, data = f.read_bytes().split(b"\n", 3)
            w, h = map(int, dims.split())
            img = np.frombuffer(data[:w * h], np.uint8).reshape(h, w)
            mm = h / 297.0
            body = img[int(top_mm * mm):int(h - bottom_mm * mm)]
            dark = np.where((body < 200).any(axis=1))[0]
            fills.append(0.0 if len(dark) == 0 else (dark[-1] + 1) / body.shape[0])
        return fills


def _squashed(text: str) -> str:
    """``text`` without white space: a PDF's text wraps where the page does."""
    return "".join(text.split())


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("chromium") is None or shutil.which("pdftoppm") is None,
                    reason="no chromium or poppler-utils: tools/setup.sh installs them")
def test_the_run_prints_a_note_whose_first_page_answers(run_folder):
    """The run's own report.pdf (headless Chromium): at most 6 A4 pages, none nearly empty
    (each filled to a third of its height or more: the last page too), a footer "page k of
    N" on each; page 1 holds the title block, every checked stress with its verdict,
    margin, safety factor and capacity, both peaks with their bands and where they sit, and
    the sensitivity sentence, each as results.json says it."""
    pdf = run_folder / "report.pdf"
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF-")
    n = _pdf_pages(data)
    assert 0 < n <= 6
    assert min(page_fills(pdf)) >= 1 / 3, page_fills(pdf)
    res = json.loads((run_folder / "results.json").read_text())
    assert res["files"]["report_pdf"] == "report.pdf"
    pages = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True,
                           check=True).stdout.split("\f")
    pages = [pg for pg in pages if pg.strip()]
    assert len(pages) == n
    for k, page in enumerate(pages, start=1):
        assert f"page {k} of {n}" in page
    first = " ".join(pages[0].split())
    assert "Document number CN-0815" in first and "Revision B" in first and "Checked by" in first
    text = subprocess.run(["pdftotext", "-l", "1", str(pdf), "-"], capture_output=True, text=True,
                          check=True).stdout
    plain, words = _squashed(text), set(re.findall(r"[\w.+-]+", text))
    from pipeline.analysis.words import verdict_word
    from pipeline.output.texts import VERDICT_NAMES
    for name, row in res["fe"]["verdict"].items():  # a table's cells wrap: its words, its numbers
        assert set(re.findall(r"[\w.+-]+", VERDICT_NAMES[name])) <= words, name
        assert f"{row['value_MPa']:.2f}" in plain and f"{row['margin_pct']:+.1f}" in plain, name
        assert f"{row['safety_factor']:.2f}" in plain, name
        assert f"{row['capacity_N']:,.0f}".replace(",", "") in plain, name
    assert plain.count(verdict_word("pass")) + plain.count(verdict_word("fail")) >= len(res["fe"]["verdict"])
    for key in ("peak", "critical"):
        block = res["fe"][key]
        band = block["error_estimate"]["band"]
        assert f"{block['value_MPa']:.2f}±{band:.2f}" in plain, key
        assert _squashed(block["feature"]) in plain and _squashed(block["status"]) in plain
    assert _squashed(res["sensitivity_summary"]["sentence"]) in plain


@pytest.mark.slow
def test_a_run_writes_its_meshes_and_sensitivity_tables(run_folder):
    """meshes.csv: one row per mesh of the error bar with results.json's fe.levels values;
    sensitivity.csv: two rows per varied input with its sensitivity list's values."""
    import csv
    res = json.loads((run_folder / "results.json").read_text())
    meshes = list(csv.DictReader((run_folder / "meshes.csv").open()))
    assert [float(r["peak_averaged_MPa"]) for r in meshes] == [lv["peak_averaged_MPa"] for lv in res["fe"]["levels"]]
    assert [int(r["dofs"]) for r in meshes] == [lv["dofs"] for lv in res["fe"]["levels"]]
    assert {r["size"] for r in meshes} == {"No. 05"}
    ends = list(csv.DictReader((run_folder / "sensitivity.csv").open()))
    assert len(ends) == 2 * len(res["sensitivity"])
    for e, (lo, hi) in zip(res["sensitivity"], zip(ends[::2], ends[1::2])):
        assert lo["input"] == hi["input"] == e["input"] and (lo["end"], hi["end"]) == ("low", "high")
        assert [float(lo["peak_MPa"]), float(hi["peak_MPa"])] == e["peak_MPa"]
        assert lo["verdict"] == e["verdicts"][0]["global_peak"]
    assert res["files"]["meshes_table"] == "meshes.csv" and res["files"]["sensitivity_table"] == "sensitivity.csv"


@pytest.mark.slow
def test_mesh_msh_says_it_holds_the_quarter_and_opens_in_gmsh_and_meshio(run_folder):
    """mesh.msh is MSH 4.1 binary with a $Comments note naming the quarter and its symmetry
    planes; meshio and gmsh read past the note, and the nodes they find do lie in x, y >= 0
    with some on each symmetry plane (the quarter the note names)."""
    import gmsh
    import meshio
    path = run_folder / "mesh.msh"
    head = path.read_bytes()[:400].decode("ascii", "replace")
    assert head.startswith("$MeshFormat\n4.1 1 8\n")  # version 4.1, binary, 8-byte size_t
    note = head.split("$Comments\n", 1)[1].split("\n$EndComments", 1)[0]
    assert "quarter model x >= 0, y >= 0" in note and "symmetry planes x = 0 and y = 0" in note
    pts = meshio.read(path).points
    assert pts[:, 0].min() > -1e-9 and pts[:, 1].min() > -1e-9
    assert np.sum(np.abs(pts[:, 0]) < 1e-9) > 0 and np.sum(np.abs(pts[:, 1]) < 1e-9) > 0
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        assert len(gmsh.model.mesh.getNodes()[0]) == len(pts)
        assert "body" in {gmsh.model.getPhysicalName(d, t) for d, t in gmsh.model.getPhysicalGroups()}
    finally:
        gmsh.finalize()


@pytest.mark.slow
def test_the_whole_part_s_mesh_is_four_connected_quarters_with_their_groups(run_folder, tmp_path):
    """pipeline.output.wholemesh from the run's mesh.msh: four times the quarter's tets and
    volume (tet corners' volumes summed here), every tet positively oriented, no face on a
    symmetry plane left on the outside (the quarters share those nodes) and none shared by
    more than two tets; the seat and the bearing keep their groups, the symmetry planes' go."""
    import meshio

    from pipeline.output.wholemesh import whole_mesh
    out = tmp_path / "whole.msh"
    whole_mesh(run_folder / "mesh.msh", out)

    def tets_of(m):
        return np.vstack([b.data[:, :4] for b in m.cells if b.type.startswith("tetra")])

    def volumes(pts, t):
        a, b, c, d = (pts[t[:, i]] for i in range(4))
        return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0

    q, w = meshio.read(run_folder / "mesh.msh"), meshio.read(out)
    vq, vw = volumes(q.points, tets_of(q)), volumes(w.points, tets_of(w))
    assert len(vw) == 4 * len(vq) and (vw > 0).all() and (vq > 0).all()
    assert vw.sum() == pytest.approx(4 * vq.sum(), rel=1e-12)
    faces = np.sort(tets_of(w)[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    _, counts = np.unique(faces, axis=0, return_counts=True)
    assert counts.max() == 2
    outer = np.unique(faces, axis=0)[counts == 1]
    on_plane = [np.all(np.abs(w.points[outer][:, :, k]) < 1e-9, axis=1).sum() for k in (0, 1)]
    assert on_plane == [0, 0]
    assert {"seat", "journal_bearing", "body"} <= set(w.field_data) and "symmetry_x" not in w.field_data
    assert b"mirrored in x = 0 and y = 0" in out.read_bytes()[:400]
