"""The one seam between a run and the work done before it: the run cache
(pipeline/cache/), and the memo of the runs in one process (RunContext.memo: a screened
study's steps on one variant solve each mesh once). Every read and write of earlier work
happens here, and no other module of the pipeline imports the cache.

A run that changes only the hook load, E or the allowable takes from an earlier run of the
same part and model (linear elasticity with traction loads: stresses scale with Q/Q0,
displacements with (Q/Q0)·(E0/E), and nothing moves where it sits):

- the pilot's refined places (:func:`places`): load, E and the allowable do not move them;
- each mesh (:class:`CachedMesher`): gmsh's output for the same part and spec;
- each mesh's solution (:func:`level`): scaled, and checked against this mesh's system;
- a sensitivity variant's solution on its moved mesh (:func:`resolved`): scaled and
  checked alike;
- an error-bar mesh's numbers (:func:`error_bar_level`): its peaks and forces scaled by
  Q/Q0, without importing the mesh, once its readings are read again from the mesh and
  solution entries they derive from (pipeline/cache/levels.py).

Every entry is checked before it is used (pipeline/cache/*: checksums and what the numbers
must be); one that fails is dropped with one line and the work is done again.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import replace
from typing import Callable, Sequence

from dolfinx import fem
from mpi4py import MPI

from geometry.table import Dimensions
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import (Level, LevelTask, MoreLoad, Problem, more_loads, more_rtol, new_solution,
                                     read_level, say_mesh, set_up)
from pipeline.analysis.pilot import Pilot, pilot, pilot_factor, refinement_places
from pipeline.cache import levels as levelcache
from pipeline.cache import meshes as meshcache
from pipeline.cache import places as placecache
from pipeline.cache import runs as runcache
from pipeline.cache import solutions as solvecache
from pipeline.fe.meshing import ImportedMesh, MeshedPart, Mesher
from pipeline.fe.solve import Solution
from pipeline.inputs.case import Case


class CachedMesher(Mesher):
    """A :class:`Mesher` that first looks for the same part and spec meshed by an earlier
    run (checked, pipeline/cache/meshes.py) and keeps what it meshes."""

    def generate(self, spec, keep_msh: bool = False) -> MeshedPart:
        t0 = time.perf_counter()
        name = mesh_key(self.d, self.model, spec)
        hit = meshcache.earlier(name)
        if hit is not None and (not keep_msh or hit.msh is not None):
            return MeshedPart(**hit.fields, timings={"geometry": 0.0, "mesh": time.perf_counter() - t0},
                              msh=hit.msh if keep_msh else None)
        part = super().generate(spec, keep_msh)
        if runcache.enabled():
            fields = {k: v for k, v in vars(part).items() if k not in ("timings", "msh")}
            meshcache.store(name, fields, part.msh)
        return part


def mesh_key(d: Dimensions, model: str, spec) -> str:
    """The run-cache name of the mesh of part ``d`` (mm) and ``model`` for ``spec`` (a MeshSpec)."""
    return runcache.key("mesh", dims=d, model=model, spec=spec)


def mesher(d: Dimensions, model: str, ctx: RunContext) -> contextlib.AbstractContextManager[Mesher]:
    """For a with-block: ctx's mesher if it is of part ``d`` (its owner closes it), else a
    new :class:`CachedMesher` of the part, closed at the block's end."""
    given = ctx.mesher
    if given is not None and (given.d, given.model) == (d, model):
        return contextlib.nullcontext(given)
    return CachedMesher(d, model, ctx.say)


def places(case: Case, ctx: RunContext) -> Pilot:
    """The places the run refines (pipeline.analysis.pilot.refinement_places); the pilot's
    are those of an earlier run of the same part and model when the memo or the cache has
    them."""
    key = ("places", _pilot_key(case))
    if ctx.memo is not None and key in ctx.memo:
        return ctx.memo[key]
    found = refinement_places(case, ctx) if case.want == "critical" else pilot_places(case, ctx)
    if ctx.memo is not None:
        ctx.memo[key] = found
    return found


def remembered(case: Case, task: LevelTask, ctx: RunContext) -> Level | None:
    """The level an earlier run of this process solved for the same case and mesh with at
    least what ``task`` asks (fields, sections, the same further loads) (ctx.memo), with
    only what it asks (an error-bar mesh's level travels between ranks: no fields), or None."""
    kept = None if ctx.memo is None else ctx.memo.get(_memo_key(case, task))
    if kept is None:
        return None
    old, lv = kept
    covers = ((old.keep_fields or not task.keep_fields) and (old.sections or not task.sections)
              and (old.keep_msh or not task.keep_msh) and old.formula_loads == task.formula_loads
              and old.load_variants == task.load_variants)
    if not covers:
        return None
    return replace(lv, fields=lv.fields if task.keep_fields else None, sections=lv.sections if task.sections else None,
                   msh=lv.msh if task.keep_msh else None)


