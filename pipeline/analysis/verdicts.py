"""The run's verdicts, decided here once (mm, N, MPa): each checked stress against the
allowable with its error bar, the safety factors, the rows at every hook load asked
(linear scaling), and the sensitivity section's ends, flips and sentence (docs/design.md
§5, §10). Output code formats what these return."""
from __future__ import annotations

from dataclasses import replace

from pipeline.analysis.result import (Flip, LoadRow, PeakAnswer, SafetyFactor, SensitivityAnswer, SensitivityEntry,
                                      Verdict)
from pipeline.analysis.ranges import CONTACT_STUDY
from pipeline.analysis.sensitivity import Sensitivity, journal_root
from pipeline.analysis.words import FLIPS_OPENING, HOLDS_OPENING, STRESS_NAMES, loads_text, range_text, value_text
from pipeline.fe.linearity import stress_factor
from pipeline.inputs.case import Case
from pipeline.post.errorbar import verdict_against
from pipeline.post.formulas import HandResults

# The stresses a verdict is given for, by their results.json names.
CHECKED = ("global_peak", "critical_peak", "critical_section_nominal", "journal_root_nominal")
# results.json's safety-factor keys, by the peak block they divide.
SAFETY_KEYS = {"peak": "safety_factor", "critical": "critical_safety_factor"}


def safety_factor(allowable_MPa: float, peak: PeakAnswer) -> SafetyFactor:
    """allowable / peak; a peak the run was not asked for, or at a singular feature, has
    none, and the note says why (the unwanted reason first: its trend over the meshes is
    that of an unrefined mesh, singular or not)."""
    if peak.not_wanted:
        return SafetyFactor(None, peak.not_wanted)
    if peak.singular:
        return SafetyFactor(None, f"the peak sits at a singular feature ({peak.singular}) and has no finite value")
    return SafetyFactor(allowable_MPa / peak.value_MPa, None)


def checked_stresses(peaks: dict[str, PeakAnswer], sections: dict | None
                     ) -> dict[str, tuple[float, PeakAnswer | None]]:
    """What the verdict checks (MPa): both peaks, and the nominal stresses of the sections
    the run has (no answer: they carry no error bar)."""
    checks: dict[str, tuple[float, PeakAnswer | None]] = {
        "global_peak": (peaks["peak"].value_MPa, peaks["peak"]),
        "critical_peak": (peaks["critical"].value_MPa, peaks["critical"])}
    if sections and "critical_section" in sections:
        checks["critical_section_nominal"] = (sections["critical_section"]["nominal_MPa"], None)
    if sections:
        checks["journal_root_nominal"] = (sections["journal_root"]["nominal_MPa"], None)
    return checks


def verdicts(allowable_MPa: float, load_N: float, checks: dict[str, tuple[float, PeakAnswer | None]],
             k: float = 1.0) -> dict[str, Verdict]:
    """Pass or fail of each checked stress against the allowable (MPa), with its margin and
    error bar, the hook load (N) that would bring it to the allowable (linear scaling:
    the part's capacity at that allowable) and the safety factor allowable / value. A peak
    at a singular feature, or not asked for, gets no verdict; a band that straddles the
    allowable gives "undecided". ``k``: the checked stresses and their bands are those of
    the case's load × k, ``load_N`` (a load of the run's list: every stress scales with the
    load, the capacity does not)."""
    out = {}
    for name, (value, peak) in checks.items():
        value = k * value
        if peak is not None and not peak.has_verdict:
            why = (peak.not_wanted if peak.not_wanted else
                   f"the peak sits at a singular feature ({peak.singular}): no finite value")
            out[name] = Verdict(value, None, "none", None, None, None, why)
            continue
        # No band (a nominal stress, or a peak read on one mesh): null, not a band of zero.
        band = None if peak is None or peak.band_MPa is None else k * peak.band_MPa
        lo, hi = value - (band or 0.0), value + (band or 0.0)
        out[name] = Verdict(value, band, verdict_against(value, band, allowable_MPa),
                            100 * (allowable_MPa / value - 1), load_N * allowable_MPa / value,
                            [load_N * allowable_MPa / hi, load_N * allowable_MPa / lo]
                            if band is not None and lo > 0 else None, None, allowable_MPa / value)
    return out


