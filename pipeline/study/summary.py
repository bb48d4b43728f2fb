"""Batch summary across hook sizes: Markdown and CSV tables and a plot (mm, N, MPa, s).

    python -m pipeline.study.summary results --out results/summary

reads every ``results/<size>/results.json`` written by ``python -m pipeline run`` (one
folder per hook number of geometry/sizes.csv; ``--all`` takes every folder that holds a
results.json) and writes ``summary.md``, ``summary.csv`` and ``summary.png`` into the
output folder. ``make sizes`` runs it after every size target.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
import tempfile
from pathlib import Path

from geometry.table import is_scaled_row

from pipeline.analysis.words import PEAK_STATUSES
from pipeline.errors import OneLineParser
from pipeline.output import flat
from pipeline.output.flat import NOT_ASKED, PEAKS, SINGULAR
from pipeline.runtime.interrupts import EXIT_FOR, NOTHING_WRITTEN, STOPPED
from pipeline.runtime.streams import silence_stdout

_S_RE = re.compile(r"s = sqrt\(Q/1000 kg\) = ([0-9.]+)")

# The summary's own columns; the rest are those of a run's row (pipeline.output.flat).
OWN_COLUMNS = {
    "dimensions": "where the row's dimensions come from: the size table's row, or scaled from No. 05 (not DIN)",
    "scale_s": "the scale s = sqrt(Q/1000 kg) of a scaled row's lengths from No. 05; 1 for No. 05",
    "warnings": "why the row's FE numbers need a look first (nearly inverted element, wide error bar)",
}
CSV_COLUMNS = ("size", "dimensions", "scale_s", *(c for c in flat.COLUMNS if c != "size"), "warnings")

SUMMARY_FILES = frozenset({"summary.md", "summary.csv", "summary.png"})
TITLE = "# Crosshead stresses across hook sizes"  # summary.md's first line
JACOBIAN_SUSPECT = 0.01   # worst det J ratio of a curved tet below this: nearly inverted
BAND_TOO_WIDE = 0.25      # error bar above this fraction of the value: not usable


def hook_value(size: str) -> float:
    """Numeric hook number for sorting: "025" → 0.25, "04" → 0.4, "1.6" → 1.6, "10" → 10."""
    try:
        if size.startswith("0") and "." not in size and len(size) > 1:
            return float("0." + size[1:])
        return float(size)
    except ValueError:
        return math.inf


def row_of(folder: Path, res: dict) -> dict:
    """One summary row (CSV_COLUMNS and the folder) from one results.json: the run's row
    at the case's own load (pipeline.output.flat), with where its dimensions come from."""
    from pipeline.study.table import decided_rows
    rows = decided_rows(res, folder)  # a screened study's variant as the study decided it
    row = next((r for r in rows if r["load_N"] == res["case"]["load_N"]), rows[0])
    src = row["source"]
    m = _S_RE.search(src)
    scaled = is_scaled_row(src)
    return {**row, "size": row["size"] if row["size"] is not None else folder.name, "folder": folder.name,
            "dimensions": "scaled (not DIN)" if scaled else "table row (see source)",
            "scale_s": float(m.group(1)) if (scaled and m) else (1.0 if row["size"] == "05" else None)}


TEXT_COLUMNS = flat.TEXT_COLUMNS | {"folder", "dimensions", "decided_by"}
NEEDED_COLUMNS = frozenset({"load_N", "approximate_MPa", "exact_MPa",
                            *(c for p in PEAKS.values() for c in (p.value, p.reading))})


def checked(row: dict) -> dict:
    """``row`` if every value has the type its column needs (text, or a finite number or
    nothing), else ValueError naming the first that does not: a results.json edited or
    cut short by hand must not stop the summary half-way."""
    for k, v in row.items():
        if k in TEXT_COLUMNS:
            ok = isinstance(v, str)
        else:
            ok = (v is None and (k not in NEEDED_COLUMNS or _may_lack(row, k))) or (
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))
        if not ok:
            raise ValueError(f"{k} = {v!r}")
    return row


def _may_lack(row: dict, column: str) -> bool:
    """Whether a needed peak column may be empty: the value of a peak with none to design
    with (flat.has_value), or the reading of a peak the run was not asked for."""
    return any((column == p.value and not flat.has_value(row, p))
               or (column == p.reading and row.get(p.status) == NOT_ASKED) for p in PEAKS.values())


