"""The two failures the CLI turns into exit codes (docs/design.md §8), and the argument
parser that reports a usage error the same way.

InputError (exit 2): something the user gave cannot be used; one line naming the field.
NumericalError (exit 3): the solve ran but its result cannot be trusted (no convergence,
NaN, loads out of balance); nothing is written.
"""
import argparse
import sys

from geometry.table import InputError  # one class for table, case file and CLI errors

__all__ = ["InputError", "NumericalError", "OneLineParser"]


class NumericalError(RuntimeError):
    """The numerical result failed a check; the message says which and by how much."""


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {' '.join(message.split())} (see --help)\n")
        sys.exit(2)
