"""results.json as a program reads it: every file the runs write holds to the committed JSON
Schema (docs/results.schema.json), carries the same keys whatever the options, and its flat
``summary`` block is one row with the shared table's columns (pipeline/output/flat.py)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest

from pipeline import __version__
from pipeline.output.flat import COLUMNS


ROOT = Path(__file__).resolve().parents[2]
COARSE = ["--mesh-factor", "3", "--no-fields", "--quiet"]
RUNS = {
    "one mesh": ["run", "--size", "05", "--levels", "1", *COARSE],
    "error bar and sensitivity": ["run", "--size", "05", *COARSE],
    "rigid support (a singular peak)": ["run", "--case", "cases/05-rigid.toml", "--no-sensitivity", *COARSE],
    "load sweep, critical peak only": ["run", "--size", "1.6", "--load", "5000,20000", "--want", "critical", *COARSE],
}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> dict[str, dict]:
    out = {}
    for name, argv in RUNS.items():
        folder = tmp_path_factory.mktemp("schema") / "run"
        p = subprocess.run([sys.executable, "-m", "pipeline", *argv, "--out", str(folder)], cwd=ROOT,
                           capture_output=True, text=True, timeout=900)
        assert p.returncode == 0, (name, p.stderr)
        out[name] = json.loads((folder / "results.json").read_text())
    return out


@pytest.mark.slow
def test_every_written_file_holds_to_the_schema(written):
    schema = json.loads((ROOT / "docs" / "results.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    for name, res in written.items():
        errors = [f"{'/'.join(map(str, e.path))}: {e.message}" for e in
                  jsonschema.Draft202012Validator(schema).iter_errors(res)]
        assert not errors, (name, errors[:5])


@pytest.mark.slow
def test_the_same_keys_in_every_run(written):
    first = next(iter(written.values()))
    for name, res in written.items():
        assert list(res) == list(first), name
        assert set(res["summary"]) == set(COLUMNS), name
        for key in ("peak", "critical"):
            assert set(res["fe"][key]) == set(first["fe"][key]), (name, key)
        assert set(res["about"]) == set(first["about"]), name
        assert set(res["fe"]) == set(first["fe"]), name
        assert set(res["comparison_pct"]) == set(first["comparison_pct"]), name
        for check in res["fe"]["verdict"].values():  # a peak without a verdict has the same keys, null
            assert set(check) == set(first["fe"]["verdict"]["global_peak"]), name
        if res["fe"]["sections"] is not None:
            assert "formula_load" in res["fe"]["sections"], name


@pytest.mark.slow
def test_about_says_where_the_numbers_come_from(written):
    import dolfinx
    import gmsh
    for name, res in written.items():
        about = res["about"]
        assert about["tool_version"] == __version__ and about["software"]["dolfinx"] == dolfinx.__version__
        assert about["software"]["gmsh"] == gmsh.__version__
        assert about["command_line"][:2] == ["crosshead", RUNS[name][0]] and "--out" in about["command_line"]


@pytest.mark.slow
def test_the_summary_is_the_run_s_own_row(written):
    """The summary block agrees with the nested blocks it flattens (an independent reading of
    the same file): the peaks, the formulas and the load."""
    for name, res in written.items():
        s, fe = res["summary"], res["fe"]
        assert s["load_N"] == res["case"]["load_N"] and s["exact_MPa"] == res["analytic"]["exact_MPa"], name
        if not fe["critical"]["not_wanted"]:
            assert s["critical_peak_MPa"] == fe["critical_peak_MPa"], name
        if not fe["peak"]["not_wanted"] and not fe["peak"]["singular_feature"]:
            assert s["peak_MPa"] == fe["peak_MPa"], name


@pytest.mark.slow
def test_a_peak_not_asked_for_is_not_in_the_answer(written):
    """--want critical: fe.peak_MPa, the field a program reads as the global peak, is null;
    the unrefined reading is kept under peak_unresolved_MPa (the global block's value), and
    the summary row keeps it as the reading, with no value: an unrefined value (14 % low on
    No. 05) is never the answer a program reads. A run for both peaks has no unresolved reading."""
    fe = written["load sweep, critical peak only"]["fe"]
    assert fe["peak_MPa"] is None and fe["peak_unresolved_MPa"] == fe["peak"]["value_MPa"]
    assert fe["critical_peak_MPa"] == fe["critical"]["value_MPa"] and fe["critical_peak_unresolved_MPa"] is None
    s = written["load sweep, critical peak only"]["summary"]
    assert s["peak_MPa"] is None and s["peak_reading_MPa"] == fe["peak_unresolved_MPa"]
    both = written["error bar and sensitivity"]["fe"]
    assert both["peak_MPa"] == both["peak"]["value_MPa"] and both["peak_unresolved_MPa"] is None


@pytest.mark.slow
def test_a_load_list_says_the_verdict_at_every_load(written):
    """5000 and 20000 N on No. 1.6 (critical peak only): each load_sweep row carries each
    checked stress's verdict there, and load_sweep_verdict says them over the loads,
    the largest named as governing; the critical peak's verdict at each load is its value
    and band scaled to it against the allowable (errorbar.verdict_against)."""
    from pipeline.post.errorbar import verdict_against
    res = written["load sweep, critical peak only"]
    allowable = res["case"]["allowable_MPa"]
    for row in res["load_sweep"]:
        want = verdict_against(row["critical_peak_MPa"], row["critical_band_MPa"], allowable)
        assert row["verdicts"]["critical_peak"] == want and row["verdicts"]["global_peak"] == "none"
        assert row["sensitivity_sentence"] is None  # a run for one peak has no sensitivity section
    assert res["load_sweep_verdict"].startswith("At the loads asked (5000 and 20000 N): critical peak ")
    assert "20000 N, governs" in res["load_sweep_verdict"]
    assert written["one mesh"]["load_sweep_verdict"] is None
