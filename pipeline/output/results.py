"""results.json: the content of a run's results file, built from the solved levels."""
from __future__ import annotations

from mpi4py import MPI

from geometry.table import published

from pipeline.post import formulas
from pipeline.inputs.case import Case
from pipeline.output.provenance import about
from pipeline.post.errorbar import METHOD_TEXT, Estimate, estimate_levels, singular_override, verdict_against
from pipeline.post.features import describe_location, singular_feature
from pipeline.analysis.level import Level
from pipeline.post.peaks import MIDPOINT, UNAVERAGED, NodalPeak
from pipeline.analysis.pilot import PILOT_FRACTION, Pilot
from pipeline.analysis.tolerance import Accuracy
from pipeline.analysis.sensitivity import CHECKED, CONTACT_STUDY, Sensitivity, journal_root
from pipeline.output.report import range_text, value_text


DEFINITION = {
    MIDPOINT: "a peak at the shoulder fillet: the midpoint of two nodal readings over the fillet, the largest "
              "element-node von Mises value without averaging (unaveraged_MPa; above the true peak there, measured) and "
              "the largest von Mises value of the nodal-averaged stress (averaged_MPa; mostly below it). The global "
              "peak is the larger of this and the largest unaveraged value elsewhere",
    UNAVERAGED: "the largest element-node von Mises value without averaging (unaveraged_MPa); the largest "
                "value of the nodal-averaged stress over the same region is shown beside it (averaged_MPa)",
}



def pct(a: float, b: float) -> float:
    """Percentage difference of a relative to b."""
    return 100.0 * (a - b) / b


def build_results(case: Case, levels: list[Level], timings: dict[str, float],
                  comm: MPI.Comm = MPI.COMM_WORLD, pl: Pilot | None = None) -> dict:
    """The results.json content of docs/design.md §7 from the solved levels (finest first)."""
    fine = levels[0]
    hand = formulas.hand_results(case.dims, case.load_N, case.approximate_span_mm,
                                 case.exact_span_mm)
    est_peak = estimate_levels(levels, case.order, "peak") if len(levels) >= 3 else None
    est_crit = estimate_levels(levels, case.order, "critical") if len(levels) >= 3 else None
    asked = {"global": case.want != "critical", "critical": case.want != "global"}
    peak_b = peak_block(case, fine.peak, est_peak, refined=asked["global"])
    crit_b = peak_block(case, fine.critical, est_crit, refined=asked["critical"])
    for name, block in (("global", peak_b), ("critical", crit_b)):
        if not asked[name]:
            block["not_wanted"] = (f"want = {case.want}: the run did not refine for the {name} peak; "
                                   "shown for orientation only")
    return {
        "about": about(case.document.as_dict()),
        "units": {"length": "mm", "force": "N", "stress": "MPa"},
        "case": case.as_dict(),
        "analytic": _analytic_block(case, hand),
        "fe": _fe_block(case, levels, peak_b, crit_b, comm, pl),
        "comparison_pct": {
            "critical_vs_exact": pct(fine.critical.value_MPa, hand.exact.sigma_MPa),
            "critical_vs_approximate": pct(fine.critical.value_MPa, hand.approximate.sigma_MPa),
            "peak_vs_exact": pct(fine.peak.value_MPa, hand.exact.sigma_MPa),
            "peak_vs_approximate": pct(fine.peak.value_MPa, hand.approximate.sigma_MPa),
            **_like_with_like_pct(fine),
        },
        "timings_s": timings,
    }


def _like_with_like_pct(fine: Level) -> dict[str, float]:
    """Per formula, the FE section's figure under the formula's own load position against
    the formula at that same position (%), ``section_vs_approximate_same_load`` and
    ``section_vs_exact_same_load``: they differ in their theory only. None without those
    sections (support rigid)."""
    rows = (fine.sections or {}).get("formula_load") or {}
    return {f"section_vs_{k}_same_load": pct(rows[k]["fe_MPa"], rows[k]["formula_at_fe_load_MPa"]) if k in rows else None
            for k in ("approximate", "exact")}


