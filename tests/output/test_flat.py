"""One flattening of results.json (pipeline/output/flat.py): the size summary and a design
study's table read a variant alike, under one set of column names (MPa, N, s). The
results.json files here are written by hand, so every expected number is the file's own
input, or that input scaled by the load (linear elasticity)."""
from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace

import pytest

from geometry.table import load_table
from pipeline.output import flat
from pipeline.runtime.folders import MARKER
from pipeline.study import summary, table
from pipeline.study.manifest import write_manifest
from pipeline.study.plan import Task, variant_folder

ROOT = Path(__file__).resolve().parents[2]
Q0 = 10_000.0   # N, the case's own load
SOURCE = load_table()["05"].source


def a_results(rf: float, *, loads: tuple[float, ...] = (), critical: str = "converged",
              peak_feature: str | None = None, levels: int = 3) -> dict:
    """A results.json of No. 05 at Q0 with rf (mm): global peak 120 MPa, critical peak
    66 MPa, nominal 40 MPa, allowable 80 MPa; ``critical``: the critical peak's status;
    ``peak_feature``: a singular feature at the global peak; ``loads``: a load sweep (N),
    its entries worked here by hand as a run's load_sweep gives them."""
    est = {"status": "converged", "band": 0.5, "extrapolated": 119.0, "values": [120.0, 119.7, 119.5]}
    crit_est = {"status": critical, "band": None if critical == "singular" else 0.25,
                "extrapolated": 65.5 if critical == "converged" else None, "values": [66.0, 65.9, 65.8]}
    peak = {"value_MPa": 120.0, "feature": "journal shoulder fillet"}
    if levels >= 3:
        peak["error_estimate"] = est
    if peak_feature:
        peak["singular_feature"] = peak_feature
        if levels >= 3:
            peak["error_estimate"] = dict(est, status="singular", band=None, extrapolated=None)
    dims = dict(asdict(load_table()["05"].dims), rf=rf)
    res = {
        "case": {"size": "05", "source": SOURCE, "load_N": Q0, "allowable_MPa": 80.0, "mesh_factor": 3.0,
                 "dims": dims},
        "analytic": {"approximate_MPa": 37.76, "exact_MPa": 43.81},
        "fe": {"peak_MPa": 120.0, "critical_peak_MPa": 66.0,
               "safety_factor": None if peak_feature else 80 / 120, "critical_safety_factor":
                   None if critical == "singular" else 80 / 66.0,
               "dofs": 8000, "levels": [{}] * levels, "mesh_min_jacobian_ratio": 0.3,
               "sections": {"critical_section": {"nominal_MPa": 40.0}},
               "peak": peak,
               "critical": {"value_MPa": 66.0, "feature": "bore edge (bottom face)", "error_estimate": crit_est}},
        "timings_s": {"total": 2.5}}
    if loads:
        res["load_sweep"] = [{"load_N": q, "peak_MPa": 120.0 * q / Q0, "critical_peak_MPa": 66.0 * q / Q0,
                              "approximate_MPa": 37.76 * q / Q0, "exact_MPa": 43.81 * q / Q0,
                              "peak_band_MPa": None if peak_feature else 0.5 * q / Q0,
                              "critical_band_MPa": 0.25 * q / Q0,
                              "safety_factor": None if peak_feature else 80 / (120.0 * q / Q0),
                              "critical_safety_factor": 80 / (66.0 * q / Q0)} for q in loads]
    return res


def a_study(out: Path, variants: dict[str, dict]) -> list[Task]:
    """A study's folder holding ``variants`` (key: results.json) as finished variants with
    their checksums, and its tasks."""
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).write_text('{"tool": "crosshead", "sweep": true}\n')
    tasks = []
    for key, res in variants.items():
        folder = variant_folder(out, key)
        folder.mkdir(parents=True)
        (folder / MARKER).write_text('{"tool": "crosshead"}\n')
        (folder / "results.json").write_text(json.dumps(res) + "\n")
        write_manifest(folder)
        loads = tuple(e["load_N"] for e in res.get("load_sweep", [])) or (Q0,)
        tasks.append(Task(key, {"dims.rf": res["case"]["dims"]["rf"]}, SimpleNamespace(size="05"), loads))
    return tasks


def test_the_summary_and_the_study_read_a_variant_alike(tmp_path):
    """The summary's row of each variant and the study's row at the case's load agree
    column by column on every column they share, and those include the peaks, bands,
    statuses and safety factors: one name per quantity in both tables."""
    study = tmp_path / "study"
    tasks = a_study(study, {"a1": a_results(1.0, loads=(Q0, 2 * Q0)),
                            "b2": a_results(1.5, critical="singular"),
                            "c3": a_results(2.0, peak_feature="the rigid support's edge", levels=1)})
    study_rows = table.rows_of(tasks, study)
    summary_rows, skipped = summary.collect(study / "variants", take_all=True)
    assert skipped == [] and len(summary_rows) == 3 and len(study_rows) == 4
    shared = set(summary.CSV_COLUMNS) & set(table.COLUMNS)
    assert {"peak_MPa", "peak_band_MPa", "peak_status", "critical_peak_MPa", "critical_band_MPa",
            "critical_status", "safety_factor", "critical_safety_factor", "critical_section_nominal_MPa",
            "load_N", "time_s", "size"} <= shared
    for s in summary_rows:
        t = next(r for r in study_rows if r["variant"] == s["folder"] and r["load_N"] == Q0)
        assert {c: s[c] for c in shared} == {c: t[c] for c in shared}, s["folder"]
    by = {s["folder"]: s for s in summary_rows}
    assert by["a1"]["peak_MPa"] == 120.0 and by["a1"]["critical_band_MPa"] == 0.25   # the file's values
    assert by["b2"]["critical_peak_MPa"] is None and by["b2"]["critical_reading_MPa"] == 66.0
    assert by["c3"]["peak_MPa"] is None and by["c3"]["peak_status"] == flat.SINGULAR


