"""The one reading of a run's results.json as table rows (mm, N, MPa, s).

A run's results.json (docs/design.md §7) nests its numbers in blocks; a table wants one
flat row per load. :func:`rows` is that flattening, used by every table made of runs: the
size summary (pipeline.study.summary) and a design study's table (pipeline.study.table).
Both add only their own columns, so one quantity has one column name and one value in
either, and what a peak with no value to design with shows is decided here only.
"""
from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

from pipeline.analysis.words import NOT_ASKED, PEAK_STATUSES, SINGLE_MESH, SINGULAR, peak_status  # noqa: F401
from pipeline.fe.linearity import stress_factor

SHOWN_ONLY = "; shown for orientation only"  # the end of results.json's not_wanted text


@dataclass(frozen=True)
class PeakColumns:
    """The column names of one peak of results.json's fe block (``block``: "peak", the
    global peak, or "critical", the peak over the bore's ligaments)."""
    block: str
    name: str            # the peak for a person
    value: str           # MPa, empty when the peak has no value to design with
    reading: str         # MPa, the finest mesh's reading, always
    band: str            # MPa
    status: str          # the peak's status (pipeline.analysis.words), as results.json's fe.<block>.status
    trend: str           # the error bar's mesh-refinement trend (results.json's error_estimate.status)
    extrapolated: str    # MPa
    last_change: str     # MPa
    feature: str
    note: str
    safety_factor: str


PEAKS = {
    "peak": PeakColumns("peak", "global peak", "peak_MPa", "peak_reading_MPa", "peak_band_MPa", "peak_status",
                        "peak_trend", "peak_extrapolated_MPa", "peak_last_change_MPa", "peak_feature", "peak_note",
                        "safety_factor"),
    "critical": PeakColumns("critical", "critical peak", "critical_peak_MPa", "critical_reading_MPa",
                            "critical_band_MPa", "critical_status", "critical_trend", "critical_extrapolated_MPa",
                            "critical_last_change_MPa", "critical_feature", "critical_note",
                            "critical_safety_factor"),
}


def _peak_descriptions(p: PeakColumns, where: str) -> dict[str, str]:
    """What each column of one peak holds (``where``: the region it is the peak of)."""
    return {
        p.value: f"{p.name} von Mises ({where}) on the finest mesh at the row's load (MPa); empty when it has "
                 f"no value to design with: not asked for (--want) or at a singular feature ({p.note} says which)",
        p.reading: f"the finest mesh's {p.name} reading at the row's load (MPa), also when {p.value} is empty: "
                   "for orientation only",
        p.band: f"error bar of {p.value} (MPa, ±); empty without one (one mesh, or a peak with no value)",
        p.status: f"the {p.name}'s status, as results.json's fe.{p.block}.status and the report say it: "
                  + "; ".join(f"{word}: {what}" for word, what in PEAK_STATUSES.items())
                  + "; in a screened study also screened (its band is the cheap level's)",
        p.trend: "the error bar's mesh-refinement trend (settled, converged, scattered, oscillatory, unsettled, "
                 "singular; docs/design.md §5); empty on one mesh or for a peak not asked for",
        p.extrapolated: "the value extrapolated to a zero mesh size (MPa); only when converged or scattered",
        p.last_change: "the finest mesh's reading minus the next coarser mesh's (MPa); empty with one mesh",
        p.feature: "where the peak sits (the feature of the part, in words)",
        p.note: "why the peak has no value (not asked for, or at a singular feature); empty when it has one",
        p.safety_factor: f"allowable_MPa / {p.value}; empty when {p.value} is",
    }


