"""Reusing meshes, pilot places and solutions between runs (pipeline/cache/runs.py,
pipeline/cache/solutions.py): a run that changes only the load or E reuses all three, and its
stresses equal those of a new solve at that load and E with the cache off (an independent
check of the scaling); what shapes the field changes the key."""
from __future__ import annotations

from dataclasses import replace

import pytest

import pipeline.cache.runs as rc
from pipeline.inputs.case import resolve
from pipeline.api import Outputs, RunOptions, write_run


def execute_run(case, out, levels):
    """A run of ``levels`` meshes without tolerance steps, sensitivity section or fields."""
    return write_run(case, RunOptions(levels=levels, to_tolerance=False, sensitivity=False,
                                      outputs=Outputs(fields=False)), out)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path / "runs")
    return tmp_path / "runs"


@pytest.mark.slow
def test_a_load_change_reuses_mesh_pilot_and_solution(cache, tmp_path, monkeypatch):
    case = resolve("05", None, {"mesh_factor": 3.0})
    first = execute_run(case, tmp_path / "a", levels=3)
    n_entries = len(list(cache.glob("*.entry")))
    # The pilot's mesh, its places; the requested mesh and its solution; each of the two
    # error-bar meshes, its solution and its results (pipeline/cache/levels.py); the
    # solutions of the journal load at the two formulas' positions on the first of them.
    assert n_entries == 12
    changed = replace(case, load_N=2.5 * case.load_N, E_MPa=70_000.0)
    second = execute_run(changed, tmp_path / "b", levels=3)
    assert len(list(cache.glob("*.entry"))) == n_entries  # nothing new: all reused
    assert second["timings_s"]["pilot"] < 0.2 * first["timings_s"]["pilot"]
    assert second["fe"]["scaled_from"] == {"load_N": case.load_N, "E_MPa": case.E_MPa}
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "1")
    fresh = execute_run(changed, tmp_path / "c", levels=3)
    assert fresh["fe"]["scaled_from"] is None
    # The same mesh (the pilot's places are the same), solved anew: equal to the solver's
    # tolerance (rtol 1e-8 on the residual).
    assert fresh["fe"]["dofs"] == second["fe"]["dofs"]
    for key in ("peak_MPa", "critical_peak_MPa"):
        assert second["fe"][key] == pytest.approx(fresh["fe"][key], rel=1e-7)
        assert second["fe"][key] == pytest.approx(2.5 * first["fe"][key], rel=1e-12)
    # The error-bar meshes: their results scaled, not solved; equal to a new solve's.
    assert len(second["fe"]["levels"]) == len(fresh["fe"]["levels"]) == 3
    for coarse2, coarsef in zip(second["fe"]["levels"][1:], fresh["fe"]["levels"][1:], strict=True):
        assert coarse2["scaled_from"] == {"load_N": case.load_N, "E_MPa": case.E_MPa}
        assert coarse2["dofs"] == coarsef["dofs"]
        for key in ("peak_MPa", "critical_peak_MPa", "peak_unaveraged_MPa", "peak_averaged_MPa"):
            assert coarse2[key] == pytest.approx(coarsef[key], rel=1e-7)
    for block in ("peak", "critical"):  # the error bars of both peaks
        assert second["fe"][block]["error_estimate"]["band"] == pytest.approx(
            fresh["fe"][block]["error_estimate"]["band"], rel=1e-5, abs=1e-9)
    sec2, secf = second["fe"]["sections"], fresh["fe"]["sections"]
    assert sec2["critical_section"]["nominal_MPa"] == pytest.approx(secf["critical_section"]["nominal_MPa"], rel=1e-7)


@pytest.mark.slow
def test_a_solution_of_another_mesh_or_poisson_ratio_is_not_reused(cache, tmp_path):
    """A changed ν or mesh factor changes the solution's key: the run solves anew."""
    case = resolve("05", None, {"mesh_factor": 3.0})
    execute_run(case, tmp_path / "a", levels=1)
    for other in (replace(case, nu=0.25), replace(case, mesh_factor=3.2)):
        res = execute_run(other, tmp_path / f"b{other.nu}{other.mesh_factor}", levels=1)
        assert res["fe"]["scaled_from"] is None


def test_keys_follow_what_shapes_the_field():
    d = resolve("05").dims
    k = rc.key("pilot", dims=d, nu=0.3, support="bearing")
    assert k == rc.key("pilot", dims=d, nu=0.3, support="bearing")
    assert k != rc.key("pilot", dims=d, nu=0.25, support="bearing")
    assert k != rc.key("pilot", dims=replace(d, rf=2.0), nu=0.3, support="bearing")


