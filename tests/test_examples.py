"""The examples run as a user runs them, and their numbers hold against independent
references: No. 05's global (fillet) peak against the P2/P3/P4 study refined at the
fillet, 113.82 MPa (docs/fillet-reference.md, make reference), and its critical peak
against P3 with MUMPS, 66.27 MPa (docs/accuracy.md). Each band must hold its reference,
and each value lie within 1 % of it (the tolerance a run asks by default)."""
from __future__ import annotations

import runpy
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCES_MPA = {"global": 113.82, "critical": 66.27}


@pytest.mark.slow
def test_the_run_example_holds_the_references(tmp_path):
    """examples/run_05.py at mesh factor 1.3 (the coarsest of the factors whose bands were
    measured to hold both references, docs/accuracy.md)."""
    example = runpy.run_path(str(ROOT / "examples" / "run_05.py"))
    answer = example["main"](["--mesh-factor", "1.3", "--out", str(tmp_path)])
    for name, ref in REFERENCES_MPA.items():
        got = answer[name]
        assert abs(got["value_MPa"] - ref) <= got["band_MPa"], (name, got)
        assert abs(got["value_MPa"] - ref) <= 0.01 * ref, (name, got)
    # No. 05 at 10 kN against the paper's 80 MPa: the fillet fails, the bore edge passes.
    assert answer["global"]["verdict"] == "fail" and answer["critical"]["verdict"] == "pass"
    assert (tmp_path / "fields.vtu").stat().st_size > 0
