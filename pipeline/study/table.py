"""A design study's results (mm, N, MPa), built only from the files its variants wrote:
one row per variant and load (sweep.csv, sweep.json), where each peak crosses the
allowable along each swept parameter, one plot per peak and parameter, the variants'
notes (as each run says them), and report.md with report.html.
"""
from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from pipeline.output import flat
from pipeline.runtime.atomicfile import write_text
from pipeline.post.errorbar import verdict_against
from pipeline.output.report import html_document
from pipeline.output.texts import pm
from pipeline.study.manifest import VariantFault, read_failure, read_results
from pipeline.study.plan import Task, failure_file, variant_folder

# The study's own columns; the rest are those of a run's row (pipeline.output.flat).
OWN_COLUMNS = {
    "variant": "the variant's key, its folder variants/<key>/ (in sweep.csv written as that folder, "
               "'variants/1f0c...', text to any reader)",
    "status": "done, invalid (breaks a rule of the size table: not analysed), failed, or not run",
    "parameters": "the variant's swept inputs as JSON (mm; size as text)",
    "verdict": "the global peak against the allowable, its error bar included: pass, fail, undecided; "
               "none at a singular feature; empty when not asked for",
    "critical_verdict": "the same for the critical peak",
    "note": "why a variant is invalid, failed or not read, or why a peak has no value",
    "decided_by": "a screened study's evidence for the row: the cheap level (one coarse mesh, its bands) or "
                  "the full error bar and why the cheap level was not enough; empty when not screened",
}
# Each peak's verdict column (pass, fail or undecided against the allowable), named as in a
# run's sensitivity.csv (flat.VERDICT_COLUMNS).
VERDICT_OF = {"peak": flat.VERDICT_COLUMNS["global_peak"], "critical": flat.VERDICT_COLUMNS["critical_peak"]}
COLUMNS = ("variant", "status", "parameters", *flat.COLUMNS, *VERDICT_OF.values(), "note", "decided_by")
# Per peak: (value, band, name) and (value, band, verdict) columns of a row.
PEAKS = tuple((p.value, p.band, p.name) for p in flat.PEAKS.values())
VERDICT_KEYS = tuple((p.value, p.band, VERDICT_OF[b]) for b, p in flat.PEAKS.items())
# The statuses of variants with no peak, as a study's plots name them.
UNANALYSED = {"invalid": "invalid geometry, not analysed", "failed": "analysis failed"}


def rows_of(tasks: list[Task], out: Path) -> list[dict]:
    """One row per variant and load: inputs, peaks with bands, safety factors, status."""
    rows = []
    for t in tasks:
        base = {"variant": t.key, "parameters": json.dumps(t.params, sort_keys=True),
                **{k: v for k, v in t.params.items()},
                "size": t.params.get("size") or (None if t.case is None else t.case.size)}
        if t.case is None:
            rows += [dict(base, status="invalid", load_N=q, note=t.note) for q in (t.loads or (None,))]
            continue
        res, error, why = variant_files(out, t.key)
        if error is not None:
            rows += [dict(base, status="failed", load_N=q, note=error) for q in t.loads]
            continue
        if res is None:
            note = {} if why is None else {"note": f"{why}: not read (the same command analyses it again)"}
            rows += [dict(base, status="not run", load_N=q, **note) for q in t.loads]
            continue
        rows += [_done_row(base, r) for r in decided_rows(res, variant_folder(out, t.key))]
    return rows


def decided_rows(res: dict, folder: Path) -> list[dict]:
    """The rows (pipeline.output.flat) of the run in ``folder`` (its results.json content
    ``res``), as its study decided it: a variant of a screened study decided on the cheap
    level carries that level's bands and the status "screened"; each row's ``decided_by``
    says on what evidence (empty for a study that was not screened)."""
    from pipeline.study.screening import FILE, evidence, screened_rows
    rows = flat.rows(res)
    f = folder / FILE
    if not f.is_file():
        return rows
    s = json.loads(f.read_text(encoding="utf-8"))
    if not s["full_error_bar"]:
        rows = screened_rows(rows, s)
    return [dict(r, decided_by=evidence(s)) for r in rows]


