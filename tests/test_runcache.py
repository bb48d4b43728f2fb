"""Reusing meshes and pilot places between runs (pipeline/runcache.py): a run that changes
only the load reuses both and gives the first run's stresses scaled by the load ratio
(linear elasticity: an independent check of the reuse); what shapes the field changes the
key."""
from __future__ import annotations

from dataclasses import replace

import pytest

import pipeline.runcache as rc
from pipeline.case import resolve
from pipeline.commands import execute_run


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path / "runs")
    return tmp_path / "runs"


def test_a_load_change_reuses_mesh_and_pilot(cache, tmp_path):
    case = resolve("05", None, {"mesh_factor": 3.0})
    first = execute_run(case, tmp_path / "a", levels=1, write_fields=False)
    n_entries = len(list(cache.glob("*.pickle")))
    assert n_entries == 3  # the pilot's mesh, its places, the requested mesh
    second = execute_run(replace(case, load_N=2.5 * case.load_N), tmp_path / "b", levels=1, write_fields=False)
    assert len(list(cache.glob("*.pickle"))) == n_entries  # nothing new: both reused
    assert second["timings_s"]["pilot"] < 0.2 * first["timings_s"]["pilot"]
    for key in ("peak_MPa", "critical_peak_MPa"):
        assert second["fe"][key] == pytest.approx(2.5 * first["fe"][key], rel=1e-9)


def test_keys_follow_what_shapes_the_field():
    d = resolve("05").dims
    k = rc.key("pilot", dims=d, nu=0.3, support="bearing")
    assert k == rc.key("pilot", dims=d, nu=0.3, support="bearing")
    assert k != rc.key("pilot", dims=d, nu=0.25, support="bearing")
    assert k != rc.key("pilot", dims=replace(d, rf=2.0), nu=0.3, support="bearing")


def test_the_cache_is_bounded(cache, monkeypatch):
    monkeypatch.setattr(rc, "MAX_ENTRIES", 3)
    for i in range(6):
        rc.store(f"x-{i}", i)
    assert sorted(p.stem for p in cache.glob("*.pickle")) == ["x-3", "x-4", "x-5"]
    assert rc.load("x-5") == 5 and rc.load("x-0") is None