def warnings_of(r: dict) -> list[str]:
    """Short reasons a person should not trust a row's FE numbers as they stand."""
    out = []
    jac = r.get("mesh_min_jacobian_ratio")
    if jac is not None and jac < JACOBIAN_SUSPECT:
        out.append(f"nearly inverted curved element on the finest mesh (det J ratio {jac:.2g})")
    for p, name in ((PEAKS["peak"], "global"), (PEAKS["critical"], "critical")):
        band, value = r[p.band], r[p.value]
        if band is not None and value and band > BAND_TOO_WIDE * abs(value):
            out.append(f"{name} error bar {100 * band / abs(value):.0f} % of the value")
    return out


def collect(results_dir: Path, take_all: bool = False) -> tuple[list[dict], list[str]]:
    """Rows for every size folder with a results.json, sorted by hook number; and notes
    on folders that were skipped. A design study's variant (in its ``variants/`` folder,
    or any folder with a variant's checksums) is read only when its files match their
    checksums (pipeline.study.manifest): one edited or cut short is named, not summarised."""
    from pipeline.runtime.folders import marked_kind
    from pipeline.study.manifest import MANIFEST, VariantFault, folder_fault, read_failure
    sizes = None if take_all else set(flat.size_table())
    in_study = results_dir.name == "variants" and marked_kind(results_dir.parent) == "sweep"
    listed = set(study_variants(results_dir)) if in_study else set()
    rows, skipped, unnamed = [], [], []
    for sub in sorted(p for p in results_dir.iterdir() if p.is_dir()):
        f = sub / "results.json"
        if not f.is_file():
            # A variant's folder, or a run's results folder, without its results: named,
            # never dropped in silence (a folder of other files is not a result).
            if (sub / MANIFEST).exists() or marked_kind(sub) == "run" or sub.name in listed:
                skipped.append(f"{sub.name} (results.json is missing; not summarised)")
            continue
        if sizes is not None and sub.name not in sizes:
            unnamed.append(sub.name)
            continue
        why = folder_fault(sub) if in_study or (sub / MANIFEST).exists() else None
        if why is not None:
            skipped.append(f"{sub.name} ({why}; not summarised)")
            continue
        try:
            row = checked(row_of(sub, json.loads(f.read_text(encoding="utf-8"))))
            row["warnings"] = "; ".join(warnings_of(row))
            rows.append(row)
        except (OSError, KeyError, TypeError, ValueError, AttributeError) as exc:
            skipped.append(f"{sub.name} (unreadable results.json: {type(exc).__name__}: {exc})")
    for f in sorted(results_dir.glob("*.failed.json")):  # a study's variant that failed (pipeline.study.sweep)
        try:
            failed = read_failure(f)
            skipped.append(f"No. {failed['size']} (its analysis failed: {failed['error']})")
        except VariantFault as exc:
            skipped.append(f"{f.name} (a failed variant: {exc}; not summarised)")
        except (KeyError, TypeError):
            skipped.append(f"{f.name} (a failed variant; its note cannot be read)")
    skipped += missing_variants(results_dir) if in_study else []
    if unnamed:  # said once: a study's variants/ folder has one per variant
        skipped.append(f"{', '.join(unnamed[:3])}{f' and {len(unnamed) - 3} more' if len(unnamed) > 3 else ''} "
                       "(not named for a hook number of the size table; use --all, as for a study's variants/)")
    rows.sort(key=lambda r: (hook_value(r["size"]), r["folder"]))
    return rows, skipped


def study_variants(variants: Path) -> dict[str, str]:
    """The variants of the study whose ``variants`` folder this is, by key, with their
    status, as its table (sweep.json beside it) lists them; empty when it cannot be read."""
    try:
        rows = json.loads((variants.parent / "sweep.json").read_text(encoding="utf-8"))["rows"]
        return {str(r["variant"]): str(r.get("status")) for r in rows}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


def missing_variants(variants: Path) -> list[str]:
    """The variants a study's table lists as analysed whose folder in ``variants`` is gone:
    named, since nothing else of them is left to name."""
    return [f"{key} (its folder is missing; not summarised)" for key, status in sorted(study_variants(variants).items())
            if status == "done" and "/" not in key and not (variants / key).is_dir()]


