"""Write (or check) the similarity-scaled rows of geometry/sizes.csv. Units: mm, kg, N.

DIN 15412 is not available to this project; only the No. 05 row is published (Imrak et
al. 2007, Table 1). Every other hook number of DIN 15400 (class S, group 2m) gets a row
scaled from No. 05 by geometric similarity with its rated load:

    s = sqrt(Q / Q05),  Q05 = 1000 kg,

every length of No. 05 (b1, b2, d14, d2, h3 and the assumed dj, rf, seat_inner,
seat_outer) times s, rounded to the nearest 0.5 mm; b6 = b1 + 2*b2 exactly. If a rounded
row broke a rule of geometry.table.validate, the bore or the seat (then the journal) is
moved by 0.5 mm steps until it holds, and the row's source says so. load_N is left empty
(= rated_load_kg * 9.81). Such rows are labelled "... NOT a DIN 15412 value".

Rows that were not written by this script (No. 05 itself, rows a user copied from the
standard) are kept verbatim, and a hook number that has such a row gets no scaled row.

    python tools/scale_sizes.py            rewrite geometry/sizes.csv
    python tools/scale_sizes.py --check    exit 1 (and show a diff) if the file differs
"""
from __future__ import annotations

import argparse
import csv
import difflib
import math
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from geometry.table import (SCALED_TAG, TABLE_PATH, Dimensions, InputError,  # noqa: E402
                            is_scaled_row, row_from_record, validate)

BASE_SIZE = "05"
BASE_KG = 1000.0
STEP_MM = 0.5

# DIN 15400 rated loads, kg, strength class S / mechanism group 2m (a transcription
# of DIN 15400 Table 3), in hook-number order.
RATED_KG: dict[str, float] = {
    "025": 500, "04": 800, "05": 1000, "08": 1600, "1": 2000, "1.6": 3200, "2.5": 5000,
    "4": 8000, "5": 10_000, "6": 12_500, "8": 16_000, "10": 20_000, "12": 25_000,
    "16": 32_000, "20": 40_000, "25": 50_000, "32": 63_000, "40": 80_000, "50": 100_000,
}

COLUMNS = ("size", "b1", "b2", "b6", "d14", "d2", "h3", "rated_load_kg", "load_N", "dj_mm",
           "rf_mm", "seat_inner_mm", "seat_outer_mm", "source")

HEADER = """\
# DIN 15412 type A crosshead dimensions, mm; rated load per DIN 15400 class S / group 2m, kg.
# Only No. 05 is published (Imrak et al. 2007, Table 1). Every row whose source starts with
# "scaled from No. 05 by geometric similarity" is NOT a DIN 15412 value: all lengths of No. 05
# (its assumed dj, rf and seat included) times s = sqrt(Q/1000 kg), rounded to 0.5 mm,
# b6 = b1 + 2*b2. Those rows are written by tools/scale_sizes.py; do not edit them by hand
# (`python tools/scale_sizes.py --check` verifies them).
# Empty dj_mm, rf_mm, seat_*_mm cells take the assumed defaults of docs/design.md §2 (dj = 0.8*h3,
# rf = 0.06*h3, seat annulus d14*(1 -/+ 0.19)). Empty load_N means rated_load_kg * 9.81.
# To add a row copied from DIN 15412: write one line with the hook number, b1 b2 b6 d14 d2 h3
# from the standard's table (type A; b6 must equal b1 + 2*b2), the DIN 15400 rated load in kg,
# load_N empty, dj_mm rf_mm seat_inner_mm seat_outer_mm empty (defaults) or your own values,
# and a source naming the standard, edition and table, e.g. "DIN 15412-1:1990 Table 1, type A,
# copied by <who> <date>; dj rf seat assumed (docs/design.md §2)". A copied row replaces the scaled row
# of the same hook number: run `python tools/scale_sizes.py` to drop that scaled row, then
# `make <size>`.
"""


def round_step(x: float, step: float = STEP_MM) -> float:
    """Nearest multiple of ``step`` (halves away from zero, no banker's rounding), mm."""
    return math.floor(x / step + 0.5) * step


def fmt(v: float) -> str:
    """A length or load as written in the table: no trailing '.0', no exponent."""
    if float(v).is_integer():
        return str(int(v))
    return f"{v:.6f}".rstrip("0").rstrip(".")


def scale_factor(kg: float) -> float:
    """Similarity scale of a hook for rated load ``kg``: sqrt(kg / 1000 kg)."""
    return math.sqrt(kg / BASE_KG)


_LABEL = {"d2": "bore d2", "dj": "journal dj"}


def _fix_for(d: Dimensions, msg: str) -> tuple[str, int]:
    """The dimension to move and the direction (+1/-1) that answers validate()'s complaint."""
    field = msg.split(":", 1)[0]
    if field == "seat_inner":
        return ("d2", -1) if "larger than the bore" in msg else ("seat_outer", +1)
    if field == "d14":
        return ("seat_inner", -1) if d.d14 <= d.seat_inner else ("seat_outer", +1)
    moves = {"seat_outer": -1, "d2": -1, "dj": -1}
    if field not in moves:
        raise InputError(msg)
    return field, moves[field]


