"""The case files in cases/ are worked examples: each one runs through the command line
(on coarse meshes here) and gives what its comments promise.

A case file says what to analyse; the test overrides only the mesh (coarse, one or three
levels) so the suite stays fast. What each asserts comes from outside the run: the file's
own inputs, statics (the loads balance), the singular feature the rigid support creates,
and the quarter model's answer for the full one.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CASES = sorted(p for p in (ROOT / "cases").glob("*.toml") if not p.name.startswith("sweep-"))
STUDIES = sorted((ROOT / "cases").glob("sweep-*.toml"))


def run(case: Path, out: Path, *extra: str) -> dict:
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--case", str(case), "--out", str(out),
                        "--no-fields", "--quiet", *extra], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    return json.loads((out / "results.json").read_text())


def test_every_case_file_is_tested():
    assert {c.name for c in CASES} == {"05.toml", "05-rigid.toml", "05-full.toml", "1.6-fillet.toml"}


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_case_runs_with_its_inputs(case, tmp_path):
    """Every input the file sets is the one the run used; the loads balance (statics)."""
    spec = tomllib.loads(case.read_text())
    factor = max(spec.get("mesh", {}).get("factor", 1.0), 3.0)
    res = run(case, tmp_path / "out", "--mesh-factor", str(factor), "--levels", "1")
    c = res["case"]
    assert c["name"] == spec["name"] and c["size"] == spec["size"]
    for section in ("model", "material"):
        for key, value in spec.get(section, {}).items():
            assert c[key] == value, (key, c[key], value)
    for key, value in spec.get("dimensions", {}).items():
        assert c["dims"][key] == value and key not in c["assumed"]
    fe = res["fe"]
    assert abs(fe["equilibrium_error_N"]) <= 1e-6 * c["load_N"]
    # The title block the file gives is the report's (results.json's about.document); a
    # field it leaves out is blank, never invented.
    doc = spec.get("document", {})
    assert res["about"]["document"] == {k: doc.get(k) for k in ("part", "number", "revision", "author", "checker")}


@pytest.mark.slow
def test_rigid_case_names_its_singular_edge(tmp_path):
    res = run(ROOT / "cases" / "05-rigid.toml", tmp_path / "out", "--mesh-factor", "3")
    fe = res["fe"]
    assert "rigid" in fe["peak"]["singular_feature"] and fe["safety_factor"] is None


@pytest.mark.slow
def test_a_peak_not_asked_for_is_not_judged_at_any_load(tmp_path):
    """--want critical at two loads on coarse meshes: the unrefined fillet peak grows over
    the meshes, which made it 'singular' (safety factor 'none (singular peak)', Kt 'the
    peak is singular') and its values were listed at every load. It is now not asked for:
    no value or band at any load, no singular verdict, no Kt; the critical peak keeps all."""
    from pipeline.output.report import render_markdown
    res = run(ROOT / "cases" / "05.toml", tmp_path / "crit", "--mesh-factor", "3", "--want", "critical",
              "--load", "5000,10000")
    fe = res["fe"]
    assert fe["peak"]["singular_feature"] is None and fe["safety_factor_note"].startswith("want = critical")
    assert all(r["peak_MPa"] is None and r["peak_band_MPa"] is None for r in res["load_sweep"])
    assert [r["critical_peak_MPa"] for r in res["load_sweep"]] == pytest.approx(
        [fe["critical_peak_MPa"] * q / 5000.0 for q in (5000.0, 10000.0)])
    md = render_markdown(res).split("## Appendix")[0]  # the appendix defines every status, "singular" too
    assert "none: the peak is not resolved" in md and "singular" not in md
    assert "| 10 000 | — | " in md


@pytest.mark.slow
def test_full_case_equals_the_quarter(tmp_path):
    """The whole part and the quarter with symmetry planes give the same critical peak on
    the same mesh sizes (the symmetry conditions are right), to 1 % on this coarse mesh."""
    full = run(ROOT / "cases" / "05-full.toml", tmp_path / "full", "--mesh-factor", "3", "--levels", "1")
    quarter = run(ROOT / "cases" / "05.toml", tmp_path / "quarter", "--mesh-factor", "3", "--levels", "1")
    assert full["fe"]["model"] == "full" and quarter["fe"]["model"] == "quarter"
    a, b = full["fe"]["critical_peak_MPa"], quarter["fe"]["critical_peak_MPa"]
    assert abs(a - b) <= 0.01 * b, (a, b)


@pytest.mark.slow
def test_want_critical_skips_the_fillet_and_keeps_the_critical_peak(tmp_path):
    """--want critical: the fillet is not refined, the global peak gets no verdict, and the
    critical peak agrees with the run that refines both (the independent reference here)
    to 0.3 %, in less time."""
    base = ["--mesh-factor", "2", "--levels", "1"]
    both = run(ROOT / "cases" / "05.toml", tmp_path / "both", *base)
    crit = run(ROOT / "cases" / "05.toml", tmp_path / "crit", *base, "--want", "critical")
    fe = crit["fe"]
    assert "want = critical" in fe["peak"]["not_wanted"] and fe["safety_factor"] is None
    assert fe["verdict"]["global_peak"]["verdict"] == "none"
    assert fe["critical_peak_MPa"] == pytest.approx(both["fe"]["critical_peak_MPa"], rel=5e-3)
    assert fe["cells"] < both["fe"]["cells"]
    # No pilot: the bore edges in x = 0 (di/2 = 10.5 mm, h = 25 mm) are refined as the
    # dimensions put them, and the critical peak lies at one of them.
    assert fe["refined_places_from"] == "known" and crit["timings_s"]["pilot"] == 0.0
    assert sorted(map(tuple, fe["refined_at_mm"])) == [(0.0, 10.5, 0.0), (0.0, 10.5, 25.0)]
    assert both["fe"]["refined_places_from"] == "pilot"


@pytest.mark.parametrize("study", STUDIES, ids=[s.stem for s in STUDIES])
def test_study_files_plan_a_grid(study):
    """A study file under cases/ names a valid base case and a grid with valid variants."""
    from pipeline.study.plan import Study, plan, read_study
    from pipeline.inputs.valuelist import MOST_DIM_VALUES, parse_values
    s = read_study(study)
    axes = {f"dims.{k}": parse_values(str(v), k, MOST_DIM_VALUES) for k, v in s["dims"].items()}
    tasks = plan(Study(s.get("size"), None, {"mesh_factor": s.get("mesh_factor", 1.0)}, axes, []))
    assert len(tasks) == len(next(iter(axes.values()))) and any(t.case is not None for t in tasks)
