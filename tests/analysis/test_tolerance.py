"""The meshes chosen for an asked accuracy (pipeline/analysis/tolerance.py; docs/design.md §5).

- The procedure (which meshes, in which order, when it stops, what a pinned mesh may do):
  a stand-in analysis whose peaks are a closed form of the mesh size, f0 + C·h² with, on
  meshes coarser than ×1.2, an added alternating term (the unresolved fillet's scatter), so
  that every expected band follows from that form.
- The FE (slow): a run at a tolerance ends within it or says it could not; a tighter
  tolerance solves more DOFs; the issue's case (No. 05 at --mesh-factor 0.85) ends within
  1 % and its bands cover the independent references of docs/fillet-reference.md (global
  113.82 MPa) and docs/accuracy.md (critical, P3 with MUMPS: 66.27 MPa).
"""
from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from pipeline.analysis import tolerance
from pipeline.inputs.case import resolve

ROOT = Path(__file__).resolve().parents[2]
FILLET = (23.14, 6.78, 4.78)      # No. 05's global peak on the shoulder fillet (mm)
BORE_EDGE = (0.0, 10.5, 0.0)      # its critical peak at the bore edge (mm)
DOFS_AT_1 = 200_000               # DOFs of the stand-in mesh ×1; DOFs ∝ factor⁻³


def _peak(value: float, half_gap: float, rule: str, where) -> SimpleNamespace:
    return SimpleNamespace(value_MPa=value, rule=rule, location_mm=where, half_width_MPa=half_gap,
                           unaveraged=SimpleNamespace(value_MPa=value + half_gap),
                           averaged=SimpleNamespace(value_MPa=value - half_gap))


def stand_in_level(factor: float, scatter_MPa: float) -> SimpleNamespace:
    """A mesh of ``factor``: global peak 100 + 50·h² MPa (h = 3·DOFs^(-1/3)), read as the
    midpoint of two readings 0.4·factor MPa apart, and ``scatter_MPa`` lower on meshes
    coarser than ×1.2; critical peak 60 MPa on every mesh."""
    dofs = round(DOFS_AT_1 * factor ** -3)
    h = 3 * dofs ** (-1 / 3)
    off = -scatter_MPa if factor > 1.2 else 0.0
    return SimpleNamespace(factor=factor, dofs=dofs,
                           peak=_peak(100 + 50 * h ** 2 + off, 0.2 * factor, "midpoint", FILLET),
                           critical=_peak(60.0, 0.0, "unaveraged", BORE_EDGE))


@pytest.fixture
def stand_in(monkeypatch):
    """Replace the FE by stand_in_level; returns the list of factors solved, in order."""
    solved: list[float] = []
    state = {"scatter": 5.0}

    def solve_meshes(case, plan, places, ctx):
        out = [stand_in_level(f, state["scatter"]) for f in plan.factors]
        solved.extend(lv.factor for lv in out)
        return out, places

    def solve_one(case, task, ctx):
        solved.append(task.factor)
        return stand_in_level(task.factor, state["scatter"])

    monkeypatch.setattr(tolerance, "solve_meshes", solve_meshes)
    monkeypatch.setattr(tolerance, "solve_one", solve_one)
    return SimpleNamespace(solved=solved, state=state)


def _run(case, levels=3, ctx=None, formula_loads=True):
    """solve_to_tolerance of ``case`` on ``levels`` meshes at ratio 1.3, from no refined places."""
    from pipeline.analysis.context import RunContext
    from pipeline.analysis.meshes import MeshPlan
    from pipeline.analysis.pilot import Pilot
    from pipeline.inputs.options import RunOptions
    options = RunOptions(levels=levels, ratio=1.3)
    plan = MeshPlan(factors=tuple(options.factors(case)), formula_loads=formula_loads)
    return tolerance.solve_to_tolerance(case, options, plan, Pilot(None, (), 0.0), ctx or RunContext())


def test_a_loose_tolerance_keeps_today_s_three_meshes(stand_in):
    case = replace(resolve("05"), mesh_factor=0.85, mesh_pinned=True, tolerance_pct=20.0)
    lv, _, out, acc, _ = _run(case)
    assert acc.met and stand_in.solved == pytest.approx([0.85, 1.105, 1.4365])
    assert out.mesh_factor == 0.85 and not acc.note