def peak_block(case: Case, p: NodalPeak, est: Estimate | None, refined: bool = True) -> dict:
    """One peak's results.json block (MPa, mm): value, place, how it is read, its error
    estimate, and the singular feature it sits at, if any (then no converged value).
    ``refined``: the meshes were refined for this peak; if not (a peak the run was not asked
    for), its growth over the meshes is that of unrefined meshes and does not make it
    singular."""
    block = {"value_MPa": p.value_MPa, "location_mm": list(p.location_mm),
             "feature": describe_location(case, p.location_mm),
             "definition": DEFINITION[p.rule], "error_bar_method": METHOD_TEXT[p.rule],
             "unaveraged_MPa": p.unaveraged.value_MPa, "averaged_MPa": p.averaged.value_MPa,
             "averaged_location_mm": list(p.averaged.location_mm)}
    est, singular = singular_override(est, singular_feature(case, p.location_mm), block["feature"], refined)
    block["error_estimate"] = None if est is None else est.as_dict()
    block["singular_feature"] = singular
    block["not_wanted"] = None  # set by build_results for a peak the run was not asked for
    return block


def _fe_block(case: Case, levels: list[Level], peak_b: dict, crit_b: dict, comm, pl: Pilot | None) -> dict:
    """results.json's "fe": the requested mesh's peaks, solver and equilibrium figures,
    safety factors, sections, verdicts and every mesh's row (N, MPa, mm)."""
    fine = levels[0]
    return {
        "peak_MPa": fine.peak.value_MPa,
        "peak_location_mm": list(fine.peak.location_mm),
        "critical_peak_MPa": fine.critical.value_MPa,
        "critical_location_mm": list(fine.critical.location_mm),
        "peak": peak_b,
        "critical": crit_b,
        "dofs": fine.dofs, "cells": fine.cells, "order": case.order,
        "model": case.model, "support": case.support, "solver": case.solver,
        "iterations": fine.iterations, "residual_rel": fine.residual_rel,
        "scaled_from": fine.scaled_from,
        "equilibrium_error_N": fine.equilibrium_error_N,
        "constraint_reaction_N": fine.constraint_reaction_N,
        "seat_force_N": fine.seat_force_N, "support_force_N": fine.support_force_N,
        "model_load_share": 0.25 if case.model == "quarter" else 1.0,
        "mesh_min_jacobian_ratio": fine.jacobian_ratio,
        **safety_factors(case.allowable_MPa, {"safety_factor": (fine.peak.value_MPa, peak_b),
                                               "critical_safety_factor": (fine.critical.value_MPa, crit_b)}),
        "mpi_ranks": comm.size,
        "refined_at_mm": [] if pl is None else [list(p) for p in pl.hotspots],
        "refined_places_from": None if pl is None else pl.source,
        "refined_bridging_places": None if pl is None else pl.bridging,
        "pilot_mesh_factor": None if pl is None else pl.factor,
        "pilot_fraction": PILOT_FRACTION,
        "sections": None if fine.sections is None else {"formula_load": None, **fine.sections},
        "verdict": verdict(case.allowable_MPa, case.load_N, _checked_stresses(fine, peak_b, crit_b)),
        "levels": [_level_row(lv) for lv in levels],
        "accuracy": None,   # set by add_accuracy for a run asked for a tolerance
    }


def _checked_stresses(fine: Level, peak_b: dict, crit_b: dict) -> dict[str, tuple[float, dict | None]]:
    """What the verdict checks: both peaks with their blocks, and the nominal stresses of
    the sections the run has (MPa, no block: they carry no error bar)."""
    checks: dict[str, tuple[float, dict | None]] = {
        "global_peak": (fine.peak.value_MPa, peak_b), "critical_peak": (fine.critical.value_MPa, crit_b)}
    if fine.sections and "critical_section" in fine.sections:
        checks["critical_section_nominal"] = (fine.sections["critical_section"]["nominal_MPa"], None)
    if fine.sections:
        checks["journal_root_nominal"] = (fine.sections["journal_root"]["nominal_MPa"], None)
    return checks


