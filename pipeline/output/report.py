"""report.md, report.html and report.pdf from results.json alone (the report reads only
what the run wrote; mm, N, MPa).

A calculation note whose first page is the answer: the title block, each checked stress
against the allowable with its error bar, status, verdict, margin, safety factor and
capacity, where the peaks sit, the hand formulas beside them and the sensitivity
sentence. Then the details a reviewer checks (the pictures, the sensitivity table, the
like-with-like comparison, the meshes, the inputs) and the method in the appendix
(pipeline/output/appendix.py). Every word for a status or a verdict is the analysis's
(pipeline.analysis.words), as results.json holds it.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from geometry.table import is_scaled_row
from pipeline.analysis.words import NOT_ASKED, SINGULAR, range_text
from pipeline.output import appendix
from pipeline.output.texts import (PEAK_KEYS, VERDICT_NAMES, accuracy_text, error_bar_text, feature_text, location,
                                   num, pm, safety_text as sf_text, status_text, verdict_text)

_f = num  # the report's number format (texts.num)
_loc = location

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
# Where each nominal stress of the verdict table sits (the peaks say their own place).
NOMINAL_WHERE = {"critical_section_nominal": "the section x = 0 through the bore (both ligaments)",
                 "journal_root_nominal": "the journal root, x = b1/2"}
REPORT_TITLE = "Crosshead calculation note: hook No. {size}"


def without_docs_links(text: str) -> str:
    """``text`` without its parenthesised pointers into the repository's docs/ (the size
    table's notes carry them): the report's reader has the report alone, whose appendix and
    Inputs table state what those pages say."""
    return re.sub(r"\s*\((?:see )?docs/[^)]*\)", "", text)


def no_safety_factor_reason(fe: dict, key: str) -> str:
    """Why ``fe[key]`` (a safety factor) is missing, in two or three words: the peak was
    not asked for (want), or it sits at a singularity."""
    return "not asked for" if "want =" in fe.get(f"{key}_note", "") else "singular peak"


def _sf(value: float | None, fe: dict, key: str) -> str:
    return f"none ({no_safety_factor_reason(fe, key)})" if value is None else f"{value:.2f}"


# ------------------------------------------------------------------------------- page 1

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
    text = " ".join(text.splitlines())
    fence = "`" * (max((len(m) for m in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") or text.startswith(" ") else ""
    return f"{fence}{pad}{text}{pad}{fence}"


def _cell(text: str | None) -> str:
    """A case file's text as a Markdown table cell (:func:`md_text`), a missing value blank
    (to fill by hand)."""
    return "" if text is None else md_text(text)


def title_block_fields(res: dict) -> list[tuple[str, str]]:
    """The title block's (label, cell) pairs: part, document number, revision, author and
    checker as results.json's about.document gives them (the case file, --document or the
    defaults file; blank where none did), the date (UTC) and the tool and software versions
    the run recorded. An empty field stays empty: no value is invented."""
    about = res.get("about") or {}
    doc = about.get("document") or {}
    sw = about.get("software") or {}
    fields = [(label, _cell(doc.get(key))) for label, key in TITLE_FIELDS]
    fields.append(("Date (UTC)", _cell((about.get("created_utc") or "")[:10] or None)))
    versions = ", ".join(f"{name} {sw[key]}" for name, key in (("DOLFINx", "dolfinx"), ("PETSc", "petsc"),
                                                               ("gmsh", "gmsh"), ("Python", "python")) if key in sw)
    tool = f"{about.get('tool', 'crosshead')} {about['tool_version']}" if "tool_version" in about else None
    fields.append(("Tool", f"{_cell(tool)}{' (' + versions + ')' if tool and versions else ''}"))
    return fields


def title_block_lines(res: dict) -> list[str]:
    """The title block as a table of two label-value pairs a row (:func:`title_block_fields`)."""
    fields = title_block_fields(res)
    L = ["| Calculation note | | | |", "|---|---|---|---|"]
    for i in range(0, len(fields), 2):
        (a, x), (b, y) = fields[i], (fields[i + 1] if i + 1 < len(fields) else ("", ""))
        L.append(f"| {a} | {x} | {b} | {y} |")
    L.append("")
    return L


def verdict_rows(res: dict) -> list[str]:
    """The answer's table rows: each checked stress with its value ± error bar, its status,
    where it sits, its verdict, margin, safety factor and capacity (MPa, N)."""
    fe = res["fe"]
    peaks = {v: k for k, (v, _) in PEAK_KEYS.items()}
    rows = []
    for name, row in (fe.get("verdict") or {}).items():
        block = fe.get(peaks[name]) if name in peaks else None
        if block is not None:
            band = None if block["status"] in (NOT_ASKED, SINGULAR) else row.get("band_MPa")
            value = f"**{_f(row['value_MPa'])}**" + ("" if band is None else f" ± {_f(band)}")
            status, where = status_text(block), f"{feature_text(block)}, {_loc(block['location_mm'])}"
        else:
            value, status, where = _f(row["value_MPa"]), "nominal: no error bar", NOMINAL_WHERE.get(name, "")
        if row["verdict"] == "none":
            rows.append(f"| {VERDICT_NAMES.get(name, name)} | {value} | {status} | {where} | **{verdict_text(row)}** "
                        f"| | | {row['why']} |")
            continue
        rng = row.get("capacity_range_N")
        cap = _f(row["capacity_N"], 0) + (f" ({_f(rng[0], 0)}–{_f(rng[1], 0)})" if rng else "")
        sf = sf_text(row["safety_factor"]) if "safety_factor" in row else "—"  # an older results.json has none
        rows.append(f"| {VERDICT_NAMES.get(name, name)} | {value} | {status} | {where} | **{verdict_text(row)}** | "
                    f"{row['margin_pct']:+.1f} % | {sf} | {cap} |")
    return rows


def answer_lines(res: dict) -> list[str]:
    """Page 1 after the title block: the verdict table, the lowest capacity, what the
    verdict rests on, the hand formulas beside the FE, the accuracy and the notes."""
    c, an, fe = res["case"], res["analytic"], res["fe"]
    L = [f"## Answer: hook No. {md_text(str(c['size']))} at Q = {_f(c['load_N'], 0)} N against the allowable "
         f"{_f(c['allowable_MPa'], 0)} MPa\n"]
    if fe.get("verdict"):
        L += ["| stress | value ± error bar (MPa) | status | where | verdict | margin | safety factor "
              "| capacity: hook load at the allowable (N) |",
              "|---|---|---|---|---|---|---|---|", *verdict_rows(res), ""]
        decided = {k: r for k, r in fe["verdict"].items() if r["verdict"] != "none" and r.get("capacity_N") is not None}
        if decided:
            k = min(decided, key=lambda key: decided[key]["capacity_N"])
            L.append(f"Lowest capacity: **{VERDICT_NAMES.get(k, k)}**, {_f(decided[k]['capacity_N'], 0)} N "
                     f"({decided[k]['margin_pct']:+.1f} % margin at {_f(c['load_N'], 0)} N).\n")
        if res.get("load_sweep_verdict"):
            L.append(f"The table is at Q = {_f(c['load_N'], 0)} N. **{res['load_sweep_verdict']}** (each load's "
                     "row: *Load sweep*.)\n")
    summ = res.get("sensitivity_summary")
    if summ:
        L.append(f"**What the verdict rests on:** {summ['sentence']}\n")
    pub = an.get("published")

    def formula(key: str) -> str:
        return f"{_f(an[f'{key}_MPa'])} MPa" + (f" (published {_f(pub[f'{key}_MPa'])})" if pub else "")
    L.append(f"Hand formulas (nominal stress of the ligament beside the bore, {appendix.FORMULAS}): approximate "
             f"{formula('approximate')}, exact {formula('exact')}; the FE peaks add the stress concentration"
             " (*Hand formulas and FE, like with like*).\n")
    if fe.get("accuracy"):
        L.append(f"Error bars ({appendix.ERROR_BAR}): {accuracy_text(fe['accuracy'])}.\n")
    L += notes_lines(res)
    L.append("The peak rows are local values at a stress raiser (concentration included), the nominal rows a "
             "section's average stress as the hand formulas define it; which one the design must satisfy is the "
             "engineer's rule (static strength, fatigue), not this tool's. Capacity scales the hook load linearly "
             "(linear elasticity, loads only); its range follows the error bar; UNDECIDED: the error bar holds the "
             "allowable. Units: mm, N, MPa; locations (x, y, z): x along the crosshead (the journal axis), y across "
             "it, z up, origin on the bore axis at the bottom face.\n")
    return L


def notes_lines(res: dict) -> list[str]:
    """What a reader must see beside the answer: the run's notes (results.json), a scaled
    row of the size table, a singular peak, a rigid support."""
    c, fe = res["case"], res["fe"]
    L = [f"> **Note:** {n}.\n" for n in res.get("notes") or []]
    if is_scaled_row(c.get("source", "")):
        L.append(f"> **Note:** the dimensions of No. {c['size']} are No. 05's scaled by geometric similarity, "
                 "**not DIN 15412 values** (source in *Inputs*).\n")
    for key in ("peak", "critical"):
        where = fe[key].get("singular_feature")
        if where:
            L.append(f"> **Warning:** the {'global' if key == 'peak' else 'critical-region'} peak sits at a "
                     f"stress singularity: {where}, at {_loc(fe[key]['location_mm'])}. It grows as the mesh "
                     "is refined and is not a converged number; do not use it as a stress.\n")
    if c["support"] == "rigid":
        L.append("> **Note:** `rigid` support fixes u_z on the lower journal halves; the edges of that "
                 "patch are stress singularities, so peaks there are not finite.\n")
    return L


# ------------------------------------------------------------------------ the details

def pictures_lines(res: dict) -> list[str]:
    """The von Mises picture and the mesh close-ups at the peaks, with what they show."""
    L = ["![von Mises on the deformed part](von_mises.png)\n",
         "Above: von Mises on the deformed part, coloured by the reported von Mises at each node (the midpoint of "
         "the node's unaveraged and averaged readings on the shoulder fillet, the unaveraged one elsewhere), so the "
         "scale's top is the global peak."
         + (" Below: the mesh at each peak, seen along the surface's normal (undeformed, the reported von Mises; the "
            "surface triangles' edges are the curved elements' chords), the peak's node marked: how many elements "
            "resolve it."
            if (res.get("files") or {}).get("mesh_closeup") else "") + "\n"]
    if (res.get("files") or {}).get("mesh_closeup"):
        L.append(f"![the mesh at the two peaks, element edges drawn]({res['files']['mesh_closeup']})\n")
    return L


# The sensitivity table's columns (results.json's sensitivity keys; every checked stress at
# each end is in sensitivity.csv).
SENSITIVITY_COLUMNS = (("peak_MPa", "global peak (MPa)", 2), ("critical_peak_MPa", "critical peak (MPa)", 2),
                       ("capacity_N", "capacity (N)", 0))


def _ends(values: list, nominal: float | None, nd: int, noise: float | None = None,
          invalid: list | None = None) -> str:
    """'low → high (change at low / at high %)' of one quantity over a range, each end's
    change from the run's value in %; a change smaller than ``noise`` (the single mesh's,
    same unit) is marked '≈'; an end that could not be analysed says so."""
    bad = invalid or [None, None]
    texts = ["not analysed" if v is None and b else _f(v, nd) for v, b in zip(values, bad)]
    if not nominal or all(v is None for v in values):
        return " → ".join(texts)

    def change(v):
        if v is None:
            return "—"
        small = noise is not None and abs(v - nominal) < noise
        return f"{'≈' if small else ''}{100 * (v / nominal - 1):+.1f}"
    return f"{texts[0]} → {texts[1]} ({change(values[0])} / {change(values[1])} %)"


# The noise of a single sensitivity mesh that each table column is compared with.
NOISE_OF = {"peak_MPa": "global_peak", "critical_peak_MPa": "critical_peak",
            "critical_section_nominal_MPa": "critical_section_nominal"}


def sensitivity_section(res: dict) -> str:
    """What the answer rests on: each assumed input (and load-model choice) over its range,
    how far it moves the peaks, the critical-section nominal stress and the capacity, the
    single-mesh noise beside those changes, the load model's measured effect, the tornado
    chart and the one verdict sentence (why each range and the method: the appendix)."""
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
         "What the verdict rests on (page 1), in figures. The error bar is the mesh's error for *this* model; "
         "the inputs below are assumed (the paper does not give them) or are choices of the load model, each "
         "varied alone over its range, the others kept "
         f"(dimensions on one mesh ×{summ['mesh_factor']:.3g} each, the load model on this run's meshes; "
         f"method and why each range: {appendix.SENSITIVITY}).\n"]
    # The chart before the table: the table's rows may run on to the next page, the chart may not.
    if (res.get("files") or {}).get("sensitivity_plot"):
        L.append(f"![sensitivity: tornado chart]({res['files']['sensitivity_plot']})\n")
    L += ["| input | range | " + " | ".join(h for _, h, _ in SENSITIVITY_COLUMNS) + " |",
         "|---|---|" + "---|" * len(SENSITIVITY_COLUMNS)]
    noise = summ.get("noise_MPa") or {}
    for e in entries:
        L.append(f"| {e['input']} | {range_text(e['range'], e['unit'])} | "
                 + " | ".join(_ends(e[k], nominal[k], nd, noise.get(NOISE_OF.get(k, ""))
                                    if e.get("kind", "dimension") == "dimension" else None, e.get("invalid"))
                              for k, _, nd in SENSITIVITY_COLUMNS) + " |")
    L.append("")
    L.append(f"Noise of one such mesh (the nominal case's change to {summ.get('noise_mesh') or 'a second mesh'}): "
             + ", ".join(f"{label} ± {_f(noise[k])} MPa" for k, label in
                         (("global_peak", "global peak"), ("critical_peak", "critical peak"),
                          ("critical_section_nominal", "critical-section nominal"))
                         if noise.get(k) is not None)
             + "; a change smaller than that (marked ≈) is not a finding. Each cell: the value at the low → the high "
               "end (its change from this run's value); every checked stress at each end: sensitivity.csv. "
               f"Sensitivity time: {summ.get('time_s', 0):.1f} s "
               "(`--no-sensitivity` skips it).\n")
    if summ.get("not_varied"):
        L.append("Not varied: " + "; ".join(f"{k} ({why})" for k, why in summ["not_varied"].items()) + ".\n")
    cs = summ.get("contact_study")
    if cs:
        def span(pct: list) -> str:
            return f"{pct[0]:+.1f} % to {pct[1]:+.1f} %"

        def applied(q: dict) -> str:
            mpa = " → ".join(_f(v) for v in q["MPa"])
            ends = [verdict_text({"verdict": v}) for v in q["verdicts"] if v]
            return f"{mpa} MPa" + (f" ({' / '.join(ends)})" if ends else "")

        by_fit = ", ".join(f"{k} {span(v)}" for k, v in cs["fillet_peak_pct_by_fit"].items())
        L.append(f"**The load model's measured effect** ({cs['source']}; {cs['applied_as']}): against the cos θ "
                 f"model (the study's own) the contact moves the fillet's peak by {span(cs['global_peak']['pct'])} over the fits "
                 f"({by_fit}), here a global peak of {applied(cs['global_peak'])}; the critical peak by "
                 f"{span(cs['critical_peak']['pct'])}, here {applied(cs['critical_peak'])}. With a loose fit "
                 f"(H9/d9) the sharp edge of a plate bore flush with the fillet's run-out becomes the most stressed "
                 f"place, {span(cs['edge_of_contact_pct'])} above this model's global peak on the study's meshes "
                 "(not converged: set by the edge's shape, which a chamfer changes).\n")
    return "\n".join(L)


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


def _peak_cell(block: dict) -> str:
    """A peak for the comparison table: value ± band (MPa) and status."""
    band = None if block["status"] in (NOT_ASKED, SINGULAR) else (block.get("error_estimate") or {}).get("band")
    return f"{pm(block['value_MPa'], band)} ({block['status']})"


def comparison_section(res: dict) -> str:
    """Like with like: per section, the formulas' nominal stress, the FE nominal stress from
    the section's resultants and its linearisation, the FE peak, and Kt (docs/design.md §5);
    then each formula against the FE under its own load position, and the sections plot."""
    fe, an, cmp_ = res["fe"], res["analytic"], res["comparison_pct"]
    sec = fe.get("sections")
    if not sec:
        return ""
    L = ["## Hand formulas and FE, like with like\n",
         "The hand formulas give a *nominal* stress; the FE field gives the same quantity from the "
         "section's force and moment (reactions of the symmetry plane, exact for the FE solution) "
         "and from the linearised stress through the section, plus the concentration on top of it. "
         f"The FE peaks differ from the formulas by: critical-region peak {cmp_['critical_vs_exact']:+.1f} % vs exact, "
         f"{cmp_['critical_vs_approximate']:+.1f} % vs approximate; global peak {cmp_['peak_vs_exact']:+.1f} % vs "
         f"exact, {cmp_['peak_vs_approximate']:+.1f} % vs approximate. {why_sentence(res)}\n",
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
                 f"{_peak_cell(crit)} | "
                 + ("none: the peak is not resolved" if crit.get("not_wanted")
                    else f"{crit['value_MPa'] / cs['nominal_MPa']:.2f}") + " |")
    pk = fe["peak"]
    kt_p = f"; Peterson's chart {root['Kt_peterson']:.2f}" if "Kt_peterson" in root else ""
    L.append(f"| journal root, x = b1/2 (M = {_f(root['M_Nmm'], 0)} N·mm) | none (the formulas do not check the "
             f"journal) | **{_f(root['nominal_MPa'])}** (32·M/(π·dj³)) | | {_peak_cell(pk)} | "
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
                 "this section's bending over the height."
                 + (f" Peterson's value is a plausibility check: {root['peterson_note']}." if "peterson_note" in root
                    else "") + "\n")
    elif "peterson_note" in root:
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
         "Here the FE part is solved again with the bearing load on a band at each formula's own position (on "
         f"the mesh ×{next(iter(rows.values())).get('mesh_factor', 1):.3g}, only the load differs), so that formula "
         "and FE differ in the theory only. A band cannot be centred on the journal's tip: there it ends at the "
         "tip, and the formula at the band's middle is given beside it. "
         f"FE section: {next(iter(rows.values()))['fe_quantity']}.\n",
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
    L.append("")
    return L


def meshes_lines(res: dict) -> list[str]:
    """The meshes of the error bar: each one's DOFs and both readings of each peak (MPa),
    and the peaks plot (each peak's band and status in its title; how it was made: A.2)."""
    fe = res["fe"]
    L = ["## The meshes and the error bars\n",
         "Each peak on each mesh of its error bar: the reported value and its two nodal readings, unaveraged "
         f"and averaged ({appendix.ERROR_BAR}: how each peak is read and its band made; "
         f"{appendix.SOLUTION}: the solution's own figures). The same rows are in meshes.csv.\n",
         "| mesh factor | DOFs | global peak (MPa) | unaveraged | averaged | critical peak (MPa) | unaveraged "
         "| averaged | iterations | time (s) |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    for lv in fe["levels"]:
        L.append(f"| {lv['mesh_factor']:.3g} | {lv['dofs']} | {_f(lv['peak_MPa'], 3)} | "
                 f"{_f(lv.get('peak_unaveraged_MPa'), 3)} | {_f(lv.get('peak_averaged_MPa'), 3)} | "
                 f"{_f(lv['critical_peak_MPa'], 3)} | {_f(lv.get('critical_unaveraged_MPa'), 3)} | "
                 f"{_f(lv.get('critical_averaged_MPa'), 3)} | {lv['iterations']} | {lv['time_s']:.2f} |")
    L.append("")
    if "peaks_plot" in res.get("files", {}):
        L.append("![peaks against degrees of freedom](peaks.png)\n")
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


def convergence_table(conv: dict) -> str:
    """Markdown table of a convergence study (crosshead converge): each mesh's peaks, and
    each peak's error bar with the trend over the meshes."""
    rows = ["| mesh factor | DOFs | global peak (MPa) | critical peak (MPa) | time (s) |", "|---|---|---|---|---|"]
    for lv in conv["levels"]:
        rows.append(f"| {lv['mesh_factor']:.3g} | {lv['dofs']} | {_f(lv['peak_MPa'], 3)} | "
                    f"{_f(lv['critical_peak_MPa'], 3)} | {lv['time_s']:.2f} |")
    rows.append("")
    for key, label in (("peak", "global peak"), ("critical", "critical peak")):
        est = conv[key]
        why = conv.get("not_wanted", {}).get(key)
        rows.append(f"- {label}: not resolved ({why})." if why else
                    f"- {label}: {error_bar_text({'error_estimate': est})}; trend `{est['status']}`.")
    if conv.get("plot"):
        rows.append(f"\n![convergence]({conv['plot']})\n")
    return "\n".join(rows) + "\n"


def _inputs_lines(res: dict) -> list[str]:
    """The dimensions with their origin, load, support, material and model (mm, N, MPa);
    the mesh sizes and where the meshes were refined are the appendix's (A.5)."""
    L: list[str] = []
    add = L.append
    c = res["case"]
    d = c["dims"]
    add("## Inputs\n")
    add(f"Hook No. {md_text(str(c['size']))}; row source: {md_text(without_docs_links(c['source']))}\n")
    keys = list(d)
    add("| " + " | ".join(f"{k}{'*' if k in c['assumed'] else ''}" for k in keys) + " |")
    add("|" + "---|" * len(keys))
    add("| " + " | ".join(_f(d[k], 3) for k in keys) + " |")
    add("")
    add("Dimensions (mm): " + "; ".join(f"{k} {DIM_NAMES.get(k, k)}" for k in keys)
        + ("; * assumed: " + ", ".join(ASSUMED_WHY[k] for k in c["assumed"] if k in ASSUMED_WHY) if c["assumed"] else "")
        + "; the others from the size table or the case.\n")
    add(f"Load Q = {_f(c['load_N'], 1)} N, downward, uniform pressure on the seat annulus. "
        f"Support: `{c['support']}`"
        + (f" ({BEARING_SHAPE_WORDS[c.get('bearing_shape', 'cosine')]} on the lower half of each journal, "
           "resultant Q/2 each, scaled to balance the seat load on the actual mesh)" if c["support"] == "bearing" else
           " (u_z = 0 on the lower half of each journal)") + f"; {appendix.LOADS}. "
        f"Material: E = {_f(c['E_MPa'], 0)} MPa, ν = {c['nu']}; allowable {_f(c['allowable_MPa'], 0)} MPa (the paper: "
        f"80–120 MPa for St 42/St 50). Model: `{c['model']}`"
        + (" (x ≥ 0, y ≥ 0 with symmetry planes; carries Q/4)" if c["model"] == "quarter" else "")
        + f". Elements: P{c['order']} tetrahedra. Solver: `{c['solver']}`. Mesh factor {c['mesh_factor']:g} "
          f"(sizes and refinement: {appendix.SOLUTION}).\n")
    return L


def render_markdown(res: dict) -> str:
    """The whole report as Markdown text: the answer first, then the details, the inputs
    and the method's appendix."""
    c = res["case"]
    head = [f"# {REPORT_TITLE.format(size=md_text(str(c['size'])))} (case {code_span(c['name'])})\n", *title_block_lines(res),
            *answer_lines(res)]
    conv = res.get("convergence")
    details = [*pictures_lines(res), sensitivity_section(res), comparison_section(res), *meshes_lines(res),
               *_load_sweep_lines(res), *(["## Convergence study\n", convergence_table(conv)] if conv else []),
               *_inputs_lines(res)]
    return "\n".join([*head, *details, *appendix.appendix_lines(res)])


PICTURE_MM = 85  # the tallest a picture prints (mm)
HTML_STYLE = """body{font-family:sans-serif;max-width:70em;margin:2em auto;line-height:1.45;color:#222}
table{border-collapse:collapse;margin:1em 0}th,td{border:1px solid #bbb;padding:.3em .6em;vertical-align:top}
th{background:#eee}img{max-width:100%}blockquote{border-left:4px solid #c60;margin:1em 0;padding:.2em 1em;background:#fff6ee}
table.title-block{border:2px solid #222;width:100%}table.title-block td{height:1.4em}
table.title-block td:nth-child(odd){font-weight:bold;width:9em;background:#f6f6f6}
pre{background:#f6f6f6;padding:.5em 1em}"""
# Print (A4): no table row, picture or quotation split over two pages, headings kept with
# what follows them, table headers repeated, pictures at most PICTURE_MM tall (the
# sections plot, a tall one, narrower), and a footer with the report's name and "page X of
# Y" (CSS page-margin boxes, Chromium 131 and later). The appendix follows on the same page:
# a page of its own left the page before it nearly empty.
PRINT_STYLE = """@page{size:A4;margin:14mm 12mm 16mm 12mm;
@bottom-left{content:FOOTER;font:8pt sans-serif;color:#444}
@bottom-right{content:"page " counter(page) " of " counter(pages);font:8pt sans-serif;color:#444}}
@media print{body{max-width:none;margin:0;font-size:9pt;line-height:1.25}h1{font-size:16pt}h2{font-size:12.5pt}
h3{font-size:10.5pt}p,table,ul,pre{margin:.5em 0}table{font-size:7.5pt}th,td{padding:.12em .3em}
thead{display:table-header-group}
tr,img,blockquote,pre,li{break-inside:avoid}p:has(img){break-inside:avoid}
h1,h2,h3{break-after:avoid}img{max-height:PICTURE_MM;object-fit:contain}img[alt^="normal stress"]{max-width:55%}}"""


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
    style = HTML_STYLE + "\n" + PRINT_STYLE.replace("FOOTER", css_string(footer or title)).replace(
        "PICTURE_MM", f"{PICTURE_MM}mm")
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n{body}\n</body></html>\n")


def write_report(folder: Path) -> Path:
    """Read folder/results.json and write folder/report.md and report.html next to it."""
    res = json.loads((Path(folder) / "results.json").read_text(encoding="utf-8"))
    out = Path(folder) / "report.md"
    text = render_markdown(res)
    out.write_text(text, encoding="utf-8")
    title = REPORT_TITLE.format(size=res["case"]["size"])
    (Path(folder) / "report.html").write_text(html_document(text, Path(folder), title, footer_text(res, title)),
                                              encoding="utf-8")
    return out


if __name__ == "__main__":
    write_report(Path(sys.argv[1]))
