"""Screened design studies (pipeline/study/screening.py, pipeline/study/table.escalations):
the cheap level's bands, which variants get the full error bar, and that the decisions
then equal the full study's. Made-up peaks (MPa) whose answers are worked out here."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from pipeline.study.screening import (FULL, MARGIN, NEXT_STEPS, SCREENED, STEPS, TWO_MESH_FACTOR, screen_case,
                                      screening_of, screened_rows, undecided)
from pipeline.errors import InputError
from pipeline.output import flat
from pipeline.study.plan import Study, plan, read_study
from pipeline.study.table import crossings, escalations, with_verdicts

ROOT = Path(__file__).resolve().parents[2]


def _res(peak, critical, mesh_factor=2.2):
    """A results.json's content as screening_of reads it: (midpoint, unaveraged, averaged) per peak."""
    fe = {"peak_MPa": peak[0], "critical_peak_MPa": critical[0]}
    for block, (_, un, av) in (("peak", peak), ("critical", critical)):
        fe[block] = {"unaveraged_MPa": un, "averaged_MPa": av}
    fe["levels"] = [{"mesh_factor": mesh_factor, "peak_MPa": peak[0], "critical_peak_MPa": critical[0]}]
    return {"fe": fe, "case": {"mesh_factor": mesh_factor}}


def test_the_band_is_the_margin_or_the_bracket_whichever_is_wider():
    s = screening_of(_res((100.0, 104.0, 96.0), (60.0, 60.0, 59.0)))
    # Global: half the gap 4 < 10 % of 100 = 10; critical: half the gap 0.5 < 3 % of 60 = 1.8.
    assert MARGIN == {"peak": 0.10, "critical": 0.03}
    assert s["peaks"]["peak"]["band_MPa"] == pytest.approx(10.0)
    assert s["peaks"]["critical"]["band_MPa"] == pytest.approx(1.8)
    wide = screening_of(_res((110.0, 130.0, 90.0), (60.0, 60.0, 59.0)))
    assert wide["peaks"]["peak"]["band_MPa"] == pytest.approx(20.0)  # the bracket, 20 > 11
    assert wide["peaks"]["peak"]["fraction"] == pytest.approx(20.0 / 110.0)
    assert s["full_error_bar"] is False


def _row(variant, rf, peak, band, critical=60.0, critical_band=0.6, status="converged", load=10000.0):
    r = {c: None for c in flat.COLUMNS}
    r.update({"variant": variant, "status": "done", "parameters": json.dumps({"dims.rf": rf}), "dims.rf": rf,
              "size": "05", "load_N": load, "peak_MPa": peak, "peak_band_MPa": band, "peak_status": status,
              "critical_peak_MPa": critical, "critical_band_MPa": critical_band, "critical_status": status})
    return r


def test_a_screened_row_carries_the_same_fraction_at_every_load():
    s = screening_of(_res((100.0, 104.0, 96.0), (60.0, 60.0, 59.0)))
    rows = screened_rows([_row("a", 1.0, 100.0, None), _row("a", 1.0, 50.0, None, 30.0, None, load=5000.0)], s)
    assert [r["peak_band_MPa"] for r in rows] == pytest.approx([10.0, 5.0])
    assert [r["critical_band_MPa"] for r in rows] == pytest.approx([1.8, 0.9])
    assert {r["peak_status"] for r in rows} == {SCREENED}


def test_the_neighbours_of_a_crossing_get_the_full_error_bar_and_straddling_bands_the_next_steps():
    # rf 1..4 at 150, 130, 110, 90 MPa, each ±10 %; allowable 120: 130 ± 13 and 110 ± 11
    # hold it, and they are also the crossing's neighbours: the full error bar at once.
    rows = [_row(k, rf, v, 0.1 * v) for k, rf, v in (("a", 1.0, 150.0), ("b", 2.0, 130.0), ("c", 3.0, 110.0),
                                                      ("d", 4.0, 90.0))]
    why = escalations(rows, ["dims.rf"], 120.0)
    assert set(why) == {"b", "c"} and {w[1] for w in why.values()} == {FULL}
    # At 100 MPa: 110 ± 11 holds it; 90 ± 9 (81..99) passes but borders the crossing.
    why = escalations(rows, ["dims.rf"], 100.0)
    assert set(why) == {"c", "d"}
    assert why["d"] == ("it borders a crossing of the global peak along rf", FULL)
    assert not undecided(rows[0], 100.0)
    # 150, 125, 140 at 120: no crossing; 125 ± 12.5 holds it and takes the next steps alone.
    rows = [_row(k, rf, v, 0.1 * v) for k, rf, v in (("a", 1.0, 150.0), ("b", 2.0, 125.0), ("c", 3.0, 140.0))]
    assert escalations(rows, ["dims.rf"], 120.0) == {"b": ("its band holds the allowable 120 MPa", NEXT_STEPS)}


