"""results.json: a run's result (pipeline.analysis.result.RunResult) as the JSON document
of docs/design.md §7. It formats what the analysis decided and decides nothing."""
from __future__ import annotations

from geometry.table import model_share, published

from pipeline.analysis.level import Level
from pipeline.analysis.pilot import PILOT_FRACTION
from pipeline.analysis.result import PeakAnswer, RunResult
from pipeline.output.flat import own_row
from pipeline.output.provenance import about, complete
from pipeline.post import formulas
from pipeline.post.errorbar import METHOD_TEXT
from pipeline.post.peaks import MIDPOINT, UNAVERAGED

DEFINITION = {
    MIDPOINT: "a peak at the shoulder fillet: the largest over the fillet's nodes of the midpoint of a node's two "
              "readings, its largest element-node von Mises value without averaging (unaveraged_MPa; above the true "
              "peak there, measured) and the von Mises of its nodal-averaged stress (averaged_MPa; mostly below it). "
              "The global peak is the larger of this and the largest unaveraged value elsewhere; fields.vtu holds "
              "the reported value at every node (von_mises_reported_MPa)",
    UNAVERAGED: "the largest over the nodes of a node's largest element-node von Mises value without averaging "
                "(unaveraged_MPa); the von Mises of the nodal-averaged stress at that node is shown beside it "
                "(averaged_MPa); fields.vtu holds the reported value at every node (von_mises_reported_MPa)",
}


def results_json(result: RunResult, files: dict[str, str], timings_s: dict[str, float]) -> dict:
    """The whole results.json content: ``files`` the run's files by key, ``timings_s`` the
    output stages' times (s) added to the analysis's."""
    r, case = result, result.case
    res = {
        "about": about(case.document.as_dict()),
        "units": {"length": "mm", "force": "N", "stress": "MPa"},
        "case": case.as_dict(),
        "analytic": analytic_block(r),
        "fe": fe_block(r),
        "comparison_pct": dict(r.comparison_pct),
        "timings_s": {**{k: v for k, v in r.timings.items() if k != "analysis"}, **timings_s},
        "files": dict(files),
        "notes": list(r.notes),
    }
    if r.load_rows is not None:
        res["load_sweep"] = [row.as_dict() for row in r.load_rows]
        res["load_sweep_verdict"] = r.loads_verdict
    if r.sensitivity is not None:
        res["sensitivity"] = [e.as_dict() for e in r.sensitivity.entries]
        res["sensitivity_summary"] = sensitivity_summary(r)
    if r.convergence is not None:
        res["convergence"] = convergence_block(r, res["fe"])
    return complete(res, own_row(res))


def peak_block(p: PeakAnswer) -> dict:
    """One peak's block (MPa, mm): value, place, how it is read, its error estimate, the
    singular feature it sits at (then no converged value), why it is not wanted and its
    status (pipeline.analysis.words)."""
    rd = p.reading
    return {"value_MPa": rd.value_MPa, "location_mm": list(rd.location_mm), "feature": p.feature,
            "definition": DEFINITION[rd.rule], "error_bar_method": METHOD_TEXT[rd.rule],
            "unaveraged_MPa": rd.unaveraged.value_MPa, "averaged_MPa": rd.averaged.value_MPa,
            "averaged_location_mm": list(rd.averaged.location_mm),
            "error_estimate": None if p.estimate is None else p.estimate.as_dict(),
            "singular_feature": p.singular, "not_wanted": p.not_wanted, "status": p.status}


def fe_block(r: RunResult) -> dict:
    """results.json's "fe": the requested mesh's peaks, solver and equilibrium figures,
    safety factors, sections, verdicts and every mesh's row (N, MPa, mm). A peak the run
    was not asked for (want) has no value in ``peak_MPa`` / ``critical_peak_MPa``, the
    answers a program reads: null there, its reading in ``*_unresolved_MPa``."""
    case, fine, pl = r.case, r.requested, r.places
    safety = {}
    for key, sf in r.safety.items():
        safety[key], safety[f"{key}_note"] = sf.value, sf.note
    answer = {k: (None if p.not_wanted else p.value_MPa, p.value_MPa if p.not_wanted else None)
              for k, p in r.peaks.items()}
    return {
        "peak_MPa": answer["peak"][0],
        "peak_unresolved_MPa": answer["peak"][1],
        "peak_location_mm": list(fine.peak.location_mm),
        "critical_peak_MPa": answer["critical"][0],
        "critical_peak_unresolved_MPa": answer["critical"][1],
        "critical_location_mm": list(fine.critical.location_mm),
        "peak": peak_block(r.peaks["peak"]),
        "critical": peak_block(r.peaks["critical"]),
        "dofs": fine.dofs, "cells": fine.cells, "order": case.order,
        "model": case.model, "support": case.support, "solver": case.solver,
        "iterations": fine.iterations, "residual_rel": fine.residual_rel,
        "scaled_from": fine.scaled_from,
        "equilibrium_error_N": fine.equilibrium_error_N,
        "constraint_reaction_N": fine.constraint_reaction_N,
        "seat_force_N": fine.seat_force_N, "support_force_N": fine.support_force_N,
        "model_load_share": model_share(case.model),
        "mesh_min_jacobian_ratio": fine.jacobian_ratio,
        **safety,
        "mpi_ranks": r.mpi_ranks,
        "refined_at_mm": [list(p) for p in pl.hotspots],
        "refined_places_from": pl.source,
        "refined_bridging_places": pl.bridging,
        "pilot_mesh_factor": pl.factor,
        "pilot_fraction": PILOT_FRACTION,
        "sections": None if fine.sections is None else {"formula_load": None, **fine.sections},
        "verdict": {k: v.as_dict() for k, v in r.verdicts.items()},
        "levels": [level_row(lv) for lv in r.levels],
        "accuracy": None if r.accuracy is None else r.accuracy.as_dict(),
    }