def _n(v: float | None, digits: int = 2) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _fe_cell(r: dict, key: str) -> str:
    """FE peak with its error bar, or why it has none (MPa); a singular peak's reading
    with why it is no value (``key``: the peak's fe block, peak or critical)."""
    p = PEAKS[key]
    value, band, status = r[p.value], r[p.band], r[p.status]
    if status == NOT_ASKED:
        return "–"
    change = r[p.last_change]
    if status == SINGULAR:
        if change is None:  # found by its place, on one mesh
            return f"{r[p.reading]:.2f} (NOT CONVERGED: singular feature)"
        return f"{r[p.reading]:.2f} (NOT CONVERGED: grows; last refinement {change:+.2f})"
    if band is None:
        return f"{value:.2f} (no error bar)"
    return f"{value:.2f} ± {band:.2f}"


def csv_text(rows: list[dict]) -> str:
    """summary.csv: one line per row, CSV_COLUMNS (N, MPa, s; empty where there is no value;
    the size as its label 'No. 05', text to any reader)."""
    return flat.csv_text(CSV_COLUMNS, rows)


def markdown(rows: list[dict], skipped: list[str], png_name: str | None) -> str:
    """summary.md: the table of every row (N, MPa, s), the rows to check before using their
    FE numbers, notes on what the rows share or lack, and the plot ``png_name`` if drawn."""
    lines = _table_lines(rows)
    lines.append("")
    lines += _warning_lines(rows)
    lines += _rests_on_lines(rows)
    if not rows:
        lines.append("No results found.")
    notes = _source_notes(rows)
    places = []
    for name, p in (("Global", PEAKS["peak"]), ("Critical", PEAKS["critical"])):
        asked = [r for r in rows if r[p.status] != NOT_ASKED]
        if asked:
            places.append(f"{name} peak at: {_peak_places(asked, p.feature)}.")
    if places:
        notes.append(" ".join(places))
    notes += _status_notes(rows)
    notes += _screening_notes(rows)
    notes += _run_notes(rows, skipped)
    lines += [f"- {n}" for n in notes]
    if png_name:
        lines += ["", f"![stresses against hook number]({png_name})"]
    return "\n".join(lines) + "\n"


def _rests_on_lines(rows: list[dict]) -> list[str]:
    """Which sizes' verdicts depend on an assumed input (from each run's sensitivity
    sentence; the study ran with --sensitivity), and which were not checked over every
    range (an end not analysed); nothing when no row has one."""
    from pipeline.analysis.words import FLIPS, HOLDS, rests_on
    told = [r for r in rows if r.get("verdict_rests_on")]
    if not told:
        return []
    others = [r for r in told if rests_on(r["verdict_rests_on"]) != HOLDS]
    flips = [r for r in others if rests_on(r["verdict_rests_on"]) == FLIPS]
    lines = [f"**What the verdicts rest on:** {len(told) - len(others)} of {len(told)} sizes keep their verdict over "
             "every assumed input's range (dj, rf, seat, the bearing load model; each run's report gives the "
             "ranges)" + (". These depend on an assumption:" if flips and flips == others else
                          ". These depend on an assumption or were not checked over every range:" if others else "."),
             ""]
    lines += [f"- No. {r['size']}: {r['verdict_rests_on']}" for r in others]
    return lines + ([""] if others else [])


def _table_lines(rows: list[dict]) -> list[str]:
    """The title, what the columns mean, and the table: one line per row, ⚠ on the rows
    with warnings (N, MPa, s)."""
    lines = [
        TITLE,
        "",
        "Units: N, MPa, s. Formulas: the paper's approximate (span b1 + b2) and exact "
        "(curved bar, span b6) hand formulas. FE: peak von Mises on the finest mesh, over the "
        "whole part (global) and over the ligaments beside the bore (critical, |x| ≤ d2/2); at the "
        "fillet the midpoint of the unaveraged and averaged nodal readings, elsewhere the "
        "unaveraged element-node value. ± the peak's error bar: the band of the mesh-refinement "
        "study or, for a fillet peak, half the gap between its two readings when that is larger; "
        "its status in the next column (explained below). Safety factor = allowable / FE peak.",
        "",
        "| No. | dimensions | load (N) | approx. (MPa) | exact (MPa) | FE global peak (MPa) | status "
        "| FE critical peak (MPa) | status | SF global | SF critical | DOFs | time (s) |",
        "|---|---|--:|--:|--:|--:|---|--:|---|--:|--:|--:|--:|",
    ]
    for r in rows:
        dims = r["dimensions"] if r["scale_s"] in (None, 1.0) or r["dimensions"].startswith("table row") \
            else f"scaled ×{r['scale_s']:.3f} (not DIN)"
        if r["changed_dims"]:
            dims += f"; changed: {r['changed_dims']}"
        flag = " ⚠" if _flagged(r) else ""
        lines.append(
            f"| {r['size']}{flag} | {dims} | {r['load_N']:.0f} | {_n(r['approximate_MPa'])} | "
            f"{_n(r['exact_MPa'])} | {_fe_cell(r, 'peak')} | "
            f"{r['peak_status']} | "
            f"{_fe_cell(r, 'critical')} | "
            f"{r['critical_status']} | {_n(r['safety_factor'])} | {_n(r['critical_safety_factor'])} | "
            f"{r['dofs'] if r['dofs'] is not None else '–'} | {_n(r['time_s'], 1)} |")
    return lines