def test_a_pinned_mesh_takes_the_smaller_step_and_never_refines(stand_in):
    # ×1.4365 lies 5 MPa low: the three meshes oscillate, band 4.9 MPa (4.9 %); ×0.85,
    # ×0.969, ×1.105 carry no scatter: GCI 1.25·0.029/(1.3 − 1) = 0.12 MPa, below the
    # readings' half gap 0.17 MPa, so the band is 0.17 %.
    case = replace(resolve("05"), mesh_factor=0.85, mesh_pinned=True, tolerance_pct=1.0)
    lv, _, out, acc, _ = _run(case)
    assert stand_in.solved == pytest.approx([0.85, 1.105, 1.4365, 0.85 * 1.3 ** 0.5])
    assert [x.factor for x in lv] == pytest.approx([0.85, 0.85 * 1.3 ** 0.5, 1.105])
    assert acc.met and acc.bands_pct["global"] <= 1.0 and len(acc.steps) == 2
    assert min(stand_in.solved) == 0.85 and out.mesh_factor == 0.85


def test_a_pinned_mesh_says_when_the_band_stays_above(stand_in):
    stand_in.state["scatter"] = 0.0
    case = replace(resolve("05"), mesh_factor=1.3, mesh_pinned=True, tolerance_pct=0.1)
    lv, _, out, acc, _ = _run(case)
    assert not acc.met and "pinned" in acc.note and acc.bands_pct["global"] > 0.1
    assert min(stand_in.solved) == 1.3 and out.mesh_factor == 1.3
    # the requested mesh's half gap, 0.26 MPa (0.26 %), is a floor above 0.1 %: no smaller step
    assert len(stand_in.solved) == 3 and "half gap" in acc.note


def test_an_unpinned_run_refines_until_within_and_a_tighter_tolerance_solves_more(stand_in):
    stand_in.state["scatter"] = 0.0
    loose = replace(resolve("05"), mesh_factor=1.3, mesh_pinned=False, tolerance_pct=5.0)
    _, _, _, acc_loose, _ = _run(loose)   # ×1.3, ×1.69, ×2.197: GCI 0.28 %
    # 0.25 %: ×1.3's meshes give 0.28 % (both steps); ×1, ×1.3, ×1.69 the half gap 0.2 %.
    lv, _, out, acc, _ = _run(replace(loose, tolerance_pct=0.25))
    assert acc_loose.met and acc.met and acc.bands_pct["global"] <= 0.25
    assert out.mesh_factor == pytest.approx(1.0) and lv[0].factor == out.mesh_factor
    assert sum(acc.solved_dofs) > sum(acc_loose.solved_dofs) and lv[0].dofs > DOFS_AT_1 * 1.3 ** -3


def test_refinement_stops_after_its_limit_and_says_so(stand_in):
    stand_in.state["scatter"] = 0.0   # the half gap 0.2·factor MPa stays above 0.1 % to ×0.77
    case = replace(resolve("05"), mesh_factor=1.3, mesh_pinned=False, tolerance_pct=0.1)
    _, _, out, acc, _ = _run(case)
    assert not acc.met and "refinements" in acc.note
    assert out.mesh_factor == pytest.approx(1.3 / 1.3 ** tolerance.MAX_REFINEMENTS)


def test_one_mesh_checks_no_tolerance(stand_in):
    case = replace(resolve("05"), tolerance_pct=1.0)
    _, _, _, acc, _ = _run(case, levels=1)
    assert not acc.met and "no error bar" in acc.note and acc.bands_pct == {"global": None, "critical": None}


def _run_cli(tmp_path: Path, *argv: str) -> tuple[dict, str]:
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", *argv, "--no-fields", "--no-sensitivity",
                        "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=1800)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads((out / "results.json").read_text()), p.stdout


