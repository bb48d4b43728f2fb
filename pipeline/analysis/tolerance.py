"""The meshes of an answer chosen for the accuracy asked: each wanted peak's error-bar band
at most ``case.tolerance_pct`` of its value (docs/design.md §5).

The run tries fixed sets of three meshes, cheapest first, and stops at the first whose
bands are within the tolerance (the estimate is never chosen among sets, which would pick
the luckiest scatter):

1. the requested mesh f and two coarser ones, f·r and f·r² (r the run's ratio, 1.3);
2. a smaller step: f, f·√r and f·r (one new mesh, 0.67 of the finest's cost at r = 1.3),
   unless the requested mesh's own half gap between a midpoint's two readings is above
   the tolerance (no coarser mesh can bring the band below it). Not a fourth, coarser
   mesh: beyond ×1.3 the shoulder fillet is not resolved, and with such meshes the global
   peak's trend scatters by more than it converges (measured in decision 0027);
3. unless the mesh is pinned (``case.mesh_pinned``: a given --mesh-factor), a finer mesh
   f/r, with f and f·r, and then its smaller step again; at most MAX_REFINEMENTS times,
   each within the case's checks and the memory free. Without a given mesh factor the run
   starts at ×1.0 (docs/decisions/0028-default-start-stays-at-one.md).

A pinned mesh is never refined: the run reports the band it reached and says that it stays
above the tolerance (docs/decisions/0027-tolerance-chooses-the-meshes.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple, Sequence

from mpi4py import MPI

from pipeline.analysis.context import RunContext
from pipeline.analysis.errorbars import bands_of, half_gap_pct, wanted_peaks
from pipeline.analysis.level import Level, LevelTask
from pipeline.analysis.memory import check_fits
from pipeline.analysis.meshes import MeshPlan, solve_meshes, solve_one
from pipeline.analysis.pilot import Pilot
from pipeline.errors import InputError
from pipeline.inputs.case import Case, check
from pipeline.inputs.options import RunOptions

MAX_REFINEMENTS = 2   # finer meshes a run may add: at r = 1.3, up to 4.8× the start's DOFs


@dataclass(frozen=True)
class Accuracy:
    """What the run was asked and what it reached: the tolerance (% of each wanted peak's
    value), each wanted peak's band (%; None when the peak has no band: one mesh, or a
    singular feature), whether every band is within the tolerance, whether the mesh was
    pinned, the mesh factors of the error bar (finest first), every mesh the run solved
    (its factor and DOFs, in order) and each step the run took, in words."""

    tolerance_pct: float
    bands_pct: dict[str, float | None]
    met: bool
    pinned: bool
    factors: tuple[float, ...]
    solved: tuple[float, ...]
    solved_dofs: tuple[int, ...]
    steps: tuple[str, ...]
    note: str = ""   # why the tolerance was not met, empty when it was

    def as_dict(self) -> dict:
        return {"tolerance_pct": self.tolerance_pct, "bands_pct": dict(self.bands_pct), "met": self.met,
                "mesh_pinned": self.pinned, "mesh_factors": list(self.factors),
                "meshes_solved": list(self.solved), "meshes_solved_dofs": list(self.solved_dofs),
                "steps": list(self.steps), "note": self.note}


class Outcome(NamedTuple):
    """What :func:`solve_to_tolerance` returns: the error bar's levels (finest first), the
    places refined, the case at the finest mesh's factor, what was reached (None when the
    run was not asked for a tolerance), and every level the run solved (in order; the
    sensitivity analysis finds its load-model variants among them)."""

    levels: list[Level]
    places: Pilot
    case: Case
    accuracy: Accuracy | None
    solved: list[Level]


def _fmt_bands(bands: dict[str, float | None]) -> str:
    return ", ".join(f"{p} {'none' if b is None else f'{b:.2f} %'}" for p, b in bands.items())


def within(bands: dict[str, float | None], tolerance_pct: float) -> bool:
    """True when every band exists and is at most the tolerance (%)."""
    return all(b is not None and b <= tolerance_pct for b in bands.values())


def allowed(case: Case, factor: float, comm: MPI.Comm = MPI.COMM_WORLD) -> bool:
    """Whether the run may solve the case at a finer ``factor``: the case's checks accept it
    and its meshes' memory estimate (pipeline/analysis/memory.py, the memory free now)
    fits; decided on rank 0 for every rank."""
    ok = True
    if comm.rank == 0:
        try:
            finer = check(replace(case, mesh_factor=factor))
            check_fits(finer, [factor, factor * 1.3], None)
        except InputError:
            ok = False
    return bool(comm.bcast(ok, root=0))


def solve_to_tolerance(case: Case, options: RunOptions, plan: MeshPlan, places: Pilot, ctx: RunContext) -> Outcome:
    """The meshes of ``plan`` (pipeline.analysis.meshes.solve_meshes), then, when
    ``options.to_tolerance``, more meshes until each wanted peak's band is at most
    ``case.tolerance_pct`` (the module's steps) or no step is left. The Outcome's case is at
    the finest mesh's factor (a refined run's requested mesh); ``ctx.on_requested`` hears
    of each new finest mesh (its fields replace the earlier ones); the load-model variants
    stay on the mesh that first solved them."""
    lv, places = solve_meshes(case, plan, places, ctx)
    every = list(lv)
    if not options.to_tolerance:
        return Outcome(lv, places, case, None, every)
    tol, ratio, say = case.tolerance_pct, options.ratio, ctx.say
    if len(lv) < 3:
        return Outcome(lv, places, case, Accuracy(tol, {p: None for p in wanted_peaks(case)}, False, case.mesh_pinned,
                                                  _factors(lv), _factors(lv), _dofs(lv), (),
                                                  "one mesh: no error bar, so the tolerance is not checked"), every)
    bands = bands_of(case, lv)
    steps = [f"meshes ×{', ×'.join(f'{x.factor:.4g}' for x in lv)}: {_fmt_bands(bands)}"]
    say(f"tolerance {tol:g} %: {steps[-1]}")
    refinements, halved = 0, False
    while not within(bands, tol):
        if any(b is None for b in bands.values()):
            note = "a wanted peak has no band (a singular feature): no mesh brings it within the tolerance"
            break
        fine = lv[0]
        nxt = next(x for x in lv if math.isclose(x.factor, fine.factor * ratio, rel_tol=1e-9))
        if not halved and half_gap_pct(case, fine) > tol:
            halved = True   # no coarser mesh brings the band below the finest mesh's half gap
            say(f"tolerance {tol:g} %: the half gap of the requested mesh's two readings, "
                f"{half_gap_pct(case, fine):.2f} %, is above it: no smaller step")
        if not halved:
            mid = solve_one(case, LevelTask(factor=fine.factor * math.sqrt(ratio), hotspots=places.hotspots), ctx)
            every.append(mid)
            lv, halved, why = [fine, mid, nxt], True, "a smaller step between the meshes"
        elif not case.mesh_pinned and refinements < MAX_REFINEMENTS and allowed(case, fine.factor / ratio, ctx.comm):
            case = replace(case, mesh_factor=fine.factor / ratio)
            new, places = solve_meshes(case, replace(plan, factors=(case.mesh_factor,), load_variants=(),
                                                     load_variants_at=None), places, ctx)
            every.append(new[0])
            lv, halved, why = [new[0], fine, nxt], False, "a finer mesh"
            refinements += 1
        else:
            note = _why_stopped(case, fine, tol)
            break
        bands = bands_of(case, lv)
        steps.append(f"{why}, meshes ×{', ×'.join(f'{x.factor:.4g}' for x in lv)}: {_fmt_bands(bands)}")
        say(f"tolerance {tol:g} %: {steps[-1]}")
    else:
        note = ""
    met = within(bands, tol)
    if not met:
        say(f"tolerance {tol:g} % not reached ({_fmt_bands(bands)}): {note}")
    return Outcome(lv, places, case, Accuracy(tol, bands, met, case.mesh_pinned, _factors(lv), _factors(every),
                                              _dofs(every), tuple(steps), note), every)


def _why_stopped(case: Case, fine: Level, tol: float) -> str:
    """Why no further step can bring the bands within the tolerance (%)."""
    if case.mesh_pinned:
        return (f"the mesh factor {fine.factor:g} is pinned (--mesh-factor): the run does not refine past it"
                + (f", and its two readings' half gap ({half_gap_pct(case, fine):.2f} %) is above the tolerance"
                   if half_gap_pct(case, fine) > tol else ""))
    return (f"no finer mesh allowed (at most {MAX_REFINEMENTS} refinements, within the case's mesh limits "
            "and the memory free)")


def _factors(levels: Sequence[Level]) -> tuple[float, ...]:
    return tuple(x.factor for x in levels)


def _dofs(levels: Sequence[Level]) -> tuple[int, ...]:
    return tuple(x.dofs for x in levels)