# Every column of :func:`rows`, in order, with what it holds and its unit.
COLUMNS: dict[str, str] = {
    "size": "hook number of the size table (text: 05, 1, 2.5, ...; in a CSV file 'No. 05', so that a "
            "reader's type inference keeps it text and its leading zero)",
    "load_N": "hook load of the row (N): the case's own, or one load of its load sweep",
    "approximate_MPa": "the paper's approximate hand formula, span b1 + b2, at the row's load (MPa)",
    "exact_MPa": "the paper's exact hand formula (curved bar, span b6) at the row's load (MPa)",
    **_peak_descriptions(PEAKS["peak"], "over the whole part"),
    **_peak_descriptions(PEAKS["critical"], "over the ligaments beside the bore, |x| <= d2/2"),
    "critical_section_nominal_MPa": "nominal stress N/(w h) + 6|M|/(w h^2) on the section x = 0 at the row's "
                                    "load (MPa); quarter model only",
    "allowable_MPa": "the case's allowable stress (MPa)",
    "mesh_min_jacobian_ratio": "worst det J ratio of a curved tet on the finest mesh (1 = straight)",
    "mesh_factor": "the case's mesh factor (finest mesh; smaller is finer)",
    "meshes": "meshes solved for the error bar",
    "dofs": "degrees of freedom of the finest mesh",
    "time_s": "the run's total time (s); every load of one run shares it",
    "source": "where the size's dimensions come from (text)",
    "changed_dims": "the dimensions that differ from the size's table row, as 'rf = 2 mm (table 1.5)' (mm)",
    "verdict_rests_on": "whether the run's verdict holds over its assumed inputs' ranges, the sentence of its "
                        "sensitivity section at the row's load (text); empty when it was not analysed "
                        "(--no-sensitivity, a study without --sensitivity)",
    "notes": "what a reader must know beside the row's numbers, as the run's terminal and report say it "
             "(results.json's notes, '; '-joined: a mesh too coarse for the fillet); empty when none",
}
TEXT_COLUMNS = frozenset({"size", "source", "changed_dims", "verdict_rests_on", "notes",
                          *(c for p in PEAKS.values() for c in (p.status, p.trend, p.feature, p.note))})
# The quantities proportional to the load: scaled from the case's load to another.
_LINEAR = ("critical_section_nominal_MPa",
           *(c for p in PEAKS.values() for c in (p.reading, p.extrapolated, p.last_change)))
# What a load sweep's entry of results.json gives itself, per load.
_PER_LOAD = ("load_N", "approximate_MPa", "exact_MPa",
             *(c for p in PEAKS.values() for c in (p.value, p.band, p.safety_factor)))


def rows(res: dict) -> list[dict]:
    """One row (COLUMNS) per load of the run in ``res`` (a results.json's content): the
    case's own load, or each entry of its ``load_sweep`` in order."""
    own = own_row(res)
    sweep = res.get("load_sweep")
    if not sweep:
        return [own]
    q0 = res["case"]["load_N"]
    out = []
    for entry in sweep:
        k = stress_factor(entry["load_N"], q0)  # linear elasticity: every stress scales with the load
        row = dict(own, **{c: None if own[c] is None else k * own[c] for c in _LINEAR})
        row.update({c: entry.get(c) for c in _PER_LOAD})
        if "sensitivity_sentence" in entry:  # what that load's verdict rests on, said at that load
            row["verdict_rests_on"] = entry["sensitivity_sentence"] or ""
        out.append(_decided(row))
    return out


def own_row(res: dict) -> dict:
    """The row at the case's own load, from the fe and analytic blocks."""
    case, fe, an = res["case"], res["fe"], res["analytic"]
    nominal = ((fe.get("sections") or {}).get("critical_section") or {}).get("nominal_MPa")
    row = {"size": case.get("size"), "load_N": case["load_N"],
           "approximate_MPa": an["approximate_MPa"], "exact_MPa": an["exact_MPa"]}
    for p in PEAKS.values():
        row.update(_peak(fe, p, case.get("tolerance_pct", 1.0)))
    row.update({
        "critical_section_nominal_MPa": nominal, "allowable_MPa": case.get("allowable_MPa"),
        "mesh_min_jacobian_ratio": fe.get("mesh_min_jacobian_ratio"), "mesh_factor": case.get("mesh_factor"),
        "meshes": len(fe.get("levels", [])) or None, "dofs": fe.get("dofs"),
        "time_s": (res.get("timings_s") or {}).get("total"),
        "source": case.get("source", ""), "changed_dims": changed_dims(case),
        "verdict_rests_on": (res.get("sensitivity_summary") or {}).get("sentence") or "",
        "notes": "; ".join(res.get("notes") or [])})
    return _decided({c: row[c] for c in COLUMNS})


