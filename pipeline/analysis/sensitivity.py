"""What a run's answer rests on: the inputs the case assumed, each varied over a stated
plausible range, and how far that moves the peaks, the critical-section nominal stress and
the capacity (mm, N, MPa; docs/design.md §10).

Why: the error bar says how far the answer is from the exact solution of *this* model
(±0.64 % on No. 05); the assumed journal diameter, fillet radius and seat move the global
peak by −7 % to +31 % over plausible values. A reader must see both.

Each end of a dimension's range is one variant: the case with that one input changed,
analysed on a single mesh coarser than the run's, refined at the places its dimensions
name (features.known_raisers: no pilot solve), over the MPI ranks. The nominal case is
analysed on such a mesh, and its values are the baseline the variants are compared with,
so the mesh's bias cancels: an end's value is the run's value × variant / baseline. A
variant's mesh is the nominal one with its nodes moved onto the variant's dimensions
(pipeline/fe/morph.py), solved on the nominal's set-up (pipeline/fe/resolve.py), unless
the move would squeeze a ring of elements too far: then it is meshed anew
(docs/decisions/0036-sensitivity-variants-by-morphing.md). The nominal case on a second
mesh of the same size, refined at the run's own pilot places instead, measures the noise
of such single meshes (how far another choice of places moves one reading), stated beside
the differences. A load-model choice changes only the right-hand side: its ends are solved
on the operator of one of the run's own meshes (MeshPlan's ``load_variants``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

from mpi4py import MPI

from geometry.part import GeometryError
from geometry.table import InputError, validate
from pipeline.analysis import reuse
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import Level, LevelTask, Problem, peaks_of, set_up
from pipeline.analysis.meshes import MeshPlan, solve_meshes
from pipeline.analysis.pilot import KNOWN, Pilot, inside_refinement, known_places
from pipeline.analysis.ranges import DIMENSION, LOAD_MODEL, Range, invalid_load, ranges_of, same_load
from pipeline.errors import NumericalError
from pipeline.fe.loads import crosshead_loads, equilibrium
from pipeline.fe.morph import Mover, MorphError, as_variant, remesh_reason
from pipeline.fe.resolve import ResolveOptions, Resolver
from pipeline.inputs.case import Case
from pipeline.post.sections import journal_nominal, section_results
from pipeline.runtime.idle import wait_for_ranks

# The dimension variants' mesh: the run's mesh factor × this, refined at the places the
# dimensions name (docs/design.md §10 gives its noise against the changes it reports).
MESH_RATIO = 2.2
# The load-model variants' mesh: the run's coarsest error-bar mesh of the default three at
# ratio 1.3, whose operator they are solved on beside the other error-bar mesh.
LOAD_MESH_RATIO = 1.69
NOISE_RATIO = 1.1  # without the run's pilot places, the second nominal mesh is this much coarser
# The relative work of one job, to spread them over the ranks: a variant meshed and set up
# anew, one moved from its rank's nominal mesh (the matrices and CG only), and what a rank
# pays once to hold that nominal mesh and its set-up (docs/decisions/0036-sensitivity-variants-by-morphing.md).
FRESH_COST, MOVED_COST, BASE_COST = 1.8, 0.6, 0.8
# The iterative solver's relative tolerance of every job of the section (the nominal's
# too, so that variant / nominal compares like with like): the readings move by a few
# 1e-4 MPa from those at the run's 1e-8, far below the section's noise, in two thirds of
# the iterations (docs/decisions/0036-sensitivity-variants-by-morphing.md).
RTOL = 1e-5


@dataclass(frozen=True)
class Reading:
    """One variant analysed on the sensitivity mesh (MPa): both peaks, the critical
    section's nominal stress (None without the quarter model's section) and the journal
    root's; or why it has none (``invalid``: the variant breaks a geometry rule;
    ``failed``: its mesh or solve failed); where its critical peak sits (mm), when known."""

    peak_MPa: float | None = None
    critical_MPa: float | None = None
    section_MPa: float | None = None
    journal_MPa: float | None = None
    invalid: str | None = None
    failed: str | None = None
    critical_at: tuple[float, float, float] | None = None

    @property
    def ok(self) -> bool:
        return self.invalid is None and self.failed is None


@dataclass
class Sensitivity:
    """The sensitivity analysis of a run: each range with the readings at its two ends and
    the reading they are compared with (a dimension's: the nominal case on the variants'
    mesh; a load-model choice's: the run's requested mesh, which its ends were solved on),
    the nominal case's reading on the variants' mesh and on a second mesh (the noise), the
    variants' mesh factor, which assumed inputs were not varied and why, and its wall time
    (s)."""

    ranges: list[Range]
    ends: list[tuple[Reading, Reading]]
    baselines: list[Reading]  # per range, what its ends are compared with
    baseline: Reading
    second: Reading
    mesh_factor: float
    not_varied: dict[str, str] = field(default_factory=dict)
    time_s: float = 0.0
    second_mesh: str = ""  # which mesh the noise was measured on, in words


def read_level(case: Case, lv: Level) -> Reading:
    """The values of one analysed variant (MPa)."""
    sec = lv.sections or {}
    return Reading(peak_MPa=lv.peak.value_MPa, critical_MPa=lv.critical.value_MPa,
                   section_MPa=(sec.get("critical_section") or {}).get("nominal_MPa"),
                   journal_MPa=journal_root(case))


def journal_root(case: Case) -> float:
    """The journal root's nominal bending stress 32·M/(π·dj³) of a case (MPa), M from Q/2 at
    the middle of its bearing band (statics, docs/design.md §5)."""
    return journal_nominal(case.dims, case.load_N, case.bearing_band().centre_mm)[1]


def analyse_variant(case: Case, factor: float, places: Sequence[tuple[float, float, float]] | None = None
                    ) -> Reading:
    """One variant on this rank alone: a single mesh at ``factor`` refined at ``places``
    (mm; None: the places its own dimensions name, features.known_raisers, with the pilot
    as solve_meshes' fallback when the critical peak falls outside them); a variant that
    breaks a geometry rule, or whose mesh or solve fails, says so."""
    try:
        validate(case.dims)
    except InputError as exc:
        return Reading(invalid=" ".join(str(exc).split()))
    variant = replace(case, mesh_factor=factor)
    pl = known_places(variant) if places is None else Pilot(factor=None, hotspots=tuple(places), time_s=0.0)
    try:
        lv, _ = solve_meshes(variant, MeshPlan(factors=(factor,)), pl, RunContext(comm=MPI.COMM_SELF))
    except (NumericalError, GeometryError) as exc:
        return Reading(failed=" ".join(str(exc).split()))
    return read_level(variant, lv[0])


Places = Sequence[tuple[float, float, float]]
NOMINAL, FRESH, MOVED = "nominal", "fresh", "moved"  # how a job is analysed


@dataclass(frozen=True)
class Job:
    """One reading the section needs: a case at mesh ``factor`` refined at ``places`` (None:
    its dimensions' own), how it is analysed (NOMINAL: the base mesh that MOVED variants are
    moved from; FRESH: a mesh of its own), and its progress line's label."""

    case: Case
    factor: float
    places: Places | None
    how: str
    label: str


def jobs_of(case: Case, ranges: Sequence[Range], places: Pilot | None) -> list[Job]:
    """The jobs of the dimension ranges, in order: the nominal case, the noise's second
    mesh (at the run's pilot ``places`` when it has its own, else NOISE_RATIO coarser), then
    each range's low and high end; an end the move cannot reach is meshed anew."""
    factor = case.mesh_factor * MESH_RATIO
    known = known_places(replace(case, mesh_factor=factor)).hotspots
    own = places is not None and places.source != KNOWN and tuple(places.hotspots) != tuple(known)
    case = replace(case, rtol=max(case.rtol, RTOL))
    base = NOMINAL if case.order == 2 and case.solver == "pmg" else FRESH  # what resolve.py solves
    jobs = [Job(case, factor, None, base, "nominal"),
            Job(case, factor, places.hotspots, FRESH, "nominal, the run's places") if own
            else Job(case, factor * NOISE_RATIO, None, FRESH, "nominal, 2nd mesh")]
    for r in ranges:
        for v in (r.low, r.high):
            c = r.variant(case, v)
            how = MOVED if _movable(case, c) else FRESH
            jobs.append(Job(c, factor, None, how, f"{r.input} = {v:.4g} {r.unit}" + (", meshed anew" if how == FRESH
                                                                                     else "")))
    return jobs


def _movable(case: Case, variant: Case) -> bool:
    """Whether the variant's mesh can be the nominal one moved: a valid variant the move
    reaches without squeezing a ring of elements too far, of a P2 case solved by the
    p-multigrid (what pipeline/fe/resolve.py solves)."""
    if case.order != 2 or case.solver != "pmg":
        return False
    try:
        validate(variant.dims)
    except InputError:
        return False
    return remesh_reason(case.dims, variant.dims) is None


def spread(jobs: Sequence[Job], ranks: int) -> list[int]:
    """The rank that analyses each job: the nominal on rank 0, then the others, the dearest
    first, each to the rank that would finish it soonest; a rank's first moved variant also
    pays for holding the nominal mesh (FRESH_COST, MOVED_COST, BASE_COST), and the nominal
    job is solved on that set-up as a moved variant is."""
    load, holds, out = [0.0] * ranks, [False] * ranks, [0] * len(jobs)
    cost = {FRESH: FRESH_COST, MOVED: MOVED_COST, NOMINAL: MOVED_COST}
    for k in sorted(range(len(jobs)), key=lambda k: (jobs[k].how != NOMINAL, -cost.get(jobs[k].how, 0.0), k)):
        how = jobs[k].how

        def finish(r: int) -> float:
            return load[r] + cost.get(how, 0.0) + (BASE_COST if how != FRESH and not holds[r] else 0.0)
        r = 0 if how == NOMINAL else min(range(ranks), key=lambda r: (finish(r), r))
        load[r], holds[r], out[k] = finish(r), holds[r] or how != FRESH, r
    return out


def analyse_jobs(jobs: Sequence[Job], comm: MPI.Comm) -> dict[int, Reading]:
    """The readings of this rank's jobs (``jobs`` are every rank's, numbered in order, and
    :func:`spread` says whose): the fresh ones each on a mesh of its own, the nominal and
    moved ones on one nominal mesh moved onto each variant (:func:`moved_readings`)."""
    who = spread(jobs, comm.size)
    mine = [k for k in range(len(jobs)) if who[k] == comm.rank]
    out = {k: analyse_variant(jobs[k].case, jobs[k].factor, jobs[k].places) for k in mine if jobs[k].how == FRESH}
    moved = [k for k in mine if jobs[k].how != FRESH]
    if moved:
        nominal = jobs[0].case
        with_nominal = jobs[moved[0]].how == NOMINAL
        variants = [jobs[k].case for k in moved[1:]] if with_nominal else [jobs[k].case for k in moved]
        readings = moved_readings(nominal, jobs[moved[0]].factor, variants, with_nominal)
        out.update(zip(moved, readings))
    return out


def moved_readings(case: Case, factor: float, variants: Sequence[Case], with_nominal: bool) -> list[Reading]:
    """On this rank alone: the nominal case's reading first when ``with_nominal``, then
    each variant's, on the nominal mesh at ``factor`` refined at its known places with its
    nodes moved onto the variant's dimensions, all solved on one set-up (its preconditioner
    kept, CG started from the last solution). A variant the move cannot reach, or whose
    critical peak falls outside the moved places' refinement, is meshed anew
    (:func:`analyse_variant`)."""
    base = replace(case, mesh_factor=factor)
    ctx = RunContext(comm=MPI.COMM_SELF)
    with reuse.mesher(base.dims, base.model, ctx) as mesher:
        prob = set_up(base, LevelTask(factor, known_places(base).hotspots), replace(ctx, mesher=mesher))
    m, out = prob.mesh, []
    mover = Mover.of(m.mesh, base.dims)
    with Resolver(m.mesh, m.facet_tags, base.order, prob.material, prob.loads.constraints, base.rtol,
                  ResolveOptions(reuse_preconditioner=True)) as solver:
        try:
            if with_nominal:
                out.append(_solved_reading(base, prob, solver))
            for v in variants:
                out.append(_moved_reading(replace(v, mesh_factor=factor), prob, mover, solver))
        finally:
            mover.reset()
    return out


def _moved_reading(v: Case, nominal: Problem, mover: Mover, solver: Resolver) -> Reading:
    """Variant ``v`` on the nominal problem's mesh moved onto its dimensions, or anew."""
    try:
        q = mover.move_to(v.dims)
    except MorphError:
        return analyse_variant(v, v.mesh_factor)
    mv = as_variant(nominal.mesh, v.dims, q)
    lc = crosshead_loads(mv, v.dims, v.load_N, v.support, shape=v.bearing_shape, band=v.bearing_band(), order=v.order)
    rd = _solved_reading(v, Problem(mv, nominal.material, lc, 0.0), solver)
    radius = v.mesh_spec(v.mesh_factor).edge_hotspot_radius
    if rd.critical_at is not None and not inside_refinement(rd.critical_at, known_places(v), radius):
        mover.reset()
        return analyse_variant(v, v.mesh_factor)
    return rd


def _solved_reading(case: Case, prob: Problem, solver: Resolver) -> Reading:
    """The reading of ``case`` on its problem as the mesh's nodes now are, solved by the
    set-up ``solver`` (or an earlier run's solve scaled, pipeline.analysis.reuse.resolved);
    loads checked to balance to 1e-6·Q."""
    try:
        sol = reuse.resolved(case, prob, lambda: solver.solve(prob.loads.tractions), solver.V)
    except NumericalError as exc:
        return Reading(failed=" ".join(str(exc).split()))
    _, eq_err, point_r = equilibrium(prob.loads, sol.reactions)
    limit = 1e-6 * case.load_N
    if not (eq_err <= limit and point_r <= limit):
        return Reading(failed=f"loads out of balance: equilibrium error {eq_err:.3g} N, constraint reaction "
                              f"{point_r:.3g} N (limit {limit:.3g} N)")
    _, pk, crit = peaks_of(case, sol.u, prob.material)
    sym_x = prob.mesh.facet_ids.get("symmetry_x")
    sym_idx = next((i for i, c in enumerate(prob.loads.constraints) if c.component == 0 and c.marker == sym_x
                    and sym_x is not None), None)
    sections = section_results(sol, prob.material, case, sym_idx, pk.value_MPa)
    return Reading(peak_MPa=pk.value_MPa, critical_MPa=crit.value_MPa,
                   section_MPa=(sections.get("critical_section") or {}).get("nominal_MPa"),
                   journal_MPa=journal_root(case), critical_at=crit.location_mm)


def analyse_sensitivity(case: Case, ctx: RunContext, levels: Sequence[Level] = (), places: Pilot | None = None,
                        analyse_one: Callable[[Case, float, Places | None], Reading] | None = None) -> Sensitivity:
    """Every range's two ends and the nominal case, spread over the ranks (each rank on
    MPI.COMM_SELF), gathered on every rank: the variants moved from the nominal mesh where
    they can be (:func:`analyse_jobs`), or each by ``analyse_one`` when it is given (a
    stand-in analysis).

    The noise is the nominal case's value on a second mesh at the same factor refined at
    the run's pilot places (``places``, the run's), or, when the run has none or they are
    the dimensions' own, at the dimensions' places on a mesh NOISE_RATIO coarser. The load
    model's ends come from ``levels`` (the run's: the one that solved them)."""
    say, comm = ctx.say, ctx.comm
    t0 = time.perf_counter()
    ranges, skipped = ranges_of(case)
    if not levels:  # no requested mesh whose operator the load model's variants are solved on
        skipped.update({r.input: "no requested mesh to solve it on" for r in ranges if r.kind == LOAD_MODEL})
        ranges = [r for r in ranges if r.kind == DIMENSION]
    jobs = jobs_of(case, [r for r in ranges if r.kind == DIMENSION], places)
    who = spread(jobs, comm.size) if analyse_one is None else [k % comm.size for k in range(len(jobs))]
    mine: dict[int, Reading] = {}
    error = None
    try:
        mine = (analyse_jobs(jobs, comm) if analyse_one is None else
                {k: analyse_one(j.case, j.factor, j.places) for k, j in enumerate(jobs) if who[k] == comm.rank})
    except Exception as exc:  # re-raised on every rank below
        error = exc
    wait_for_ranks(comm)
    gathered = comm.allgather((mine, error))
    errors = [e for _, e in gathered if e is not None]
    if errors:
        raise errors[0]
    readings = {k: rd for m, _ in gathered for k, rd in m.items()}
    for k, job in enumerate(jobs):
        say(_line(job.label, who[k], readings[k]))
    second = readings[1]
    k = 2  # the first dimension variant's job
    # The load model's ends were solved on one of the run's meshes (MeshPlan's
    # load_variants_at): its nominal reading is their baseline, its variants their ends.
    host = next((lv for lv in levels if lv.load_variants), levels[0] if levels else None)
    run = read_level(case, host) if host is not None else None
    solved = iter(host.load_variants if any(r.kind == LOAD_MODEL for r in ranges) else [])
    ends, baselines = [], []
    for r in ranges:
        if r.kind == DIMENSION:
            ends.append((readings[k], readings[k + 1]))
            baselines.append(readings[0])
            k += 2
            continue
        pair = []
        for v in (r.low, r.high):
            c = r.variant(case, v)
            why = invalid_load(c)
            pair.append(Reading(invalid=why) if why else run if same_load(case, c)
                        else _reading(c, *next(solved)))
            if pair[-1].ok:
                say(f"sensitivity {r.input} = {v if isinstance(v, str) else f'{v:.4g} {r.unit}'} (the run's mesh "
                    f"×{host.factor:.3g}, its operator): peak {pair[-1].peak_MPa:.2f} MPa, "
                    f"critical {pair[-1].critical_MPa:.2f} MPa")
        ends.append((pair[0], pair[1]))
        baselines.append(run)
    factor = jobs[0].factor
    own = jobs[1].places is not None
    how = (f"a mesh ×{factor:.3g} refined at the run's pilot places instead of the dimensions' places" if own
           else f"a mesh ×{factor * NOISE_RATIO:.3g}, refined at the dimensions' places")
    return Sensitivity(ranges=ranges, ends=ends, baselines=baselines, baseline=readings[0], second=second,
                       mesh_factor=factor,
                       not_varied=skipped, time_s=time.perf_counter() - t0, second_mesh=how)


def _reading(case: Case, peak, critical, sections: dict | None) -> Reading:
    """The values (MPa) of a load-model variant solved on the run's mesh (level.Level's
    load_variants)."""
    sec = sections or {}
    return Reading(peak_MPa=peak.value_MPa, critical_MPa=critical.value_MPa,
                   section_MPa=(sec.get("critical_section") or {}).get("nominal_MPa"),
                   journal_MPa=(sec.get("journal_root") or {}).get("nominal_MPa"))


def _line(label: str, rank: int, rd: Reading) -> str:
    """The progress line of one variant."""
    return f"sensitivity {label} (rank {rank}): " + (
        f"peak {rd.peak_MPa:.2f} MPa, critical {rd.critical_MPa:.2f} MPa" if rd.ok
        else f"invalid: {rd.invalid}" if rd.invalid else f"failed: {rd.failed}")
