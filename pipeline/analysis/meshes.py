"""The meshes of an answer: the requested mesh and the coarser error-bar meshes, made and
solved over the MPI ranks (mm, N, MPa).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

from pipeline.analysis import reuse
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import Level, LevelTask
from pipeline.analysis.pilot import KNOWN, Pilot, inside_refinement
from pipeline.fe.meshing import make_meshes, owners
from pipeline.inputs.case import Case
from pipeline.runtime.idle import wait_for_ranks


@dataclass(frozen=True)
class MeshPlan:
    """The meshes to solve, by mesh factor, finest first (the requested one, then the error
    bar's), and what besides the case's own load they carry: the journal load at each hand
    formula's position (on the first error-bar mesh, or the requested one when it is
    alone), cases that differ only in the journal load model (on the error-bar mesh at
    factor ``load_variants_at``, or the requested one), and whether the requested mesh's
    gmsh file is kept (mesh.msh)."""

    factors: tuple[float, ...]
    formula_loads: bool = False
    load_variants: tuple[Case, ...] = ()
    load_variants_at: float | None = None
    keep_msh: bool = False

    def tasks(self, places: Pilot) -> list[LevelTask]:
        """Each mesh's task: the requested one keeps its fields and sections."""
        host = next((k for k in range(1, len(self.factors)) if self.load_variants_at is not None
                     and math.isclose(self.factors[k], self.load_variants_at, rel_tol=1e-9)), 0)
        formula_at = 1 if self.formula_loads and len(self.factors) > 1 else 0
        out = []
        for k, f in enumerate(self.factors):
            variants = self.load_variants if k == host else ()
            formula = self.formula_loads and k == formula_at
            out.append(LevelTask(factor=f, hotspots=places.hotspots, keep_fields=k == 0, keep_msh=self.keep_msh and k == 0,
                                 sections=k == 0 or bool(variants) or formula, formula_loads=formula,
                                 load_variants=variants))
        return out


def solve_meshes(case: Case, plan: MeshPlan, places: Pilot, ctx: RunContext) -> tuple[list[Level], Pilot]:
    """Every mesh of ``plan`` refined at ``places``, finest first, and the places used.

    All meshes are made at once, one per rank (gmsh is serial); the requested mesh is
    solved on every rank and handed to ``ctx.on_requested``, then the coarser ones side by
    side, each on one rank (:func:`error_bar_ranks`). If the places were the ones the
    dimensions name and the requested mesh's critical peak lies outside them (an unusual
    part), the pilot finds the places and the meshes are made again, before anything is
    handed on."""
    levels = _solve(case, plan, places, ctx)
    if levels is None:
        places = reuse.pilot_places(case, ctx)
        levels = _solve(case, plan, places, ctx)
    return levels, places


def _solve(case: Case, plan: MeshPlan, places: Pilot, ctx: RunContext) -> list[Level] | None:
    """:func:`solve_meshes` at ``places``; None when they are the known ones and the
    critical peak fell outside them."""
    factors, comm, say = plan.factors, ctx.comm, ctx.say
    tasks = plan.tasks(places)
    on = error_bar_ranks(factors, comm.size)
    t0 = time.perf_counter()
    known = [reuse.remembered(case, t, ctx) is not None for t in tasks]  # solved by this process before
    todo = [k for k in range(len(tasks)) if not known[k]]
    with reuse.mesher(case.dims, case.model, ctx) as m:
        made = make_meshes(case.dims, case.model, [tasks[k].spec(case) for k in todo], comm=comm,
                           keep_msh=[tasks[k].keep_msh for k in todo], solve_on=[on[k] for k in todo], mesher=m)
    loaders = dict(zip(todo, made))
    if comm.size > 1 and len(factors) > 1:
        say(f"meshes ×{', ×'.join(f'{f:.3g}' for f in factors)} made on {min(comm.size, len(factors))} ranks at once "
            f"({time.perf_counter() - t0:.2f} s)")
    fine = reuse.level(case, tasks[0], ctx, loaders.get(0))
    if places.source == KNOWN and not inside_refinement(fine.critical.location_mm, places,
                                                        case.mesh_spec(factors[0]).edge_hotspot_radius):
        say(f"the critical peak at ({', '.join(f'{c:.2f}' for c in fine.critical.location_mm)}) mm lies outside "
            f"the known places' refinement: finding the places by a pilot solve instead")
        return None
    if ctx.on_requested is not None:
        ctx.on_requested(fine, places)
    alone = ctx.alone()
    mine: list[tuple[int, Level]] = []
    error = None
    for k in range(1, len(factors)):
        if on[k] == comm.rank and error is None:
            try:
                mine.append((k, reuse.error_bar_level(case, tasks[k], alone, loaders.get(k))))
            except Exception as exc:  # re-raised on every rank below
                error = (k, exc)
    wait_for_ranks(comm)
    gathered = comm.allgather((mine, error))
    errors = [e for _, e in gathered if e is not None]
    if errors:
        raise min(errors, key=lambda e: e[0])[1]
    out = [fine] + [lv for _, lv in sorted((kl for m_, _ in gathered for kl in m_), key=lambda kl: kl[0])]
    formula_at = next((k for k, t in enumerate(tasks) if t.formula_loads), 0)
    if formula_at and fine.sections is not None:
        fine.sections["formula_load"] = (out[formula_at].sections or {}).get("formula_load")
    for k in range(1, len(factors)):
        if on[k] != 0:  # rank 0 said its own
            lv = out[k]
            how = (f"scaled from an earlier run at Q = {lv.scaled_from['load_N']:g} N, "
                   f"E = {lv.scaled_from['E_MPa']:g} MPa" if lv.scaled_from
                   else f"{lv.dofs} DOFs, {lv.iterations} iterations")
            say(f"mesh ×{lv.factor:.3g} (rank {on[k]}): {how}; "
                f"peak {lv.peak.value_MPa:.2f} MPa, critical {lv.critical.value_MPa:.2f} MPa")
    return out


def solve_one(case: Case, task: LevelTask, ctx: RunContext) -> Level:
    """One more mesh of the case over every rank (a tolerance step's), made with ctx's
    mesher, its solution reused where an earlier run's is kept."""
    with reuse.mesher(case.dims, case.model, ctx) as m:
        return reuse.level(case, task, replace(ctx, mesher=m))


def error_bar_ranks(factors: Sequence[float], ranks: int) -> list[int | None]:
    """Where each mesh of the error bar is solved: the requested one (first) on all ranks
    (None); the coarser ones each on one rank, the largest first to the least loaded rank
    (cost factor⁻³), counting ranks from the last, so that rank 0, which also starts the
    picture, gets the least.

    Why: a small mesh scales badly over ranks; one mesh per rank, side by side with the
    picture process, finishes the error bar sooner (docs/decisions/0006-error-bar-meshes-over-the-ranks.md).
    """
    who = owners([f ** -3 for f in factors[1:]], ranks)
    return [None] + [ranks - 1 - r for r in who]