def load_rows(case: Case, loads: tuple[float, ...], peaks: dict[str, PeakAnswer], hand: HandResults,
              checks: dict[str, tuple[float, PeakAnswer | None]], sens: Sensitivity | None = None) -> list[LoadRow]:
    """Peaks, formula stresses, safety factors (MPa), the verdict of each checked stress
    (``checks``, at the case's load) and, with ``sens``, the sensitivity sentence at each
    hook load (N), every stress scaled from the case's load (pipeline/fe/linearity.py). A
    peak the run was not asked for has no value or band at any load; a singular one no
    safety factor."""
    rows = []
    for q in loads:
        k = stress_factor(q, case.load_N)
        values = {key: k * p.value_MPa if not p.not_wanted else None for key, p in peaks.items()}
        bands = {key: None if p.band_MPa is None or p.not_wanted else k * p.band_MPa for key, p in peaks.items()}
        sf = {key: None if not p.has_verdict else case.allowable_MPa / values[key] for key, p in peaks.items()}
        judged = verdicts(case.allowable_MPa, q, checks, k)
        said = None if sens is None else sensitivity_answer(sens, judged, replace(case, load_N=q)).sentence
        rows.append(LoadRow(q, values["peak"], values["critical"], k * hand.approximate.sigma_MPa,
                            k * hand.exact.sigma_MPa, bands["peak"], bands["critical"], sf["peak"], sf["critical"],
                            {name: v.verdict for name, v in judged.items()}, said))
    return rows


def loads_verdict(rows: list[LoadRow]) -> str:
    """One sentence: each checked stress's verdict over the run's loads (N), the loads
    grouped by verdict in rising order (every stress scales with the load, so a verdict
    changes once at most: pass, undecided, fail). The largest load governs: a stress that
    passes there passes at every load."""
    order = sorted(rows, key=lambda r: r.load_N)
    parts = []
    for name in order[0].verdicts:
        if order[0].verdicts[name] == "none":
            continue
        groups: list[tuple[str, list[float]]] = []
        for r in order:
            v = r.verdicts[name]
            if groups and groups[-1][0] == v:
                groups[-1][1].append(r.load_N)
            else:
                groups.append((v, [r.load_N]))
        said = (f"{groups[0][0]} at every load" if len(groups) == 1 else
                ", ".join(f"{v} at {loads_text(qs)}" for v, qs in groups))
        parts.append(f"{STRESS_NAMES[name]} {said}")
    top = order[-1]
    if not parts:
        return f"At the loads asked ({loads_text([r.load_N for r in order])}) no stress has a verdict."
    return (f"At the loads asked ({loads_text([r.load_N for r in order])}): " + "; ".join(parts)
            + f". The largest, {top.load_N:g} N, governs.")


def sentence_over_loads(rows: list[LoadRow]) -> str:
    """The sensitivity sentence of a multi-load run: each load's (LoadRow.sensitivity_sentence),
    the loads that share one said together ("At 5000 and 7500 N: ... At 10000 N: ..."), in
    rising load; one sentence for every load when all share it ("At every load asked, 5000
    and 10000 N: ...")."""
    groups: dict[str, list[float]] = {}
    for r in sorted(rows, key=lambda r: r.load_N):
        groups.setdefault(r.sensitivity_sentence or "", []).append(r.load_N)
    if len(groups) == 1:
        (said, qs), = groups.items()
        return f"At every load asked, {loads_text(qs)}: {said}"
    return " ".join(f"At {loads_text(qs)}: {said}" for said, qs in groups.items())


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


