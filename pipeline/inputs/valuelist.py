"""The grammar of a list of numbers the user gives: hook loads (N) and a study's swept
dimensions (mm). One value, a comma list ``a,b,c``, or a range ``START:STOP:COUNT`` (COUNT
values, both ends included). Every value is finite and given once: a repeated value would
be analysed once and listed twice. The command line and study files both read lists here,
so a list means the same wherever it is written.
"""
from __future__ import annotations

import math

from pipeline.errors import InputError, given_twice

MOST_LOADS = 1000  # loads are cheap: one solve, scaled to each
MOST_DIM_VALUES = 200  # each swept value of a dimension is a full analysis


def parse_values(text: str, name: str, most: int) -> list[float]:
    """The numbers of ``text`` (at most ``most`` of them); ``name`` starts every error line.
    Raises InputError naming what is wrong."""
    parts = text.split(":")
    if len(parts) == 3:
        a, b = (_number(p, name) for p in parts[:2])
        try:
            n = int(parts[2])
        except ValueError:
            raise InputError(f"{name}: range count {parts[2].strip()!r} is not an integer") from None
        if not 2 <= n <= most:
            raise InputError(f"{name}: a range needs 2..{most} values, got {n}")
        values = [a + (b - a) * k / (n - 1) for k in range(n)]
    elif len(parts) == 1:
        items = text.split(",")
        if any(not v.strip() for v in items):
            raise InputError(f"{name}: {text!r} has an empty item")
        if len(items) > most:
            raise InputError(f"{name}: give at most {most} values, got {len(items)}")
        values = [_number(v, name) for v in items]
    else:
        raise InputError(f"{name}: {text!r}: give one value, a list v1,v2,... or a range START:STOP:COUNT")
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{name}: {text!r}: every value must be a finite number")
    twice = given_twice(values)
    if twice:
        raise InputError(f"{name}: {text!r}: {', '.join(f'{v:g}' for v in twice)} given twice")
    return values


def parse_loads(text: str) -> list[float]:
    """Hook loads (N): :func:`parse_values`, every load > 0."""
    values = parse_values(text, "load_N", MOST_LOADS)
    for v in values:
        if not v > 0:
            raise InputError(f"load_N: must be > 0, got {v:g}")
    return values


def _number(text: str, name: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{name}: {text.strip()!r} is not a number") from None
