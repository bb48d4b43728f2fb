"""The grammar of a list of numbers the user gives: hook loads (N) and a study's swept
dimensions (mm). One value, a comma list ``a,b,c``, or a range ``START:STOP:COUNT`` (COUNT
values, both ends included). Every value is finite and given once: a repeated value would
be analysed once and listed twice. The command line and study files both read lists here,
so a list means the same wherever it is written.

A number is read as an engineer writes it (:func:`as_number`): digits 0-9 with an optional
sign, decimal point and exponent ("12.5", "-3", "1e4", ".5"), or the words nan and inf (so
that their line says "must be finite", as a case file's nan does). Python's own readers
accept more ("1_0" is 10, "١٢" is 12): those are refused.
"""
from __future__ import annotations

import math
import re

from pipeline.errors import InputError

# Two values closer than this are one value (relative, and absolute in mm or N for values
# near zero): far above the round-off of a range's arithmetic (~1e-16), far below any
# difference a dimension or a load can be made or measured to.
SAME_REL = 1e-9
SAME_ABS = 1e-12
MOST_LOADS = 1000  # loads are cheap: one solve, scaled to each
MOST_DIM_VALUES = 200  # each swept value of a dimension is a full analysis

NUMBER = re.compile(r"[+-]?(?:(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|nan|inf|infinity)",
                    re.IGNORECASE | re.ASCII)
INTEGER = re.compile(r"[+-]?[0-9]+", re.ASCII)


def as_number(text: str) -> float:
    """The number ``text`` is (surrounding spaces aside), as an engineer writes it (see the
    module); ValueError when it is not one."""
    t = text.strip()
    if not NUMBER.fullmatch(t):
        raise ValueError(f"{text!r} is not a number")
    return float(t)


def as_integer(text: str) -> int:
    """The whole number ``text`` is (digits 0-9 with an optional sign, surrounding spaces
    aside); ValueError when it is not one."""
    t = text.strip()
    if not INTEGER.fullmatch(t):
        raise ValueError(f"{text!r} is not an integer")
    return int(t)


def parse_values(text: str, name: str, most: int) -> list[float]:
    """The numbers of ``text`` (at most ``most`` of them); ``name`` starts every error line.
    Raises InputError naming what is wrong."""
    parts = text.split(":")
    if len(parts) == 3:
        a, b = (_number(p, name) for p in parts[:2])
        try:
            n = as_integer(parts[2])
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
    values = [v + 0.0 for v in values]  # -0.0 + 0.0 is 0.0
    twice = same_values(values)
    if twice:
        raise InputError(f"{name}: {text!r}: {', '.join(twice)} given twice")
    return values


def same_values(values: list[float]) -> list[str]:
    """The values of ``values`` given more than once, as text, sorted: a value repeated
    exactly ("5000"), or two that are equal to round-off (within SAME_REL, or SAME_ABS
    near zero), both named in full ("1.0 and 1.0000000000000002 (equal to round-off)")."""
    order = sorted(values)
    found: list[str] = []
    for a, b in zip(order, order[1:]):
        if not math.isclose(a, b, rel_tol=SAME_REL, abs_tol=SAME_ABS):
            continue
        text = f"{a:g}" if a == b else f"{a!r} and {b!r} (equal to round-off)"
        if text not in found:
            found.append(text)
    return found


def parse_loads(text: str) -> list[float]:
    """Hook loads (N): :func:`parse_values`, every load > 0."""
    values = parse_values(text, "load_N", MOST_LOADS)
    for v in values:
        if not v > 0:
            raise InputError(f"load_N: must be > 0, got {v:g}")
    return values


def _number(text: str, name: str) -> float:
    try:
        return as_number(text)
    except ValueError:
        raise InputError(f"{name}: {text.strip()!r} is not a number") from None
