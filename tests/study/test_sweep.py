"""Design studies (pipeline/study/sweep.py): the grid, the CSV/JSON contract, invalid variants
skipped, resuming, 1 against 2 ranks, and the crossing of the allowable."""
from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.errors import InputError
from pipeline.study.plan import read_study
from pipeline.study.sweep import time_left_s
from pipeline.inputs.valuelist import parse_loads, parse_values
from pipeline.study.table import (COLUMNS, _passing_lines, band_reach, crossing_text, crossings, parameters_text,
                                  passing_count, series, sides, unanalysed, varying_names, with_verdicts)

ROOT = Path(__file__).resolve().parents[2]
GRID = ["--size", "05", "--dim", "rf=1.0,1.5,2.5", "--mesh-factor", "3", "--levels", "1"]


def sweep(out: Path, *args: str, ranks: int = 1) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pipeline"] if ranks == 1 else [sys.executable, "-m", "pipeline.runtime.launch", str(ranks)]
    # env=dict(os.environ): this process's mpi4py put OMPI_* variables into the C environment,
    # and a child mpirun that inherits them exits 1 (see tests/verification/test_invariance.py).
    p = subprocess.run(cmd + ["sweep", *args, "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                       timeout=600, env=dict(os.environ))
    assert p.returncode == 0, p.stderr
    return p


def test_parse_values():
    assert parse_values("0.5:2.5:5", "rf", 200) == pytest.approx([0.5, 1.0, 1.5, 2.0, 2.5])
    assert parse_values("16,18,20", "dj", 200) == [16.0, 18.0, 20.0]
    assert parse_values("3:1:3", "rf", 200) == [3.0, 2.0, 1.0]
    for bad in ("1:2", "a,b", "1:2:1", "1:inf:3", "nan,1", "1,-inf", "", "1,,2", "1,1", "2:2:3", "1:2:x",
                "1:2:2.5", "1,2,3,4"):
        with pytest.raises(InputError):
            parse_values(bad, "rf", 3)


@pytest.mark.parametrize("text, says", [
    ("1:2:1", "a range needs 2..3 values, got 1"),  # was swallowed by the generic line
    ("1:2:x", "range count 'x' is not an integer"),
    ("1:y:3", "'y' is not a number"),
    ("1,2,3,4", "at most 3 values, got 4"),
    ("1:2", "give one value, a list"),
])
def test_a_bad_list_is_named_for_what_is_wrong(text, says):
    with pytest.raises(InputError, match=f"^rf: .*{re.escape(says)}"):
        parse_values(text, "rf", 3)


def test_the_time_left_follows_every_rank():
    """Two ranks at different paces: one finished 1 variant, the other 3, in 30 s; 4 are
    left. At the pace of both (4 in 30 s) that is 30 s; rank 0's own pace times the ranks
    (1 in 30 s, 2 ranks) said 60 s."""
    assert time_left_s(30.0, 4, 4) == pytest.approx(30.0)
    assert time_left_s(0.0, 0, 4) == 0.0  # nothing finished yet: no pace, no estimate


def test_loads_are_read_alike_everywhere():
    """The command line's --load and a study file's load take one grammar: a range with
    equal ends repeats a load (refused like 5000,5000), and every load is > 0."""
    assert parse_loads("5000:20000:4") == pytest.approx([5000, 10000, 15000, 20000])
    for bad, says in (("5000:5000:3", "5000 given twice"), ("-5,10000", "must be > 0, got -5"),
                      ("0", "must be > 0")):
        with pytest.raises(InputError, match=f"^load_N: .*{re.escape(says)}"):
            parse_loads(bad)


@pytest.mark.slow
def test_the_command_line_overrides_the_study_file(tmp_path):
    """--levels 1 beside a study file with levels = 8, ratio = 3 (whose coarsest error-bar
    mesh, 3 x 3^7, would be refused): the command line wins, as it does for the axes, the
    mesh factor and the output folder; one mesh has no ratio, and --ratio with --levels 1
    is refused (it could not take effect)."""
    study = tmp_path / "s.toml"
    study.write_text('[sweep]\nsize = "05"\ndims = { rf = "1.0,1.5" }\nmesh_factor = 3.0\nlevels = 8\nratio = 3.0\n')
    sweep(tmp_path / "out", "--study", str(study), "--levels", "1", "--quiet")
    rows = json.loads((tmp_path / "out" / "sweep.json").read_text(encoding="utf-8"))["rows"]
    assert [r["status"] for r in rows] == ["done", "done"]


def test_a_study_file_takes_an_array_of_values_like_a_list(tmp_path):
    """``rf = [1.0, 1.5]`` in a study file means what ``rf = "1.0,1.5"`` means."""
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('[sweep]\nsize = "05"\ndims = { rf = [1.0, 1.5] }\n')
    b.write_text('[sweep]\nsize = "05"\ndims = { rf = "1.0,1.5" }\n')
    va, vb = (parse_values(str(read_study(p)["dims"]["rf"]), "rf", 200) for p in (a, b))
    assert va == vb == [1.0, 1.5]
    # The loads too (refused as 'expected a string or an integer or a number' before), and
    # an array of anything but numbers is named as such.
    c = tmp_path / "c.toml"
    c.write_text('[sweep]\nsize = "05"\nload = [5000, 10000]\n')
    assert parse_loads(str(read_study(c)["load"])) == [5000.0, 10000.0]
    c.write_text('[sweep]\nsize = "05"\nload = ["5000", 1]\n')
    with pytest.raises(InputError, match="sweep.load: expected an array of numbers"):
        read_study(c)


def test_crossing_is_interpolated_with_its_band():
    """Peaks 120 and 80 MPa at rf = 1 and 2 cross 100 MPa at rf = 1.5; with bands of 10 MPa
    on both the crossing moves to 1.25 (values + 10) and 1.75 (values - 10): hand computed."""
    rows = [{"status": "done", "variant": "a", "dims.rf": 1.0, "load_N": 1.0, "peak_MPa": 120.0, "peak_band_MPa": 10.0,
             "critical_peak_MPa": 50.0, "critical_band_MPa": None},
            {"status": "done", "variant": "b", "dims.rf": 2.0, "load_N": 1.0, "peak_MPa": 80.0, "peak_band_MPa": 10.0,
             "critical_peak_MPa": 60.0, "critical_band_MPa": None}]
    found = crossings(rows, "dims.rf", 100.0)
    assert len(found) == 1 and found[0]["peak"] == "global peak" and found[0]["falls_below"]
    assert found[0]["at"] == pytest.approx(1.5) and found[0]["range"] == pytest.approx([1.25, 1.75])
    assert crossing_text(found[0], 100.0) == ("- The global peak falls below 100 MPa at rf ≈ 1.5 mm (between 1.25 "
                                              "and 1.75 mm within the error bars) and stays below it in every "
                                              "variant up to rf = 2 mm, for load = 1 N.")
    # A third variant back above 100 MPa: two crossings, neither the only one of its line.
    back = dict(rows[1], variant="c", **{"dims.rf": 3.0, "peak_MPa": 110.0})
    again = crossings(rows + [back], "dims.rf", 100.0)
    # 80 -> 110 MPa over rf 2 -> 3 and not any(x["only_crossing"] for x in again)
    assert [x["at"] for x in again] == pytest.approx([1.5, 2 + 20 / 30])
    assert "stays" not in crossing_text(again[0], 100.0)
    # In a study where the load is the same everywhere, the line does not name it.
    assert crossing_text(found[0], 100.0, varying=set()).endswith("up to rf = 2 mm.")


def test_a_crossing_s_range_holds_the_crossing_when_the_bands_differ():
    """114.90 ± 96.18 and 75.37 ± 9.18 MPa at rf = 1 and 2 mm against 80 MPa (a sweep at
    mesh factor 3 gave these): the peak crosses at rf = 1 + 34.90/39.53 = 1.883 mm. Crossing
    the bands' edges with 80 MPa put the range at 2.036..2.291 mm, beyond the crossing and
    the step; the allowable lies within both variants' own bands, so the range is the whole
    step and reaches both neighbours. With bands of 2 MPa on both it is hand computed:
    |34.90 − 39.53 t| <= 2, t in [32.90, 36.90] / 39.53."""
    def rows(wa, wb):
        return [{"status": "done", "variant": v, "dims.rf": rf, "load_N": 1.0, "peak_MPa": p, "peak_band_MPa": w,
                 "critical_peak_MPa": 50.0, "critical_band_MPa": None}
                for v, rf, p, w in (("a", 1.0, 114.90, wa), ("b", 2.0, 75.37, wb))]
    wide, = crossings(rows(96.18, 9.18), "dims.rf", 80.0)
    assert wide["at"] == pytest.approx(1 + 34.90 / 39.53)
    assert wide["range"] == pytest.approx([1.0, 2.0]) and wide["range_reaches"] == [1.0, 2.0]
    assert "within the error bars, which reach the variants at 1 mm and 2 mm: it may lie beyond)" in \
        crossing_text(wide, 80.0)
    narrow, = crossings(rows(2.0, 2.0), "dims.rf", 80.0)
    assert narrow["range"] == pytest.approx([1 + 32.90 / 39.53, 1 + 36.90 / 39.53])
    assert narrow["range_reaches"] == [] and "beyond" not in crossing_text(narrow, 80.0)
    assert band_reach(20.0, -20.0, 0.0, 0.0) == (0.5, 0.5)  # no band: the crossing itself


def test_each_peak_is_placed_against_the_allowable_by_hand_counted_rows():
    """Global peaks 120, 90 and 85 ± 6 MPa, critical 50, 60 and 81 MPa, against 80 MPa:
    the global peak above in all three, one of them (85 ± 6) within its band of 80; the
    critical above in one of three; an invalid row counts for neither."""
    def row(rf, g, gb, c):
        return {"status": "done", "parameters": json.dumps({"dims.rf": rf}), "peak_MPa": g, "peak_band_MPa": gb,
                "critical_peak_MPa": c, "critical_band_MPa": None}
    rows = [row(1.0, 120.0, 1.0, 50.0), row(1.5, 90.0, None, 60.0), row(2.0, 85.0, 6.0, 81.0),
            {"status": "invalid", "parameters": json.dumps({"dims.rf": 9.0})}]
    g, c = sides(rows, 80.0)
    assert (g["peak"], g["rows"], g["above"], g["within_band"]) == ("global peak", 3, 3, 1)
    assert (c["peak"], c["rows"], c["above"], c["within_band"]) == ("critical peak", 3, 1, 0)
    assert g["lowest"]["peak_MPa"] == 85.0 and c["highest"]["critical_peak_MPa"] == 81.0
    assert parameters_text(rows[0]) == "rf = 1 mm"
    assert parameters_text({"parameters": json.dumps({"size": "2.5", "dims.dj": 16.0})}) == "No. 2.5, dj = 16 mm"


def test_the_report_names_the_cases_that_pass_with_their_error_bars():
    """Against 80 MPa, by hand: 70 ± 1 / 60 ± 1 passes; 70 ± 1 / 79.5 ± 1 is undecided (the
    critical bar holds 80); 90 ± 1 / 60 fails; 75 ± 1 with no critical peak (not asked for)
    passes on the peak it has; an invalid variant is none of these."""
    def row(rf, g, c, cb=1.0):
        return {"status": "done", "parameters": json.dumps({"dims.rf": rf}), "dims.rf": rf, "load_N": 1.0,
                "peak_MPa": g, "peak_band_MPa": 1.0, "critical_peak_MPa": c, "critical_band_MPa": None if c is None else cb}
    rows = with_verdicts([row(1.0, 70.0, 60.0), row(2.0, 70.0, 79.5), row(3.0, 90.0, 60.0), row(4.0, 75.0, None),
                          {"status": "invalid", "parameters": json.dumps({"dims.rf": 9.0}), "dims.rf": 9.0}], 80.0)
    assert [(r.get("verdict"), r.get("critical_verdict")) for r in rows] == [
        ("pass", "pass"), ("pass", "undecided"), ("fail", "pass"), ("pass", None), (None, None)]
    assert passing_count(rows) == 2
    lines = _passing_lines({"rows": rows, "allowable_MPa": 80.0})
    assert lines == ["- 2 of 4 analysed cases pass 80 MPa with every peak, error bars included: rf = 1 mm; rf = 4 mm.",
                     "- Undecided in 1 of 4 (an error bar holds 80 MPa, no peak fails): rf = 2 mm."]


@pytest.mark.slow
def test_a_singular_peak_gives_no_verdict_and_the_case_does_not_pass(tmp_path):
    """The rigid support (cases/05-rigid.toml) puts the global peak on a singular edge: it
    grows without bound under refinement, and the run gives it no verdict. The study had
    judged its 918 MPa at mesh factor 3 'fail' like a value (and, once left out, would have
    let the case 'pass' on its critical peak alone). Now: no value, verdict 'none', the
    reason in the note, and the case is counted under 'no verdict', not as passing."""
    out = tmp_path / "rigid"
    p = sweep(out, "--case", "cases/05-rigid.toml", "--dim", "rf=1,2", "--mesh-factor", "3", "--levels", "3")
    assert "0 of 2 pass 80 MPa" in p.stdout
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert all(r["peak_MPa"] is None and r["verdict"] == "none" and "singular" in r["note"] for r in rows)
    assert all(r["critical_verdict"] == "pass" for r in rows)
    report = (out / "report.md").read_text(encoding="utf-8")
    assert "No verdict in 2 of 2 (a peak at a singular feature" in report and "The global peak" not in report
    # No plot of the peak left out, not even one from an earlier run into the same folder.
    (out / "peak_vs_rf.png").write_bytes(b"an earlier run's plot")
    (out / "notes_peak_vs_rf.png").write_bytes(b"not the study's name")
    sweep(out, "--case", "cases/05-rigid.toml", "--dim", "rf=1,2", "--mesh-factor", "3", "--levels", "3")
    assert not (out / "peak_vs_rf.png").exists() and (out / "critical_peak_vs_rf.png").is_file()
    assert (out / "notes_peak_vs_rf.png").is_file()


def test_a_plot_draws_one_line_per_value_of_the_other_parameters():
    """rf x dj = 3 x 2 finished rows (one failed) at one load: along rf, two lines (dj 16 and
    18), each ordered by rf; along dj, three. A sweep of rf alone is one line. (The plots
    grouped rows by all their parameters, the plotted one included: every point was a line
    of its own.)"""
    def row(rf, dj, status="done"):
        return {"status": status, "dims.rf": rf, "dims.dj": dj, "load_N": 1e4,
                "parameters": json.dumps({"dims.dj": dj, "dims.rf": rf})}
    rows = [row(rf, dj) for dj in (18.0, 16.0) for rf in (2.0, 1.0, 1.5)] + [row(3.0, 16.0, "failed")]
    along_rf = series(rows, "dims.rf")
    assert sorted(dict(k)["dims.dj"] for k in along_rf) == [16.0, 18.0]
    assert all([r["dims.rf"] for r in g] == [1.0, 1.5, 2.0] for g in along_rf.values())
    assert len(series(rows, "dims.dj")) == 3
    single = [{k: v for k, v in r.items() if k != "dims.dj"} for r in rows if r["dims.dj"] == 16.0]
    assert [len(g) for g in series(single, "dims.rf").values()] == [3]
    # Two sizes at the same load (--sizes with --load) are two lines, not one zigzag.
    sized = [dict(r, size=s) for s in ("05", "1") for r in single]
    assert sorted(dict(k)["size"] for k in series(sized, "dims.rf")) == ["05", "1"]


def test_a_plot_marks_the_variants_without_a_peak():
    """A study's plot shows where the geometry rules end the swept range, and where an
    analysis failed: those variants' values along the axis, once each (rows at two loads),
    on the line of the other values that vary (dj here), not as if every line ended there."""
    rows = [{"status": s, "size": "05", "dims.dj": dj, "dims.rf": rf, "load_N": q} for s, dj, rf in
            (("done", 16.0, 1.0), ("done", 18.0, 1.0), ("done", 16.0, 3.0), ("invalid", 18.0, 3.0),
             ("failed", 16.0, 2.0)) for q in (5000.0, 10000.0)]
    varying = varying_names(rows, {"size", "dims.dj", "load_N"})
    assert varying == {"dims.dj", "load_N"}
    assert unanalysed(rows, "dims.rf", varying) == {  # a geometry is invalid at every load: one mark
        ("invalid", "dj = 18 mm"): [3.0],
        ("failed", "dj = 16 mm, load = 5000 N"): [2.0], ("failed", "dj = 16 mm, load = 10000 N"): [2.0]}
    one_line = [dict(r, **{"dims.dj": 16.0, "load_N": 5000.0}) for r in rows]
    assert unanalysed(one_line, "dims.rf", set()) == {("invalid", ""): [3.0], ("failed", ""): [2.0]}
    assert unanalysed(rows[:2], "dims.rf", varying) == {}


def test_a_failed_variant_writes_why_with_its_size_and_inputs(tmp_path, monkeypatch):
    """A variant whose analysis fails is reported, not fatal: its <key>.failed.json says
    why, and which size and inputs it was (the size summary names it from there)."""
    from pipeline.study import sweep as sweep_module
    from pipeline.errors import NumericalError
    from pipeline.study.manifest import read_failure
    from pipeline.study.plan import Study, failure_file, plan

    def fails(*a, **k):
        raise NumericalError("solver pmg did not converge (PETSc reason -3, 1000 iterations)")
    monkeypatch.setattr(sweep_module, "write_run", fails)
    study = Study("1.6", None, {"mesh_factor": 3.0}, {"dims.rf": [2.0]}, [], levels=1)
    task, = plan(study)
    (tmp_path / "variants").mkdir()
    sweep_module.run_task(task, tmp_path, study)
    note = read_failure(failure_file(tmp_path, task.key))  # checked against its checksum
    assert note == {"error": "solver pmg did not converge (PETSc reason -3, 1000 iterations)", "size": "1.6",
                    "parameters": {"dims.rf": 2.0}}


def test_only_results_of_other_variants_are_removed(tmp_path):
    """What a finished study removes from its variants/: the folders (with the tool's own
    marker) and failure notes (matching their checksums) of keys it does not have; its own,
    and anything the tool did not write, stay: a folder whose marker is empty JSON or a
    note that is not the tool's is a user's."""
    import json

    from pipeline.runtime.folders import MARKER
    from pipeline.study.manifest import write_failure
    from pipeline.study.sweep import remove_earlier_variants
    from pipeline.study.plan import Task
    v = tmp_path / "variants"
    for key in ("aaa", "bbb"):
        (v / key).mkdir(parents=True)
        (v / key / MARKER).write_text(json.dumps({"tool": "crosshead"}))
    (v / "fake").mkdir()
    (v / "fake" / MARKER).write_text("{}")     # a marker the tool did not write
    for key in ("ccc", "ddd"):
        write_failure(v / f"{key}.failed.json", {"error": "x"})
    (v / "eee.failed.json").write_text("{}")   # no checksum: not the tool's note
    (v / "users").mkdir()                      # no marker: not a variant's
    (v / "notes.txt").write_text("mine")
    said = []
    remove_earlier_variants(tmp_path, [Task("aaa", {}, None, (1.0,)), Task("ddd", {}, None, (1.0,))], said.append)
    assert sorted(p.name for p in v.iterdir()) == ["aaa", "ddd.failed.json", "eee.failed.json", "fake", "notes.txt",
                                                   "users"]
    assert said == ["sweep: removed the results of 2 variants that this study does not have (earlier inputs or code)"]
    said.clear()
    remove_earlier_variants(tmp_path, [Task("aaa", {}, None, (1.0,))], said.append)
    assert said == ["sweep: removed the results of 1 variant that this study does not have (earlier inputs or code)"]


@pytest.mark.slow
def test_small_sweep_contract_invalid_variant_and_resume(tmp_path):
    out = tmp_path / "study"
    first = sweep(out, *GRID)
    assert "3 variants (2 valid, 1 invalid)" in (first.stdout + first.stderr)
    assert "2 done, 1 invalid, 0 failed; 0 of 2 pass 80 MPa with every peak" in first.stdout
    with open(out / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[:len(COLUMNS)] == list(COLUMNS) and "dims.rf" in rows[0]
    status = {float(r["dims.rf"]): r["status"] for r in rows}
    assert status == {1.0: "done", 1.5: "done", 2.5: "invalid"}
    bad = next(r for r in rows if r["status"] == "invalid")
    assert "rf" in bad["note"] and bad["peak_MPa"] == ""
    # The size summary of the study's variants reads each variant as the study did: one
    # name per quantity, the same text in both CSV files on every column they share.
    from pipeline.study import summary
    assert summary.main([str(out / "variants"), "--all", "--out", str(tmp_path / "sum")]) == 0
    with open(tmp_path / "sum" / "summary.csv", newline="") as f:
        summarised = list(csv.DictReader(f))
    shared = set(summarised[0]) & set(rows[0])
    assert {"peak_MPa", "critical_peak_MPa", "peak_status", "critical_band_MPa", "safety_factor",
            "critical_section_nominal_MPa", "dofs", "changed_dims"} <= shared
    for r in (r for r in rows if r["status"] == "done"):
        s = next(s for s in summarised if s["changed_dims"] == r["changed_dims"])
        assert {c: s[c] for c in shared} == {c: r[c] for c in shared}
    data = json.loads((out / "sweep.json").read_text())
    assert data["units"]["stress"] == "MPa" and data["counts"]["done"] == 2
    assert all(r["peak_MPa"] > r["critical_peak_MPa"] > 0 for r in data["rows"] if r["status"] == "done")
    assert (out / "report.md").is_file() and (out / "peak_vs_rf.png").is_file()
    # A variant keeps its results, not its 7 MB mesh (at the default mesh): the study asks for peaks.
    for folder in (out / "variants").iterdir():  # and the checksums of the two (pipeline.study.manifest)
        assert sorted(p.name for p in folder.iterdir()) == [".crosshead-results", "manifest.json", "results.json"]
        variant = json.loads((folder / "results.json").read_text())
        assert "mesh" not in variant["files"]
        # ... nor the solves at the hand formulas' load positions, which its table does not read
        assert variant["fe"]["sections"]["formula_load"] is None
        assert variant["comparison_pct"]["section_vs_exact_same_load"] is None
    report = (out / "report.md").read_text(encoding="utf-8")
    assert "## Against the allowable (80 MPa)" in report and report.count("analysed case") == 3
    assert "No analysed case passes 80 MPa with every peak" in report  # the global peaks are > 100 MPa
    assert all(r["verdict"] == "fail" and r["critical_verdict"] == "pass" for r in data["rows"] if r["status"] == "done")
    assert "load =" not in report  # one load (the invalid variant's missing one is not a second)
    assert "| rf = 1 mm |" in report and "| rf = 2.5 mm |" in report
    again = sweep(out, *GRID)
    assert "2 already done" in (again.stdout + again.stderr)
    assert json.loads((out / "sweep.json").read_text())["rows"] == data["rows"]
    changed = sweep(out, *GRID, "--E", "200000")  # another input: not mistaken for a finished variant
    assert "0 already done" in (changed.stdout + changed.stderr)
    # The first run's two variants are gone once the study is done: only this study's remain
    # (a summary of variants/ listed both before).
    assert "removed the results of 2 variants that this study does not have" in (changed.stdout + changed.stderr)
    keys = {r["variant"] for r in json.loads((out / "sweep.json").read_text())["rows"] if r["status"] == "done"}
    assert {p.name for p in (out / "variants").iterdir()} == keys and len(keys) == 2


@pytest.mark.slow
def test_a_study_leaves_out_the_peak_it_was_not_asked_for(tmp_path):
    """--want critical: each run says its global peak is not resolved (shown for orientation
    only), so the study gives it no value, side, crossing or plot, and says why per row.
    At mesh factor 3 the unresolved fillet peaks of rf = 1 and 2 mm lie either side of
    80 MPa (115 and 75 MPa): the study reported that crossing before."""
    out = tmp_path / "critical"
    sweep(out, "--size", "05", "--dim", "rf=1,2", "--want", "critical", "--mesh-factor", "3", "--levels", "1")
    data = json.loads((out / "sweep.json").read_text())
    done = [r for r in data["rows"] if r["status"] == "done"]
    assert len(done) == 2 and all(r["peak_MPa"] is None and r["safety_factor"] is None for r in done)
    assert all(r["critical_peak_MPa"] > 0 and "global peak" in r["note"] for r in done)
    assert not any(x["peak"] == "global peak" for x in data["crossings"])
    assert (out / "critical_peak_vs_rf.png").is_file() and not (out / "peak_vs_rf.png").exists()
    assert "The global peak" not in (out / "report.md").read_text(encoding="utf-8")


@pytest.mark.slow
def test_a_study_too_large_for_memory_is_refused_on_two_ranks(tmp_path):
    """Two variants at once on this machine, each estimated at about 2.6 GiB (mesh factor
    0.6, pipeline/analysis/memory.py), against --memory-limit 3: one fits, two at once do not.
    Refused with one line and exit 2, nothing written. (Rank 0's probe loaded DOLFINx alone,
    whose PETSc start-up is collective, and rank 1 aborted with 'stack smashing detected'.)"""
    out = tmp_path / "big"
    p = subprocess.run([sys.executable, "-m", "pipeline.runtime.launch", "2", "sweep", "--size", "05", "--dim", "rf=1,2",
                        "--mesh-factor", "0.6", "--memory-limit", "3", "--out", str(out)], cwd=ROOT,
                       capture_output=True, text=True, timeout=600, env=dict(os.environ))
    assert p.returncode == 2, p.stderr
    lines = [ln for ln in p.stderr.strip().splitlines() if not ln.startswith("[")]  # not the progress lines
    assert len(lines) == 1, p.stderr
    line = lines[0]
    assert "2 at once" in line and "3.0 GiB allowed" in line, line
    assert not out.exists()


@pytest.mark.slow
def test_one_and_two_ranks_give_the_same_rows(tmp_path):
    one = json.loads(sweep(tmp_path / "one", *GRID, "--quiet") and (tmp_path / "one" / "sweep.json").read_text())
    p2 = sweep(tmp_path / "two", *GRID, ranks=2)
    two = json.loads((tmp_path / "two" / "sweep.json").read_text())
    strip = lambda rows: [{k: v for k, v in r.items() if k != "time_s"} for r in rows]  # noqa: E731
    assert strip(one["rows"]) == strip(two["rows"])
    # The ranks speak through rank 0: each line once (the plan's line came from every rank).
    assert (p2.stdout + p2.stderr).count("3 variants (2 valid, 1 invalid)") == 1, (p2.stdout + p2.stderr)
    assert p2.stdout.count("written to") == 1, p2.stdout


@pytest.mark.slow
def test_a_sweep_never_writes_into_a_user_folder(tmp_path):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep")
    p = subprocess.run([sys.executable, "-m", "pipeline", "sweep", *GRID, "--out", str(user)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "refusing" in p.stderr
    assert [x.name for x in user.iterdir()] == ["notes.txt"]


@pytest.mark.slow
def test_sweep_over_sizes_uses_each_rated_load(tmp_path):
    """--sizes: one variant per hook number, each at its table load (independent: sizes.csv)."""
    from geometry.table import lookup
    out = tmp_path / "sizes"
    sweep(out, "--sizes", "05,1", "--mesh-factor", "3", "--levels", "1", "--quiet")
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert {r["size"]: r["load_N"] for r in rows} == {s: lookup(s).load_N for s in ("05", "1")}
    assert all(r["status"] == "done" for r in rows)


@pytest.mark.slow
def test_a_study_at_several_loads_counts_variants_and_cases_apart(tmp_path):
    """Two geometries (one invalid: rf = 3 mm breaks the rules) at two loads are 2 variants
    and 4 cases (rows). The first line counted variants and the last one cases, both
    unnamed: "2 variants (1 valid, 1 invalid)" and then "2 done, 2 invalid"."""
    p = sweep(tmp_path / "s", "--size", "05", "--dim", "rf=1,3", "--load", "5000,10000", "--mesh-factor", "3",
              "--levels", "1")
    said = p.stdout + p.stderr
    assert "sweep: 2 variants at 2 loads each (1 valid, 1 invalid), 0 already done" in said, said
    assert "sweep: 4 cases (2 variants at 2 loads): 2 done, 2 invalid, 0 failed; " in p.stdout, p.stdout


def test_an_input_every_variant_shares_is_named_as_it_is():
    """E = -5 MPa makes every variant invalid for one reason, which is not the variants':
    the line is the one a run gives ("E_MPa: must be > 0, got -5"), not "every variant is
    invalid; the first: ...". Variants invalid for reasons of their own keep that line."""
    from pipeline.study.plan import Study, plan
    with pytest.raises(InputError) as shared:
        plan(Study("05", None, {"E_MPa": -5.0}, {"dims.rf": [1.0, 2.0]}, []))
    assert str(shared.value) == "E_MPa: must be > 0, got -5"
    with pytest.raises(InputError) as own:
        plan(Study("05", None, {}, {"dims.rf": [-1.0, -2.0]}, []))
    assert str(own.value).startswith("sweep: every variant is invalid; the first: ")


def test_a_variant_s_key_follows_the_code_that_analyses_it(monkeypatch):
    """A variant's key holds the code key (pipeline.cache.codekey): a study re-run under other
    code analyses its variants again instead of taking the older code's results."""
    from pipeline.study import plan as study
    keys = {}
    for code in ("old", "new"):
        monkeypatch.setattr(study, "code_key", lambda code=code: code)
        keys[code] = [t.key for t in study.plan(study.Study("05", None, {}, {"dims.rf": [1.0, 2.0]}, []))]
    assert not set(keys["old"]) & set(keys["new"])