def test_the_two_mesh_band_is_the_trend_times_its_factor_or_the_margin():
    """Two meshes, ×1.3 then ×1.69: the band is the larger of the finer mesh's half
    bracket plus TWO_MESH_FACTOR × their difference and the step's fraction of the value."""
    two = next(s for s in STEPS if s.levels == 2)
    res = _res((100.0, 100.4, 99.6), (60.0, 60.1, 59.9), mesh_factor=1.0)
    res["fe"]["levels"] = [{"mesh_factor": 1.3, "peak_MPa": 100.0, "critical_peak_MPa": 60.0},
                           {"mesh_factor": 1.69, "peak_MPa": 101.5, "critical_peak_MPa": 60.05}]
    s = screening_of(res, two)
    # The bracket 0.4 plus 3 × |100 − 101.5| = 4.9, against the step's fraction of 100.
    assert s["peaks"]["peak"]["band_MPa"] == pytest.approx(max(0.4 + TWO_MESH_FACTOR * 1.5, two.margin["peak"] * 100))
    assert s["peaks"]["critical"]["band_MPa"] == pytest.approx(max(two.margin["critical"] * 60.0, 0.1 + 3 * 0.05))
    assert s["meshes"] == [1.3, 1.69] and s["step"] == two.name


def test_a_singular_peak_is_left_to_the_full_analysis():
    r = _row("a", 1.0, None, None, status=flat.SINGULAR)
    assert undecided(r, 120.0)


def _screened_study(full: list[dict], cheap: dict[str, tuple[float, float]], allowable: float) -> list[dict]:
    """What a screened study ends with: every row at its cheap value and band, then rows
    escalated to their full values until escalations() asks for none (as sweep.escalate)."""
    by = {r["variant"]: r for r in full}
    rows = {k: dict(by[k], peak_MPa=v, peak_band_MPa=b, peak_status=SCREENED) for k, (v, b) in cheap.items()}
    while True:
        why = {k for k in escalations(list(rows.values()), ["dims.rf"], allowable)
               if rows[k]["peak_status"] == SCREENED}
        if not why:
            return with_verdicts(list(rows.values()), allowable)
        rows.update({k: dict(by[k]) for k in why})


def test_the_decisions_equal_the_full_study_when_the_cheap_bands_hold_the_full_ones():
    """A line along rf whose peak crosses the allowable twice; the cheap values off by
    +6 %, -4 %, ... with ±10 % bands, each holding the full value ± its 1 % band. The
    screened study must give the full study's verdicts and crossings, place and range."""
    full_values = [170.0, 140.0, 118.0, 96.0, 84.0, 100.0, 130.0]
    offsets = [0.06, -0.04, 0.05, -0.06, 0.03, 0.07, -0.05]
    full = [_row(f"v{i}", float(i), v, 0.01 * v) for i, v in enumerate(full_values)]
    cheap = {f"v{i}": (v * (1 + d), 0.1 * v * (1 + d)) for i, (v, d) in enumerate(zip(full_values, offsets))}
    for k, (c, b) in cheap.items():  # the premise: each cheap band holds the full value ± band
        f = next(r for r in full if r["variant"] == k)
        assert abs(c - f["peak_MPa"]) + f["peak_band_MPa"] <= b
    for allowable in (80.0, 105.0, 120.0, 150.0):
        want = with_verdicts([dict(r) for r in full], allowable)
        got = _screened_study(full, cheap, allowable)
        assert [r["verdict"] for r in got] == [r["verdict"] for r in want], allowable
        assert crossings(got, "dims.rf", allowable) == crossings(want, "dims.rf", allowable), allowable
    # At 150 MPa the cheap values 180.2 ± 18.0 (fails) and 134.4 ± 13.4 (passes) border the
    # one crossing and get the full error bar; the other five pass on their cheap bands.
    got = _screened_study(full, cheap, 150.0)
    assert sum(r["peak_status"] == SCREENED for r in got) == 5  # only 170 and 140 border the crossing


