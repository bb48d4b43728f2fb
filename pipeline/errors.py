"""The two failures the CLI turns into exit codes (docs/design.md §8), and the argument
parser that reports a usage error the same way.

InputError (exit 2): something the user gave cannot be used; one line naming the field.
OutputError (exit 2): the output folder could not be written.
NumericalError (exit 3): the solve ran but its result cannot be trusted (no convergence,
NaN, loads out of balance); nothing is written.
"""
import argparse
import sys
from collections import Counter
from collections.abc import Hashable, Iterable
from typing import TypeVar

from geometry.table import InputError  # one class for table, case file and CLI errors

__all__ = ["InputError", "NumericalError", "OneLineParser", "OutputError", "given_twice"]

T = TypeVar("T", bound=Hashable)


class NumericalError(RuntimeError):
    """The numerical result failed a check; the message says which and by how much."""


class OutputError(OSError):
    """The output folder could not be written (disk full, permission); the message names
    ``--out``. ``outcome`` says what became of the folder when it is not "nothing written"."""

    def __init__(self, line: str, outcome: str | None = None) -> None:
        super().__init__(line)
        self.outcome = outcome


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {' '.join(message.split())} (see --help)\n")
        sys.exit(2)


def given_twice(items: Iterable[T]) -> list[T]:
    """The items that occur more than once, sorted: every list the user gives (loads, sizes,
    dimension values, dimension names) names each value once, since a repeated one would be
    analysed once and listed twice."""
    return sorted(v for v, n in Counter(items).items() if n > 1)