def _level_row(lv: Level) -> dict:
    """One mesh's row of results.json's "levels" (MPa, s)."""
    return {"mesh_factor": lv.factor, "dofs": lv.dofs, "cells": lv.cells,
            "peak_MPa": lv.peak.value_MPa, "critical_peak_MPa": lv.critical.value_MPa,
            "peak_unaveraged_MPa": lv.peak.unaveraged.value_MPa,
            "peak_averaged_MPa": lv.peak.averaged.value_MPa,
            "critical_unaveraged_MPa": lv.critical.unaveraged.value_MPa,
            "critical_averaged_MPa": lv.critical.averaged.value_MPa,
            "iterations": lv.iterations, "scaled_from": lv.scaled_from,
            "time_s": sum(lv.timings.values())}


def _analytic_block(case: Case, hand: formulas.HandResults) -> dict:
    """results.json's "analytic": the paper's two hand formulas worked for the case (MPa,
    mm, N), with the published values where the case's row has them."""
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
        "published": published(case.size, case.load_N, ap.span_mm, ex.span_mm),
    }


def safety_factors(allowable_MPa: float, peaks: dict[str, tuple[float, dict]]) -> dict:
    """{key: allowable / peak} for each (peak MPa, peak block); a peak at a singular feature
    has no finite value, so its key is None and ``<key>_note`` says why (docs/design.md §5)."""
    out: dict = {}
    for key, (value, block) in peaks.items():
        where = block.get("singular_feature")
        out[key] = None if where or block.get("not_wanted") else allowable_MPa / value
        out[f"{key}_note"] = None
        # A peak the run did not refine for says so first: its trend over the meshes, singular
        # or not, is that of an unrefined mesh.
        if block.get("not_wanted"):
            out[f"{key}_note"] = block["not_wanted"]
        elif where:
            out[f"{key}_note"] = f"the peak sits at a singular feature ({where}) and has no finite value"
    return out


def verdict(allowable_MPa: float, load_N: float, checks: dict[str, tuple[float, dict | None]]) -> dict:
    """Pass or fail of each checked stress against the allowable (MPa), with its margin and
    error bar, and the hook load (N) that would bring it to the allowable (linear scaling:
    the part's capacity at that allowable). ``checks``: name -> (value MPa, peak block or
    None for a nominal stress). A peak at a singular feature gets no verdict; a band that
    straddles the allowable gives "undecided"."""
    out = {}
    for name, (value, block) in checks.items():
        if block is not None and (block.get("singular_feature") or block.get("not_wanted")):
            why = (block["not_wanted"] if block.get("not_wanted") else
                   f"the peak sits at a singular feature ({block['singular_feature']}): no finite value")
            out[name] = {"value_MPa": value, "band_MPa": None, "verdict": "none", "margin_pct": None,
                         "capacity_N": None, "capacity_range_N": None, "why": why}
            continue
        # No band (a nominal stress, or a peak read on one mesh): null, not a band of zero.
        band = ((block or {}).get("error_estimate") or {}).get("band")
        lo, hi = value - (band or 0.0), value + (band or 0.0)
        status = verdict_against(value, band, allowable_MPa)
        out[name] = {"value_MPa": value, "band_MPa": band, "verdict": status,
                     "margin_pct": 100 * (allowable_MPa / value - 1),
                     "capacity_N": load_N * allowable_MPa / value,
                     "capacity_range_N": [load_N * allowable_MPa / hi, load_N * allowable_MPa / lo]
                     if band is not None and lo > 0 else None, "why": None}
    return out