def _adjust(d: Dimensions) -> tuple[Dimensions, list[str]]:
    """Move bore, seat, then journal by 0.5 mm steps until validate() passes."""
    notes: list[str] = []
    for _ in range(40):
        try:
            validate(d)
            return d, notes
        except InputError as exc:
            name, sign = _fix_for(d, str(exc))
            d = replace(d, **{name: getattr(d, name) + sign * STEP_MM})
            notes.append(f"{_LABEL.get(name, name)} {'+' if sign > 0 else '-'}0.5")
    raise InputError(f"size: could not make a scaled row valid: {notes}")


def scaled_dims(base: Dimensions, s: float) -> tuple[Dimensions, list[str]]:
    """No. 05's dimensions times s, rounded to 0.5 mm, b6 = b1 + 2*b2, made valid."""
    r = {k: round_step(getattr(base, k) * s) for k in
         ("b1", "b2", "d14", "d2", "h3", "dj", "rf", "seat_inner", "seat_outer")}
    d = Dimensions(b6=r["b1"] + 2 * r["b2"], **r)
    return _adjust(d)


def scaled_line(size: str, kg: float, base: Dimensions) -> str:
    """The CSV line of a scaled row."""
    s = scale_factor(kg)
    d, notes = scaled_dims(base, s)
    source = (f"{SCALED_TAG}, s = sqrt(Q/1000 kg) = {s:.3f}, lengths (incl. No. 05's assumed "
              f"dj rf seat) rounded to 0.5 mm, b6 = b1 + 2*b2")
    if notes:
        source += "; adjusted to satisfy the validator: " + ", ".join(notes)
    source += "; load = rated kg * 9.81; NOT a DIN 15412 value"
    cells = [size, d.b1, d.b2, d.b6, d.d14, d.d2, d.h3, kg, "", d.dj, d.rf,
             d.seat_inner, d.seat_outer]
    text = ",".join(c if isinstance(c, str) else fmt(c) for c in cells)
    return text + ',"' + source.replace('"', '""') + '"'


def read_rows(path: Path) -> list[tuple[dict[str, str], str]]:
    """Data rows of the table as (record, raw line), comments and header skipped."""
    out = []
    header = None
    for raw in path.read_text(encoding="utf-8").splitlines():
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        cells = next(csv.reader([raw]))
        if header is None:
            header = cells
            if tuple(header) != COLUMNS:
                raise InputError(f"{path.name}: header must be {','.join(COLUMNS)}")
            continue
        if len(cells) != len(header):
            raise InputError(f"{path.name}: row {cells[:1]} has {len(cells)} cells, expected {len(header)}")
        out.append((dict(zip(header, cells)), raw))
    return out


def generate(path: Path = TABLE_PATH) -> str:
    """The table's text with every scaled row (re)computed and other rows kept verbatim."""
    rows = read_rows(path)
    kept = [(rec, raw) for rec, raw in rows if not is_scaled_row(rec["source"])]
    kept_sizes = [rec["size"].strip() for rec, _ in kept]
    dup = {s for s in kept_sizes if kept_sizes.count(s) > 1}
    if dup:
        raise InputError(f"size: hook numbers given more than once: {', '.join(sorted(dup))}")
    if BASE_SIZE not in kept_sizes:
        raise InputError(f"size: the table needs the No. {BASE_SIZE} row the scaled rows derive from")
    base = validate(row_from_record(next(r for r, _ in kept if r["size"].strip() == BASE_SIZE)).dims)
    by_size = {rec["size"].strip(): raw for rec, raw in kept}
    lines = [HEADER.rstrip("\n"), ",".join(COLUMNS)]
    for size, kg in RATED_KG.items():
        lines.append(by_size.pop(size) if size in by_size else scaled_line(size, kg, base))
    lines += list(by_size.values())          # user rows of other hook numbers, in file order
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--table", type=Path, default=TABLE_PATH, help="size table (default geometry/sizes.csv)")
    p.add_argument("--check", action="store_true",
                   help="do not write; exit 1 and print a diff if the table differs from the generated one")
    args = p.parse_args(argv)
    try:
        new = generate(args.table)
    except InputError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    old = args.table.read_text(encoding="utf-8")
    if args.check:
        if old == new:
            print(f"{args.table}: up to date ({new.count(SCALED_TAG) - HEADER.count(SCALED_TAG)} scaled rows)")
            return 0
        sys.stdout.writelines(difflib.unified_diff(old.splitlines(True), new.splitlines(True),
                                                   str(args.table), "generated"))
        sys.stderr.write(f"{args.table}: differs from tools/scale_sizes.py output; run it to update\n")
        return 1
    args.table.write_text(new, encoding="utf-8")
    print(f"wrote {args.table}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
