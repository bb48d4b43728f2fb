"""report.md from results.json alone (the report reads only what the run wrote)."""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from geometry.table import is_scaled_row
from pipeline.analysis.words import range_text
from pipeline.output import appendix
from pipeline.post.errorbar import SETTLED, SETTLED_BAND

# Why a dimension was assumed: the paper's table does not give it; its default rule.
ASSUMED_WHY = {
    "dj": "journal diameter, 0.8·h (not in the paper's table)",
    "rf": "shoulder fillet radius, 0.06·h (not in the paper's table)",
    "seat_inner": "seat annulus inner diameter (not in the paper's table)",
    "seat_outer": "seat annulus outer diameter (not in the paper's table)",
}
# The journals' bearing pressure in words, by the case's bearing_shape (results.json "case").
BEARING_SHAPE_WORDS = {"cosine": "cos θ bearing pressure", "uniform": "uniform bearing pressure"}
DIM_NAMES = {"b1": "body width and length", "b2": "journal length", "b6": "tip-to-tip length",
             "d14": "bearing track mean diameter Dm", "d2": "bore diameter di",
             "h3": "body height h", "dj": "journal diameter", "rf": "shoulder fillet radius",
             "seat_inner": "seat annulus inner diameter", "seat_outer": "seat annulus outer diameter"}


def without_docs_links(text: str) -> str:
    """``text`` without its parenthesised pointers into the repository's docs/ (the size
    table's notes carry them): the report's reader has the report alone, whose appendix and
    Inputs table state what those pages say."""
    return re.sub(r"\s*\((?:see )?docs/[^)]*\)", "", text)


def _f(x, nd=2) -> str:
    return "—" if x is None else f"{x:,.{nd}f}".replace(",", " ")


def pm(value: float | None, band: float | None) -> str:
    """A peak (MPa) with its error bar when it has one: '114.28 ± 2.37' (the report's, the
    terminal's and a study's tables write it alike)."""
    return _f(value) + ("" if band is None or value is None else f" ± {_f(band)}")


def error_bar_text(block: dict) -> str:
    """One line saying how sure we are of a peak, from its error_estimate."""
    if block.get("not_wanted"):
        return f"not resolved ({block['not_wanted']})"
    est = block.get("error_estimate")
    if est is None:
        return "no error estimate (fewer than three meshes)"
    bracket, trend = est.get("bracket"), est.get("band_trend")
    if bracket is not None and trend is not None and bracket > trend:
        of_trend = dict(est, band=trend, gci_fine=trend / max(abs(est["values"][0]), 1e-300))
        return (f"± {_f(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), half the gap between the unaveraged "
                f"and averaged nodal values; the meshes' trend alone: {_trend_text(of_trend)}")
    return _trend_text(est)


def accuracy_text(acc: dict) -> str:
    """One line on the accuracy asked and reached (results.json's fe.accuracy): the
    tolerance, each wanted peak's band (%), the meshes of the error bar and, when the bands
    stay above the tolerance, why."""
    bands = ", ".join(f"{p} {'no band' if b is None else f'{b:.2f} %'}" for p, b in acc["bands_pct"].items())
    meshes = f"meshes ×{', ×'.join(f'{f:.4g}' for f in acc['mesh_factors'])}"
    extra = len(acc["meshes_solved"]) - len(acc["mesh_factors"])
    solved = f" ({len(acc['meshes_solved'])} solved in all)" if extra > 0 else ""
    if acc["met"]:
        return f"tolerance {acc['tolerance_pct']:g} %: reached, band {bands}, on {meshes}{solved}"
    if all(b is None for b in acc["bands_pct"].values()):
        return f"tolerance {acc['tolerance_pct']:g} %: not checked, {acc['note']}"
    return (f"tolerance {acc['tolerance_pct']:g} %: NOT reached, band {bands}, on {meshes}{solved}: "
            f"{acc['note']}")


def _trend_text(est: dict) -> str:
    """error_bar_text of an estimate's band from the meshes' trend."""
    st = est["status"]
    if st == "converged":
        if est["order_used"] < est["order_observed"] - 1e-9:
            return (f"± {_f(est['band'])} MPa (GCI {100 * est['gci_fine']:.2f} %), extrapolated "
                    f"{_f(est['extrapolated'])} MPa with the element's formal order {est['order_used']:g}: the "
                    f"observed order {est['order_observed']:.2f} is above it (a coarse mesh off the trend), "
                    "so neither the limit nor the band uses it")
        return (f"± {_f(est['band'])} MPa (GCI {100 * est['gci_fine']:.2f} %), extrapolated "
                f"{_f(est['extrapolated'])} MPa, observed order {est['order_observed']:.2f}")
    if st == "exact":
        return "unchanged across meshes"
    if st == "settled":
        return (f"± {_f(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), the same on every mesh to within "
                f"{100 * SETTLED:g} %; band = {100 * SETTLED_BAND:g} %, what such nodal readings are still off by, "
                "not their smaller spread")
    if st == "scattered":
        return (f"± {_f(est['band'])} MPa ({100 * est['gci_fine']:.1f} %), values scatter between meshes "
                f"(unstructured meshes move nodal peaks by ~1 %); least-squares limit {_f(est['extrapolated'])} MPa, "
                "band with safety factor 3")
    if st == "unsettled":
        return (f"± {_f(est['band'])} MPa ({100 * est['gci_fine']:.1f} %), values still changing between "
                "meshes (not in the asymptotic range); band = largest change, no extrapolation")
    if st == "oscillatory":
        return (f"± {_f(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), values oscillate "
                "between meshes; band = largest change")
    if st == "singular":
        return (f"NOT CONVERGED: grows with refinement (observed order "
                f"{est['order_observed']:.2f}); the peak sits at a singular feature and has no finite value")
    return f"NOT CONVERGED (status {st}, observed order {est['order_observed']:.2f})"