def sum_timings(levels: list[Level], pl: Pilot | None = None) -> dict[str, float]:
    """Per-stage times (s): the requested mesh's stages, the pilot's and the error-bar meshes' totals."""
    stages = ("geometry", "mesh", "import", "assemble", "solve", "post")
    out = {k: levels[0].timings.get(k, 0.0) for k in stages}
    if pl is not None:
        out["pilot"] = pl.time_s
    out["error_bar_meshes"] = sum(sum(lv.timings.values()) for lv in levels[1:])
    return out


def load_sweep(res: dict, case: Case, loads: list[float]) -> list[dict]:
    """Peaks, formula stresses and safety factors (MPa) at each load (N), scaled linearly."""
    fe, an = res["fe"], res["analytic"]
    rows = []
    # A peak the run was not asked for (want) has no value or band at any load.
    asked = {key: not fe[key].get("not_wanted") for key in ("peak", "critical")}
    for q in loads:
        k = q / case.load_N
        row = {"load_N": q, "peak_MPa": k * fe["peak_MPa"] if asked["peak"] else None,
               "critical_peak_MPa": k * fe["critical_peak_MPa"] if asked["critical"] else None,
               "approximate_MPa": k * an["approximate_MPa"], "exact_MPa": k * an["exact_MPa"]}
        for key, name in (("peak", "peak_band_MPa"), ("critical", "critical_band_MPa")):
            band = (fe[key].get("error_estimate") or {}).get("band")
            row[name] = None if band is None or not asked[key] else k * band
        for key, peak in (("safety_factor", "peak_MPa"), ("critical_safety_factor", "critical_peak_MPa")):
            row[key] = None if fe[key] is None else case.allowable_MPa / row[peak]
        rows.append(row)
    return rows


def add_accuracy(res: dict, acc: Accuracy) -> None:
    """Put what the run was asked and reached into ``res["fe"]["accuracy"]``
    (pipeline/analysis/tolerance.py): the tolerance and each wanted peak's band (% of its
    value), whether every band is within it, whether the mesh was pinned, the error bar's
    mesh factors, every mesh factor solved, the steps taken and why the tolerance was not
    met (empty when it was)."""
    res["fe"]["accuracy"] = acc.as_dict()


def add_sensitivity(res: dict, sens: Sensitivity, case: Case) -> None:
    """Put the sensitivity analysis (pipeline/analysis/sensitivity.py) into ``res``: the
    list ``sensitivity`` (per input its range and, at its low and high end, each peak, the
    critical-section and journal-root nominal stress (MPa), the capacity (N) and the
    verdicts), ``sensitivity_summary`` (its mesh, noise, what flips, the one sentence) and
    its wall time under timings_s (s)."""
    vals = run_values_of(res)
    verdicts = res["fe"].get("verdict") or {}
    entries = sensitivity_entries(sens, vals, verdicts, case)
    res["sensitivity"] = entries
    res["sensitivity_summary"] = sensitivity_summary(sens, entries, vals, verdicts)
    res["sensitivity_summary"]["contact_study"] = contact_study_effect(case, vals, verdicts)
    res["timings_s"]["sensitivity"] = sens.time_s


def contact_study_effect(case: Case, run_values: dict[str, float | None], verdicts: dict) -> dict | None:
    """The load model's measured effect on the peaks: the contact study's changes of the
    fillet's peak and of the critical peak against the cos θ model (CONTACT_STUDY, %, measured
    on one size) applied to this run's global and critical peak (MPa), with the verdict at
    each end; None when the run's load model is not the one the study was measured against
    (support "bearing", cos θ over the whole bearing surface)."""
    if case.support != "bearing" or case.bearing_shape != "cosine" or not case.bearing_band().whole:
        return None
    cs = CONTACT_STUDY

    def applied(key: str, pct: tuple[float, float]) -> dict:
        v = run_values.get(key)
        vals = [None if v is None else v * (1 + p / 100) for p in pct]
        run = verdicts.get(key) or {}
        band = run.get("band_MPa")
        ends = [None if x is None or run.get("verdict") in (None, "none") else
                verdict_against(x, None if band is None else band * x / run["value_MPa"], case.allowable_MPa)
                for x in vals]
        return {"pct": list(pct), "MPa": vals, "verdicts": ends}

    return {"source": cs.source, "measured_on": cs.size,
            "applied_as": f"measured on No. {cs.size}, this size" if str(case.size) == cs.size else
            f"relative changes measured on No. {cs.size}, not on this size",
            "global_peak": applied("global_peak", cs.fillet_range_pct),
            "critical_peak": applied("critical_peak", cs.critical_peak_pct),
            "fillet_peak_pct_by_fit": {k: list(v) for k, v in cs.fillet_peak_pct.items()},
            "edge_of_contact_pct": list(cs.edge_of_contact_pct)}


