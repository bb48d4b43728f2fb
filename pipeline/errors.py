"""The two failures the CLI turns into exit codes (docs/design.md §8), and the argument
parser that reports a usage error the same way.

InputError (exit 2): something the user gave cannot be used; one line naming the field.
OutputError (exit 2): the output folder could not be written.
NumericalError (exit 3): the solve ran but its result cannot be trusted (no convergence,
NaN, loads out of balance); nothing is written. OutOfMemory (exit 3): the run met the end of
the memory it may use while computing (a run estimated not to fit is refused before, exit 2).

An option given twice on the command line is refused (exit 2, one line): the last one would
win silently, and every list the user gives names each value once (:func:`given_twice`).
"""
import argparse
import sys
from collections import Counter
from collections.abc import Hashable, Iterable
from typing import TypeVar

from geometry.table import InputError  # one class for table, case file and CLI errors

__all__ = ["InputError", "NumericalError", "OneLineParser", "OutOfMemory", "OutputError", "given_option",
           "given_twice", "out_of_memory"]

T = TypeVar("T", bound=Hashable)


class NumericalError(RuntimeError):
    """The numerical result failed a check; the message says which and by how much."""


class OutOfMemory(NumericalError):
    """The run met the end of the memory it may use (the machine's, its control group's or
    its address-space limit, ``ulimit -v``) while computing; the message says where."""


# What a library says when it cannot have memory: Python's MemoryError aside, these words
# in an exception (a thread or a shared library that cannot be mapped, C++'s bad_alloc).
NO_MEMORY_WORDS = ("can't start new thread", "failed to map segment", "cannot allocate memory", "bad_alloc",
                   "out of memory", "memoryerror")


def out_of_memory(exc: BaseException) -> bool:
    """Whether ``exc`` says that memory ran out (MemoryError, ENOMEM, or a library's words
    for it: NO_MEMORY_WORDS)."""
    import errno
    if isinstance(exc, (MemoryError, OutOfMemory)):
        return True
    if isinstance(exc, OSError) and exc.errno == errno.ENOMEM:
        return True
    text = f"{type(exc).__name__}: {exc}".lower()
    return any(w in text for w in NO_MEMORY_WORDS)


class OutputError(OSError):
    """The output folder could not be written (disk full, permission); the message names
    ``--out``. ``outcome`` says what became of the folder when it is not "nothing written"."""

    def __init__(self, line: str, outcome: str | None = None) -> None:
        super().__init__(line)
        self.outcome = outcome


GIVEN = "_options_given"  # the attribute of a parsed namespace naming the options given


def given_option(args: argparse.Namespace, dest: str) -> bool:
    """Whether the option that sets ``dest`` was given on the command line (not its default)."""
    return dest in getattr(args, GIVEN, ())


class _Once(argparse.Action):
    """An option's action that records that it was given and refuses it a second time (an
    ``argparse.ArgumentError``: one line, exit 2)."""

    def given(self, namespace: argparse.Namespace, option_string: str | None) -> None:
        seen = getattr(namespace, GIVEN, None)
        if seen is None:
            seen = set()
            setattr(namespace, GIVEN, seen)
        if option_string is not None and self.dest in seen:
            raise argparse.ArgumentError(self, "given twice; give it once")
        seen.add(self.dest)


class OnceStore(_Once, argparse._StoreAction):
    def __call__(self, parser, namespace, values, option_string=None):
        self.given(namespace, option_string)
        super().__call__(parser, namespace, values, option_string)


class OnceStoreTrue(_Once, argparse._StoreTrueAction):
    def __call__(self, parser, namespace, values, option_string=None):
        self.given(namespace, option_string)
        super().__call__(parser, namespace, values, option_string)


class OnceAppend(_Once, argparse._AppendAction):
    """An option given once per value (--dim, --vary, --document): recorded as given; each
    value's name is checked once by the command (given_twice)."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = getattr(namespace, GIVEN, None)
        if seen is None:
            setattr(namespace, GIVEN, {self.dest})
        else:
            seen.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2, and refuses an
    option given twice (the registry's store actions are the _Once ones, shared with
    argument groups and sub-parsers of this class)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, OnceStore)
        self.register("action", "store", OnceStore)
        self.register("action", "store_true", OnceStoreTrue)
        self.register("action", "append", OnceAppend)

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {' '.join(message.split())} (see --help)\n")
        sys.exit(2)


def given_twice(items: Iterable[T]) -> list[T]:
    """The items that occur more than once, sorted: every list the user gives (loads, sizes,
    dimension values, dimension names) names each value once, since a repeated one would be
    analysed once and listed twice."""
    return sorted(v for v, n in Counter(items).items() if n > 1)