def feature_text(block: dict) -> str:
    """Where a peak sits, in words; a singular one says at which singular feature (the
    location's name alone, e.g. the fillet, would hide that the peak is not finite)."""
    where = block.get("singular_feature")
    return f"{block['feature']} (singular: {where})" if where else block["feature"]


def no_safety_factor_reason(fe: dict, key: str) -> str:
    """Why ``fe[key]`` (a safety factor) is missing, in two or three words: the peak was
    not asked for (want), or it sits at a singularity."""
    return "not asked for" if "want =" in fe.get(f"{key}_note", "") else "singular peak"


def _sf(value: float | None, fe: dict, key: str) -> str:
    return f"none ({no_safety_factor_reason(fe, key)})" if value is None else f"{value:.2f}"


def safety_text(fe: dict, key: str) -> str:
    """The safety factor in bold, or why there is none (a singular peak)."""
    value = fe.get(key)
    if value is None:
        return f"**none** ({fe.get(key + '_note', 'no finite peak')})"
    return f"**{value:.2f}**"


def why_sentence(res: dict) -> str:
    """Plain explanation of why the FE peak differs from the nominal formula stress."""
    fe = res["fe"]
    crit = fe["critical"]["feature"]
    return (
        "The hand formulas give a nominal bending stress averaged over the ligament beside the "
        f"bore (beam or curved-bar theory); the FE field also resolves the stress concentration at "
        f"the {crit} where the ligament's bending stress peaks, the local bearing pressure and the "
        "3-D load path, so its node-level peak is higher than the nominal value. "
        f"The global peak ({fe['peak']['feature']}) is a different mechanism, the journal bending "
        "at its root, which neither formula covers; it depends directly on the assumed journal "
        "diameter dj and shoulder fillet radius rf, which the paper does not give, so check them "
        "against the real part before acting on it."
        if fe["peak"]["feature"] != crit else
        "The hand formulas give a nominal bending stress averaged over the ligament beside the "
        "bore; the FE field resolves the stress concentration at the bore edge and the 3-D load "
        "path, so its node-level peak is higher than the nominal value.")


def comparison_section(res: dict) -> str:
    """Like with like: per section, the formulas' nominal stress, the FE nominal stress from
    the section's resultants and its linearisation, the FE peak, and Kt (docs/design.md §5)."""
    fe, an = res["fe"], res["analytic"]
    sec = fe.get("sections")
    if not sec:
        return ""
    L = ["## Like with like: nominal stresses at the two sections\n",
         "The hand formulas give a *nominal* stress; the FE field gives the same quantity from the "
         "section's force and moment (reactions of the symmetry plane, exact for the FE solution) "
         "and from the linearised stress through the section, plus the concentration on top of it.\n",
         "| section | formula, nominal (MPa) | FE nominal: N/(w·h) + 6M/(w·h²) (MPa) | FE linearised σ_xx, m + b (MPa) "
         "| FE peak von Mises (MPa) | Kt = peak / nominal |",
         "|---|---|---|---|---|---|"]
    cs, lines, root = sec.get("critical_section"), sec["lines"], sec["journal_root"]
    crit = fe["critical"]
    if cs:
        lin = lines["mid_ligament_height"]["membrane_plus_bending_MPa"]
        edge = lines["bore_edge_height"]["membrane_plus_bending_MPa"]
        L.append(f"| ligaments beside the bore, x = 0 (N = {_f(cs['N_N'], 1)} N, M = {_f(cs['M_Nmm'], 0)} N·mm) | "
                 f"approximate {_f(an['approximate_MPa'])} (span {_f(an['approximate_span_mm'], 1)} mm); "
                 f"exact {_f(an['exact_MPa'])} (span {_f(an['exact_span_mm'], 1)} mm) | "
                 f"**{_f(cs['nominal_MPa'])}** | mid-ligament {_f(lin)}; bore edge {_f(edge)} | "
                 f"{_f(crit['value_MPa'])} {error_bar_text(crit)} | "
                 + ("none: the peak is not resolved" if crit.get("not_wanted")
                    else f"{crit['value_MPa'] / cs['nominal_MPa']:.2f}") + " |")
    pk = fe["peak"]
    kt_p = f"; Peterson's chart {root['Kt_peterson']:.2f}" if "Kt_peterson" in root else ""
    L.append(f"| journal root, x = b1/2 (M = {_f(root['M_Nmm'], 0)} N·mm) | none (the formulas do not check the "
             f"journal) | **{_f(root['nominal_MPa'])}** (32·M/(π·dj³)) | | {_f(pk['value_MPa'])} "
             f"{error_bar_text(pk)} | "
             + (f"none: the peak is not resolved{kt_p}" if pk.get("not_wanted")
                else f"none: the peak is singular{kt_p}" if pk.get("singular_feature") else f"{root['Kt']:.2f}{kt_p}")
             + " |")
    L.append("")
    if cs:
        L.append(f"The approximate formula is the beam-bending stress of this section, 6·Me/((b − di)·h²) with "
                 f"Me = {_f(an['approximate_terms']['Me_Nmm'], 0)} N·mm; the FE section carries "
                 f"|M| = {_f(abs(cs['M_Nmm']), 0)} N·mm (the loads' real centroids instead of the formula's "
                 "points), hence the difference in the nominal stress. The exact formula models the ring "
                 "around the bore as a curved bar bent in its own plane; its stress is not a stress of "
                 "this section's bending over the height. The peak sits on top of the nominal stress at the "
                 "bore edge (3-D concentration).\n")
    if "peterson_note" in root:
        L.append(f"Peterson's value is a plausibility check: {root['peterson_note']}.\n")
    L += formula_load_lines(sec.get("formula_load"))
    L.append("![normal stress along the ligament](sections.png)\n" if res.get("files", {}).get("sections_plot") else "")
    return "\n".join(L)