def level_row(lv: Level) -> dict:
    """One mesh's row of results.json's "levels" (MPa, s)."""
    return {"mesh_factor": lv.factor, "dofs": lv.dofs, "cells": lv.cells,
            "peak_MPa": lv.peak.value_MPa, "critical_peak_MPa": lv.critical.value_MPa,
            "peak_unaveraged_MPa": lv.peak.unaveraged.value_MPa,
            "peak_averaged_MPa": lv.peak.averaged.value_MPa,
            "critical_unaveraged_MPa": lv.critical.unaveraged.value_MPa,
            "critical_averaged_MPa": lv.critical.averaged.value_MPa,
            "iterations": lv.iterations, "scaled_from": lv.scaled_from,
            "time_s": sum(lv.timings.values())}


def analytic_block(r: RunResult) -> dict:
    """results.json's "analytic": the paper's two hand formulas worked for the case (MPa,
    mm, N), with the published values where the case's row has them."""
    hand: formulas.HandResults = r.hand
    ex, ap = hand.exact, hand.approximate
    return {
        "approximate_MPa": ap.sigma_MPa, "exact_MPa": ex.sigma_MPa,
        "approximate_span_mm": ap.span_mm, "exact_span_mm": ex.span_mm,
        "approximate_terms": {"lever_mm": ap.lever_mm, "Me_Nmm": ap.Me_Nmm},
        "exact_terms": {"N1_N": ex.N1_N, "M1_Nmm": ex.M1_Nmm, "N2_N": ex.N2_N,
                        "M2_Nmm": ex.M2_Nmm, "R_mm": ex.R_mm, "F_mm2": ex.F_mm2,
                        "W_mm3": ex.W_mm3},
        "consistent_span": {
            "approximate_at_exact_span_MPa": hand.approximate_at_exact_span.sigma_MPa,
            "exact_at_approximate_span_MPa": hand.exact_at_approximate_span.sigma_MPa},
        "published": published(r.case.size, r.case.load_N, ap.span_mm, ex.span_mm),
    }


def sensitivity_summary(r: RunResult) -> dict:
    """results.json's ``sensitivity_summary``: the variants' mesh factor, the noise of a
    single such mesh (MPa), the inputs not varied, what flips, the ends not analysed, the
    one sentence, its time (s) and the contact study's effect."""
    s = r.sensitivity
    a = s.analysis
    return {"mesh_factor": a.mesh_factor, "noise_MPa": dict(s.noise_MPa), "noise_mesh": a.second_mesh,
            "not_varied": dict(a.not_varied), "flips": [f.as_dict() for f in s.flips], "invalid": list(s.invalid),
            "sentence": s.sentence, "time_s": a.time_s, "contact_study": s.contact_study}


def convergence_block(r: RunResult, fe: dict) -> dict:
    """A convergence study's block: the ratio, every mesh's row with its error against the
    extrapolated value (%), both peaks' estimates and where each mesh's peaks sit."""
    c = r.convergence
    rows = fe["levels"]   # the same rows as fe.levels: they carry the errors too
    for key in ("peak", "critical"):
        for row, err in zip(rows, c["errors_pct"][key]):
            row[f"{key}_error_pct"] = err
    return {"ratio": r.options.ratio, "levels": rows,
            "peak": fe["peak"]["error_estimate"], "critical": fe["critical"]["error_estimate"],
            "peak_features": c["peak_features"], "critical_features": c["critical_features"],
            "not_wanted": {k: fe[k]["not_wanted"] for k in ("peak", "critical") if fe[k].get("not_wanted")}}
