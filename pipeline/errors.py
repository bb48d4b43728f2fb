"""The two failures the CLI turns into exit codes (docs/design.md §8).

InputError (exit 2): something the user gave cannot be used; one line naming the field.
NumericalError (exit 3): the solve ran but its result cannot be trusted (no convergence,
NaN, loads out of balance); nothing is written.
"""
from geometry.table import InputError  # one class for table, case file and CLI errors

__all__ = ["InputError", "NumericalError"]


class NumericalError(RuntimeError):
    """The numerical result failed a check; the message says which and by how much."""