def _peak(fe: dict, p: PeakColumns, tolerance_pct: float) -> dict:
    """One peak's columns as its fe block gives them (MPa); :func:`_decided` then applies
    what a peak with no value shows. ``tolerance_pct``: the case's (%), for a results.json
    whose peak blocks carry no status yet."""
    block = fe[p.block]
    key = "peak_MPa" if p.block == "peak" else "critical_peak_MPa"
    # A peak not asked for has no value (null); its reading is kept under *_unresolved_MPa.
    reading = fe[key] if fe.get(key) is not None else fe.get(key.replace("_MPa", "_unresolved_MPa"))
    est = block.get("error_estimate")
    out = {p.value: reading, p.reading: reading, p.band: None, p.trend: "" if est is None else est["status"],
           p.extrapolated: None, p.last_change: None,
           p.feature: block.get("feature", ""), p.note: "", p.safety_factor: fe.get(p.safety_factor)}
    if block.get("not_wanted"):
        return dict(out, **{p.status: NOT_ASKED, p.trend: "", p.note: block["not_wanted"].replace(SHOWN_ONLY, "")})
    if est is not None:
        vals = est.get("values") or []
        out.update({p.band: est.get("band"), p.last_change: vals[0] - vals[1] if len(vals) >= 2 else None,
                    p.extrapolated: est.get("extrapolated") if est["status"] in ("converged", "scattered") else None})
    where = block.get("singular_feature") or (
        f"{out[p.feature]} (values do not converge under refinement)"
        if est is not None and est["status"] == SINGULAR else None)
    if where is not None:
        return dict(out, **{p.status: SINGULAR, p.extrapolated: None,
                            p.note: f"{p.name} at a singular feature ({where}): no finite value"})
    # A results.json written before the status was: decided by the same rule from its band.
    status = block.get("status") or peak_status(tolerance_pct, reading, out[p.band], None, True)
    return dict(out, **{p.status: status})


def _decided(row: dict) -> dict:
    """``row`` with what a peak that has no value to design with shows, decided once for
    every table: not asked for (--want) or at a singular feature, it has no value, error bar
    or safety factor (its reading stays, for orientation)."""
    for p in PEAKS.values():
        if row[p.status] in (NOT_ASKED, SINGULAR):
            row.update({p.value: None, p.band: None, p.safety_factor: None})
    return row


def has_value(row: dict, p: PeakColumns) -> bool:
    """Whether a row's peak ``p`` is a value to design with (not asked for, or at a
    singular feature: none)."""
    return row[p.status] not in (NOT_ASKED, SINGULAR)


@functools.cache
def size_table() -> dict:
    """The size table's rows by hook number (geometry/sizes.csv), read once per process."""
    from geometry.table import load_table
    return load_table()


def changed_dims(case: dict) -> str:
    """The dimensions (mm) in which a run's case differs from its size's row of the table,
    as "rf = 2 mm (table 1.5)", comma-separated; '' when none does or the size is not in
    the table (a design study's variants are rows with changed dimensions)."""
    row = size_table().get(str(case.get("size")))
    dims = case.get("dims")
    if row is None or not isinstance(dims, dict):
        return ""
    table = asdict(row.dims)
    return ", ".join(f"{k} = {v:g} mm (table {table[k]:g})" for k, v in dims.items()
                     if k in table and not math.isclose(v, table[k], rel_tol=1e-12, abs_tol=1e-12))


def markdown_table(columns: dict[str, str] = COLUMNS) -> str:
    """``columns`` as a Markdown table of column and meaning (docs/sweeps.md holds it)."""
    lines = ["| column | meaning |", "|---|---|"]
    lines += [f"| `{c}` | {d.replace('|', '&#124;')} |" for c, d in columns.items()]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- a run's own tables (CSV)

# Each checked stress's verdict column (results.json's fe.verdict names): the same names
# in a run's sensitivity.csv and a study's sweep.csv.
VERDICT_COLUMNS = {"global_peak": "verdict", "critical_peak": "critical_verdict",
                   "critical_section_nominal": "critical_section_verdict",
                   "journal_root_nominal": "journal_root_verdict"}