@pytest.mark.slow
def test_a_run_ends_within_its_tolerance_or_says_it_could_not(tmp_path):
    res, stdout = _run_cli(tmp_path, "--size", "05", "--want", "critical", "--mesh-factor", "3",
                           "--tolerance", "0.1")
    acc, crit = res["fe"]["accuracy"], res["fe"]["critical"]["error_estimate"]
    band_pct = 100 * crit["band"] / res["fe"]["critical_peak_MPa"]
    assert acc["met"] == (band_pct <= 0.1 + 1e-9) and acc["bands_pct"] == {"critical": pytest.approx(band_pct)}
    assert min(acc["meshes_solved"]) == 3 and acc["mesh_pinned"]
    # The peak's status says it in the words every output uses, on the terminal too.
    status = "within tolerance" if acc["met"] else "above tolerance"
    line = next(ln for ln in stdout.splitlines() if ln.startswith("critical peak"))
    assert res["fe"]["critical"]["status"] == status and f"  {status} (" in line
    assert "tolerance 0.1 %" in " ".join(stdout.split())
    if not acc["met"]:
        assert "pinned" in acc["note"] and acc["note"] in " ".join(stdout.split())


@pytest.mark.slow
def test_a_tighter_tolerance_solves_more_dofs():
    """The global peak alone from a coarse start (×2.5, unpinned): a 50 % tolerance keeps
    the first three meshes, a 3 % one adds meshes (beyond ×1.3 the fillet is not resolved
    and the coarse meshes' band is several %, docs/accuracy.md)."""
    base = replace(resolve("05", overrides={"want": "global"}), mesh_factor=2.5, mesh_pinned=False)
    got = {}
    for tol in (50.0, 3.0):
        lv, _, out, acc, _ = _run(replace(base, tolerance_pct=tol), formula_loads=False)
        assert acc.met == (acc.bands_pct["global"] is not None and acc.bands_pct["global"] <= tol), tol
        assert acc.met or acc.note, tol
        got[tol] = acc
    assert got[50.0].met and len(got[50.0].solved) == 3
    assert sum(got[3.0].solved_dofs) > sum(got[50.0].solved_dofs)


@pytest.mark.slow
@pytest.mark.parametrize("factor", ["0.85", "1.3"])
def test_the_issue_s_mesh_ends_within_one_percent_and_covers_the_references(tmp_path, factor):
    """No. 05 at --mesh-factor 0.85 read 114.05 ± 1.49 MPa (1.3 %, oscillatory) before the
    tolerance; at 1.3 the bore edge reads lowest of the factors 0.8 ... 1.3 (66.195 MPa,
    docs/accuracy.md). The references are P3/P4 studies (docs/fillet-reference.md:
    113.82 MPa; docs/accuracy.md: 66.27 MPa), not this code's P2 output."""
    res, _ = _run_cli(tmp_path, "--size", "05", "--mesh-factor", factor)
    fe = res["fe"]
    assert fe["accuracy"]["met"] and fe["accuracy"]["tolerance_pct"] == 1.0
    for key, ref in (("peak", 113.82), ("critical", 66.27)):
        band = fe[key]["error_estimate"]["band"]
        assert band <= 0.01 * fe[key]["value_MPa"]
        assert abs(fe[key]["value_MPa"] - ref) <= band, (key, fe[key]["value_MPa"], band)


def test_the_tolerance_is_an_input_with_its_default_its_key_and_its_check(tmp_path):
    from pipeline.errors import InputError
    assert resolve("05").tolerance_pct == 1.0 and not resolve("05").mesh_pinned
    assert resolve("05", overrides={"mesh_factor": 1.0}).mesh_pinned   # given, even at the default value
    f = tmp_path / "c.toml"
    f.write_text('size = "05"\n[mesh]\ntolerance_pct = 0.5\nfactor = 0.9\n')
    case = resolve(case_file=f)
    assert case.tolerance_pct == 0.5 and case.mesh_pinned and case.mesh_factor == 0.9
    for bad in (0.0, 0.05, 60.0, float("nan")):
        with pytest.raises(InputError, match="tolerance_pct"):
            resolve("05", overrides={"tolerance_pct": bad})


def test_a_bad_tolerance_exits_2_with_one_line(tmp_path):
    out = tmp_path / "never"
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--tolerance", "0", "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "tolerance_pct" in p.stderr
    assert not out.exists()
