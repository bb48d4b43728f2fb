"""The checks of a reused error-bar mesh's results (pipeline/cache/levels.py: problem and
earlier), on a stored result written here: what a solve must meet (docs/design.md §8: the
seat force the model's share of Q to 1e-9, equilibrium and the constraint's reaction within
1e-6·Q), and the scaling of linear elasticity (every stress and force × Q/Q0) (N, MPa)."""
from __future__ import annotations

from dataclasses import replace

import pytest

import pipeline.cache.levels as cl
import pipeline.cache.runs as rc
from pipeline.inputs.case import resolve

CASE = resolve("05")  # quarter model, Q = 10 000 N
Q0 = 10_000.0


def stored(**over) -> dict:
    """A consistent stored result of the quarter model at Q0 = 10 kN (seat −Q0/4)."""
    peak = {"unaveraged": [120.0, [22.9, 6.9, 4.8]], "averaged": [108.0, [22.9, 6.9, 4.9]], "rule": "midpoint"}
    crit = {"unaveraged": [66.3, [0.0, 10.5, 0.0]], "averaged": [66.1, [0.0, 10.5, 0.0]], "rule": "unaveraged"}
    m = {"factor": 1.3, "dofs": 30_000, "cells": 5_000, "iterations": 40, "residual_rel": 1e-9,
         "seat_force_N": -Q0 / 4, "support_force_N": Q0 / 4, "equilibrium_error_N": 1e-7,
         "constraint_reaction_N": 1e-7, "jacobian_ratio": 0.4, "load_N": Q0, "E_MPa": 210_000.0,
         "peak": peak, "critical": crit, "timings": {}, "scaled_from": None}
    m.update(over)
    return m


def test_a_consistent_result_passes():
    assert cl.problem(stored(), CASE, 1.3) is None


@pytest.mark.parametrize("over, why", [
    ({"seat_force_N": -Q0 / 4 * (1 + 2e-9)}, "seat force"),       # beyond 1e-9 of the share
    ({"seat_force_N": -Q0}, "seat force"),                          # the full model's share
    ({"equilibrium_error_N": 2e-6 * Q0}, "out of balance"),
    ({"constraint_reaction_N": 2e-6 * Q0}, "out of balance"),
    ({"factor": 1.69}, "mesh factor"),
    ({"dofs": 30_001}, "sizes not whole"),
    ({"residual_rel": 1.0}, "residual"),
    ({"E_MPa": 0.0}, "not above zero"),
])
def test_an_inconsistent_result_is_refused_naming_why(over, why):
    assert why in cl.problem(stored(**over), CASE, 1.3)


def test_the_limits_themselves_pass():
    """At 0.5e-9 and 0.9e-6 of the load: within the limits of a solve."""
    assert cl.problem(stored(seat_force_N=-Q0 / 4 * (1 + 0.5e-9), equilibrium_error_N=0.9e-6 * Q0,
                             constraint_reaction_N=0.9e-6 * Q0), CASE, 1.3) is None


def test_a_reused_result_is_scaled_by_q_over_q0(monkeypatch):
    """Linear elasticity: at Q = 25 kN every stress and force is 2.5× the stored one, E
    changes nothing, and the peaks stay where they were."""
    monkeypatch.setattr(rc, "load", lambda name, redo: rc.Entry(stored()))
    monkeypatch.setattr(cl, "derivation_problem", lambda m, case: None)  # no mesh and solution here
    case = replace(CASE, load_N=2.5 * Q0, E_MPa=70_000.0)
    lv = cl.earlier("x", case, 1.3)
    assert lv.peak.unaveraged.value_MPa == pytest.approx(2.5 * 120.0, rel=1e-15)
    assert lv.peak.averaged.value_MPa == pytest.approx(2.5 * 108.0, rel=1e-15)
    assert lv.critical.value_MPa == pytest.approx(2.5 * 66.3, rel=1e-15)
    assert lv.numbers["seat_force_N"] == pytest.approx(-2.5 * Q0 / 4, rel=1e-15)
    assert lv.numbers["support_force_N"] == pytest.approx(2.5 * Q0 / 4, rel=1e-15)
    assert lv.peak.location_mm == (22.9, 6.9, 4.8) and lv.numbers["dofs"] == 30_000
    assert lv.scaled_from == {"load_N": Q0, "E_MPa": 210_000.0}


def test_a_result_that_names_nothing_it_derives_from_is_refused(monkeypatch):
    """A stored result without the mesh and solution entries it derives from cannot be
    checked against them: refused, and one that would be stored without them is not kept."""
    assert cl.derivation_problem(stored(), CASE) == "it names no mesh and solution it derives from"
    kept = []
    monkeypatch.setattr(rc, "store", lambda name, entry: kept.append(name))
    lv = cl.StoredLevel({k: stored()[k] for k in cl.NUMBERS}, None, None, {})
    cl.store("x", lv, CASE, None)
    assert kept == []