def _scaled_verdict(value: float, run: Verdict, allowable_MPa: float) -> str:
    """The verdict of ``value`` (MPa) with the run's band scaled to it."""
    band = None if run.band_MPa is None else run.band_MPa * value / run.value_MPa
    return verdict_against(value, band, allowable_MPa)


def decided_keys(run: dict[str, Verdict]) -> list[str]:
    """The checked stresses that have a verdict (pass, fail or undecided), in CHECKED order."""
    return [k for k in CHECKED if k in run and run[k].verdict != "none"]


def sensitivity_entries(sens: Sensitivity, run: dict[str, Verdict], case: Case) -> list[SensitivityEntry]:
    """Per input its range and each checked value at the low and the high end, from the run's
    values (MPa, by verdict name) scaled by the variants; a stress without a verdict in the
    run gets none here either and is left out of the capacity."""
    attrs = {"global_peak": "peak_MPa", "critical_peak": "critical_MPa",
             "critical_section_nominal": "section_MPa", "journal_root_nominal": "journal_MPa"}
    checked = decided_keys(run)
    out = []
    for r, ends, base in zip(sens.ranges, sens.ends, sens.baselines):
        vals = {key: [scaled(run[key].value_MPa if key in run else None, getattr(e, attr), getattr(base, attr))
                      if e.ok else None for e in ends] for key, attr in attrs.items()}
        # The journal root's nominal stress is statics: its value at each end is exact.
        vals["journal_root_nominal"] = [journal_root(r.variant(case, v)) if e.invalid is None else None
                                        for v, e in zip((r.low, r.high), ends)]
        caps = [capacity(case.load_N, case.allowable_MPa, {k: vals[k][i] for k in checked}) if e.ok else None
                for i, e in enumerate(ends)]
        ends_verdicts = [{k: _scaled_verdict(vals[k][i], run[k], case.allowable_MPa) for k in checked
                          if vals[k][i] is not None} if e.ok else None for i, e in enumerate(ends)]
        out.append(SensitivityEntry(r.input, r.kind, r.unit, r.nominal, [r.low, r.high], r.reason, r.note,
                                    vals["global_peak"], vals["critical_peak"], vals["critical_section_nominal"],
                                    vals["journal_root_nominal"], caps, ends_verdicts,
                                    [e.invalid or e.failed for e in ends]))
    return out


def noise(sens: Sensitivity, run: dict[str, Verdict]) -> dict[str, float | None]:
    """The noise of a single sensitivity mesh (MPa): the nominal case's reading on two such
    meshes, their difference scaled to the run's value."""
    out = {}
    for key, attr in (("global_peak", "peak_MPa"), ("critical_peak", "critical_MPa"),
                      ("critical_section_nominal", "section_MPa")):
        a, b = getattr(sens.baseline, attr), getattr(sens.second, attr)
        v = run[key].value_MPa if key in run else None
        out[key] = abs(a - b) * v / a if sens.baseline.ok and sens.second.ok and None not in (a, b, v) and a else None
    return out


def flips(entries: list[SensitivityEntry], run: dict[str, Verdict]) -> list[Flip]:
    """Every end at which a stress's verdict differs from the run's."""
    out = []
    for e in entries:
        for i, end in enumerate(e.verdicts):
            for key, v in (end or {}).items():
                if v != run[key].verdict:
                    out.append(Flip(e.input, e.range[i], e.unit, key, run[key].verdict, v))
    return out