# meshes.csv: one row per mesh of the error bar, the requested (finest) one first.
MESH_COLUMNS: dict[str, str] = {
    "size": COLUMNS["size"],
    "mesh_factor": "the mesh's factor (smaller is finer; the first row is the requested mesh)",
    "dofs": "degrees of freedom of the mesh",
    "cells": "tetrahedra of the mesh (of the model: the quarter for the quarter model)",
    "peak_MPa": "the global peak reported on this mesh (MPa): the midpoint of the two readings at the fillet, "
                "else the unaveraged one",
    "peak_unaveraged_MPa": "the global peak's unaveraged reading (largest element-node value, MPa)",
    "peak_averaged_MPa": "the global peak's averaged reading (nodal-averaged stress, MPa)",
    "critical_peak_MPa": "the critical peak reported on this mesh (MPa): its unaveraged reading",
    "critical_unaveraged_MPa": "the critical peak's unaveraged reading (MPa)",
    "critical_averaged_MPa": "the critical peak's averaged reading (MPa)",
    "iterations": "solver iterations on this mesh",
    "time_s": "the mesh's own time (s): meshing, assembly, solve, reading",
}

# sensitivity.csv: one row per varied input and end of its range.
SENSITIVITY_COLUMNS: dict[str, str] = {
    "size": COLUMNS["size"],
    "input": "the input varied: a dimension (dj, rf, seat_inner, seat_outer) or a load-model option "
             "(bearing_shape, bearing_centre_mm, bearing_length_mm)",
    "kind": "dimension or load model",
    "end": "low or high: the end of the input's range",
    "value": "the input's value at that end, in unit; empty for a choice",
    "choice": "the choice at that end (bearing_shape: cosine or uniform); empty for a number",
    "unit": "the value's unit (mm); empty for a choice",
    "peak_MPa": "the global peak at that end (MPa): the run's value scaled by the variant",
    "critical_peak_MPa": "the critical peak at that end (MPa)",
    "critical_section_nominal_MPa": "the nominal stress of the section x = 0 at that end (MPa)",
    "journal_root_nominal_MPa": "the journal root's nominal bending stress at that end (MPa)",
    "capacity_N": "the hook load at which the first checked stress reaches the allowable at that end (N)",
    **{col: f"the {name.replace('_', ' ')}'s verdict at that end (pass, fail, undecided), as results.json says it; "
            "empty without one" for name, col in VERDICT_COLUMNS.items()},
    "note": "why that end was not analysed (a broken geometry rule, a failed mesh or solve); empty when it was",
}


def size_label(size) -> str:
    """A hook number as a table's cell: 'No. 05', text that a reader's type inference keeps
    as it is (a bare 05 reads as the number 5, and 025 and 25 as one)."""
    return "" if size in (None, "") else f"No. {size}"


def csv_text(columns, rows: list[dict]) -> str:
    """``rows`` as CSV text with the header ``columns`` (an iterable of names): a missing
    or None value an empty cell, the size column as its label (:func:`size_label`)."""
    import csv
    import io
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: size_label(v) if k == "size" else ("" if v is None else v) for k, v in r.items()})
    return fh.getvalue()


def mesh_rows(res: dict) -> list[dict]:
    """meshes.csv's rows (MESH_COLUMNS) from a run's results.json content ``res``."""
    size = res["case"].get("size")
    return [dict({c: lv.get(c) for c in MESH_COLUMNS}, size=size) for lv in res["fe"].get("levels") or []]


def sensitivity_rows(res: dict) -> list[dict]:
    """sensitivity.csv's rows (SENSITIVITY_COLUMNS) from a run's results.json content
    ``res``: each varied input at its low and its high end; none without a sensitivity
    section."""
    rows = []
    for e in res.get("sensitivity") or []:
        for i, end in enumerate(("low", "high")):
            v = e["range"][i]
            verdicts = (e.get("verdicts") or [None, None])[i] or {}
            rows.append({
                "size": res["case"].get("size"), "input": e["input"], "kind": e.get("kind", "dimension"), "end": end,
                "value": None if isinstance(v, str) else v, "choice": v if isinstance(v, str) else None,
                "unit": "" if isinstance(v, str) else e["unit"],
                **{k: e[k][i] for k in ("peak_MPa", "critical_peak_MPa", "critical_section_nominal_MPa",
                                        "journal_root_nominal_MPa", "capacity_N")},
                **{col: verdicts.get(name) for name, col in VERDICT_COLUMNS.items()},
                "note": (e.get("invalid") or [None, None])[i] or ""})
    return rows