def _flagged(r: dict) -> bool:
    """Whether a row is marked for a look first: it has warnings (:func:`warnings_of`) or its
    run's notes (a mesh too coarse for the fillet, as the run said)."""
    return bool(r.get("warnings") or r.get("notes"))


def _warning_lines(rows: list[dict]) -> list[str]:
    """The rows whose FE numbers need a look first (see :func:`warnings_of`), each with
    its reasons, after what the thresholds mean; then the runs' notes, each once with the
    rows it is of; nothing when no row is flagged."""
    if not any(_flagged(r) for r in rows):
        return []
    lines = [f"**⚠ Check these rows before using their FE numbers** (a curved tet with det J "
             f"ratio below {JACOBIAN_SUSPECT:g} can carry a spurious peak; an error bar above "
             f"{100 * BAND_TOO_WIDE:.0f} % of the value means one of the meshes disagrees wildly: "
             "look at its levels in results.json, rerun finer or with another --mesh-factor):", ""]
    lines += [f"- No. {r['size']}: {r['warnings']}." for r in rows if r.get("warnings")]
    by_note: dict[str, list[str]] = {}
    for r in rows:
        if r.get("notes"):
            by_note.setdefault(r["notes"], []).append(r["size"])
    lines += [f"- {'Every row' if len(sizes) == len(rows) else 'No. ' + ', '.join(sizes)}: {note}."
              for note, sizes in by_note.items()]
    lines.append("")
    return lines


def _source_notes(rows: list[dict]) -> list[str]:
    """Where the rows' dimensions come from: the rows taken from the table as given, with
    their sources, and what the scaled (not DIN) rows are."""
    notes = []
    own = {r["size"]: r["source"] for r in rows if r["dimensions"].startswith("table row")}
    if own:  # each size once: a study's variants are several rows of one size
        notes.append("Rows from the table (not scaled): " + "; ".join(
            f"No. {size}: {source}" for size, source in own.items()) + ".")
    if any(r["changed_dims"] for r in rows):
        notes.append("Rows with *changed* dimensions differ from their size's table row in the "
                     "dimensions named (mm); the formulas and the FE are of the changed part.")
    if any(not r["dimensions"].startswith("table row") for r in rows):
        notes.append(
            "Rows marked *scaled* are NOT DIN 15412 dimensions: every length of No. 05 times "
            "s = sqrt(Q/1000 kg), rounded to 0.5 mm (geometry/sizes.csv, tools/scale_sizes.py). "
            "Under exact similarity with load ∝ s² the stresses would equal No. 05's × 0.981 "
            "(No. 05 carries the paper's rounded 10 000 N, the scaled rows kg × 9.81 N); the "
            "remaining differences come from the 0.5 mm rounding (notably the fillet radius rf, "
            "which drives the global peak at the journal shoulder) and the mesh.")
    return notes


def _peak_places(rows: list[dict], column: str) -> str:
    """The features a peak sits at (``column``: the peak's feature column) with the hook
    numbers at each, the most common first; one feature is said once for every row."""
    by: dict[str, list[str]] = {}
    for r in rows:
        by.setdefault(r[column] or "?", []).append(r["size"])
    if len(by) == 1:
        return f"{next(iter(by))} (every row)"
    return "; ".join(f"{f} (No. {', '.join(s)})" for f, s in sorted(by.items(), key=lambda kv: -len(kv[1])))