def scaled(run_value: float | None, variant: float | None, baseline: float | None) -> float | None:
    """An end's value: the run's value × variant / baseline, both read on the sensitivity
    mesh, so that the coarser mesh's bias cancels (MPa); None where one is missing."""
    if run_value is None or variant is None or not baseline:
        return None
    return run_value * variant / baseline


def capacity(load_N: float, allowable_MPa: float, values: dict[str, float | None]) -> float | None:
    """The hook load (N) at which the first of the checked stresses (MPa) reaches the
    allowable: Q·allowable / the largest (linear elasticity, loads only)."""
    vs = [v for v in values.values() if v is not None and v > 0]
    return load_N * allowable_MPa / max(vs) if vs else None


def sensitivity_entries(sens: Sensitivity, run_values: dict[str, float | None], verdicts: dict, case: Case) -> list[dict]:
    """results.json's ``sensitivity`` list (docs/design.md §7, §10): per input its range and
    each checked value at the low and the high end, from the run's values (MPa, by
    results.json's verdict names) scaled by the variants.

    ``verdicts``: results.json's fe.verdict (a stress without a verdict there, a singular
    or unwanted peak, gets none here either, and is left out of the capacity)."""
    attrs = {"global_peak": "peak_MPa", "critical_peak": "critical_MPa",
             "critical_section_nominal": "section_MPa", "journal_root_nominal": "journal_MPa"}
    checked = [k for k in CHECKED if (verdicts.get(k) or {}).get("verdict") not in (None, "none")]
    out = []
    for r, ends, base in zip(sens.ranges, sens.ends, sens.baselines):
        vals = {}
        for key, attr in attrs.items():
            vals[key] = [scaled(run_values.get(key), getattr(e, attr), getattr(base, attr))
                         if e.ok else None for e in ends]
        # The journal root's nominal stress is statics: its value at each end is exact.
        vals["journal_root_nominal"] = [
            journal_root(r.variant(case, v)) if e.invalid is None else None
            for v, e in zip((r.low, r.high), ends)]
        caps = [capacity(case.load_N, case.allowable_MPa, {k: vals[k][i] for k in checked}) if e.ok else None
                for i, e in enumerate(ends)]
        out.append({
            "input": r.input, "kind": r.kind, "unit": r.unit, "nominal": r.nominal, "range": [r.low, r.high],
            "reason": r.reason, "note": r.note,
            "peak_MPa": vals["global_peak"], "critical_peak_MPa": vals["critical_peak"],
            "critical_section_nominal_MPa": vals["critical_section_nominal"],
            "journal_root_nominal_MPa": vals["journal_root_nominal"], "capacity_N": caps,
            "verdicts": [_end_verdicts(vals, i, checked, verdicts, case.allowable_MPa) if e.ok else None
                         for i, e in enumerate(ends)],
            "invalid": [e.invalid or e.failed for e in ends],
        })
    return out


def _end_verdicts(vals: dict[str, list], i: int, checked: list[str], verdicts: dict, allowable: float) -> dict:
    """The verdict of each checked stress at end ``i`` (0 low, 1 high): its value there
    against the allowable (MPa), with the run's band scaled to that value."""
    out = {}
    for key in checked:
        v = vals[key][i]
        if v is None:
            continue
        run = verdicts[key]
        band = run.get("band_MPa")
        out[key] = verdict_against(v, None if band is None else band * v / run["value_MPa"], allowable)
    return out


