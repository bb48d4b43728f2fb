"""The analysis of a case: the requested mesh and the coarser error-bar meshes, made and
solved over the MPI ranks.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable, Sequence

from mpi4py import MPI

from pipeline.inputs.case import Case
from pipeline.cache import levels as levelcache
from pipeline.runtime.idle import wait_for_ranks
from pipeline.analysis.level import Level, Progress, solve_level
from pipeline.fe.meshing import ImportedMesh, Mesher, given_or_new, make_meshes, owners
from pipeline.analysis.pilot import KNOWN, Pilot, inside_refinement, pilot, refinement_places


def analyse(case: Case, levels: int = 3, ratio: float = 1.3, msh_path: Path | None = None,
            progress: Progress | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
            pl: Pilot | None = None,
            on_requested: Callable[[Level, Pilot], None] | None = None,
            mesher: Mesher | None = None, load_variants: Sequence[Case] = (),
            load_variants_at: float | None = None, formula_loads: bool = True) -> tuple[list[Level], Pilot]:
    """Solve on ``levels`` meshes, the requested one and coarser by ``ratio`` each; finest first.

    The refinement goes where the peaks are (:func:`pilot.refinement_places`: a pilot
    solve, or for the critical peak alone the known bore edges). Then all
    meshes are made at once, one per rank (gmsh is serial; see meshing.make_meshes). The
    requested mesh is solved on every rank and handed to ``on_requested`` (which may start
    work that runs beside what follows: the picture). The coarser meshes are then solved
    side by side, each on one rank (see :func:`error_bar_ranks`). ``mesher``: this
    process's meshing.Mesher of the case's part, if it has one (else one for the pilot
    and the meshes). If places known from the dimensions were refined and the critical
    peak of the requested mesh lies outside them, the analysis starts again with the
    pilot's places, before anything is handed on. ``load_variants``: cases that differ only
    in the journal load model, solved on the operator of the error-bar mesh at mesh factor
    ``load_variants_at`` if the run has one (on its own rank, beside the others), else of
    the requested mesh (that level's ``load_variants``). ``formula_loads``: the journal load
    at each hand formula's position is solved too, on the first error-bar mesh's operator
    (on its own rank, beside the others) or the requested mesh's when the run has only
    that; its sections go into the requested level's (sections' ``formula_load``, with
    that mesh's factor): section quantities, integrals over a section, which the meshes
    agree on.
    """
    with given_or_new(mesher, case.dims, case.model) as m:
        pl = pl or refinement_places(case, comm=comm, progress=progress, mesher=m)
        factors = [case.mesh_factor * ratio ** k for k in range(levels)]
        on = error_bar_ranks(factors, comm.size)
        t0 = time.perf_counter()
        specs = [case.mesh_spec(f, pl.hotspots) for f in factors]
        loaders = make_meshes(case.dims, case.model, specs,
                              comm=comm, msh_paths=[msh_path] + [None] * (levels - 1), solve_on=on,
                              mesher=m)
    say = progress or (lambda s: None)
    if comm.size > 1 and levels > 1:
        say(f"meshes ×{', ×'.join(f'{f:.3g}' for f in factors)} made on {min(comm.size, levels)} ranks at once "
            f"({time.perf_counter() - t0:.2f} s)")
    host = next((k for k in range(1, levels) if load_variants_at is not None
                 and math.isclose(factors[k], load_variants_at, rel_tol=1e-9)), 0)
    formula_at = 1 if formula_loads and levels > 1 else 0
    fine = solve_level(case, factors[0], keep_fields=True, with_sections=True, comm=comm, progress=progress,
                       load_mesh=loaders[0], load_variants=load_variants if host == 0 else (),
                       formula_loads=formula_loads and formula_at == 0)
    if pl.source == KNOWN and not inside_refinement(fine.critical.location_mm, pl,
                                                    case.mesh_spec(factors[0]).edge_hotspot_radius):
        say(f"the critical peak at ({', '.join(f'{c:.2f}' for c in fine.critical.location_mm)}) mm lies outside "
            f"the known places' refinement: finding the places by a pilot solve instead")
        return analyse(case, levels, ratio, msh_path, progress, comm,
                       pilot(case, comm=comm, progress=progress, mesher=mesher), on_requested, mesher, load_variants,
                       load_variants_at, formula_loads)
    if on_requested is not None:
        on_requested(fine, pl)
    mine: list[tuple[int, Level]] = []
    error = None
    for k in range(1, levels):
        if on[k] == comm.rank and error is None:
            try:
                mine.append((k, error_bar_level(case, specs[k], loaders[k], progress if comm.rank == 0 else None,
                                                load_variants if k == host else (), formula_loads=k == formula_at)))
            except Exception as exc:  # re-raised on every rank below
                error = (k, exc)
    wait_for_ranks(comm)
    gathered = comm.allgather((mine, error))
    errors = [e for _, e in gathered if e is not None]
    if errors:
        raise min(errors, key=lambda e: e[0])[1]
    out = [fine] + [lv for _, lv in sorted((kl for m, _ in gathered for kl in m), key=lambda kl: kl[0])]
    if formula_at and fine.sections is not None:
        fine.sections["formula_load"] = (out[formula_at].sections or {}).get("formula_load")
    for k in range(1, levels):
        if on[k] != 0:  # rank 0 printed its own
            lv = out[k]
            how = (f"scaled from an earlier run at Q = {lv.scaled_from['load_N']:g} N, "
                   f"E = {lv.scaled_from['E_MPa']:g} MPa" if lv.scaled_from
                   else f"{lv.dofs} DOFs, {lv.iterations} iterations")
            say(f"mesh ×{lv.factor:.3g} (rank {on[k]}): {how}; "
                f"peak {lv.peak.value_MPa:.2f} MPa, critical {lv.critical.value_MPa:.2f} MPa")
    return out, pl


def error_bar_level(case: Case, spec, load_mesh: Callable[[], ImportedMesh], progress: Progress | None,
                    load_variants: Sequence[Case] = (), formula_loads: bool = False) -> Level:
    """One error-bar mesh solved on this rank alone: the results of an earlier run of the
    same mesh and problem scaled to the case's load (pipeline/cache/levels.py), or else a
    new solve of the mesh ``load_mesh`` gives (``spec`` its MeshSpec), then kept. With
    ``load_variants`` (load-model cases solved on this mesh's operator, with the sections
    of each and of the case) or ``formula_loads`` (the journal load at each hand formula's
    position, level.solve_level's) it goes through level.solve_level, since the level cache
    keeps no variants' readings; their solutions, like the case's, come scaled from an
    earlier run's when the solution cache has them (level.solve_or_scale)."""
    name = levelcache.key(case, spec)
    lv = None if load_variants or formula_loads else levelcache.earlier(name, case, spec.factor)
    if lv is not None:
        (progress or (lambda s: None))(
            f"mesh ×{spec.factor:.3g}: the results of an earlier run at Q = {lv.scaled_from['load_N']:g} N scaled "
            f"({lv.timings['post']:.2f} s); peak {lv.peak.value_MPa:.2f} MPa, critical {lv.critical.value_MPa:.2f} MPa")
        return lv
    lv = solve_level(case, spec.factor, comm=MPI.COMM_SELF, load_mesh=load_mesh, progress=progress,
                     with_sections=bool(load_variants) or formula_loads, load_variants=load_variants,
                     formula_loads=formula_loads)
    levelcache.store(name, lv, case)
    return lv


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