def _done_row(base: dict, r: dict) -> dict:
    """A finished variant's row at one load: its inputs ``base`` and the run's row ``r``
    (pipeline.output.flat). A peak with no value to design with is left out of the study
    (no value, side, crossing or plot; flat decides which), and the row's note says why,
    as the run's report does; one at a singular feature gets the verdict "none", as in the
    run's verdict table (the case cannot pass)."""
    row = dict(base, **r, status="done")
    for block, p in flat.PEAKS.items():
        if r[p.status] == flat.SINGULAR:
            row[VERDICT_OF[block]] = "none"
    notes = [r[p.note] for p in flat.PEAKS.values() if r[p.note]]
    if notes:
        row["note"] = "; ".join(notes)
    return row


def variant_files(out: Path, key: str) -> tuple[dict | None, str | None, str | None]:
    """What task ``key`` of the study in ``out`` left, read only when its files match
    their checksums (pipeline.study.manifest): (its results.json or None, why it failed
    or None, why what it left cannot be read or None). A file edited or cut short after
    its run is never summarised."""
    failed, folder = failure_file(out, key), variant_folder(out, key)
    why = None
    if failed.is_file():
        try:
            return None, str(read_failure(failed)["error"]), None
        except (VariantFault, KeyError) as exc:
            why = str(exc) if isinstance(exc, VariantFault) else f"{failed.name} names no error"
    if folder.is_dir():
        try:
            return read_results(folder), None, None
        except VariantFault as exc:
            why = str(exc)
    return None, None, why


def series(rows: list[dict], axis: str, status: str = "done") -> dict[tuple, list[dict]]:
    """The rows of ``status`` (the finished ones by default) as lines along ``axis``: one
    list per combination of the size, the other swept parameters and the load, keyed by
    those (name, value) pairs, sorted by ``axis``."""
    others = [k for k in rows[0] if k not in COLUMNS and k != axis] if rows else []
    fixed_keys = ["size"] + others + (["load_N"] if axis != "load_N" else [])
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["status"] == status and r.get(axis) is not None:
            groups.setdefault(tuple((k, r.get(k)) for k in fixed_keys), []).append(r)
    return {fixed: sorted(g, key=lambda r: r[axis]) for fixed, g in groups.items()}


def crossings(rows: list[dict], axis: str, allowable: float) -> list[dict]:
    """Where each peak crosses the allowable along ``axis`` (the other parameters fixed):
    linear interpolation between neighbouring variants; the range, when both neighbours
    have a band, is where the allowable lies within value ± band between them
    (:func:`band_reach`), and ``range_reaches`` names the neighbours it reaches (their own
    bands hold the allowable: the crossing may lie beyond them). ``only_crossing``:
    every variant of the line before it lies on one side and every one after it on the
    other, so the peak stays on its new side up to ``last``, the line's last value."""
    found = []
    for fixed, (key, band_key, label), group, i in crossing_pairs(rows, axis, allowable):
        a, b = group[i], group[i + 1]
        ya, yb = a[key] - allowable, b[key] - allowable
        x = a[axis] + ya / (ya - yb) * (b[axis] - a[axis])
        lo_hi, reaches = None, []
        if a.get(band_key) is not None and b.get(band_key) is not None:
            t0, t1 = band_reach(ya, yb, a[band_key], b[band_key])
            lo_hi = [a[axis] + t * (b[axis] - a[axis]) for t in (t0, t1)]
            reaches = [r[axis] for r, t in ((a, t0), (b, t1)) if t in (0.0, 1.0)]
        falls = yb < ya
        before, after = group[:i + 1], group[i + 1:]
        only = (all((r[key] >= allowable) == falls for r in before)
                and all((r[key] < allowable) == falls for r in after))
        found.append({"peak": label, "axis": axis, "at": x, "range": lo_hi, "range_reaches": reaches,
                      "falls_below": falls, "fixed": dict(fixed),
                      "only_crossing": only, "last": group[-1][axis]})
    return found


