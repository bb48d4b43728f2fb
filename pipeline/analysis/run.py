"""The run: from a case and its options to the answer, decided (mm, N, MPa).

Read :func:`run` top to bottom: it is everything `crosshead run` computes. It writes no
file and draws nothing; pipeline.output.folder writes what it returns, and every command
(run, converge, a study's variants) and the bench go through it.
"""
from __future__ import annotations

import time
from dataclasses import replace

from pipeline.analysis import reuse
from pipeline.analysis.context import RunContext
from pipeline.analysis.errorbars import PEAKS, peak_estimate
from pipeline.analysis.level import Level
from pipeline.analysis.meshes import MeshPlan
from pipeline.analysis.pilot import Pilot
from pipeline.analysis.result import PeakAnswer, RunResult
from pipeline.analysis.ranges import load_variant_cases
from pipeline.analysis.sensitivity import LOAD_MESH_RATIO, analyse_sensitivity
from pipeline.analysis.tolerance import solve_to_tolerance
from pipeline.analysis.verdicts import (SAFETY_KEYS, checked_stresses, load_rows, loads_verdict, safety_factor,
                                        sensitivity_answer, sentence_over_loads, verdicts)
from pipeline.analysis.words import coarse_mesh_note, peak_status
from pipeline.inputs.case import Case
from pipeline.inputs.options import RunOptions
from pipeline.post import formulas
from pipeline.post.features import describe_location


def run(case: Case, options: RunOptions, ctx: RunContext = RunContext()) -> RunResult:
    """The analysis of ``case`` as ``options`` ask, over the ranks of ``ctx.comm``: both
    peaks with their error bars and statuses, the verdicts against the allowable, the hand
    formulas beside them and, when asked, what the verdict rests on. Raises InputError or
    NumericalError (pipeline.errors) when the case cannot be analysed."""
    t0 = time.perf_counter()
    vary = options.sensitivity and case.want == "both"   # a scene (want) does not vary its inputs
    with reuse.mesher(case.dims, case.model, ctx) as mesher:
        ctx = replace(ctx, mesher=mesher)
        # 1. Where the peaks sit: a coarse pilot solve finds the places within 15 % of a peak
        #    (for the critical peak alone, the bore edges the dimensions name); every mesh is
        #    refined there.
        places = reuse.places(case, ctx)
        factors = options.factors(case)  # finest first: a convergence study's finest is finer than the case's
        case = replace(case, mesh_factor=factors[0])
        # 2. The requested mesh and the error bar's coarser ones, over the ranks; then more
        #    meshes until each wanted peak's band is within the tolerance. The load model's
        #    variants and the hand formulas' load positions ride on those meshes' operators.
        plan = MeshPlan(factors=tuple(factors), formula_loads=options.formula_loads,
                        load_variants=tuple(load_variant_cases(case)) if vary else (),
                        load_variants_at=case.mesh_factor * LOAD_MESH_RATIO, keep_msh=options.outputs.mesh)
        meshes = solve_to_tolerance(case, options, plan, places, ctx)
        case = meshes.case
        # 3. Each peak's error bar and status, decided once.
        peaks = {key: peak_answer(case, meshes.levels, key) for key in PEAKS.values()}
        # 4. The verdicts against the allowable, beside the paper's hand formulas.
        hand = formulas.hand_results(case.dims, case.load_N, case.approximate_span_mm, case.exact_span_mm)
        checks = checked_stresses(peaks, meshes.levels[0].sections)
        judged = verdicts(case.allowable_MPa, case.load_N, checks)
        # 5. What the verdict rests on: each assumed input varied over its plausible range.
        sens = (sensitivity_answer(analyse_sensitivity(case, ctx, meshes.solved, meshes.places), judged, case)
                if vary else None)
        # 6. Every load of a load list: the verdicts and what they rest on at each, scaled.
        rows = load_rows(case, options.loads, peaks, hand, checks, sens and sens.analysis) if options.loads else None
        if rows and sens is not None:  # the sentence speaks for every load, each named
            sens = replace(sens, sentence=sentence_over_loads(rows))
    return RunResult(
        case=case, options=options, places=meshes.places, levels=meshes.levels, solved=meshes.solved, peaks=peaks,
        hand=hand, safety={SAFETY_KEYS[k]: safety_factor(case.allowable_MPa, p) for k, p in peaks.items()},
        verdicts=judged, comparison_pct=comparison_pct(meshes.levels[0], hand), accuracy=meshes.accuracy,
        load_rows=rows, sensitivity=sens, loads_verdict=loads_verdict(rows) if rows else None,
        notes=run_notes(case), timings=stage_timings(meshes.levels, meshes.places, sens and sens.analysis.time_s, t0),
        mpi_ranks=ctx.comm.size, convergence=convergence(case, meshes.levels, peaks) if options.convergence else None)