def test_a_study_file_asks_for_screening_with_true_only(tmp_path):
    good = tmp_path / "a.toml"
    good.write_text('[sweep]\nsize = "05"\ndims = { rf = "1,2" }\nscreen = true\n')
    assert read_study(good)["screen"] is True
    bad = tmp_path / "b.toml"
    bad.write_text('[sweep]\nsize = "05"\ndims = { rf = "1,2" }\nscreen = "yes"\n')
    with pytest.raises(InputError, match="sweep.screen: expected true or false"):
        read_study(bad)


def test_a_screened_study_is_refused_on_a_mesh_coarser_than_its_bands_were_measured_on():
    """At mesh factor 2 the cheap level (×4.4) read No. 05's global peak at rf = 1 mm as
    134.9 ± 13.5 MPa against the full study's 126.1 ± 5.0: its band does not hold the full
    value (docs/accuracy.md, *The screening level*). A screened study coarser than the mesh
    its bands were measured on is refused before any work, with the line saying why."""
    from pipeline.study.screening import SCREEN_MAX_MESH_FACTOR
    coarse = Study("05", None, {"mesh_factor": 2.0}, {"dims.rf": [1.0, 2.0]}, [], screen=True)
    with pytest.raises(InputError, match=r"^screen: .* do not hold at 2; give --mesh-factor 1 "):
        plan(coarse)
    assert SCREEN_MAX_MESH_FACTOR == 1.0
    assert len(plan(replace(coarse, base={"mesh_factor": 1.0}))) == 2    # at the bands' own mesh: accepted
    assert len(plan(replace(coarse, screen=False))) == 2                 # unscreened, any mesh factor


