"""The meshes a run solves (pipeline/analysis/run.py): the factors its options name, each
once — a convergence study's finest below the case's mesh, a screened study's steps above
it. The analysis is stopped where it would solve; the expected factors are worked out here
from the ratio (mesh factors, no unit)."""
from __future__ import annotations

import contextlib

import pytest

from pipeline.analysis import run as run_module
from pipeline.analysis.pilot import Pilot
from pipeline.inputs.case import resolve
from pipeline.inputs.options import RunOptions, converge_options


class _Stop(Exception):
    pass


@pytest.fixture
def planned(monkeypatch):
    """The case's mesh factor and the plan's factors of a run, nothing solved."""
    seen = {}

    def stop(case, options, plan, places, ctx):
        seen.update(case=case.mesh_factor, factors=plan.factors)
        raise _Stop

    monkeypatch.setattr(run_module.reuse, "mesher", lambda dims, model, ctx: contextlib.nullcontext())
    monkeypatch.setattr(run_module.reuse, "places", lambda case, ctx: Pilot.__new__(Pilot))
    monkeypatch.setattr(run_module, "solve_to_tolerance", stop)

    def plan_of(options: RunOptions) -> dict:
        with pytest.raises(_Stop):
            run_module.run(resolve("05", overrides={"mesh_factor": 3.0}), options)
        return seen
    return plan_of


def test_a_convergence_study_starts_one_ratio_step_below_the_case_s_mesh(planned):
    seen = planned(converge_options(4, 1.3))
    assert seen["factors"] == pytest.approx((3.0 / 1.3, 3.0, 3.9, 5.07))
    assert seen["case"] == pytest.approx(3.0 / 1.3)


def test_a_run_solves_its_mesh_and_two_coarser_ones(planned):
    assert planned(RunOptions())["factors"] == pytest.approx((3.0, 3.9, 5.07))


def test_a_screened_step_solves_the_error_bar_s_coarser_meshes(planned):
    assert planned(RunOptions(levels=2, finer=-1))["factors"] == pytest.approx((3.9, 5.07))
    assert planned(RunOptions(levels=1, finer=-2))["factors"] == pytest.approx((5.07,))