def crossing_pairs(rows: list[dict], axis: str, allowable: float):
    """The neighbouring variants between which a peak crosses the allowable (MPa) along
    ``axis``: per line of :func:`series` and peak, (the line's fixed (name, value) pairs,
    the peak's (value, band, name) columns, the line's rows that have the peak, the index
    of the first of the two). A row on the allowable counts as a crossing to its next."""
    for fixed, line in series(rows, axis).items():
        for cols in PEAKS:
            key = cols[0]
            group = [r for r in line if r.get(key) is not None]  # a peak not asked for has none
            for i, (a, b) in enumerate(zip(group, group[1:])):
                ya, yb = a[key] - allowable, b[key] - allowable
                if ya == 0 or ya * yb < 0:
                    yield fixed, cols, group, i


def escalations(rows: list[dict], axes: list[str], allowable: float) -> dict[str, tuple[str, str]]:
    """The variants of a screened study that need more than they have, each with why and
    how far: a neighbour of a crossing of the allowable along one of ``axes`` goes to the
    full error bar (its value and band set the crossing's place and range); a row whose
    band holds the allowable (MPa) or that has a singular peak
    (pipeline.study.screening.undecided) takes the next steps (screening.NEXT_STEPS).
    Rows already analysed in full count as they are."""
    from pipeline.study.screening import FULL, NEXT_STEPS, undecided
    why: dict[str, tuple[str, str]] = {}
    for axis in axes:
        for _, (_, _, label), group, i in crossing_pairs(rows, axis, allowable):
            for r in group[i:i + 2]:
                why.setdefault(r["variant"], (f"it borders a crossing of the {label} along "
                                              f"{axis.replace('dims.', '')}", FULL))
    for r in rows:
        if r["status"] == "done" and undecided(r, allowable):
            why.setdefault(r["variant"], (f"its band holds the allowable {allowable:g} MPa", NEXT_STEPS))
    return why


def band_reach(ya: float, yb: float, wa: float, wb: float) -> tuple[float, float]:
    """Where between two neighbouring variants (t = 0 at the first, 1 at the second) the
    allowable lies within the error bar: |y(t)| <= w(t), with y = peak − allowable (MPa)
    going from ya to yb across zero and the band w from wa to wb, both linear in t. Two
    linear conditions, y − w <= 0 and −y − w <= 0, each hold on a part of [0, 1] that ends
    where it changes sign; the crossing y = 0 satisfies both, so the interval holds it.
    (Crossing the band's edges with the allowable instead can put both ends on one side of
    the crossing, or outside the step, when the bands differ much.)"""
    lo, hi = 0.0, 1.0
    for f0, f1 in ((ya - wa, yb - wb), (-ya - wa, -yb - wb)):
        if f0 > 0:
            lo = max(lo, f0 / (f0 - f1))
        elif f1 > 0:
            hi = min(hi, f0 / (f0 - f1))
    return lo, hi


def with_verdicts(rows: list[dict], allowable: float) -> list[dict]:
    """``rows`` with each finished row's verdict per peak against the allowable (MPa), its
    error bar included, as a run's verdict table says it (errorbar.verdict_against); none
    for a peak the row has no value of."""
    for r in rows:
        if r["status"] == "done":
            for key, band_key, name in VERDICT_KEYS:
                if r.get(key) is not None:
                    r[name] = verdict_against(r[key], r.get(band_key), allowable)
                else:
                    r.setdefault(name, None)  # rows_of's "none" of a singular peak stays
    return rows


def swept_axes(axes: dict[str, list[float]]) -> list[str]:
    """The axes a study's lines run along: those with several values, numeric only (not
    the hook number)."""
    return [n for n in axes if len(axes[n]) > 1 and n != "size"]


