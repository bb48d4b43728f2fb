"""Command line: crosshead {run,converge,sweep} ... (units: mm, N, MPa). One module per
command (run.py, converge.py, sweep.py) adds its options and does its work.

Exit status (docs/design.md §8): 0 done; 2 bad input or an output folder that cannot be
used; 3 the computation failed; 130 / 143 stopped by Ctrl-C / SIGTERM. One line on stderr
naming what failed (the input, --out, stdout, the cache) and what became of the output:
nothing written and an earlier result left as it was, unless the results were already in
place (pipeline.runtime.interrupts.declared_outcome).
"""
from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
from pathlib import Path

from pipeline.cli.terminal import T_START  # noqa: F401  (the clock of every progress line starts here)
from pipeline.runtime.environment import CACHE_HOME, configure

configure()  # before numpy, PETSc or DOLFINx load (pipeline/runtime/environment.py)

from pipeline import __version__  # noqa: E402
from pipeline.cli import converge, run, sweep  # noqa: E402
from pipeline.cli.sweep import SWEEP_DEFAULTS  # noqa: E402,F401  (the help's defaults, tests/cli/test_help.py)
from pipeline.cli.terminal import StdoutError  # noqa: E402
from pipeline.errors import (InputError, NumericalError, OneLineParser, OutOfMemory, OutputError,  # noqa: E402
                             out_of_memory)
from pipeline.runtime.environment import address_space_refusal  # noqa: E402
from pipeline.runtime.interrupts import (  # noqa: E402
    NOTHING_WRITTEN, declared_outcome, first_rank_by_environment, install as install_interrupts, new_command, stop_line,
    yield_to_stop)
from pipeline.runtime.streams import silence_stdout  # noqa: E402

COMMANDS = {"run": run, "converge": converge, "sweep": sweep}
DESCRIPTION = """\
Finite-element stress analysis of a DIN 15412 crane hook-block crosshead.

Builds the part from its table dimensions (gmsh/OpenCASCADE), meshes it, solves 3-D
linear elasticity (DOLFINx) and reports the peak von Mises stress, where it sits and its
discretisation error bar, beside the paper's approximate and exact hand formulas.
Units everywhere: mm, N, MPa.
"""
EPILOG = """\
examples:
  crosshead run --size 05                        hook No. 05 under its 10 kN load
  crosshead run --case cases/05.toml --out results/my05
  crosshead run --size 05 --load 12500 --support rigid
  crosshead run --size 05 --dim rf=2.0 --mesh-factor 0.8
  crosshead converge --size 05                   mesh convergence study

exit status: 0 done; 2 bad input or an output folder that cannot be used (nothing written);
3 numerical failure (nothing written); 130 interrupted (Ctrl-C), 143 terminated (SIGTERM):
the earlier result in the output folder is left as it was
"""
NO_COMMAND = "error: command: choose run, converge or sweep (see crosshead --help)"


def make_parser() -> argparse.ArgumentParser:
    """The whole command line's parser: every command's options."""
    parser = OneLineParser(prog="crosshead", description=DESCRIPTION, epilog=EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"crosshead {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{run,converge,sweep}", parser_class=OneLineParser)
    for module in COMMANDS.values():
        module.add_parser(sub, DESCRIPTION, EPILOG)
    return parser


def main(argv: list[str] | None = None, handle_signals: bool = False) -> int:
    """The command line; ``handle_signals`` (the program, not a test calling in) makes
    Ctrl-C and SIGTERM stop a run cleanly with exit 130 / 143 (pipeline.runtime.interrupts)."""
    try:
        args = make_parser().parse_args(argv)
    except OSError as exc:  # --help on a full stdout: argparse lets the write's error through
        silence_stdout()
        sys.stderr.write(f"error: stdout: cannot write the help ({exc.strerror or exc})\n")
        return 2
    if args.command is None:
        with contextlib.suppress(OSError):  # a full stdout: the error line below still says what to do
            make_parser().print_help()
        sys.stderr.write(NO_COMMAND + "\n")
        return 2
    refused = address_space_refusal()  # before a thread, a library or MPI is started
    if refused is not None:
        if first_rank_by_environment():  # under mpirun every rank meets it: one line
            sys.stderr.write(f"error: {refused}\n")
        return 2
    if handle_signals:
        try:
            install_interrupts(speak=first_rank_by_environment())
        except RuntimeError as exc:  # no thread can start: the memory this process may have is used up
            sys.stderr.write(f"out of memory: {one_line(exc)}; {NOTHING_WRITTEN}\n")
            return 3
    try:
        code = dispatch(args)
    except KeyboardInterrupt:  # without handle_signals: a test calling in
        sys.stderr.write(stop_line(signal.SIGINT) + "\n")
        return 130
    yield_to_stop()  # a signal's stop, once begun, ends the process with its own status
    return code