def _status_notes(rows: list[dict]) -> list[str]:
    """What each peak status that occurs in the rows means (pipeline.analysis.words, the
    words of every run's report and results.json)."""
    notes = []
    statuses = {r[p.status] for r in rows for p in PEAKS.values()}
    notes += [f"*{word}*: {what}." for word, what in PEAK_STATUSES.items() if word in statuses and word != SINGULAR]
    singular = [r[p.last_change] is None for r in rows for p in PEAKS.values() if r[p.status] == SINGULAR]
    if not all(singular):  # read on several meshes
        notes.append("*singular*: the peak grows under refinement by 0.5 % or more at every step (observed "
                     "order < 0.5); it sits "
                     "at a singular feature, has no finite value and is not a number to design with.")
    if any(singular):
        notes.append("*singular* on one mesh: the peak sits at a singular feature found by its place (a "
                     "re-entrant corner, a rigid support's edge), has no finite value and is not a number "
                     "to design with.")
    return notes


def _screening_notes(rows: list[dict]) -> list[str]:
    """Which rows of a screened study were decided on its cheap level and which got the
    full error bar, with the evidence (pipeline.study.screening); nothing otherwise."""
    by: dict[str, list[str]] = {}
    for r in rows:
        if r.get("decided_by"):
            # A grid's variants share a size: each is named by its changed dimensions too.
            label = f"{r['size']} ({r['changed_dims']})" if r.get("changed_dims") else r["size"]
            by.setdefault(r["decided_by"], []).append(label)
    return [f"Decided by {how}: No. {'; No. '.join(names)}." for how, names in by.items()]


def _run_notes(rows: list[dict], skipped: list[str]) -> list[str]:
    """How the rows were run: whether alike (mesh factor, meshes per error bar), the
    allowable stress (MPa) when one for all, their total run time (s), and the folders
    skipped."""
    notes = []
    factors = {r["mesh_factor"] for r in rows}
    meshes = {r["meshes"] for r in rows}
    if len(factors) > 1 or len(meshes) > 1:
        notes.append(f"The rows were not all run alike: mesh factors {sorted(factors, key=str)}, "
                     f"meshes per error bar {sorted(meshes, key=str)}.")
    elif rows:
        notes.append(f"Every row: mesh factor {factors.pop()}, {meshes.pop()} meshes for the error bar.")
    allow = {r["allowable_MPa"] for r in rows}
    if len(allow) == 1 and rows:
        notes.append(f"Allowable stress {allow.pop():g} MPa (St 50, paper: 80–120 MPa).")
    if rows:
        total = sum(r["time_s"] or 0.0 for r in rows)
        notes.append(f"Total run time of the rows: {total:.0f} s.")
    if skipped:
        notes.append("Not in the table: " + "; ".join(skipped) + ".")
    return notes