def write_outputs(tasks: list[Task], out: Path, axes: dict[str, list[float]], allowable: float) -> dict:
    """sweep.csv, sweep.json, plots, report.md and report.html from the variants' results (rank 0)."""
    rows = with_verdicts(rows_of(tasks, out), allowable)
    names = [n for n in axes]
    cols = list(COLUMNS) + [n for n in names if n not in COLUMNS]
    # Sizes as 'No. 05' and keys as their folders: text to any reader (a key of digits alone read as a number).
    write_text(out / "sweep.csv", flat.csv_text(cols, [dict(r, variant=f"variants/{r['variant']}") for r in rows]))
    swept = swept_axes(axes)
    cross = [c for n in swept for c in crossings(rows, n, allowable)]
    first = next((t.case for t in tasks if t.case is not None), None)
    summary = {"units": {"length": "mm", "force": "N", "stress": "MPa"}, "allowable_MPa": allowable,
               "mesh_factor": None if first is None else first.mesh_factor,
               "notes": notes_of(rows), "axes": axes, "rows": rows, "crossings": cross,
               "counts": {s: sum(r["status"] == s for r in rows) for s in ("done", "invalid", "failed", "not run")}}
    write_text(out / "sweep.json", json.dumps(summary, indent=2, default=str) + "\n")
    plots = [p for n in swept for p in _plots(rows, n, allowable, out)]
    # A re-run into the same folder must not leave a plot this run no longer draws (another
    # axis, a peak now left out) beside the report: only the study's own plot names.
    for old in [*out.glob("peak_vs_*.png"), *out.glob("critical_peak_vs_*.png")]:
        if old.name not in plots:
            old.unlink(missing_ok=True)
    text = _report(summary, swept, plots)
    write_text(out / "report.md", text)
    write_text(out / "report.html", html_document(text, out, "Design study"))
    return summary


def notes_of(rows: list[dict]) -> list[str]:
    """The notes of the study's finished variants (each run's own, as its terminal and
    report say them; a row's notes together), each once, in the order first met."""
    return list(dict.fromkeys(r["notes"] for r in rows if r.get("status") == "done" and r.get("notes")))


def _plots(rows: list[dict], axis: str, allowable: float, out: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    lines = series(rows, axis)
    if not lines:
        return []
    # One line per combination of the other parameters, named by those that differ; the
    # values every line shares go into the title.
    varying = varying_names(rows, {k for fixed in lines for k, _ in fixed})
    common = _fixed_text([(k, v) for k, v in next(iter(lines)) if k not in varying], None)
    names = []
    for key, band_key, label in PEAKS:
        if not any(r.get(key) is not None for g in lines.values() for r in g):
            continue  # a peak no variant was asked for (--want): no plot
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        colors = {}
        for fixed, g in lines.items():
            g = [r for r in g if r.get(key) is not None]
            text = _fixed_text(fixed, varying)
            drawn = ax.errorbar([r[axis] for r in g], [r[key] for r in g], yerr=[r.get(band_key) or 0 for r in g],
                                marker="o", capsize=3, lw=1, label=text or None)
            colors[text] = drawn[0].get_color()
        ax.axhline(allowable, color="red", ls="--", label=f"allowable {allowable:g} MPa")
        # Variants with no peak still belong on the axis, on its line: where the geometry
        # rules end the design space, or where an analysis failed.
        for (status, text), xs in unanalysed(rows, axis, varying).items():
            what = UNANALYSED[status]
            ax.plot(xs, [0.0] * len(xs), ls="none", marker="x" if status == "invalid" else "X",
                    color=colors.get(text, "0.45"), ms=9, mew=2, transform=ax.get_xaxis_transform(),
                    clip_on=False, zorder=5, label=f"{text}: {what}" if text else what)
        if common:
            ax.set_title(common, fontsize=10)
        ax.set_xlabel("load (N)" if axis == "load_N" else f"{axis.replace('dims.', '')} (mm)")
        ax.set_ylabel(f"{label} von Mises (MPa)")
        # Below the axes: inside, a legend of several lines covered their points.
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, frameon=False)
        fig.tight_layout()
        name = f"{key.replace('_MPa', '')}_vs_{axis.replace('dims.', '')}.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        names.append(name)
    return names


def unanalysed(rows: list[dict], axis: str, varying: set[str]) -> dict[tuple[str, str], list[float]]:
    """The values along ``axis`` of the variants that have no peak, each once, sorted, keyed
    by (status, their line's ``varying`` values as text: '' for a study of one line).
    Statuses: those of UNANALYSED. An invalid geometry is invalid at every load, so its
    text leaves the load out (one mark, not one per load)."""
    out: dict[tuple[str, str], set[float]] = {}
    for status in UNANALYSED:
        for fixed, g in series(rows, axis, status).items():
            named = [(k, v) for k, v in fixed if not (status == "invalid" and k == "load_N")]
            out.setdefault((status, _fixed_text(named, varying)), set()).update(r[axis] for r in g)
    return {k: sorted(v) for k, v in out.items()}