def _memo_key(case: Case, task: LevelTask) -> tuple:
    """What makes one mesh's level in the memo: the case (its load included) whatever its
    own mesh factor and tolerance, and the mesh's factor and refined places."""
    return ("level", repr(replace(case, mesh_factor=1.0, mesh_pinned=False, tolerance_pct=1.0)), task.factor,
            tuple(task.hotspots))


def _remember(case: Case, task: LevelTask, ctx: RunContext, lv: Level) -> Level:
    """Keep ``lv``, solved for ``task``, in ctx.memo (when it has one); returns it."""
    if ctx.memo is not None:
        ctx.memo[_memo_key(case, task)] = (task, lv)
    return lv


def _pilot_key(case: Case) -> str:
    """The run-cache key of the case's pilot places: what shapes the stress field, not its
    size (load, E and the allowable do not move the places)."""
    return runcache.key("pilot", dims=case.dims, model=case.model, support=case.support, nu=case.nu, want=case.want,
                        bearing=case.load_model(), order=case.order, solver=case.solver,
                        spec=case.mesh_spec(pilot_factor(case)))


def pilot_places(case: Case, ctx: RunContext) -> Pilot:
    """The pilot's places of the case: an earlier run's (load, E and the allowable do not
    move them), or a new pilot solve, then kept. Read on rank 0 for every rank."""
    t0 = time.perf_counter()
    name = _pilot_key(case)
    reach = max(case.dims.b1, case.dims.b6, case.dims.h3)  # mm: the part's largest dimension
    known = placecache.earlier(name, pilot_factor(case), reach) if ctx.comm.rank == 0 else None
    known = ctx.comm.bcast(known, root=0)
    if known is not None:
        ctx.say(f"pilot skipped: the places found by an earlier run of this part and model are reused "
                f"({len(known.hotspots)} places; load, E and the allowable do not move them)")
        return Pilot(factor=known.factor, hotspots=known.hotspots, time_s=time.perf_counter() - t0,
                     bridging=known.bridging)
    found = pilot(case, ctx)
    if ctx.comm.rank == 0:
        placecache.store(name, placecache.StoredPlaces(found.factor, found.hotspots, found.bridging, found.time_s))
    return found


def solve_or_scale(case: Case, prob: Problem, reuse: bool = True, more: Sequence[MoreLoad] = ()) -> Solution:
    """The displacement of the problem: with ``reuse`` and the run cache on, an earlier
    solve of the same mesh and problem at another load or E, scaled
    (pipeline/cache/solutions.py: exact in linear elasticity), or else a new solve, which is
    then kept for the next run; without them, a new solve. ``more``: further load cases
    under the same constraints (a load model's variants), the result's ``more`` in order:
    each scaled from an earlier solve of its own load model on this mesh or, with the ones
    not found, solved on the same operator, and kept alike."""
    m, lc = prob.mesh, prob.loads
    V = fem.VectorFunctionSpace(m.mesh, ("Lagrange", case.order)) if reuse and runcache.enabled() else None
    ids = None if V is None else solvecache.node_ids(V, m)
    keep = m.mesh.comm.allreduce(ids is not None, op=MPI.LAND)
    t0 = time.perf_counter()
    if not keep:
        return new_solution(case, prob, [lc_k for _, lc_k in more], V)
    target = solvecache.Target(m, V, ids)

    # The further right-hand sides are solved (and kept, and checked on reuse) at their own
    # tolerance (level.more_rtol).
    cases = [case] + [replace(case, rtol=more_rtol(case))] * len(more)

    names = [solvecache.key(case, m, V)] + [solvecache.key(cases[1], m, V, model) for model, _ in more]
    loads = [lc] + [lc_k for _, lc_k in more]
    found = [_earlier(n, target, lc_k, c, prob.material) for n, lc_k, c in zip(names, loads, cases)]
    t_key = time.perf_counter() - t0
    missing = [k for k, s in enumerate(found) if s is None]
    timings = {"assemble": 0.0, "solve": 0.0}
    if missing:
        new = _solve_loads(case, prob, V, [loads[k] for k in missing])
        timings = dict(new.timings)
        t0 = time.perf_counter()
        for k, s in zip(missing, [new, *new.more]):
            s.more = []
            solvecache.store(names[k], s, ids, cases[k])
            found[k] = s
        timings["solve"] += time.perf_counter() - t0
    sol = found[0]
    sol.more = found[1:]
    timings["solve"] += t_key
    sol.timings = timings
    return sol


