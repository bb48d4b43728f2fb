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