NAMES = {"global_peak": "global peak", "critical_peak": "critical peak",
         "critical_section_nominal": "critical-section nominal stress",
         "journal_root_nominal": "journal-root nominal stress"}


def sensitivity_summary(sens: Sensitivity, entries: list[dict], run_values: dict[str, float | None], verdicts: dict) -> dict:
    """results.json's ``sensitivity_summary``: the variants' mesh factor, the noise of a
    single such mesh (MPa: the nominal case on two meshes), the inputs not varied, what
    flips and the one sentence that says whether the verdict holds over every range."""
    noise = {}
    for key, attr in (("global_peak", "peak_MPa"), ("critical_peak", "critical_MPa"),
                      ("critical_section_nominal", "section_MPa")):
        a, b, run = getattr(sens.baseline, attr), getattr(sens.second, attr), run_values.get(key)
        noise[key] = abs(a - b) * run / a if sens.baseline.ok and sens.second.ok and None not in (a, b, run) and a \
            else None
    flips = []
    for e in entries:
        for i, end in enumerate(e["verdicts"]):
            for key, v in (end or {}).items():
                if v != verdicts[key]["verdict"]:
                    flips.append({"input": e["input"], "value": e["range"][i], "unit": e["unit"], "stress": key,
                                  "from": verdicts[key]["verdict"], "to": v})
    invalid = [(e["input"], e["range"][i], e["unit"], why) for e in entries for i, why in enumerate(e["invalid"]) if why]
    return {"mesh_factor": sens.mesh_factor, "noise_MPa": noise, "noise_mesh": sens.second_mesh,
            "not_varied": sens.not_varied,
            "flips": flips, "invalid": [{"input": n, "value": v, "why": w} for n, v, _, w in invalid],
            "sentence": verdict_sentence(entries, flips, invalid, verdicts), "time_s": sens.time_s}


def verdict_sentence(entries: list[dict], flips: list[dict], invalid: list[tuple], verdicts: dict) -> str:
    """One sentence: the verdict holds over every range, or flips, on which input."""
    decided = {k: v["verdict"] for k, v in verdicts.items() if v.get("verdict") not in (None, "none")}
    if not entries:
        return "Nothing was varied: every assumed input was set by the user without a range."
    if not decided:
        return "No stress has a verdict (singular or unwanted peaks), so there is no verdict to hold or flip."
    tail = ("" if not invalid else " (not checked at " + ", ".join(f"{n} = {value_text(v, u)}" for n, v, u, _ in invalid)
            + ": invalid or failed variants)")
    if not flips:
        ranges = ", ".join(f"{e['input']} {range_text(e['range'], e['unit'])}" for e in entries)
        return (f"The verdict holds over every range ({ranges}): "
                + ", ".join(f"{NAMES[k]} {v}" for k, v in decided.items()) + f" at both ends{tail}.")
    by_input: dict[str, list[str]] = {}
    for f in flips:
        by_input.setdefault(f["input"], []).append(
            f"{NAMES[f['stress']]} {f['from']} → {f['to']} at {f['input']} = {value_text(f['value'], f['unit'])}")
    return (f"The verdict flips on {', '.join(by_input)}: "
            + "; ".join(s for v in by_input.values() for s in v) + f"{tail}.")


def run_values_of(res: dict) -> dict[str, float | None]:
    """The run's checked values (MPa) from its results.json content, by verdict name."""
    fe = res["fe"]
    sec = fe.get("sections") or {}
    return {"global_peak": fe["peak_MPa"], "critical_peak": fe["critical_peak_MPa"],
            "critical_section_nominal": (sec.get("critical_section") or {}).get("nominal_MPa"),
            "journal_root_nominal": (sec.get("journal_root") or {}).get("nominal_MPa")}