def resolved(case: Case, prob: Problem, solve: Callable[[], Solution], V) -> Solution:
    """The displacement of ``case`` on a mesh of the sensitivity section as its nodes now
    are (the nominal mesh, or it moved onto a variant's dimensions; space ``V``): an
    earlier run's solve of the same case on the same nodes, scaled to this load and E and
    checked against this mesh's system (pipeline/cache/solutions.py), or else ``solve()``
    (the set-up Resolver's), then kept. A changed-load re-run thus solves no variant again."""
    m = prob.mesh
    ids = solvecache.node_ids(V, m) if runcache.enabled() else None
    if ids is None:
        return solve()
    name = solvecache.key(case, m, V)
    found = _earlier(name, solvecache.Target(m, V, ids), prob.loads, case, prob.material)
    if found is not None:
        return found
    sol = solve()
    solvecache.store(name, sol, ids, case)
    return sol


def _earlier(name: str, target: solvecache.Target, lc, case: Case, material) -> Solution | None:
    """The stored solution ``name`` scaled to ``case``'s load and E on ``target`` and checked
    against its system under loads ``lc`` (pipeline/cache/solutions.py), or None."""
    entry = solvecache.earlier(name, target.m.mesh.comm)
    return None if entry is None else solvecache.scaled(entry, target, lc, case, material, name)


def _solve_loads(case: Case, prob: Problem, V, loads: list) -> Solution:
    """A new solve of ``loads[0]`` on the problem's operator (the case's own load or a
    variant's), with ``loads[1:]`` as further right-hand sides."""
    first = Problem(prob.mesh, prob.material, loads[0], prob.loads_s)
    return new_solution(case, first, loads[1:], V)


def level(case: Case, task: LevelTask, ctx: RunContext, load_mesh: Callable[[], ImportedMesh] | None = None
          ) -> Level:
    """One mesh of the case as pipeline.analysis.level.solve_level reads it, its solution
    (and its further right-hand sides') scaled from an earlier run's when the cache has
    them (:func:`solve_or_scale`), else solved and kept; the memo's, when this process
    solved it already."""
    lv = remembered(case, task, ctx)
    if lv is not None:
        return lv
    return _level(case, task, ctx, load_mesh, named=False)[0]


def _level(case: Case, task: LevelTask, ctx: RunContext, load_mesh: Callable[[], ImportedMesh] | None,
           named: bool = True) -> tuple[Level, str | None]:
    """:func:`level` solved here (kept in the memo) and, when ``named``, the run-cache name
    of its solution (None when none is kept: the cache is off, or a P3 solution).
    Collective over ctx.comm when named."""
    prob = set_up(case, task, ctx, load_mesh)
    say_mesh(prob, task.factor, ctx.say)
    more = more_loads(case, task, prob)
    sol = solve_or_scale(case, prob, task.reuse, more.loads)
    lv = _remember(case, task, ctx, read_level(case, task, prob, sol, more, ctx.say))
    if not named or not (task.reuse and runcache.enabled()):
        return lv, None
    V = sol.u.function_space
    return lv, solvecache.key(case, prob.mesh, V) if solvecache.node_ids(V, prob.mesh) is not None else None


def error_bar_level(case: Case, task: LevelTask, ctx: RunContext, load_mesh: Callable[[], ImportedMesh]) -> Level:
    """An error-bar mesh on this rank alone: an earlier run's numbers of the same mesh and
    problem scaled to the case's load (pipeline/cache/levels.py), without importing the mesh;
    or else :func:`level`, then kept. A task with further right-hand sides always goes
    through :func:`level`: the level cache keeps no variants' readings."""
    if remembered(case, task, ctx) is not None:
        return remembered(case, task, ctx)
    spec = task.spec(case)
    name = levelcache.key(case, spec)
    plain = not task.load_variants and not task.formula_loads
    stored = levelcache.earlier(name, case, spec.factor) if plain else None
    if stored is not None:
        ctx.say(f"mesh ×{spec.factor:.3g}: the results of an earlier run at Q = {stored.scaled_from['load_N']:g} N "
                f"scaled ({stored.timings['post']:.2f} s); peak {stored.peak.value_MPa:.2f} MPa, "
                f"critical {stored.critical.value_MPa:.2f} MPa")
        return Level(**stored.numbers, peak=stored.peak, critical=stored.critical, timings=dict(stored.timings),
                     scaled_from=stored.scaled_from)
    lv, solution = _level(case, task, ctx, load_mesh)
    numbers = {k: getattr(lv, k) for k in levelcache.NUMBERS}
    levelcache.store(name, levelcache.StoredLevel(numbers, lv.peak, lv.critical, lv.timings, lv.scaled_from), case,
                     levelcache.derives_from(mesh_key(case.dims, case.model, spec), solution))
    return lv
