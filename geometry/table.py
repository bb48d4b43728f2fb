"""DIN 15412 crosshead dimension table and the rules a buildable row must obey.

Units: every length in mm, every load in N (the table also carries the rated load in kg).

The table (``sizes.csv`` beside this file) has one row per hook number. Only the
No. 05 row is published (Imrak et al. 2007, Table 1); every row says in its ``source``
column where it came from. The columns ``dj_mm``, ``rf_mm``, ``seat_inner_mm`` and
``seat_outer_mm`` are this project's assumptions (docs/design.md §2): left empty they take
the default rules of :func:`default_extras`.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

TABLE_PATH = Path(__file__).with_name("sizes.csv")
MODELS = ("quarter", "full")  # the part as built: a quarter with symmetry planes, or whole


def model_share(model: str) -> float:
    """The share of the whole part that a model holds: its volume, seat area and hook load
    (the quarter model x >= 0, y >= 0 with two symmetry planes holds a quarter)."""
    return 0.25 if model == "quarter" else 1.0


G_MS2 = 9.81  # m/s², kg → N for the rated loads (docs/design.md §6)
# How a row that tools/scale_sizes.py made from No. 05 begins its source (such rows are not
# DIN 15412 values; docs/design.md §2).
SCALED_TAG = "scaled from No. 05 by geometric similarity"


def is_scaled_row(source: str) -> bool:
    """Whether a size-table row's ``source`` says it is No. 05 scaled (not a DIN value)."""
    return source.strip().startswith(SCALED_TAG)


class InputError(ValueError):
    """A value the user gave (table row, case file, CLI option) that cannot be used.

    The message is one line naming the field and the rule it breaks.
    """


@dataclass(frozen=True)
class Dimensions:
    """Everything that fixes the crosshead's shape. All lengths in mm.

    b1: body width (y) and body length (x); b2: journal length; b6: tip-to-tip length;
    d14: mean diameter of the thrust-bearing track (Dm); d2: bore diameter (di);
    h3: body height (h); dj: journal diameter; rf: shoulder fillet radius;
    seat_inner/seat_outer: diameters of the loaded seat annulus on the top face.
    """

    b1: float
    b2: float
    b6: float
    d14: float
    d2: float
    h3: float
    dj: float
    rf: float
    seat_inner: float
    seat_outer: float


RF_PER_H = 0.06  # the assumed fillet radius, × h3 (docs/design.md §2)


def default_extras(b1: float, d14: float, h3: float) -> dict[str, float]:
    """The assumed dimensions of docs/design.md §2 that the paper does not give, in mm.

    dj = 0.8·h, rf = 0.06·h, seat annulus Dm·(1 ∓ 0.19).
    """
    return {
        "dj": 0.8 * h3,
        "rf": RF_PER_H * h3,
        "seat_inner": d14 * (1 - 0.19),
        "seat_outer": d14 * (1 + 0.19),
    }


def validate(d: Dimensions) -> Dimensions:
    """Return ``d`` unchanged if a crosshead can be built from it, else raise InputError.

    The rules are checked in a fixed order so the message names the first broken one.
    """
    for f in fields(d):
        v = getattr(d, f.name)
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise InputError(f"{f.name}: must be a number in mm, got {v!r}")
        if not math.isfinite(v):
            raise InputError(f"{f.name}: must be finite, got {v!r} mm")
        if f.name == "rf":
            if v < 0:
                raise InputError(f"rf: fillet radius must be >= 0, got {v:g} mm")
        elif v <= 0:
            raise InputError(f"{f.name}: must be > 0, got {v:g} mm")
    tol = 1e-9 * max(d.b6, 1.0)
    if abs(d.b6 - (d.b1 + 2 * d.b2)) > tol:
        raise InputError(
            f"b6: must equal b1 + 2*b2 = {d.b1 + 2 * d.b2:g} mm, got {d.b6:g} mm")
    if d.d2 >= d.b1:
        raise InputError(f"d2: bore diameter {d.d2:g} mm must be smaller than the body width b1 = {d.b1:g} mm")
    if d.seat_inner >= d.seat_outer:
        raise InputError(
            f"seat_inner: {d.seat_inner:g} mm must be smaller than seat_outer = {d.seat_outer:g} mm")
    if d.seat_inner <= d.d2:
        raise InputError(
            f"seat_inner: seat annulus inner diameter {d.seat_inner:g} mm must be larger than the bore d2 = {d.d2:g} mm")
    if d.seat_outer >= d.b1:
        raise InputError(
            f"seat_outer: seat annulus outer diameter {d.seat_outer:g} mm must be smaller than the body width b1 = {d.b1:g} mm")
    if not (d.seat_inner < d.d14 < d.seat_outer):
        raise InputError(
            f"d14: bearing track diameter {d.d14:g} mm must lie inside the seat annulus "
            f"({d.seat_inner:g}..{d.seat_outer:g} mm)")
    if d.dj / 2 + d.rf >= d.h3 / 2:
        raise InputError(
            f"dj, rf: journal radius plus fillet dj/2 + rf = {d.dj / 2 + d.rf:g} mm must be smaller than h3/2 = {d.h3 / 2:g} mm")
    if d.dj / 2 + d.rf >= d.b1 / 2:
        raise InputError(
            f"dj, rf: journal radius plus fillet dj/2 + rf = {d.dj / 2 + d.rf:g} mm must be smaller than b1/2 = {d.b1 / 2:g} mm")
    if d.rf >= d.b2:
        raise InputError(f"rf: fillet radius {d.rf:g} mm must be shorter than the journal b2 = {d.b2:g} mm")
    return d