def formula_load_lines(rows: dict | None) -> list[str]:
    """The like-with-like table proper: each formula beside the FE section solved with the
    journal load at that formula's own position (mm, MPa), so that the two differ in their
    theory only (docs/design.md §5)."""
    if not rows:
        return []
    L = ["### Each formula against the FE under its own load position\n",
         f"The paper puts the journal load at a different place in each formula ({appendix.FORMULAS}). "
         "Here the FE part is solved again with the bearing load on a band at each formula's own "
         f"position (on the mesh ×{next(iter(rows.values())).get('mesh_factor', 1):.3g} with its stiffness "
         "matrix, only the load differs; section quantities, on which the meshes agree), so that formula and FE "
         "differ in the theory only, not in where the load sits. A band cannot be centred on the "
         "journal's tip: there it ends at the tip, and the formula at the FE load's own position is "
         "given beside it.\n",
         "| formula | its load at (mm from x = 0) | FE load band (mm), its middle | formula (MPa) | "
         "formula with its load at the band's middle (MPa) | FE section (MPa) | FE − formula, same load | "
         "FE linearised σ_xx, m + b: mid-ligament; bore edge (MPa) |",
         "|---|---|---|---|---|---|---|---|"]
    for which, r in rows.items():
        a, b = r["fe_load_band_mm"]
        diff = 100 * (r["fe_MPa"] - r["formula_at_fe_load_MPa"]) / r["formula_at_fe_load_MPa"]
        L.append(f"| {which} | {_f(r['formula_load_at_mm'], 2)} | {_f(a, 2)} to {_f(b, 2)}, {_f(r['fe_load_at_mm'], 2)} | "
                 f"{_f(r['formula_MPa'])} | {_f(r['formula_at_fe_load_MPa'])} | **{_f(r['fe_MPa'])}** | {diff:+.1f} % | "
                 f"{_f(r['lines']['mid_ligament_height']['membrane_plus_bending_MPa'])}; "
                 f"{_f(r['lines']['bore_edge_height']['membrane_plus_bending_MPa'])} |")
    L.append(f"\nFE section: {next(iter(rows.values()))['fe_quantity']}.\n")
    return L


VERDICT_NAMES = {"global_peak": "global peak (whole part)", "critical_peak": "critical-region peak",
                 "critical_section_nominal": "critical section, nominal (N, M)",
                 "journal_root_nominal": "journal root, nominal bending"}


def verdict_section(res: dict) -> str:
    """Pass/fail against the allowable, margin, error bar, and the load capacity."""
    v, c = res["fe"].get("verdict"), res["case"]
    if not v:
        return ""
    L = [f"## Verdict against the allowable {_f(c['allowable_MPa'], 0)} MPa\n",
         "| stress | value (MPa) | verdict | margin | capacity: hook load at the allowable (N) |",
         "|---|---|---|---|---|"]
    for key, row in v.items():
        name = VERDICT_NAMES.get(key, key)
        if row["verdict"] == "none":
            L.append(f"| {name} | {_f(row['value_MPa'])} | **no verdict** | | {row['why']} |")
            continue
        band = f" ± {_f(row['band_MPa'])}" if row.get("band_MPa") else ""
        rng = row.get("capacity_range_N")
        cap = _f(row["capacity_N"], 0) + (f" ({_f(rng[0], 0)}–{_f(rng[1], 0)})" if rng and band else "")
        L.append(f"| {name} | {_f(row['value_MPa'])}{band} | **{row['verdict']}** | {row['margin_pct']:+.1f} % | {cap} |")
    decided = {k: r for k, r in v.items() if r["verdict"] != "none" and r.get("capacity_N") is not None}
    if decided:
        k = min(decided, key=lambda key: decided[key]["capacity_N"])
        L.append(f"\nLowest capacity: **{VERDICT_NAMES.get(k, k)}**, {_f(decided[k]['capacity_N'], 0)} N "
                 f"({decided[k]['margin_pct']:+.1f} % margin at {_f(c['load_N'], 0)} N). The peak rows are local "
                 "values at a stress raiser (concentration included), the nominal rows the section's average "
                 "stress as the hand formulas define it; which one the design must satisfy is the engineer's "
                 "rule (static strength, fatigue), not this tool's.")
    if res.get("load_sweep_verdict"):
        L.append(f"\nThe table is at Q = {_f(c['load_N'], 0)} N. **{res['load_sweep_verdict']}** (each load's "
                 "row: *Load sweep*.)")
    L.append("\nCapacity scales the hook load linearly (linear elasticity, loads only): the load at which "
             "that stress reaches the allowable; the range follows the error bar. \"undecided\": the "
             "error bar straddles the allowable.\n")
    return "\n".join(L)


SENSITIVITY_COLUMNS = (("peak_MPa", "global peak (MPa)", 2), ("critical_peak_MPa", "critical peak (MPa)", 2),
                       ("critical_section_nominal_MPa", "critical-section nominal (MPa)", 2),
                       ("capacity_N", "capacity (N)", 0))


def _ends(values: list, nominal: float | None, nd: int, noise: float | None = None) -> str:
    """'low → high' of one quantity over a range, with each end's change from the run's
    value in %; a change smaller than ``noise`` (the single mesh's, same unit) is marked."""
    def one(v):
        if v is None:
            return "—"
        small = noise is not None and nominal is not None and abs(v - nominal) < noise
        return _f(v, nd) + (f" ({100 * (v / nominal - 1):+.1f} %{', within noise' if small else ''})"
                            if nominal else "")
    return f"{one(values[0])} → {one(values[1])}"


# The noise of a single sensitivity mesh that each table column is compared with.
NOISE_OF = {"peak_MPa": "global_peak", "critical_peak_MPa": "critical_peak",
            "critical_section_nominal_MPa": "critical_section_nominal"}