def test_the_cache_is_bounded_by_bytes_and_keeps_the_recently_used(cache, monkeypatch):
    """Six entries of one size with room for three and a half: the three newest stay; an
    old entry read again counts as new (least recently used goes first)."""
    import os
    import time

    import numpy as np

    def entry(i: int) -> rc.Entry:
        return rc.Entry({"i": i}, {"b": np.full(1000, i, dtype=np.uint8)})
    rc.store("probe", entry(0))
    size = (cache / "probe.entry").stat().st_size
    (cache / "probe.entry").unlink()
    monkeypatch.setattr(rc, "MAX_BYTES", int(3.5 * size))
    for i in range(6):
        rc.store(f"x-{i}", entry(i))
        os.utime(cache / f"x-{i}.entry", ns=(time.time_ns(), 1_000_000_000 * (100 + i)))  # distinct ages
    assert sorted(p.stem for p in cache.glob("*.entry")) == ["x-3", "x-4", "x-5"]
    assert rc.load("x-3", "redo").meta == {"i": 3} and rc.load("x-0", "redo") is None  # x-3 read: now the newest
    rc.store("x-6", entry(6))
    assert sorted(p.stem for p in cache.glob("*.entry")) == ["x-3", "x-5", "x-6"]


def test_a_stored_solution_is_found_node_by_node_or_not_at_all():
    """solvecache.stored_rows on made-up nodes: a rank's nodes in any order find their rows
    by the mesher's node numbers; a number that is not stored, or a node 1e-5 mm away from
    its stored position (another mesh with the same counts), finds nothing."""
    import numpy as np

    from pipeline.cache.solutions import Stored, stored_rows
    ids = np.array([0, 3, 5, 9])
    nodes = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    entry = Stored(10_000.0, 210_000.0, ids, nodes, nodes * 0.1, 1, 2, 1e-9, 12, "pmg")
    mine = np.array([9, 0, 5])
    rows = stored_rows(entry, mine, nodes[[3, 0, 2]], 1e-6)
    assert rows.tolist() == [3, 0, 2]
    assert stored_rows(entry, np.array([9, 4]), nodes[[3, 1]], 1e-6) is None
    assert stored_rows(entry, np.array([10]), nodes[[3]], 1e-6) is None
    moved = nodes[[3, 0, 2]] + [0.0, 0.0, 1e-5]
    assert stored_rows(entry, mine, moved, 1e-6) is None


@pytest.mark.slow
def test_a_load_change_scales_the_load_models_variants_too(cache, monkeypatch):
    """The load model's variants and the formulas' load positions, solved on one mesh's
    operator beside the case, are kept like its solution: a run at another load takes all
    of them scaled (no entry added), equal to the same mesh solved anew with the cache off
    (an independent check of the scaling) and to the first run's values times the load."""
    from mpi4py import MPI

    from pipeline.analysis import reuse
    from pipeline.analysis.context import RunContext
    from pipeline.analysis.level import LevelTask
    from pipeline.analysis.ranges import load_variant_cases

    def level(case):
        task = LevelTask(case.mesh_factor, sections=True, formula_loads=True,
                         load_variants=tuple(load_variant_cases(case)))
        ctx = RunContext(comm=MPI.COMM_SELF)
        with reuse.mesher(case.dims, case.model, ctx) as m:
            return reuse.level(case, task, replace(ctx, mesher=m))

    case = resolve("05", None, {"mesh_factor": 3.0})
    first = level(case)
    n_entries = len(list(cache.glob("*.entry")))
    assert len(first.load_variants) == 3 and n_entries == 7  # mesh, the case's and 5 more solutions
    changed = replace(case, load_N=2.5 * case.load_N)
    second = level(changed)
    assert len(list(cache.glob("*.entry"))) == n_entries and second.scaled_from is not None
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "1")
    fresh = level(changed)
    assert fresh.scaled_from is None
    for a, b, f in zip(second.load_variants, fresh.load_variants, first.load_variants, strict=True):
        for k in (0, 1):  # the global and the critical peak
            assert a[k].value_MPa == pytest.approx(b[k].value_MPa, rel=1e-7)
            assert a[k].value_MPa == pytest.approx(2.5 * f[k].value_MPa, rel=1e-12)
        assert a[2]["critical_section"]["nominal_MPa"] == pytest.approx(b[2]["critical_section"]["nominal_MPa"],
                                                                       rel=1e-7)
    for which in ("approximate", "exact"):
        a, b = (lv.sections["formula_load"][which]["fe_MPa"] for lv in (second, fresh))
        assert a == pytest.approx(b, rel=1e-7)
