"""The tables a run, a study and the size summary write (pipeline/output/flat.py csv_text)
read right with a reader's default type inference: a column whose every cell parses as a
number becomes numbers, any other column text (pandas' read_csv default, emulated here
with the csv module). Sizes stay distinct and keep their leading zeros; a run's meshes.csv
and sensitivity.csv hold results.json's own values under the shared column names."""
from __future__ import annotations

import csv
import io

from geometry.table import load_table
from pipeline.output import flat
from pipeline.study import summary, table


def inferred(text: str) -> dict[str, list]:
    """The columns of CSV ``text`` as a reader's default inference types them: ints, else
    floats, when every non-empty cell parses as one; else the cells as text. An empty cell
    is None (missing)."""
    rows = list(csv.DictReader(io.StringIO(text)))
    out = {}
    for col in rows[0]:
        cells = [r[col] for r in rows]
        present = [c for c in cells if c != ""]
        for kind in (int, float):
            try:
                [kind(c) for c in present]
            except ValueError:
                continue
            out[col] = [kind(c) if c != "" else None for c in cells]
            break
        else:
            out[col] = [c if c != "" else None for c in cells]
    return out


def test_every_size_of_the_table_stays_a_distinct_label_with_its_leading_zeros():
    """025 and 25 were one number (25.0) and 05 was 5.0: now each is the text 'No. 025',
    'No. 25', 'No. 05' in a run's row, a study's sweep.csv and the size summary."""
    sizes = list(load_table())
    assert {"025", "05"} <= set(sizes)
    rows = [{c: None for c in flat.COLUMNS} | {"size": s, "load_N": 1000.0} for s in sizes]
    for columns in (flat.COLUMNS, summary.CSV_COLUMNS, table.COLUMNS):
        got = inferred(flat.csv_text(columns, rows))["size"]
        assert got == [f"No. {s}" for s in sizes]
        assert len(set(got)) == len(sizes)
    assert inferred(flat.csv_text(flat.COLUMNS, rows))["load_N"] == [1000.0] * len(sizes)


def _results() -> dict:
    """A results.json's blocks the run's tables read: two meshes, two inputs varied (a
    dimension and a choice), the high end of rf not analysed."""
    levels = [{"mesh_factor": f, "dofs": d, "cells": c, "peak_MPa": p, "peak_unaveraged_MPa": p + 0.7,
               "peak_averaged_MPa": p - 0.7, "critical_peak_MPa": q, "critical_unaveraged_MPa": q,
               "critical_averaged_MPa": q - 0.03, "iterations": 30, "time_s": 9.5}
              for f, d, c, p, q in ((1.0, 197862, 43377, 113.77, 66.22), (1.3, 118302, 25288, 113.84, 66.23))]
    ends = {"global_peak": "fail", "critical_peak": "pass", "critical_section_nominal": "pass",
            "journal_root_nominal": "pass"}
    sens = [{"input": "rf", "kind": "dimension", "unit": "mm", "range": [1.2, 1.8], "peak_MPa": [124.3, None],
             "critical_peak_MPa": [65.7, None], "critical_section_nominal_MPa": [38.7, None],
             "journal_root_nominal_MPa": [43.6, 45.5], "capacity_N": [6434.0, None], "verdicts": [ends, None],
             "invalid": [None, "dj/2 + rf > min(h3, b1)/2 - 0.5"]},
            {"input": "bearing_shape", "kind": "load model", "unit": "", "range": ["cosine", "uniform"],
             "peak_MPa": [113.77, 116.4], "critical_peak_MPa": [66.22, 66.23],
             "critical_section_nominal_MPa": [39.0, 39.0], "journal_root_nominal_MPa": [44.6, 44.6],
             "capacity_N": [7032.0, 6875.0], "verdicts": [ends, ends], "invalid": [None, None]}]
    return {"case": {"size": "05"}, "fe": {"levels": levels}, "sensitivity": sens}


def test_meshes_csv_holds_each_mesh_with_both_readings_of_each_peak():
    res = _results()
    cols = inferred(flat.csv_text(flat.MESH_COLUMNS, flat.mesh_rows(res)))
    assert list(cols) == list(flat.MESH_COLUMNS)
    assert cols["size"] == ["No. 05", "No. 05"] and cols["dofs"] == [197862, 118302]
    for key in ("peak_MPa", "peak_unaveraged_MPa", "peak_averaged_MPa", "critical_peak_MPa",
                "critical_unaveraged_MPa", "critical_averaged_MPa", "mesh_factor"):
        assert cols[key] == [lv[key] for lv in res["fe"]["levels"]], key
    # The names it shares with a run's row mean the same quantity there (MPa, the peak reported).
    assert {"size", "peak_MPa", "critical_peak_MPa", "mesh_factor", "dofs", "time_s"} <= set(flat.COLUMNS)


def test_sensitivity_csv_is_one_row_per_input_and_end():
    """input, end, value (a number) or choice (text), unit, both peaks, both nominal
    stresses, capacity and each verdict, as results.json's sensitivity list has them; an
    end not analysed is empty with its reason in note."""
    cols = inferred(flat.csv_text(flat.SENSITIVITY_COLUMNS, flat.sensitivity_rows(_results())))
    assert list(cols) == list(flat.SENSITIVITY_COLUMNS)
    assert cols["input"] == ["rf", "rf", "bearing_shape", "bearing_shape"]
    assert cols["end"] == ["low", "high", "low", "high"]
    assert cols["value"] == [1.2, 1.8, None, None] and cols["choice"] == [None, None, "cosine", "uniform"]
    assert cols["unit"] == ["mm", "mm", None, None]
    assert cols["peak_MPa"] == [124.3, None, 113.77, 116.4] and cols["capacity_N"] == [6434.0, None, 7032.0, 6875.0]
    assert cols["verdict"] == ["fail", None, "fail", "fail"] and cols["critical_verdict"][0] == "pass"
    assert cols["note"] == [None, "dj/2 + rf > min(h3, b1)/2 - 0.5", None, None]
    # The verdict columns are named as in a study's sweep.csv.
    assert {"verdict", "critical_verdict"} <= set(table.COLUMNS) & set(flat.SENSITIVITY_COLUMNS)


def test_the_run_s_tables_are_described_in_the_contract():
    """docs/design.md §7 holds the columns of meshes.csv and sensitivity.csv as flat.py
    describes them."""
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "design.md").read_text(encoding="utf-8")
    for columns in (flat.MESH_COLUMNS, flat.SENSITIVITY_COLUMNS):
        assert flat.markdown_table(columns) in doc