def sides(rows: list[dict], allowable: float) -> list[dict]:
    """For each peak: how many finished rows lie above the allowable (MPa), how many below,
    how many within their error bar of it, and the rows with the lowest and highest value.
    A peak that no finished row has is left out."""
    out = []
    for key, band_key, label in PEAKS:
        have = [r for r in rows if r["status"] == "done" and r.get(key) is not None]
        if not have:
            continue
        near = [r for r in have if abs(r[key] - allowable) <= (r.get(band_key) or 0.0)]
        out.append({"peak": label, "key": key, "rows": len(have),
                    "above": sum(r[key] > allowable for r in have), "within_band": len(near),
                    "lowest": min(have, key=lambda r: r[key]), "highest": max(have, key=lambda r: r[key])})
    return out


def value_text(name: str, value: float | str) -> str:
    """One input for a person, with its unit: 'rf = 0.5 mm', 'load = 12000 N', 'No. 2.5'."""
    if name == "size":
        return f"No. {value}"
    if name == "load_N":
        return f"load = {value:g} N"
    return f"{name.replace('dims.', '')} = {value:g} mm"


def inputs_text(params: dict, load_N: float | None = None) -> str:
    """A variant's swept inputs for a person: 'No. 2.5, dj = 16 mm, rf = 0.5 mm' (the size
    first), then the load (N) when given; 'the base case' when none."""
    parts = [value_text(k, v) for k, v in sorted(params.items(), key=lambda kv: (kv[0] != "size", kv[0]))]
    if load_N is not None:
        parts.append(value_text("load_N", load_N))
    return ", ".join(parts) or "the base case"


def parameters_text(row: dict, with_load: bool = False) -> str:
    """A row's swept inputs for a person (:func:`inputs_text`), and its load when
    ``with_load`` (a study over loads)."""
    return inputs_text(json.loads(row["parameters"]), row.get("load_N") if with_load else None)


def _side_lines(summary: dict) -> list[str]:
    """One line per peak: above or below the allowable in every variant, or how many on
    each side, with its lowest and highest value and where."""
    a = summary["allowable_MPa"]
    loads = "load_N" in varying_names(summary["rows"], {"load_N"})  # then a row is named with its load
    lines = []
    for sd in sides(summary["rows"], a):
        key, lo, hi = sd["key"], sd["lowest"], sd["highest"]
        span = (f"{lo[key]:.2f} MPa ({parameters_text(lo, loads)}) to {hi[key]:.2f} MPa ({parameters_text(hi, loads)})"
                if lo is not hi else f"{lo[key]:.2f} MPa")
        if sd["above"] == sd["rows"]:
            where = f"above {a:g} MPa in every analysed case"
        elif sd["above"] == 0:
            where = f"below {a:g} MPa in every analysed case"
        else:
            where = f"above {a:g} MPa in {sd['above']} of {sd['rows']} analysed cases"
        near = (f"; {sd['within_band']} within their error bar of it" if sd["within_band"] else "")
        lines.append(f"- The {sd['peak']} is {where}: {span}{near}.")
    return lines


MOST_NAMED = 12  # cases named in a line of the report; more are counted


def _verdicts(row: dict) -> set[str]:
    """The verdicts of the peaks a row has (with_verdicts)."""
    return {row[k] for _, _, k in VERDICT_KEYS if row.get(k) is not None}


def passing_count(rows: list[dict]) -> int:
    """How many analysed cases pass with every peak they have, error bars included."""
    return sum(r["status"] == "done" and _verdicts(r) <= {"pass"} for r in rows)