def test_a_load_sweep_is_one_row_per_load_scaled_by_the_load():
    """At 2.5 × the case's load every stress is 2.5 × (linear elasticity) and each safety
    factor 1/2.5 ×: the load sweep's own entries and the quantities it does not list
    (extrapolated value, last change, nominal stress) alike."""
    rows = flat.rows(a_results(1.0, loads=(Q0, 2.5 * Q0)))
    assert [r["load_N"] for r in rows] == [Q0, 2.5 * Q0]
    hi = rows[1]
    assert hi["peak_MPa"] == pytest.approx(300.0) and hi["peak_band_MPa"] == pytest.approx(1.25)
    assert hi["peak_extrapolated_MPa"] == pytest.approx(297.5)
    assert hi["peak_last_change_MPa"] == pytest.approx(2.5 * 0.3)
    assert hi["critical_peak_MPa"] == pytest.approx(165.0) and hi["critical_reading_MPa"] == pytest.approx(165.0)
    assert hi["critical_section_nominal_MPa"] == pytest.approx(100.0)
    assert hi["exact_MPa"] == pytest.approx(2.5 * 43.81) and hi["safety_factor"] == pytest.approx(80 / 300)
    assert hi["time_s"] == 2.5 and hi["peak_feature"] == "journal shoulder fillet"
    assert rows[0] == flat.rows(a_results(1.0))[0]  # the case's own load: the row without a load sweep
    assert list(rows[0]) == list(flat.COLUMNS)


def test_a_peak_with_no_value_is_decided_once_for_both_tables(tmp_path):
    """A global peak at a singular feature read on one mesh (no error estimate) has no
    value in either table and is called singular, not "single mesh": the summary shows its
    reading marked NOT CONVERGED, the study gives it the verdict "none" and its note says
    why. A peak not asked for (--want) has no value in either, and no verdict."""
    res = a_results(1.0, peak_feature="the rigid support's edge", levels=1)
    wanted = a_results(1.5)
    wanted["fe"]["peak"]["not_wanted"] = ("want = critical: the run did not refine for the global peak; "
                                          "shown for orientation only")
    wanted["fe"]["safety_factor"] = None
    study = tmp_path / "study"
    tasks = a_study(study, {"a1": res, "b2": wanted})
    rows = {r["variant"]: r for r in table.with_verdicts(table.rows_of(tasks, study), 80.0)}
    assert rows["a1"]["peak_MPa"] is None and rows["a1"]["verdict"] == "none"
    assert rows["a1"]["note"] == "global peak at a singular feature (the rigid support's edge): no finite value"
    assert rows["b2"]["peak_MPa"] is None and rows["b2"]["verdict"] is None
    assert rows["b2"]["note"] == "want = critical: the run did not refine for the global peak"
    assert summary.main([str(study / "variants"), "--all", "--out", str(tmp_path / "sum")]) == 0
    md = (tmp_path / "sum" / "summary.md").read_text(encoding="utf-8")
    line = next(ln for ln in md.splitlines() if ln.startswith("| 05 ") and "rf = 1 mm" in ln)
    assert "| 120.00 (NOT CONVERGED: singular feature) | singular |" in line and "| – |" in line
    assert "*singular* on one mesh: the peak sits at a singular feature found by its place" in md
    assert "grows under refinement" not in md
    other = next(ln for ln in md.splitlines() if ln.startswith("| 05 ") and "rf = 1 mm" not in ln)
    assert "| – | not asked |" in other


def test_every_column_is_described_once_in_the_docs():
    """docs/sweeps.md holds the table of a run's row's columns, the study's and the
    summary's own, as the modules describe them, each column once."""
    doc = (ROOT / "docs" / "sweeps.md").read_text(encoding="utf-8")
    for columns in (flat.COLUMNS, table.OWN_COLUMNS, summary.OWN_COLUMNS):
        assert flat.markdown_table(columns) in doc
    for c in {*flat.COLUMNS, *table.OWN_COLUMNS, *summary.OWN_COLUMNS}:
        assert doc.count(f"| `{c}` |") == 1, c
    assert set(table.COLUMNS) == {*flat.COLUMNS, *table.OWN_COLUMNS}
    assert set(summary.CSV_COLUMNS) == {*flat.COLUMNS, *summary.OWN_COLUMNS}