def plot(rows: list[dict], path: Path) -> bool:
    """FE peaks with error bars and the formula stresses against hook number (categorical)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    x = list(range(len(rows)))
    # A mesh artefact can be 20× the rest (see warnings_of): clip the axis and label it.
    glob = sorted(v for r in rows if (v := _drawn(r, PEAKS["peak"])) is not None) or [0.0]
    cap = max(2.5 * glob[len(glob) // 2], *(1.3 * (r["allowable_MPa"] or 0) for r in rows),
              *(1.2 * (_drawn(r, PEAKS["critical"]) or 0.0) for r in rows))
    # The axis ends just above what is drawn; at the cap only when something is clipped.
    tops = [_drawn(r, p) + (r[p.band] or 0.0) for r in rows for p in PEAKS.values() if _drawn(r, p) is not None]
    tops += [r["exact_MPa"] for r in rows] + [r["allowable_MPa"] or 0.0 for r in rows]
    ylim_top = 1.05 * cap if max(tops) > cap else 1.08 * max(tops)
    fig, ax = plt.subplots(figsize=(min(16.0, max(7.0, 0.42 * len(rows) + 3) + 3.0), 6.0))

    def series(p: flat.PeakColumns, fmt: str, color: str, label: str):
        have = [(xi, r, v) for xi, r in zip(x, rows) if (v := _drawn(r, p)) is not None]  # not asked: none
        if not have:
            return
        xs = [xi for xi, _, _ in have]
        vals = [min(v, cap) for _, _, v in have]
        for xi, _, v in have:
            if v > cap:
                ax.plot([xi], [cap], "^", color=color, ms=10)
                ax.annotate(f"{v:.0f} MPa\n(off scale)", (xi, cap), textcoords="offset points",
                            xytext=(6, -22), fontsize=7, color=color)
        bars = [r[p.band] if r[p.band] is not None else 0.0 for _, r, _ in have]
        ax.errorbar(xs, vals, yerr=bars, fmt=fmt, color=color, capsize=3, lw=1.2, ms=5, label=label)
        bad = [i for i, (_, r, _) in enumerate(have) if r[p.status] == SINGULAR]
        if bad:
            ax.plot([xs[i] for i in bad], [vals[i] for i in bad], "x", color="k", ms=9,
                    label=f"{label.split(' (')[0].split(' ±')[0]}: no error bar (not converged)")

    series(PEAKS["critical"], "o-", "C3", "FE critical peak (bore ligament) ± error bar")
    series(PEAKS["peak"], "s--", "C0", "FE global peak ± error bar")
    ax.plot(x, [r["exact_MPa"] for r in rows], "^-", color="C2", label="exact formula (curved bar)")
    ax.plot(x, [r["approximate_MPa"] for r in rows], "v-", color="C1", label="approximate formula")
    allow = {r["allowable_MPa"] for r in rows}
    if len(allow) == 1 and rows:
        a = allow.pop()
        ax.axhline(a, color="0.4", ls=":", label=f"allowable {a:g} MPa")
    ax.set_xticks(x)
    ax.set_xticklabels([("! " if _flagged(r) else "") + f"{r['size']}\n{r['load_N'] / 1000:.3g}"
                        + ("" if r["dimensions"].startswith("table row") else "*") for r in rows], fontsize=8)
    ax.set_xlabel("hook No. (categorical axis) and load in kN\n* = dimensions scaled from No. 05, not DIN; "
                  "! = see the warnings in summary.md")
    ax.set_ylabel("von Mises / nominal stress (MPa)")
    ax.set_ylim(0, ylim_top)
    ax.set_title("DIN 15412 crosshead: stress against hook number")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _drawn(r: dict, p: flat.PeakColumns) -> float | None:
    """The value the plot draws for peak ``p`` of a row (MPa): its reading, marked when
    singular; none for a peak the run was not asked for."""
    return None if r[p.status] == NOT_ASKED else r[p.reading]


def default_out(results: Path) -> Path:
    """Where the summary of ``results`` goes without --out: ``<results>/summary``, except
    for a design study's ``variants/`` folder, whose sub-folders are the study's variants
    only: there it is ``summary/`` in the study's folder, beside ``variants/``."""
    from pipeline.runtime.folders import marked_kind
    study = results.parent
    if results.name == "variants" and marked_kind(study) == "sweep":
        return study / "summary"
    return results / "summary"


def refusal(out: Path) -> str | None:
    """Why the summary may not write into ``out``, or None. It writes into a new or empty
    folder, or one that holds a summary it wrote (its marker says "summary"; an earlier
    version's: nothing but its files, summary.md under its title), never into another
    kind of results folder, a user's folder or a protected one (pipeline.runtime.folders)."""
    from pipeline.runtime.folders import MARKER, refusal as folder_refusal
    return folder_refusal(out, SUMMARY_FILES | {MARKER}, _not_a_summary)


def _not_a_summary(out: Path) -> str | None:
    """Why ``out``, holding only a summary's file names, is still not a summary's folder."""
    from pipeline.runtime.folders import MARKER
    if (out / MARKER).exists():
        try:
            mine = json.loads((out / MARKER).read_text(encoding="utf-8")).get("summary") is True
        except (OSError, ValueError, AttributeError):
            mine = False
        return None if mine else "its marker is a run's or a sweep's, not a summary's"
    if not _earlier_summary(out / "summary.md"):
        return f"it holds files crosshead did not write (no {MARKER} marker); choose a new or empty folder"
    return None


def _earlier_summary(md: Path) -> bool:
    """Whether ``md`` is a summary.md this tool wrote (its first line)."""
    try:
        with md.open(encoding="utf-8") as fh:
            return fh.readline().rstrip("\n") == TITLE
    except (OSError, ValueError):
        return False