def dispatch(args: argparse.Namespace) -> int:
    """Do the command; a failure becomes one line on stderr (rank 0) and its exit status:
    2 bad input or an output folder that cannot be written, 3 the computation failed.
    Under more than one MPI rank a failure on any rank ends the run on all of them
    (pipeline.runtime.rankfailure)."""
    from mpi4py import MPI  # MPI starts here, not when --help is asked

    from geometry.part import GeometryError
    from pipeline.runtime.rankfailure import RankFailures
    rank0 = MPI.COMM_WORLD.rank == 0
    new_command()
    with RankFailures(MPI.COMM_WORLD) as failures:
        try:
            with contextlib.ExitStack() as stack:  # clean-ups that last as long as this command
                return COMMANDS[args.command].execute(args, rank0, stack)
        except OutputError as exc:  # before InputError and OSError: it is both an output and an OS failure
            code, line = 2, f"error: {one_line(exc)}; {exc.outcome or declared_outcome()}"
        except StdoutError as exc:
            code, line = 2, f"error: {one_line(exc)}; {declared_outcome()}"
        except InputError as exc:
            code, line = 2, f"error: {one_line(exc)}"
        except OutOfMemory as exc:
            code, line = 3, f"out of memory: {memory_failure(exc)}; {declared_outcome()}"
        except (NumericalError, GeometryError) as exc:
            code, line = 3, f"numerical failure: {one_line(exc)}; {declared_outcome()}"
        except OSError as exc:  # disk full, permission, ... outside the output folder (the cache, say)
            if out_of_memory(exc):
                code, line = 3, f"out of memory: {memory_failure(exc)}; {declared_outcome()}"
            else:
                code, line = 2, f"error: {os_failure(exc)}; {declared_outcome()}"
        except Exception as exc:  # a failure no check foresaw: still one line, and what became of the output
            if os.environ.get("CROSSHEAD_TRACEBACK"):
                raise
            if out_of_memory(exc):  # memory ran out while computing (the estimate let the run start)
                code, line = 3, f"out of memory: {memory_failure(exc)}; {declared_outcome()}"
            else:
                code, line = 3, (f"failure: {type(exc).__name__}: {one_line(exc)}; {declared_outcome()} "
                                 "(set CROSSHEAD_TRACEBACK=1 for the traceback)")
        return failures.fail(code, line)


def one_line(exc: Exception) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split())


def memory_failure(exc: BaseException) -> str:
    """What ran out of memory, for the failure line: the exception's words (a MemoryError has
    none: its kind then), and the address-space limit when one is set (``ulimit -v``)."""
    from pipeline.runtime.environment import GIB, address_space_limit
    words = one_line(exc) or type(exc).__name__
    limit = address_space_limit()
    return words + (f" (the address space is limited to {limit / GIB:.2f} GiB: ulimit -v)" if limit else "")


def os_failure(exc: OSError) -> str:
    """The thing an OSError met outside the output folder, named for the failure line:
    the cache (compiled forms, meshes kept for later runs) or the file itself."""
    reason = exc.strerror or one_line(exc)
    if exc.filename is None:
        return f"a file operation failed ({reason})"
    path = Path(os.fsdecode(exc.filename))
    if CACHE_HOME == path or CACHE_HOME in path.parents:
        runs = CACHE_HOME / "runs"  # the run cache can be turned off; the form compiler's cannot
        hint = "; CROSSHEAD_NO_CACHE=1 runs without it" if runs == path or runs in path.parents else ""
        return f"cache: cannot use {path} ({reason}{hint})"
    return f"{path}: {reason}"