def sensitivity_section(res: dict) -> str:
    """What the answer rests on: each assumed input (and load-model choice) over its range,
    how far it moves the peaks, the critical-section nominal stress and the capacity, the
    single-mesh noise beside those changes, the tornado chart and the one verdict sentence."""
    entries, summ = res.get("sensitivity"), res.get("sensitivity_summary")
    if entries is None or summ is None:
        return ""
    fe = res["fe"]
    sec = (fe.get("sections") or {}).get("critical_section") or {}
    caps = [r["capacity_N"] for r in (fe.get("verdict") or {}).values()
            if r.get("verdict") not in (None, "none") and r.get("capacity_N") is not None]
    nominal = {"peak_MPa": fe["peak_MPa"], "critical_peak_MPa": fe["critical_peak_MPa"],
               "critical_section_nominal_MPa": sec.get("nominal_MPa"), "capacity_N": min(caps) if caps else None}
    L = ["## What the answer rests on (sensitivity)\n",
         f"**{summ['sentence']}**\n",
         "The error bar above is the mesh's error for *this* model. The inputs below are assumed (the "
         "paper does not give them) or are choices of the load model; each is varied alone over the range "
         "stated, the others kept. Each end of a dimension's range is analysed on one mesh at mesh factor "
         f"{summ['mesh_factor']:.3g} refined at the places its dimensions name (no pilot solve); the nominal "
         "case on such a mesh is the baseline, "
         "so an end's value is this run's value × end / baseline. Each end of a load-model choice is solved "
         "on one of this run's own meshes with its operator (a new right-hand side: the error-bar mesh at "
         "that factor, or the requested one), with that mesh's own value as the baseline. Capacity: the "
         "hook load at which the first checked stress reaches the allowable.\n",
         "| input | range | why this range | " + " | ".join(h for _, h, _ in SENSITIVITY_COLUMNS) + " |",
         "|---|---|---|" + "---|" * len(SENSITIVITY_COLUMNS)]
    noise = summ.get("noise_MPa") or {}
    for e in entries:
        rng = range_text(e["range"], e["unit"])
        why = e["reason"] + (f"; {e['note']}" if e.get("note") else "")
        bad = [f"{'low' if i == 0 else 'high'} end invalid: {w}" for i, w in enumerate(e["invalid"]) if w]
        if bad:
            why += "; " + "; ".join(bad)
        L.append(f"| {e['input']} | {rng} | {why} | "
                 + " | ".join(_ends(e[k], nominal[k], nd, noise.get(NOISE_OF.get(k, ""))
                                    if e.get("kind", "dimension") == "dimension" else None)
                              for k, _, nd in SENSITIVITY_COLUMNS) + " |")
    L.append("")
    L.append(f"Noise of one such mesh (the nominal case's change to {summ.get('noise_mesh') or 'a second mesh'}): "
             + ", ".join(f"{label} ± {_f(noise[k])} MPa" for k, label in
                         (("global_peak", "global peak"), ("critical_peak", "critical peak"),
                          ("critical_section_nominal", "critical-section nominal"))
                         if noise.get(k) is not None)
             + "; a change smaller than that is not a finding.\n")
    if summ.get("not_varied"):
        L.append("Not varied: " + "; ".join(f"{k} ({why})" for k, why in summ["not_varied"].items()) + ".\n")
    cs = summ.get("contact_study")
    if cs:
        def span(pct: list) -> str:
            return f"{pct[0]:+.1f} % to {pct[1]:+.1f} %"

        def applied(q: dict) -> str:
            mpa = " → ".join(_f(v) for v in q["MPa"])
            ends = [v for v in q["verdicts"] if v]
            return f"{mpa} MPa" + (f" ({' / '.join(ends)})" if ends else "")

        by_fit = ", ".join(f"{k} {span(v)}" for k, v in cs["fillet_peak_pct_by_fit"].items())
        L.append(f"**The load model's measured effect** ({cs['source']}; {cs['applied_as']}): against the cos θ "
                 f"model (the study's own) the contact moves the fillet's peak by {span(cs['global_peak']['pct'])} over the fits "
                 f"({by_fit}), here a global peak of {applied(cs['global_peak'])}; the critical peak by "
                 f"{span(cs['critical_peak']['pct'])}, here {applied(cs['critical_peak'])}. With a loose fit "
                 f"(H9/d9) the sharp edge of a plate bore flush with the fillet's run-out becomes the most stressed "
                 f"place, {span(cs['edge_of_contact_pct'])} above this model's global peak on the study's meshes "
                 "(not converged: set by the edge's shape, which a chamfer changes).\n")
    if (res.get("files") or {}).get("sensitivity_plot"):
        L.append(f"![sensitivity: tornado chart]({res['files']['sensitivity_plot']})\n")
    L.append(f"Sensitivity time: {summ.get('time_s', 0):.1f} s (`--no-sensitivity` skips it).\n")
    return "\n".join(L)


# The title block's rows: (label, the about.document key), then the automatic ones.
TITLE_FIELDS = (("Part", "part"), ("Document number", "number"), ("Revision", "revision"),
                ("Author", "author"), ("Checked by", "checker"))


# The characters from which Markdown (Python-Markdown, and its tables extension's "|") makes
# markup inside a line, each of which a backslash escapes: code, emphasis, links and images
# ("[", "]"), a table cell's end. (#, +, - and "1." are markup at a line's start only, and a
# user's text never starts one: it sits in a table cell or after words.)
MARKDOWN_PUNCTUATION = "\\`*_[]|"