def sentence(entries: list[SensitivityEntry], flipped: list[Flip], invalid: list[tuple], run: dict[str, Verdict]
             ) -> str:
    """One sentence, true of what was analysed: the verdict holds over every range (only
    when both ends of every range were analysed), or flips, on which input; the ranges an
    end of which could not be analysed are named as such, never counted among those it
    holds over."""
    decided = {k: v.verdict for k, v in run.items() if v.verdict != "none"}
    if not entries:
        return "Nothing was varied: every assumed input was set by the user without a range."
    if not decided:
        return "No stress has a verdict (singular or unwanted peaks), so there is no verdict to hold or flip."
    missing = ", ".join(f"{n} = {value_text(v, u)}" for n, v, u, _ in invalid)
    tail = "" if not invalid else f" (not checked at {missing}: invalid or failed variants)"
    verdict_list = ", ".join(f"{STRESS_NAMES[k]} {v}" for k, v in decided.items())
    if flipped:
        by_input: dict[str, list[str]] = {}
        for f in flipped:
            by_input.setdefault(f.input, []).append(
                f"{STRESS_NAMES[f.stress]} {f.was} → {f.becomes} at {f.input} = {value_text(f.value, f.unit)}")
        return (f"{FLIPS_OPENING} {', '.join(by_input)}: "
                + "; ".join(s for v in by_input.values() for s in v) + f"{tail}.")
    whole = [e for e in entries if not any(e.invalid)]
    if len(whole) == len(entries):
        ranges = ", ".join(f"{e.input} {range_text(e.range, e.unit)}" for e in whole)
        return f"{HOLDS_OPENING} ({ranges}): {verdict_list} at both ends."
    # Some end was not analysed: say where the verdict was seen to hold, and name the rest.
    said = []
    if whole:
        said.append("over the ranges analysed at both ends ("
                    + ", ".join(f"{e.input} {range_text(e.range, e.unit)}" for e in whole) + ")")
    one = [e for e in entries if any(e.invalid) and not all(e.invalid)]
    if one:
        said.append("at the one end analysed of " + ", ".join(
            f"{e.input} ({value_text(e.range[0] if e.invalid[1] else e.range[1], e.unit)})" for e in one))
    if not said:
        return (f"Not checked: no end of any range could be analysed{tail}, so what the verdict rests on is "
                "not known.")
    return (f"The verdict holds {' and '.join(said)}: {verdict_list}; not checked at {missing} (invalid or "
            "failed variants), where no verdict is claimed.")


def contact_study_effect(case: Case, run: dict[str, Verdict]) -> dict | None:
    """The load model's measured effect on the peaks: the contact study's changes of the
    fillet's peak and of the critical peak against the cos θ model (CONTACT_STUDY, %, measured
    on one size) applied to this run's global and critical peak (MPa), with the verdict at
    each end; None when the run's load model is not the one the study was measured against
    (support "bearing", cos θ over the whole bearing surface)."""
    if case.support != "bearing" or case.bearing_shape != "cosine" or not case.bearing_band().whole:
        return None
    cs = CONTACT_STUDY

    def applied(key: str, pct: tuple[float, float]) -> dict:
        r = run.get(key)
        vals = [None if r is None else r.value_MPa * (1 + p / 100) for p in pct]
        ends = [None if x is None or r.verdict == "none" else _scaled_verdict(x, r, case.allowable_MPa) for x in vals]
        return {"pct": list(pct), "MPa": vals, "verdicts": ends}

    return {"source": cs.source, "measured_on": cs.size,
            "applied_as": f"measured on No. {cs.size}, this size" if str(case.size) == cs.size else
            f"relative changes measured on No. {cs.size}, not on this size",
            "global_peak": applied("global_peak", cs.fillet_range_pct),
            "critical_peak": applied("critical_peak", cs.critical_peak_pct),
            "fillet_peak_pct_by_fit": {k: list(v) for k, v in cs.fillet_peak_pct.items()},
            "edge_of_contact_pct": list(cs.edge_of_contact_pct)}


def sensitivity_answer(sens: Sensitivity, run: dict[str, Verdict], case: Case) -> SensitivityAnswer:
    """The sensitivity section decided against the run's verdicts."""
    entries = sensitivity_entries(sens, run, case)
    flipped = flips(entries, run)
    invalid = [(e.input, e.range[i], e.unit, why) for e in entries for i, why in enumerate(e.invalid) if why]
    return SensitivityAnswer(sens, entries, noise(sens, run), flipped,
                             [{"input": n, "value": v, "why": w} for n, v, _, w in invalid],
                             sentence(entries, flipped, invalid, run), contact_study_effect(case, run))