def _passing_lines(summary: dict) -> list[str]:
    """Which analysed cases pass with every peak they have (value + error bar at or below
    the allowable), named when some do and some do not, and which are undecided (an error
    bar holds the allowable, no peak fails): the study's answer to 'which variants pass at
    this allowable?'."""
    done = [r for r in summary["rows"] if r["status"] == "done"]
    if not done:
        return []
    loads = "load_N" in varying_names(summary["rows"], {"load_N"})
    a = f"{summary['allowable_MPa']:g} MPa"

    def named(rows: list[dict]) -> str:
        more = len(rows) - MOST_NAMED
        return "; ".join(parameters_text(r, loads) for r in rows[:MOST_NAMED]) + (f"; and {more} more" if more > 0 else "")
    passing = [r for r in done if _verdicts(r) <= {"pass"}]
    undecided = [r for r in done if "undecided" in _verdicts(r) and not _verdicts(r) & {"fail", "none"}]
    if len(passing) == len(done):
        lines = [f"- Every analysed case passes {a} with every peak, error bars included."]
    elif not passing:
        lines = [f"- No analysed case passes {a} with every peak, error bars included."]
    else:
        lines = [f"- {len(passing)} of {len(done)} analysed cases pass {a} with every peak, error bars "
                 f"included: {named(passing)}."]
    if undecided:
        lines.append(f"- Undecided in {len(undecided)} of {len(done)} (an error bar holds {a}, no peak fails): "
                     f"{named(undecided)}.")
    judged_none = [r for r in done if "none" in _verdicts(r)]
    if judged_none:
        lines.append(f"- No verdict in {len(judged_none)} of {len(done)} (a peak at a singular feature has no "
                     f"finite value): {named(judged_none)}.")
    return lines


def crossing_text(x: dict, allowable: float, varying: set[str] | None = None) -> str:
    """A crossing of :func:`crossings` as a line of the report: where (mm or N), its range
    from the error bars, and the values of the other parameters, of those in ``varying``
    (the ones that differ across the study; all when None)."""
    axis = x["axis"]
    unit, name = ("N", "load") if axis == "load_N" else ("mm", axis.replace("dims.", ""))
    num = (lambda v: f"{v:.0f}") if axis == "load_N" else (lambda v: f"{v:.4g}")
    fixed = _fixed_text(x["fixed"].items(), varying)
    rng = ""
    if x["range"]:
        reach = x.get("range_reaches") or []
        beyond = ("" if not reach else f", which reach the variant{'s' if len(reach) > 1 else ''} at "
                  + " and ".join(f"{num(v)} {unit}" for v in reach) + ": it may lie beyond")
        rng = f" (between {num(x['range'][0])} and {num(x['range'][1])} {unit} within the error bars{beyond})"
    word = "falls below" if x["falls_below"] else "rises above"
    stays = (f" and stays {'below' if x['falls_below'] else 'above'} it in every variant up to "
             f"{name} = {num(x['last'])} {unit}" if x.get("only_crossing") else "")
    return (f"- The {x['peak']} {word} {allowable:g} MPa at {name} ≈ {num(x['at'])} {unit}{rng}{stays}"
            + (f", for {fixed}" if fixed else "") + ".")


def screening_lines(rows: list[dict]) -> list[str]:
    """A screened study's evidence: how many variants its cheap level decided, on what
    (mesh, bands), and which got the full error bar and why; nothing for a study that was
    not screened."""
    by: dict[str, list[dict]] = {}
    for r in rows:
        if r["status"] == "done" and r.get("decided_by"):
            by.setdefault(r["decided_by"], []).append(r)
    if not by:
        return []
    n = sum(len(v) for v in by.values())
    cheap = sum(len(v) for k, v in by.items() if k.startswith("screened"))
    lines = [f"- Screened study: {cheap} of {n} analysed cases decided on the cheap level, "
             f"{n - cheap} with the full error bar (docs/sweeps.md, *Screened studies*)."]
    for how, rs in by.items():
        more = len(rs) - MOST_NAMED
        names = "; ".join(parameters_text(r, False) for r in rs[:MOST_NAMED]) + (f"; and {more} more" if more > 0 else "")
        lines.append(f"  - {how}: {names}.")
    return lines