@pytest.mark.slow
def test_a_screened_study_behaves_like_a_run_without_an_allowable(tmp_path):
    """`sweep --screen` without --allowable was refused although a run takes its default
    allowable, 80 MPa (README, docs/design.md §7: the case's default). Now the screened
    study decides against 80 MPa; its variants, decided on the cheap level (×2.2 coarser),
    say the run's coarse-mesh note in its closing lines (stdout, each at most 100
    characters) and its report, and it writes report.html beside report.md."""
    from pipeline.analysis.words import coarse_mesh_note
    from pipeline.inputs.case import resolve
    out = tmp_path / "study"
    p = subprocess.run([sys.executable, "-m", "pipeline", "sweep", "--size", "05", "--dim", "rf=1,2", "--screen",
                        "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                       timeout=900, env=dict(os.environ, CROSSHEAD_NO_CACHE="1"))
    assert p.returncode == 0, p.stderr
    assert json.loads((out / "sweep.json").read_text())["allowable_MPa"] == 80.0
    cheap = coarse_mesh_note(screen_case(resolve("05")))
    assert cheap and f"note: {cheap}" in " ".join(p.stdout.split())  # wrapped on the terminal
    assert max(len(ln) for ln in p.stdout.splitlines()) <= 100
    assert cheap in (out / "report.md").read_text(encoding="utf-8")
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and "data:image/png;base64," in html  # the plots embedded


@pytest.mark.slow
def test_a_study_on_a_coarse_mesh_says_the_run_s_note(tmp_path):
    """A study at a mesh factor above 1.3 said nothing of the fillet while a run says so:
    it now prints the run's coarse-mesh note before its work (stderr)."""
    from pipeline.analysis.words import coarse_mesh_note
    from pipeline.inputs.case import resolve
    p = subprocess.run([sys.executable, "-m", "pipeline", "sweep", "--size", "05", "--dim", "rf=1,2", "--levels", "1",
                        "--mesh-factor", "2", "--out", str(tmp_path / "study")], cwd=ROOT, capture_output=True,
                       text=True, timeout=900, env=dict(os.environ, CROSSHEAD_NO_CACHE="1"))
    assert p.returncode == 0, p.stderr
    note = coarse_mesh_note(resolve("05", overrides={"mesh_factor": 2.0}))
    assert note and f"note: {note}" in p.stderr


def _sweep(out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline", "sweep", "--size", "05", "--dim", "rf=1,2",
                           "--out", str(out), "--quiet", *extra], cwd=ROOT,
                          capture_output=True, text=True, timeout=900,
                          env=dict(os.environ, CROSSHEAD_NO_CACHE="1"))


@pytest.mark.slow
def test_a_real_screened_study_decides_as_the_full_one_and_its_summary_names_the_evidence(tmp_path):
    """rf = 1 and 2 mm of No. 05 at 125 MPa (their global peaks 134.7 ± 1.0 and 101.2 ± 1.8 MPa
    in a full study on the default mesh): the global peak falls below it between them, so
    both border the crossing and get the full error bar; their verdicts and the crossing
    are the full study's (the same variants without --screen). The size summary of the
    screened study's variants reads them and says how each was decided."""
    screened, full = tmp_path / "screened", tmp_path / "full"
    for out, extra in ((screened, ("--allowable", "125", "--screen")), (full, ("--allowable", "125"))):
        p = _sweep(out, *extra)
        assert p.returncode == 0, p.stderr
    a, b = (json.loads((out / "sweep.json").read_text()) for out in (screened, full))
    verdicts = [[(r["verdict"], r["critical_verdict"]) for r in d["rows"]] for d in (a, b)]
    assert verdicts[0] == verdicts[1] and {v[0] for v in verdicts[0]} == {"pass", "fail"}
    assert [r["decided_by"] for r in a["rows"]] == ["full error bar (it borders a crossing of the global peak "
                                                    "along rf)"] * 2
    assert a["crossings"] == b["crossings"] and a["crossings"]
    from pipeline.study import summary
    assert summary.main([str(screened / "variants"), "--all", "--out", str(tmp_path / "sum")]) == 0
    md = (tmp_path / "sum" / "summary.md").read_text(encoding="utf-8")
    line = next(ln for ln in md.splitlines()
                if ln.startswith("- Decided by full error bar (it borders a crossing of the global peak along rf): "))
    assert "No. 05 (rf = 1 mm" in line and "No. 05 (rf = 2 mm" in line  # in the order of the variants' keys


def _stepping(monkeypatch, tmp_path, allowable: float, full_reading: float = 126.0):
    """A screened variant sent to the next steps, with runs replaced by made-up readings
    (global peak 130 MPa on the ×1.69 mesh, 126 on ×1.3, ``full_reading`` on ×1, each with
    a ±0.2 MPa bracket; critical 60 MPa everywhere): the meshes each step asked for, and
    the variant's screening.json."""
    from pipeline.study import sweep as sweep_module
    from pipeline.study.plan import Study, plan
    by_factor = {1.69: 130.0, 1.3: 126.0, 1.0: full_reading}
    asked: list[list[float]] = []

    def write_run(case, options, folder, ctx):
        factors = [round(f / case.mesh_factor, 2) for f in options.factors(case)]
        asked.append(factors)
        levels = [{"mesh_factor": f, "peak_MPa": by_factor[f], "critical_peak_MPa": 60.0} for f in factors]
        res = _res((by_factor[factors[0]], by_factor[factors[0]] + 0.2, by_factor[factors[0]] - 0.2),
                   (60.0, 60.1, 59.9), mesh_factor=factors[0])
        res["fe"]["levels"] = levels
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "results.json").write_text(json.dumps(res))
        return res

    def rows(res):
        return [_row("a", 1.0, res["fe"]["peak_MPa"], None, critical=60.0, critical_band=None)]

    monkeypatch.setattr(sweep_module, "write_run", write_run)
    monkeypatch.setattr(sweep_module.flat, "rows", rows)
    study = Study("05", None, {"allowable_MPa": allowable}, {"dims.rf": [1.2]}, [], screen=True)
    task = plan(study)[0]
    sweep_module.run_task(task, tmp_path, study, escalation=("its band holds the allowable", NEXT_STEPS))
    kept = json.loads((sweep_module.variant_folder(tmp_path, task.key) / "screening.json").read_text())
    return asked, kept


def test_an_undecided_variant_stops_at_the_first_step_that_decides_it(monkeypatch, tmp_path):
    # At 120 MPa: one mesh, 130 ± 5 % (123.5..136.5) fails clear of it: no more meshes.
    asked, kept = _stepping(monkeypatch, tmp_path, 120.0)
    assert asked == [[1.69]]
    assert kept["step"] == "one mesh" and kept["full_error_bar"] is False
    assert [s["step"] for s in kept["steps"]] == ["one mesh"]
    # At 128 MPa: 130 ± 6.5 holds it; two meshes, 126 ± 3 × 4 = 12 still do; the full error bar.
    asked, kept = _stepping(monkeypatch, tmp_path, 128.0)
    assert asked == [[1.69], [1.3, 1.69], [1.0, 1.3, 1.69]]
    assert kept["full_error_bar"] is True and [s["step"] for s in kept["steps"]] == ["one mesh", "two meshes"]
