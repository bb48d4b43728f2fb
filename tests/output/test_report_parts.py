"""The report's parts that need no run: the title block's blank fields, the print footer's
escaping, user text as text in report.md and report.html, the close-up's view of a known
surface (mm)."""
from __future__ import annotations

from html.parser import HTMLParser

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.inputs.case import DOCUMENT_KEYS
from pipeline.output.closeup import ELEMENTS_ACROSS, peak_view
from pipeline.output.report import (TITLE_FIELDS, code_span, css_string, footer_text, html_document, md_text,
                                    title_block_fields, title_block_lines, without_docs_links)


def title_rows(lines: list[str]) -> dict[str, str]:
    """The title block's label → cell pairs from its Markdown rows (two pairs a row)."""
    rows = {}
    for ln in lines[2:]:
        if not ln.strip():
            break
        cells = [c.strip() for c in ln.strip().strip("|").split(" | ")]
        rows.update({cells[i]: cells[i + 1] for i in range(0, len(cells) - 1, 2) if cells[i]})
    return rows


def test_a_title_block_without_a_document_table_is_blank_not_invented():
    about = {"tool": "crosshead", "tool_version": "9.9", "created_utc": "2030-01-02T03:04:05+00:00",
             "software": {"dolfinx": "0.5.2"},
             "document": {"part": None, "number": None, "revision": None, "author": None, "checker": None}}
    rows = title_rows(title_block_lines({"about": about}))
    assert [rows[k] for k in ("Part", "Document number", "Revision", "Author", "Checked by")] == [""] * 5
    assert rows["Date (UTC)"] == "2030-01-02" and rows["Tool"] == "crosshead 9.9 (DOLFINx 0.5.2)"
    assert dict(title_block_fields({"about": about})) == rows  # the table holds every field, each once
    # An older results.json, without an about block: every field blank, nothing made up.
    old = title_rows(title_block_lines({}))
    assert len(old) == 7 and all(not v for v in old.values())


def test_the_footer_is_a_css_string_a_case_file_cannot_break_out_of():
    doc = {"number": 'N"1</style><script>', "revision": None}
    text = footer_text({"about": {"document": doc}}, "Report")
    assert text == 'Report · N"1</style><script>'
    css = css_string(text)
    assert css.startswith('"') and css.endswith('"') and "<" not in css and '\\"' in css
    assert css[1:-1].replace('\\"', "").count('"') == 0


class _Page(HTMLParser):
    """Every tag of a page with its attributes, and the text of each table cell and code
    element (entities resolved: the text a reader sees)."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.cells: list[str] = []
        self.code: list[str] = []
        self._in: str | None = None

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag in ("td", "code"):
            self._in = tag
            (self.cells if tag == "td" else self.code).append("")

    def handle_endtag(self, tag):
        if tag == self._in:
            self._in = None

    def handle_data(self, data):
        if self._in == "td":
            self.cells[-1] += data
        elif self._in == "code":
            self.code[-1] += data


# Markup a user might type into a title-block field or a case name, hostile or by accident.
HOSTILE = ["[click](javascript:alert(1))", "![x](javascript:alert(1))", "<a href=\"javascript:alert(1)\">x</a>",
           "<javascript:alert(1)>", "[x][1] [1]: javascript:alert(1)", "<script>alert(1)</script>",
           "&#106;avascript:alert(1)", "JaVaScRiPt:alert(1)", "**bold** _it_ `code` | cell \\ end", "a`b``c"]
TEXT = st.one_of(st.sampled_from(HOSTILE),
                 st.text(alphabet=st.sampled_from(list("[]()!<>&*_`|\\#:;/.\"'=- ajvscriptJAVSCRIPT1")), min_size=1,
                         max_size=40),
                 st.text(alphabet=st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp", "Cf")), min_size=1,
                         max_size=20)).map(str.strip).filter(bool)


@settings(max_examples=150, deadline=None)
@given(doc=st.fixed_dictionaries({k: TEXT for k in DOCUMENT_KEYS}), name=TEXT)
def test_user_text_is_text_in_the_report(tmp_path_factory, doc, name):
    """Whatever a case file's [document] fields and name hold, report.html shows them as that
    very text: no link (a javascript: URL least of all), image, script or other element comes
    of them, and each table cell and the name's code span read back as typed."""
    about = {"tool": "crosshead", "tool_version": "9.9", "created_utc": "2030-01-02T03:04:05+00:00",
             "software": {}, "document": doc}
    md = "\n".join([f"# Crosshead stress report: hook No. 05 (case {code_span(name)})\n",
                    *title_block_lines({"about": about})])
    page = _Page()
    page.feed(html_document(md, tmp_path_factory.getbasetemp(), "Report"))
    assert {t for t, _ in page.tags} <= {"html", "head", "meta", "title", "style", "body", "h1", "code", "table",
                                         "thead", "tbody", "tr", "th", "td"}, page.tags
    assert not any("javascript" in str(v).lower() for _, attrs in page.tags for v in attrs.values())
    pairs = list(zip(page.cells[0::2], page.cells[1::2]))  # two label | value pairs a row
    assert [v for label, v in pairs if label in dict(TITLE_FIELDS)] == [doc[k] for _, k in TITLE_FIELDS]
    assert page.code == [name]


def test_a_javascript_link_in_a_field_stays_text(tmp_path):
    """A Markdown link to a javascript: URL in a title-block field is the characters typed
    in report.html, never a live link, and in report.md too."""
    assert md_text("[click](javascript:alert(1))") == "\\[click\\](javascript:alert(1))"
    page = _Page()
    table = "| field | value |\n|---|---|\n| Part | " + md_text("[click](javascript:alert(1))") + " |\n"
    page.feed(html_document(table, tmp_path, "R"))
    assert "a" not in {t for t, _ in page.tags} and page.cells == ["Part", "[click](javascript:alert(1))"]


def test_pointers_into_docs_are_dropped_from_the_size_table_s_notes():
    assert without_docs_links("as printed; dj rf seat assumed (docs/design.md §2)") == "as printed; dj rf seat assumed"


def test_a_close_up_looks_along_the_outward_normal_at_the_surface_node_nearest_the_peak():
    """A flat square grid of spacing s in z = 1 (triangles counter-clockwise seen from +z:
    outward normal +z): the view centres on the grid node nearest the peak, looks along
    +z, and spans ELEMENTS_ACROSS edge lengths (each triangle's edges s, s, s·√2: median s)."""
    s, n = 0.5, 21
    x, y = np.meshgrid(np.arange(n) * s, np.arange(n) * s, indexing="ij")
    points = np.column_stack([x.ravel(), y.ravel(), np.ones(n * n)])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tri = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    view = peak_view(points, tri, (5.1, 4.9, 1.3), h_mm=100.0)
    np.testing.assert_allclose(view.node, [5.0, 5.0, 1.0])
    np.testing.assert_allclose(view.normal, [0.0, 0.0, 1.0], atol=1e-12)
    assert view.edge_mm == pytest.approx(s)
    assert view.half_height_mm == pytest.approx(ELEMENTS_ACROSS * s)