def md_text(text: str) -> str:
    """A user's text (a title-block field, a row's source) as Markdown that renders as that
    very text, in report.md as in report.html: HTML's &, < and > as entities, Markdown's
    punctuation backslash-escaped, so that no link, image, emphasis, raw HTML or table cell
    boundary comes of it (a ``[x](javascript:...)`` stays those characters), and line
    breaks as spaces."""
    import html
    out = html.escape(" ".join(text.splitlines()), quote=False)
    return "".join("\\" + ch if ch in MARKDOWN_PUNCTUATION else ch for ch in out)


def code_span(text: str) -> str:
    """A user's text as a Markdown code span (shown as typed, in a fixed-width font): fenced
    by one backtick more than its longest run of them, so that none of its own ends the
    span; Markdown HTML-escapes a code span's content itself."""
    import re
    text = " ".join(text.splitlines())
    fence = "`" * (max((len(m) for m in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") or text.startswith(" ") else ""
    return f"{fence}{pad}{text}{pad}{fence}"


def _cell(text: str | None) -> str:
    """A case file's text as a Markdown table cell (:func:`md_text`), a missing value blank
    (to fill by hand)."""
    return "" if text is None else md_text(text)


def title_block_lines(res: dict) -> list[str]:
    """The title block: part, document number, revision, author and checker from the case
    file (results.json about.document; blank where not given), the date (UTC) and the tool
    and software versions the run recorded. Empty rows stay empty: no value is invented."""
    about = res.get("about") or {}
    doc = about.get("document") or {}
    sw = about.get("software") or {}
    L = ["| Calculation note | |", "|---|---|"]
    L += [f"| {label} | {_cell(doc.get(key))} |" for label, key in TITLE_FIELDS]
    L.append(f"| Date (UTC) | {_cell((about.get('created_utc') or '')[:10] or None)} |")
    versions = ", ".join(f"{name} {sw[key]}" for name, key in (("DOLFINx", "dolfinx"), ("PETSc", "petsc"),
                                                               ("gmsh", "gmsh"), ("Python", "python")) if key in sw)
    tool = f"{about.get('tool', 'crosshead')} {about['tool_version']}" if "tool_version" in about else None
    L.append(f"| Tool | {_cell(tool)}{' (' + versions + ')' if tool and versions else ''} |")
    L.append("")
    return L


def _summary_lines(res: dict) -> list[str]:
    """Title, title block, the summary table, the like-with-like and verdict sections,
    warnings, safety factors, the pictures."""
    L: list[str] = []
    add = L.append
    c, an, fe, cmp_ = res["case"], res["analytic"], res["fe"], res["comparison_pct"]
    add(f"# Crosshead stress report: hook No. {md_text(str(c['size']))} (case {code_span(c['name'])})\n")
    L += title_block_lines(res)
    add("Units: lengths mm, forces N, stresses MPa. Locations (x, y, z) in mm: x along the crosshead "
        "(the journal axis), y across it, z up; origin on the bore axis at the bottom face.\n")
    if is_scaled_row(c.get("source", "")):
        add(f"> **Note:** the dimensions of No. {c['size']} are No. 05's scaled by geometric similarity, "
            "**not DIN 15412 values** (source in *Inputs*).\n")
    add("## Summary\n")
    add("| quantity | value (MPa) | error bar | where |")
    add("|---|---|---|---|")
    for name, key in (("whole part", "peak"), ("critical region (\\|x\\| ≤ di/2)", "critical")):
        p = fe[key]
        add(f"| FE peak von Mises, {name} | **{_f(p['value_MPa'])}** | {error_bar_text(p)} | "
            f"{feature_text(p)} at {_loc(p['location_mm'])} |")
    pub = an.get("published")
    add(f"| approximate formula (span {_f(an['approximate_span_mm'], 1)} mm) | {_f(an['approximate_MPa'])} | "
        f"{'published ' + _f(pub['approximate_MPa']) if pub else ''} | nominal, ligament beside bore |")
    add(f"| exact formula (span {_f(an['exact_span_mm'], 1)} mm) | {_f(an['exact_MPa'])} | "
        f"{'published ' + _f(pub['exact_MPa']) if pub else ''} | nominal, ring ligament |")
    add("")
    if fe.get("accuracy"):
        add(f"Accuracy: {accuracy_text(fe['accuracy'])}.\n")
    add(comparison_section(res))
    add(verdict_section(res))
    add(sensitivity_section(res))
    for key in ("peak", "critical"):
        where = fe[key].get("singular_feature")
        if where:
            add(f"> **Warning:** the {'global' if key == 'peak' else 'critical-region'} peak sits at a "
                f"stress singularity: {where}, at {_loc(fe[key]['location_mm'])}. It grows as the mesh "
                "is refined and is not a converged number; do not use it as a stress.\n")
    if c["support"] == "rigid":
        add("> **Note:** `rigid` support fixes u_z on the lower journal halves; the edges of that "
            "patch are stress singularities, so peaks there are not finite.\n")
    add(f"Safety factor against the allowable {_f(c['allowable_MPa'], 0)} MPa "
        "(paper: 80–120 MPa for St 42/St 50): "
        f"{safety_text(fe, 'safety_factor')} on the global peak, "
        f"{safety_text(fe, 'critical_safety_factor')} on the critical-region peak.\n")
    add("Difference of the FE peaks from the formulas: critical-region peak "
        f"{cmp_['critical_vs_exact']:+.1f} % vs exact, {cmp_['critical_vs_approximate']:+.1f} % vs approximate; "
        f"global peak {cmp_['peak_vs_exact']:+.1f} % vs exact, {cmp_['peak_vs_approximate']:+.1f} % vs approximate.\n")
    add(why_sentence(res) + "\n")
    add("![von Mises on the deformed part](von_mises.png)\n")
    add("Colours: the reported von Mises at each node (the midpoint of the node's unaveraged and averaged "
        "readings on the shoulder fillet, the unaveraged one elsewhere), so the colour scale's top is the "
        "global peak.\n")
    if (res.get("files") or {}).get("mesh_closeup"):
        add(f"![the mesh at the two peaks, element edges drawn]({res['files']['mesh_closeup']})\n")
        add("The mesh at each peak, seen along the surface's normal there (undeformed, the reported von Mises, "
            "the surface triangles' edges drawn: the curved elements' straight chords), the peak's node marked: "
            "how many elements resolve each peak.\n")
    return L


def _inputs_lines(res: dict) -> list[str]:
    """The dimensions with their origin, load, support, material, model and mesh sizes (mm, N, MPa)."""
    L: list[str] = []
    add = L.append
    c, fe = res["case"], res["fe"]
    d = c["dims"]
    add("## Inputs\n")
    add(f"Hook No. {md_text(str(c['size']))}; row source: {md_text(without_docs_links(c['source']))}\n")
    add("| symbol | meaning | value (mm) | origin |")
    add("|---|---|---|---|")
    for k, v in d.items():
        origin = f"assumed: {ASSUMED_WHY[k]}" if k in c["assumed"] else "table / case"
        add(f"| {k} | {DIM_NAMES.get(k, k)} | {_f(v, 3)} | {origin} |")
    add("")
    add(f"Load Q = {_f(c['load_N'], 1)} N, downward, uniform pressure on the seat annulus. "
        f"Support: `{c['support']}`"
        + (f" ({BEARING_SHAPE_WORDS[c.get('bearing_shape', 'cosine')]} on the lower half of each journal, "
           "resultant Q/2 each, scaled to balance the seat load on the actual mesh)" if c["support"] == "bearing" else
           " (u_z = 0 on the lower half of each journal)") + f"; {appendix.LOADS}.\n")
    add(f"Material: E = {_f(c['E_MPa'], 0)} MPa, ν = {c['nu']}. Model: `{c['model']}`"
        + (" (x ≥ 0, y ≥ 0 with symmetry planes; carries Q/4)" if c["model"] == "quarter" else "")
        + f". Elements: P{c['order']} tetrahedra. Solver: `{c['solver']}`.\n")
    ms = c["mesh_sizes_mm"]
    add(f"Mesh sizes (× factor {c['mesh_factor']:g}): body {_f(ms['size_body'], 3)}, bore and seat edges "
        f"{_f(ms['size_feature'], 3)}, fillets {_f(ms['size_fillet'], 3)}, grading distance {_f(ms['grading'], 3)}.\n")
    spots = fe.get("refined_at_mm") or []
    if spots and "size_hotspot" in ms:
        if fe.get("refined_places_from") == "known":
            where = (f"{len(spots)} places known from the dimensions, the bore edges in x = 0 (no pilot solve: "
                     f"only the critical peak is asked for, and it fell inside their refinement)")
        else:
            between = fe.get("refined_bridging_places") or 0
            where = (f"{len(spots) - between} places where a pilot solve (mesh × {fe['pilot_mesh_factor']:.3g}) found "
                     f"von Mises within {100 * (1 - fe['pilot_fraction']):.0f} % of the global or critical peak"
                     + (f" and {between} added between neighbouring ones on the fillet's crest, so that their balls "
                        "leave no gap" if between else ""))
        sizes = f"{_f(ms['size_hotspot'], 3)} mm within {_f(ms['hotspot_radius'], 3)} mm"
        if "size_edge_hotspot" in ms:  # an older results.json has one size, or one radius
            edge_radius = ms.get("edge_hotspot_radius", ms["hotspot_radius"])
            sizes += (f" on the journal root and {_f(ms['size_edge_hotspot'], 3)} mm within "
                      f"{_f(edge_radius, 3)} mm elsewhere")
        add(f"Refined to {sizes} (× factor) of {where}: {', '.join(_loc(p) for p in spots)} "
            f"(and their mirror images).\n")
    return L


def _formulas_lines(res: dict) -> list[str]:
    """The paper's two hand formulas worked for this case, with the published values where the row has them."""
    L: list[str] = []
    add = L.append
    an = res["analytic"]
    pub = an.get("published")
    add(f"## Hand formulas (paper; {appendix.FORMULAS})\n")
    at = an["approximate_terms"]
    add(f"Approximate: Me = Q/2·(l/2 − Dm/π) with l = {_f(an['approximate_span_mm'], 2)} mm: "
        f"lever {_f(at['lever_mm'], 3)} mm, Me = {_f(at['Me_Nmm'], 0)} N·mm, "
        f"σ = 6·Me/((b − di)·h²) = **{_f(an['approximate_MPa'])} MPa**"
        + (f" (published {_f(pub['approximate_MPa'])}).\n" if pub else ".\n"))
    et = an["exact_terms"]
    add(f"Exact (Rudenko curved bar), l = {_f(an['exact_span_mm'], 2)} mm, R = (b + di)/4 = {_f(et['R_mm'], 2)} mm:\n")
    rows = [("N1 (N)", _f(et["N1_N"], 1), "N1_N", 1), ("M1 (N·mm)", _f(et["M1_Nmm"], 1), "M1_Nmm", 0),
            ("N2 (N)", _f(et["N2_N"], 1), "N2_N", 1), ("M2 (N·mm)", _f(et["M2_Nmm"], 1), "M2_Nmm", 0),
            ("F (mm²), W (mm³)", f"{_f(et['F_mm2'], 1)}, {_f(et['W_mm3'], 1)}", None, 0),
            ("σ = M2/W + N2/F (MPa)", f"**{_f(an['exact_MPa'])}**", "exact_MPa", 2)]
    add("| term | value |" + (" published |" if pub else ""))
    add("|---|---|" + ("---|" if pub else ""))
    for name, value, key, nd in rows:
        add(f"| {name} | {value} |" + (f" {_f(pub[key], nd) if key else ''} |" if pub else ""))
    add("")
    cs = an["consistent_span"]
    add("The paper uses different spans in the two methods. With one span for both: approximate at "
        f"l = {_f(an['exact_span_mm'], 1)} mm gives {_f(cs['approximate_at_exact_span_MPa'])} MPa; exact at "
        f"l = {_f(an['approximate_span_mm'], 1)} mm gives {_f(cs['exact_at_approximate_span_MPa'])} MPa."
        + (f" Published FE result: {_f(pub['fe_MPa'])} MPa ({pub['source']}).\n" if pub else "\n"))
    return L


def _fe_lines(res: dict) -> list[str]:
    """The FE solution: sizes, residual, equilibrium, how the peaks are read and each mesh level."""
    L: list[str] = []
    add = L.append
    fe = res["fe"]
    add("## Finite-element solution\n")
    add(f"{fe['cells']} tetrahedra, {fe['dofs']} DOFs, {fe['iterations']} solver iterations, true relative "
        f"residual {fe['residual_rel']:.1e}, {fe['mpi_ranks']} MPI rank(s). Worst element det J ratio "
        f"{fe['mesh_min_jacobian_ratio']:.3f} (≤ 0 would be an inverted element"
        + ("; below 0.1 is poor" if fe['mesh_min_jacobian_ratio'] >= 0.1 else "; **below 0.1: poor, check the mesh**") + ").\n")
    scaled = [lv["mesh_factor"] for lv in fe["levels"] if lv.get("scaled_from")]
    if scaled:
        src = next(lv["scaled_from"] for lv in fe["levels"] if lv.get("scaled_from"))
        add(f"Not solved again: on the mesh(es) ×{', ×'.join(f'{f:g}' for f in scaled)} the displacement is an "
            f"earlier run's solution of the same mesh and problem at Q = {_f(src['load_N'], 1)} N, E = "
            f"{_f(src['E_MPa'], 0)} MPa, scaled by the load ratio and the inverse modulus ratio (exact in linear "
            "elasticity; the solver figures above are that solve's); on an error-bar mesh the earlier run's peaks "
            "and forces themselves are scaled, the mesh is not read again.\n")
    add(f"Equilibrium: seat load {_f(fe['seat_force_N'], 3)} N, support {_f(fe['support_force_N'], 3)} N on the "
        f"model (share {fe['model_load_share']:g} of Q); imbalance {fe['equilibrium_error_N']:.2e} N; force "
        f"carried by the rigid-motion constraint {fe['constraint_reaction_N']:.2e} N (limit 1e-6·Q).\n")
    add("### How the peaks are read\n")
    add(f"Each peak is read two ways, unaveraged and averaged ({appendix.ERROR_BAR}):\n")
    for key, label in (("peak", "Global peak"), ("critical", "Critical peak")):
        b = fe[key]
        if "definition" in b:
            add(f"- **{label}**: {b['definition']}. Error bar: {b['error_bar_method']}. Here: unaveraged "
                f"{_f(b['unaveraged_MPa'])} MPa, averaged {_f(b['averaged_MPa'])} MPa, reported "
                f"**{_f(b['value_MPa'])}** MPa {error_bar_text(b)}.")
    add("")
    add(f"The error bar: the trend over the meshes below ({appendix.ERROR_BAR}).\n")
    add("| mesh factor | DOFs | global peak (MPa) | unaveraged | averaged | critical peak (MPa) | iterations | time (s) |")
    add("|---|---|---|---|---|---|---|---|")
    for lv in fe["levels"]:
        add(f"| {lv['mesh_factor']:.3g} | {lv['dofs']} | {_f(lv['peak_MPa'], 3)} | "
            f"{_f(lv.get('peak_unaveraged_MPa'), 3)} | {_f(lv.get('peak_averaged_MPa'), 3)} | "
            f"{_f(lv['critical_peak_MPa'], 3)} | {lv['iterations']} | {lv['time_s']:.2f} |")
    add("")
    if "peaks_plot" in res.get("files", {}):
        add("![peaks against degrees of freedom](peaks.png)\n")
        add(f"The status in each panel's title: see {appendix.ERROR_BAR}.\n")
    return L


def _load_sweep_lines(res: dict) -> list[str]:
    """The loads solved by scaling one solution (linear elasticity); empty without a load sweep."""
    L: list[str] = []
    add = L.append
    c, fe = res["case"], res["fe"]
    sweep = res.get("load_sweep")
    if sweep:
        add("## Load sweep\n")
        add(f"Analysed at the first load, Q = {_f(c['load_N'], 0)} N (the rest of this report is that "
            "load's), and scaled to the others: linear elasticity with traction loads only, so every "
            "stress scales with the load.\n")
        # The bands scale with the load too (the relative error is the first load's).
        add("| load (N) | global peak (MPa) | critical peak (MPa) | approximate (MPa) | exact (MPa) "
            "| safety factor (global / critical) |")
        add("|---|---|---|---|---|---|")
        for r in sweep:
            add(f"| {_f(r['load_N'], 0)} | {pm(r['peak_MPa'], r.get('peak_band_MPa'))} | "
                f"{pm(r['critical_peak_MPa'], r.get('critical_band_MPa'))} | "
                f"{_f(r['approximate_MPa'])} | {_f(r['exact_MPa'])} | {_sf(r['safety_factor'], fe, 'safety_factor')} / "
                f"{_sf(r['critical_safety_factor'], fe, 'critical_safety_factor')} |")
        add("")
        if res.get("load_sweep_verdict"):
            add(f"{res['load_sweep_verdict']}\n")
    return L


def _study_timings_files_lines(res: dict) -> list[str]:
    """The convergence study (if any), the stage timings (s) and the files written."""
    L: list[str] = []
    add = L.append
    conv = res.get("convergence")
    if conv:
        add("## Convergence study\n")
        add(convergence_table(conv))
    add("## Timings (s)\n")
    add("| stage | time |")
    add("|---|---|")
    for k, v in res["timings_s"].items():
        add(f"| {k} | {v:.2f} |")
    add("")
    add("The stages above the pilot are the requested mesh's. The error-bar meshes' row adds up "
        "their own stages (with several MPI ranks, run on other ranks beside the requested mesh's), "
        "and the picture is drawn in a process of its own beside the solves, so the rows can add up "
        "to more than the total (the run's wall time).")
    add("")
    add("## Files\n")
    for k, v in res.get("files", {}).items():
        add(f"- {k}: `{v}`")
    add("")
    return L


def render_markdown(res: dict) -> str:
    """The whole report as Markdown text."""
    return "\n".join([*_summary_lines(res), *_inputs_lines(res), *_formulas_lines(res), *_fe_lines(res),
                      *_load_sweep_lines(res), *_study_timings_files_lines(res), *appendix.appendix_lines(res)])


def convergence_table(conv: dict) -> str:
    """Markdown table of a convergence study (see pipeline.commands)."""
    rows = ["| mesh factor | DOFs | global peak (MPa) | critical peak (MPa) | time (s) |", "|---|---|---|---|---|"]
    for lv in conv["levels"]:
        rows.append(f"| {lv['mesh_factor']:.3g} | {lv['dofs']} | {_f(lv['peak_MPa'], 3)} | "
                    f"{_f(lv['critical_peak_MPa'], 3)} | {lv['time_s']:.2f} |")
    rows.append("")
    for key, label in (("peak", "global peak"), ("critical", "critical peak")):
        est = conv[key]
        why = conv.get("not_wanted", {}).get(key)
        rows.append(f"- {label}: not resolved ({why})." if why else
                    f"- {label}: {error_bar_text({'error_estimate': est})}; status `{est['status']}`.")
    if conv.get("plot"):
        rows.append(f"\n![convergence]({conv['plot']})\n")
    return "\n".join(rows) + "\n"


def _loc(xyz) -> str:
    return "(" + ", ".join(f"{v:.2f}" for v in xyz) + ") mm"


HTML_STYLE = """body{font-family:sans-serif;max-width:70em;margin:2em auto;line-height:1.45;color:#222}
table{border-collapse:collapse;margin:1em 0}th,td{border:1px solid #bbb;padding:.3em .6em;vertical-align:top}
th{background:#eee}img{max-width:100%}blockquote{border-left:4px solid #c60;margin:1em 0;padding:.2em 1em;background:#fff6ee}
table.title-block{border:2px solid #222;min-width:60%}table.title-block td{height:1.5em}
table.title-block td:first-child{font-weight:bold;width:12em;background:#f6f6f6}
pre{background:#f6f6f6;padding:.5em 1em}"""
# Print (A4): no table, picture or quotation split over two pages, headings kept with what
# follows them, table headers repeated, the appendix on a page of its own, and a footer
# with the report's name and "page X of Y" (CSS page-margin boxes, Chromium 131 and later).
PRINT_STYLE = """@page{size:A4;margin:16mm 14mm 18mm 14mm;
@bottom-left{content:FOOTER;font:8pt sans-serif;color:#444}
@bottom-right{content:"page " counter(page) " of " counter(pages);font:8pt sans-serif;color:#444}}
@media print{body{max-width:none;margin:0;font-size:9.5pt;line-height:1.3}
table{font-size:8pt}th,td{padding:.15em .35em}thead{display:table-header-group}
table,tr,img,blockquote,pre,li{break-inside:avoid}p:has(img){break-inside:avoid}
h1,h2,h3{break-after:avoid}h2.appendix{break-before:page}img{max-height:125mm;object-fit:contain}}"""


def css_string(text: str) -> str:
    """``text`` as a quoted CSS string (backslashes, quotes, newlines and '<' escaped, so
    that a case file's text can neither end the string nor the style element)."""
    escaped = (text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", " ")
               .replace("<", "\\3C "))
    return f'"{escaped}"'


def footer_text(res: dict, title: str) -> str:
    """The printed pages' footer: the report's title, and its document number and revision
    where the case file gives them."""
    doc = (res.get("about") or {}).get("document") or {}
    number = " · ".join(x for x in (doc.get("number"), doc.get("revision") and f"rev. {doc['revision']}") if x)
    return title + (f" · {number}" if number else "")


def html_document(markdown_text: str, folder: Path, title: str, footer: str | None = None) -> str:
    """report.md as one self-contained HTML page (Python-Markdown; pictures embedded), styled
    for the screen and for print (``footer``: the printed pages' footer, else ``title``)."""
    import base64
    import html

    import markdown
    body = markdown.markdown(markdown_text, extensions=["tables"])
    for png in sorted(Path(folder).glob("*.png")):
        data = base64.b64encode(png.read_bytes()).decode("ascii")
        body = body.replace(f'src="{png.name}"', f'src="data:image/png;base64,{data}"')
    body = body.replace("<table>", '<table class="title-block">', 1) if "<th>Calculation note</th>" in body else body
    body = body.replace("<h2>Appendix", '<h2 class="appendix">Appendix', 1)
    style = HTML_STYLE + "\n" + PRINT_STYLE.replace("FOOTER", css_string(footer or title))
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n{body}\n</body></html>\n")


def write_report(folder: Path) -> Path:
    """Read folder/results.json and write folder/report.md and report.html next to it."""
    res = json.loads((Path(folder) / "results.json").read_text(encoding="utf-8"))
    out = Path(folder) / "report.md"
    text = render_markdown(res)
    out.write_text(text, encoding="utf-8")
    title = f"Crosshead stress report: hook No. {res['case']['size']}"
    (Path(folder) / "report.html").write_text(html_document(text, Path(folder), title, footer_text(res, title)),
                                              encoding="utf-8")
    return out


if __name__ == "__main__":
    write_report(Path(sys.argv[1]))
