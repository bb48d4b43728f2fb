"""The report's parts that need no run: the title block's blank fields, the print footer's
escaping, the close-up's view of a known surface (mm)."""
from __future__ import annotations

import numpy as np
import pytest

from pipeline.output.closeup import ELEMENTS_ACROSS, peak_view
from pipeline.output.report import css_string, footer_text, title_block_fields, title_block_lines, without_docs_links


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