class _Stopped(BaseException):
    """A stop (Ctrl-C or SIGTERM), raised in the main thread. Code that swallows it (a
    library's broad except while matplotlib loads, say) does not lose it: the signal is
    also recorded, and nothing is written once one has come."""


def main(argv: list[str] | None = None) -> int:
    """The command line: exit 0 written, 2 bad input or an output folder it may not use,
    130 / 143 stopped (one line each time). The three files are made in memory, then
    written with Ctrl-C and SIGTERM held off, so a stop leaves the earlier summary whole."""
    p = OneLineParser(prog="python -m pipeline.study.summary", description=__doc__.split("\n\n")[0])
    p.add_argument("results", type=Path, nargs="?", default=Path("results"),
                   help="folder holding one sub-folder per size (default results)")
    p.add_argument("--out", type=Path, help="output folder (default <results>/summary; for a study's "
                   "variants/ folder, summary/ beside it in the study's folder)")
    p.add_argument("--all", action="store_true", help="every sub-folder with a results.json, not only table sizes")
    args = p.parse_args(argv)
    received: list[int] = []

    def stop(signum: int, frame) -> None:
        received.append(signum)
        raise _Stopped

    previous = {s: signal.signal(s, stop) for s in EXIT_FOR}
    try:
        return _summarise(args, received)
    except _Stopped:
        signum = received[0]
        sys.stderr.write(f"{STOPPED[signal.Signals(signum)]}: {NOTHING_WRITTEN}\n")  # not stop_line: no run's outcome applies
        return EXIT_FOR[signum]
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _summarise(args: argparse.Namespace, received: list[int]) -> int:
    """Check, read, make the files in memory, write them; ``received``: the stop signals
    that have come (none may have come when the writing starts)."""
    from pipeline.runtime.atomicfile import replacing, write_text
    from pipeline.runtime.folders import MARKER
    if not args.results.is_dir():
        sys.stderr.write(f"error: results: no such folder {args.results}\n")
        return 2
    out = args.out or default_out(args.results)
    why = refusal(out)
    if why is not None:
        sys.stderr.write(why + "\n")
        return 2
    rows, skipped = collect(args.results, args.all)
    if not rows:
        sys.stderr.write(f"error: results: no usable results/<size>/results.json under {args.results}"
                         + (f" ({'; '.join(skipped)})" if skipped else "") + "\n")
        return 2
    with tempfile.TemporaryDirectory(prefix="crosshead-summary-") as tmp:
        png = Path(tmp) / "summary.png"
        have_png = plot(rows, png)
        files = {"summary.csv": csv_text(rows).encode("utf-8"),
                 "summary.md": markdown(rows, skipped, "summary.png" if have_png else None).encode("utf-8")}
        if have_png:
            files["summary.png"] = png.read_bytes()
    if received:  # a stop that something above swallowed
        raise _Stopped
    held = signal.pthread_sigmask(signal.SIG_BLOCK, set(EXIT_FOR))  # a stop waits until all is written
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_text(out / MARKER, '{"tool": "crosshead", "summary": true}\n')
        for name, data in files.items():
            with replacing(out / name, "wb") as fh:
                fh.write(data)
    except OSError as exc:
        sys.stderr.write(f"error: out: cannot write {out}: {exc.strerror or exc}\n")
        return 2
    finally:
        came = signal.sigtimedwait(set(EXIT_FOR), 0)  # taken here, so it cannot strike after the unblocking
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
    if came is not None:
        signum = signal.Signals(came.si_signo)
        sys.stderr.write(f"{STOPPED[signum]}: the summary was already written to {out}\n")
        return EXIT_FOR[signum]
    return _show(files["summary.md"].decode("utf-8") + f"written to {out}/ ({', '.join(files)})\n", out)


def _show(text: str, out: Path) -> int:
    """Print the summary written to ``out``: 0, also when the reader closed the pipe (``|
    head`` wanted no more); 2 with one line on stderr when stdout cannot take it (a full
    disk), which says the files are written."""
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except (BrokenPipeError, ValueError):  # ValueError: a stream closed in this process
        silence_stdout()
    except OSError as exc:
        silence_stdout()
        sys.stderr.write(f"error: stdout: cannot write ({exc.strerror or exc}); the summary was written to {out}\n")
        return 2
    return 0



if __name__ == "__main__":
    sys.exit(main())