def peak_answer(case: Case, levels: list[Level], key: str) -> PeakAnswer:
    """The peak ``key`` ("peak" the global one, or "critical") of the requested mesh with its
    error bar over ``levels`` and its status. A peak the run was not asked for (want) is
    shown for orientation only: its growth over the meshes is not a singularity's."""
    name = "global" if key == "peak" else "critical"
    wanted = case.want in ("both", name)
    est, singular = peak_estimate(case, levels, key, refined=wanted)
    reading = getattr(levels[0], key)
    return PeakAnswer(reading=reading, feature=describe_location(case, reading.location_mm), estimate=est,
                      singular=singular,
                      not_wanted=None if wanted else (f"want = {case.want}: the run did not refine for the {name} "
                                                      "peak; shown for orientation only"),
                      status=peak_status(case.tolerance_pct, reading.value_MPa, None if est is None else est.band,
                                         singular, wanted))


def run_notes(case: Case) -> list[str]:
    """What a reader must know beside the numbers, in the words every output prints them
    (pipeline.analysis.words): a mesh too coarse for the fillet."""
    return [n for n in (coarse_mesh_note(case),) if n]


def pct(a: float, b: float) -> float:
    """Percentage difference of a relative to b."""
    return 100.0 * (a - b) / b


def comparison_pct(fine: Level, hand: formulas.HandResults) -> dict[str, float | None]:
    """The FE peaks against both hand formulas (%), and per formula the FE section under
    the formula's own load position against the formula at that same position (%; None
    without those sections): they differ in their theory only."""
    rows = (fine.sections or {}).get("formula_load") or {}
    return {"critical_vs_exact": pct(fine.critical.value_MPa, hand.exact.sigma_MPa),
            "critical_vs_approximate": pct(fine.critical.value_MPa, hand.approximate.sigma_MPa),
            "peak_vs_exact": pct(fine.peak.value_MPa, hand.exact.sigma_MPa),
            "peak_vs_approximate": pct(fine.peak.value_MPa, hand.approximate.sigma_MPa),
            **{f"section_vs_{k}_same_load": pct(rows[k]["fe_MPa"], rows[k]["formula_at_fe_load_MPa"])
               if k in rows else None for k in ("approximate", "exact")}}


def stage_timings(levels: list[Level], places: Pilot, sensitivity_s: float | None, t0: float) -> dict[str, float]:
    """Per-stage times (s): the requested mesh's stages, the pilot's, the error-bar meshes'
    total, the sensitivity section's (when it ran) and the analysis's in all (since ``t0``)."""
    stages = ("geometry", "mesh", "import", "assemble", "solve", "post")
    out = {k: levels[0].timings.get(k, 0.0) for k in stages}
    out["pilot"] = places.time_s
    out["error_bar_meshes"] = sum(sum(lv.timings.values()) for lv in levels[1:])
    if sensitivity_s is not None:
        out["sensitivity"] = sensitivity_s
    out["analysis"] = time.perf_counter() - t0
    return out


def convergence(case: Case, levels: list[Level], peaks: dict[str, PeakAnswer]) -> dict:
    """A convergence study's own figures: where each mesh's peaks sit, and each mesh's error
    against the extrapolated value (%; None for a peak the meshes were not refined for, or
    without an extrapolated value)."""
    out: dict = {"peak_features": [describe_location(case, lv.peak.location_mm) for lv in levels],
                 "critical_features": [describe_location(case, lv.critical.location_mm) for lv in levels],
                 "errors_pct": {}}
    for key, p in peaks.items():
        ext = None if p.not_wanted or p.estimate is None else p.estimate.extrapolated
        out["errors_pct"][key] = [None if ext is None else pct(getattr(lv, key).value_MPa, ext) for lv in levels]
    return out