@dataclass(frozen=True)
class TableRow:
    """One row of the size table: hook number, dimensions (mm), rated load and its origin."""

    size: str
    dims: Dimensions
    rated_load_kg: float
    load_N: float
    source: str


REQUIRED_COLUMNS = ("size", "b1", "b2", "b6", "d14", "d2", "h3", "rated_load_kg", "source")
OPTIONAL_COLUMNS = ("load_N", "dj_mm", "rf_mm", "seat_inner_mm", "seat_outer_mm")


def _number(text: str, column: str, size: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{column}: size {size}: {text!r} is not a number") from None


def row_from_record(rec: dict[str, str]) -> TableRow:
    """Build (unvalidated) a TableRow from one CSV record; empty optional cells take defaults."""
    size = rec["size"].strip()
    base = {k: _number(rec[k], k, size) for k in ("b1", "b2", "b6", "d14", "d2", "h3")}
    extras = default_extras(base["b1"], base["d14"], base["h3"])
    for col, key in (("dj_mm", "dj"), ("rf_mm", "rf"), ("seat_inner_mm", "seat_inner"),
                     ("seat_outer_mm", "seat_outer")):
        cell = (rec.get(col) or "").strip()
        if cell:
            extras[key] = _number(cell, col, size)
    kg = _number(rec["rated_load_kg"], "rated_load_kg", size)
    load_cell = (rec.get("load_N") or "").strip()
    load = _number(load_cell, "load_N", size) if load_cell else kg * G_MS2
    return TableRow(size=size, dims=Dimensions(**base, **extras), rated_load_kg=kg,
                    load_N=load, source=rec["source"].strip())


def load_table(path: Path = TABLE_PATH) -> dict[str, TableRow]:
    """Read the size table, keyed by hook number as written (``"05"``, ``"1.6"``)."""
    with open(path, newline="", encoding="utf-8") as fh:
        lines = [ln for ln in fh if ln.strip() and not ln.lstrip().startswith("#")]
    reader = csv.DictReader(lines)
    missing = [c for c in REQUIRED_COLUMNS if c not in (reader.fieldnames or [])]
    if missing:
        raise InputError(f"{path.name}: missing columns {', '.join(missing)}")
    rows: dict[str, TableRow] = {}
    for rec in reader:
        row = row_from_record(rec)
        rows[row.size] = row
    return rows


def lookup(size: str, path: Path = TABLE_PATH) -> TableRow:
    """The row of hook number ``size``; InputError naming the known sizes if absent."""
    table = load_table(path)
    if size not in table:
        raise InputError(f"size: unknown hook number {size!r}; known: {', '.join(table)}")
    return table[size]


def with_overrides(d: Dimensions, **over: float) -> Dimensions:
    """Dimensions with some fields replaced (case file or CLI overrides), mm."""
    return replace(d, **over)


PUBLISHED_PATH = Path(__file__).with_name("published.csv")


def paper_spans(d: Dimensions) -> tuple[float, float]:
    """(approximate span, exact span) as the paper chose them for part d: (b1 + b2, b6), mm."""
    return d.b1 + d.b2, d.b6


def published(size: str, load_N: float, approximate_span_mm: float, exact_span_mm: float,
              path: Path = PUBLISHED_PATH) -> dict | None:
    """The published results (MPa, N, N·mm) for this size, if a source gives them for the
    same load and spans (else None: another size or other inputs have no reference)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    for row in rows:
        same = (row["size"] == size and math.isclose(float(row["load_N"]), load_N, rel_tol=1e-9)
                and math.isclose(float(row["approximate_span_mm"]), approximate_span_mm, rel_tol=1e-9)
                and math.isclose(float(row["exact_span_mm"]), exact_span_mm, rel_tol=1e-9))
        if same:
            return {k: (v if k == "source" else float(v)) for k, v in row.items() if k != "size"}
    return None