def _report(summary: dict, swept: list[str], plots: list[str]) -> str:
    c = summary["counts"]
    L = ["# Design study\n", "Units: mm, N, MPa.\n",
         f"{c['done']} cases analysed, {c['invalid']} invalid (skipped), {c['failed']} failed, "
         f"{c['not run']} not run (a case is a variant at one load). "
         f"Allowable {summary['allowable_MPa']:g} MPa.\n"]
    mf = summary.get("mesh_factor")
    if mf is not None:
        L.append(f"Every variant at mesh factor {mf:g}.\n")
    L += [f"> **Note:** {n}.\n" for n in summary.get("notes") or []]
    L.append(f"## Against the allowable ({summary['allowable_MPa']:g} MPa)\n")
    L += _side_lines(summary)
    L += _passing_lines(summary)
    L += screening_lines(summary["rows"])
    L.append("")
    # A study over sizes alone has no numeric axis to cross the allowable along: no line.
    if swept and not summary["crossings"]:
        L.append("No peak crosses the allowable between neighbouring variants of a swept parameter.\n")
    elif summary["crossings"]:
        L.append("Where a peak crosses the allowable between neighbouring variants (linear "
                 "interpolation; the range from their error bars):\n")
    varying = varying_names(summary["rows"], {k for x in summary["crossings"] for k in x["fixed"]})
    L += [crossing_text(x, summary["allowable_MPa"], varying) for x in summary["crossings"]]
    L.append("")
    L.append("## Variants\n")
    L.append("| variant | status | parameters | load (N) | global peak (MPa) | critical peak (MPa) "
             "| verdict (global / critical) | note |")
    L.append("|---|---|---|---|---|---|---|---|")
    for r in summary["rows"]:
        def f(v, band=None):
            return "" if v is None else pm(v, band)
        verdicts = " / ".join(r.get(k) or "–" for k in ("verdict", "critical_verdict")) if r["status"] == "done" else ""
        L.append(f"| {r['variant']} | {r['status']} | {parameters_text(r)} | {_n0(r.get('load_N'))} | "
                 f"{f(r.get('peak_MPa'), r.get('peak_band_MPa'))} | "
                 f"{f(r.get('critical_peak_MPa'), r.get('critical_band_MPa'))} | "
                 f"{verdicts} | {r.get('note') or ''} |")
    L.append("")
    L += _rests_on_lines(summary["rows"])
    for p in plots:
        L.append(f"![{p}]({p})\n")
    return "\n".join(L) + "\n"


def _rests_on_lines(rows: list[dict]) -> list[str]:
    """What each variant's verdict rests on (sweep --sensitivity): how many keep their verdict
    over every assumed input's range, then the variants whose verdict flips, and those not
    checked over every range (an end not analysed), each named with its sentence; nothing
    without it."""
    from pipeline.analysis.words import FLIPS, HOLDS, rests_on
    told = [r for r in rows if r["status"] == "done" and r.get("verdict_rests_on")]
    if not told:
        return []
    kind = {id(r): rests_on(r["verdict_rests_on"]) for r in told}
    flips = [r for r in told if kind[id(r)] == FLIPS]
    unchecked = [r for r in told if kind[id(r)] not in (FLIPS, HOLDS)]
    holds = len(told) - len(flips) - len(unchecked)
    L = ["## What the verdicts rest on\n",
         f"{holds} of {len(told)} analysed variants keep their verdict over every assumed "
         "input's range (each variant's report.md and results.json: the ranges and values)"
         + (": the others depend on an assumption or were not checked over every range:\n"
            if flips or unchecked else ".\n")]
    L += [f"- {r['variant']} ({parameters_text(r)}): {r['verdict_rests_on']}" for r in flips + unchecked]
    return L + ([""] if flips or unchecked else [])


def _n0(v: float | None) -> str:
    """A load (N) for the table: whole newtons, empty when there is none."""
    return "" if v is None else f"{v:.0f}"


def varying_names(rows: list[dict], names: set[str]) -> set[str]:
    """Of ``names``, those whose value differs between the study's finished rows."""
    done = [r for r in rows if r["status"] == "done"]
    return {k for k in names if len({r.get(k) for r in done}) > 1}


def _fixed_text(fixed: Iterable[tuple[str, float | str | None]], varying: set[str] | None) -> str:
    """The values of a line's other parameters for a person ('dj = 16 mm, load = 10000 N'),
    of those in ``varying`` (all when None); empty when none is left."""
    return ", ".join(value_text(k, v) for k, v in fixed if v is not None and (varying is None or k in varying))
