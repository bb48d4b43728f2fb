"""Command line: crosshead {run,converge,sweep} ... (units: mm, N, MPa).

Exit status (docs/design.md §8): 0 done; 2 bad input or an output folder that cannot be
used; 3 the computation failed; 130 / 143 stopped by Ctrl-C / SIGTERM. One line on stderr
naming what failed (the input, --out, stdout, the cache) and what became of the output:
nothing written and an earlier result left as it was, unless the results were already in
place (pipeline.runtime.interrupts.declared_outcome).
"""
from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline import __version__

if TYPE_CHECKING:  # for annotations only: the commands import what they use when they run
    from pipeline.inputs.case import Case

T_START = time.perf_counter()

from pipeline.runtime.environment import configure  # noqa: E402

configure()  # before numpy, PETSc or DOLFINx load (pipeline/runtime/environment.py)

from geometry.table import is_scaled_row  # noqa: E402
from pipeline.inputs.choices import BEARING_AT, BEARING_SHAPES, MODELS, SOLVERS, SUPPORTS, WANTS  # noqa: E402
from pipeline.errors import OneLineParser, given_twice  # noqa: E402
from pipeline.runtime.interrupts import (  # noqa: E402
    declared_outcome, first_rank_by_environment, install as install_interrupts, new_command, stop_line, yield_to_stop)
from pipeline.runtime.streams import silence_stdout  # noqa: E402

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


def _number(text: str) -> float:
    """An option's number; its range is checked with the case (pipeline/inputs/case.py), so that a
    case file's value and the option's are refused alike."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    return v


def _gib(text: str) -> float:
    """--memory-limit: a finite amount of memory > 0, GiB."""
    v = _number(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"memory_limit: must be a finite number of GiB > 0, got {text!r}")
    return v


def _loads(text: str) -> list[float]:
    """--load: one value, a comma list (5000,10000) or a range START:STOP:COUNT, in N
    (pipeline.inputs.valuelist, the grammar study files use too)."""
    from pipeline.errors import InputError
    from pipeline.inputs.valuelist import parse_loads
    try:
        return parse_loads(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _dim(text: str) -> tuple[str, float]:
    from geometry.table import Dimensions
    names = list(Dimensions.__dataclass_fields__)
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=VALUE with NAME one of {', '.join(names)}")
    k, v = text.split("=", 1)
    if k not in names:
        raise argparse.ArgumentTypeError(f"unknown dimension {k!r}; known: {', '.join(names)}")
    try:
        return k, _number(v)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{k}: {exc}") from None


def _vary(text: str) -> tuple[str, list[float]]:
    """--vary NAME=LOW:HIGH: a sensitivity range in mm (checked with the case: low < high)."""
    from pipeline.inputs.case import SENSITIVITY_KEYS
    k, sep, v = text.partition("=")
    lo, sep2, hi = v.partition(":")
    if not sep or not sep2 or k not in SENSITIVITY_KEYS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=LOW:HIGH in mm with NAME one of "
                                         f"{', '.join(SENSITIVITY_KEYS)}")
    try:
        return k, [_number(lo), _number(hi)]
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"vary {k}: {exc}") from None


def _document(text: str) -> tuple[str, str]:
    """--document FIELD=TEXT: a field of the report's title block (the case file's [document])."""
    from pipeline.inputs.case import DOCUMENT_KEYS
    k, sep, v = text.partition("=")
    if not sep or k not in DOCUMENT_KEYS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected FIELD=TEXT with FIELD one of {', '.join(DOCUMENT_KEYS)}")
    if not v.isprintable():
        raise argparse.ArgumentTypeError(f"document {k}: a control character in {v!r}")
    return k, v


def _dim_spec(text: str) -> tuple[str, str]:
    """--dim NAME=VALUES for a sweep: VALUES is START:STOP:COUNT or v1,v2,..."""
    from geometry.table import Dimensions
    names = list(Dimensions.__dataclass_fields__)
    k, sep, v = text.partition("=")
    if not sep or k not in names:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=START:STOP:COUNT or NAME=v1,v2 with NAME one of "
                                         f"{', '.join(names)}")
    return k, v


# A study's defaults when neither the command line nor the study file sets them (None in
# the parser, so that a study file's value is not overridden by a default).
SWEEP_DEFAULTS = {"levels": 3, "ratio": 1.3}
OUT_HELP = {"run": "output folder (default results/<case name>)",
            "converge": "output folder (default results/<case name>-converge)",
            "sweep": "output folder (default results/sweep-<size or case file name>, or the study file's out)"}


def add_case_options(p: argparse.ArgumentParser, dim_type=None, command: str = "run") -> None:
    """Options shared by run and converge: what to analyse and how finely."""
    g = p.add_argument_group("what to analyse")
    g.add_argument("--size", help="hook number from geometry/sizes.csv, e.g. 05, 1.6, 10")
    g.add_argument("--case", type=Path, help="case file (TOML), e.g. cases/05.toml")
    g.add_argument("--load", type=_loads, dest="loads", metavar="N",
                   help="hook load Q in N (default: the size's rated load); a list 5000,10000 or a range "
                        "5000:20000:4 is solved once and scaled (linear elasticity)")
    g.add_argument("--dim", type=dim_type or _dim, action="append", default=[], metavar="NAME=MM",
                   help="override one dimension in mm (b1 b2 b6 d14 d2 h3 dj rf seat_inner seat_outer); repeatable")
    g.add_argument("--support", choices=SUPPORTS,
                   help="journal support: cosine bearing pressure (default) or rigid u_z = 0 (singular edges)")
    g.add_argument("--bearing-shape", choices=BEARING_SHAPES, dest="bearing_shape",
                   help="bearing pressure on each journal's lower half: p0·cos θ (default) or uniform "
                        "(uniform over the projected area); support bearing only")
    g.add_argument("--bearing-length", type=_number, dest="bearing_length_mm", metavar="MM",
                   help="loaded length along each journal, mm: the side plate's thickness (default: the whole "
                        "journal from the fillet's end b1/2 + rf to the tip b6/2)")
    g.add_argument("--bearing-centre", type=_number, dest="bearing_centre_mm", metavar="MM",
                   help="distance from the centre plane x = 0 to the middle of the loaded length, mm (default: "
                        "the middle of the journal's bearing surface)")
    g.add_argument("--bearing-at", choices=BEARING_AT, dest="bearing_at",
                   help="put the journal load at a hand formula's own position: approximate (b1 + b2)/2, or "
                        "exact b6/2 (a band ending at the tip); the band is --bearing-length long, or a fifth "
                        "of the journal's bearing length (docs/design.md §3)")
    g.add_argument("--want", choices=WANTS,
                   help="the peaks wanted: both (default), critical (bore ligaments; the fillet is not refined) "
                        "or global (fillet); a run skips the refinement the other needs")
    g.add_argument("--model", choices=MODELS, help="quarter with symmetry planes (default) or full part")
    g.add_argument("--E", type=_number, dest="E_MPa", metavar="MPA", help="Young's modulus, MPa (default 210000)")
    g.add_argument("--nu", type=_number, metavar="NU", help="Poisson's ratio (default 0.3)")
    g.add_argument("--allowable", type=_number, dest="allowable_MPa", metavar="MPA",
                   help="allowable stress for the safety factor, MPa (default 80)")
    g.add_argument("--span-approximate", type=_number, dest="approximate_span_mm", metavar="MM",
                   help="span l of the approximate formula, mm (default b1 + b2, as the paper)")
    g.add_argument("--span-exact", type=_number, dest="exact_span_mm", metavar="MM",
                   help="span l of the exact formula, mm (default b6, as the paper)")
    m = p.add_argument_group("mesh and solver")
    m.add_argument("--order", type=int, help="element order of the displacement: 1, 2 (default) or 3")
    m.add_argument("--mesh-factor", type=_number, dest="mesh_factor", metavar="F",
                   help="multiply every mesh size by F (<1 finer, >1 coarser; default 1)")
    m.add_argument("--size-body", type=_number, dest="size_body_mm", metavar="MM", help="element size away from features, mm")
    m.add_argument("--size-feature", type=_number, dest="size_feature_mm", metavar="MM",
                   help="element size at bore and seat edges, mm")
    m.add_argument("--size-fillet", type=_number, dest="size_fillet_mm", metavar="MM",
                   help="element size on the shoulder fillets, mm")
    m.add_argument("--grading", type=_number, dest="grading_mm", metavar="MM", help="distance over which sizes grow, mm")
    m.add_argument("--solver", choices=SOLVERS,
                   help="CG + p-multigrid over P1 with GAMG (default), CG + GAMG, CG + BoomerAMG, or direct MUMPS")
    m.add_argument("--rtol", type=_number, help="relative tolerance of the iterative solver on the true residual (default 1e-8)")
    m.add_argument("--memory-limit", type=_gib, dest="memory_limit", metavar="GB",
                   help="refuse a run estimated to need more memory than this, GiB (default: what the machine has free)")
    p.add_argument("--out", type=Path, help=OUT_HELP[command])
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def make_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="crosshead", description=DESCRIPTION, epilog=EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"crosshead {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{run,converge,sweep}", parser_class=OneLineParser)
    run = sub.add_parser("run", help="analyse one case and write results, report, fields, picture",
                         description=DESCRIPTION, epilog=EPILOG,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(run)
    run.add_argument("--levels", type=int, default=3,
                     help="meshes solved for the error bar: the requested one and coarser ones "
                          "(default 3, up to 8; 1 = no error bar; 2 is refused)")
    run.add_argument("--ratio", type=_number, default=1.3, help="mesh-size ratio between those meshes (default 1.3)")
    run.add_argument("--tolerance", type=_number, dest="tolerance_pct", metavar="PCT",
                     help="the accuracy asked: each wanted peak's error-bar band at most PCT %% of its value; the run "
                          "adds meshes (a smaller step, then finer ones) until it is, but never refines past a given "
                          "--mesh-factor (default 1; docs/design.md §5)")
    run.add_argument("--no-fields", action="store_true", help="skip ParaView files, picture and report (benchmarks)")
    run.add_argument("--no-sensitivity", action="store_true",
                     help="skip varying the assumed inputs (dj, rf, seat, the bearing load model) over their "
                          "plausible ranges; a run with --want skips it too")
    run.add_argument("--vary", type=_vary, action="append", default=[], metavar="NAME=LOW:HIGH",
                     help="the range (mm) over which the sensitivity section varies NAME (dj rf seat_inner "
                          "seat_outer bearing_centre_mm bearing_length_mm), instead of its default; varies it "
                          "even when --dim or a --bearing option sets it; repeatable")
    run.add_argument("--document", type=_document, action="append", default=[], metavar="FIELD=TEXT",
                     help="a field of the report's title block (part, number, revision, author, checker), as a "
                          "case file's [document] gives it; it overrides the case file's; repeatable")
    run.add_argument("--quarter-fields", action="store_true",
                     help="picture and both .vtu files of the quarter model only (default: mirrored to the whole part)")
    conv = sub.add_parser("converge", help="mesh convergence study: >= 4 meshes, extrapolation, GCI, plot",
                          description=DESCRIPTION, epilog=EPILOG,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(conv, command="converge")
    conv.add_argument("--levels", type=int, default=5,
                      help="number of meshes (default 5, at least 4); the finest is the case's mesh / ratio^(levels-3)")
    conv.add_argument("--ratio", type=_number, default=1.3, help="mesh-size ratio between meshes, >= 1.3 (default 1.3)")
    sweep = sub.add_parser("sweep", help="design study: a grid of dimensions and loads, each variant with its error bar",
                           description=DESCRIPTION, epilog=SWEEP_EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(sweep, dim_type=_dim_spec, command="sweep")
    sweep.add_argument("--sizes", metavar="LIST", help="hook numbers to sweep over, e.g. 05,1,2.5, or 'all' rows of "
                       "geometry/sizes.csv (each at its own rated load unless --load is given)")
    sweep.add_argument("--study", type=Path, help="a study file (TOML with a [sweep] table), e.g. cases/sweep-rf.toml")
    sweep.add_argument("--levels", type=int, help="meshes per variant for its error bar (default 3; 1 = none; 2 is refused)")
    sweep.add_argument("--ratio", type=_number, help="mesh-size ratio between them (default 1.3)")
    sweep.add_argument("--screen", action="store_true",
                       help="decide each variant with the least work: one coarse mesh first, the full error bar only "
                            "where its band holds the allowable or the variant borders a crossing; needs an allowable "
                            "(--allowable or the case file's)")
    sweep.add_argument("--sensitivity", action="store_true",
                       help="each variant also varies its assumed inputs (dj, rf, seat, bearing load model) over "
                            "their ranges, and the table says which verdicts depend on one (about doubles a variant's "
                            "time)")
    return parser


SWEEP_EPILOG = """\
examples:
  crosshead sweep --size 05 --dim rf=0.5:2.5:5              the fillet radius from 0.5 to 2.5 mm
  crosshead sweep --size 05 --dim rf=1,2 --dim dj=16,18,20   a grid of six variants
  crosshead sweep --study cases/sweep-rf.toml
  python -m pipeline.runtime.launch 2 sweep --size 05 --dim rf=1:2:3         variants spread over 2 ranks
A re-run with the same --out skips the variants already finished.
"""


CASE_KEYS = ("want", "support", "model", "E_MPa", "nu", "allowable_MPa", "approximate_span_mm",
             "exact_span_mm", "order", "mesh_factor", "size_body_mm", "size_feature_mm",
             "size_fillet_mm", "grading_mm", "solver", "rtol", "bearing_shape", "bearing_length_mm",
             "bearing_centre_mm")


NO_COMMAND = "error: command: choose run, converge or sweep (see crosshead --help)"
LOADS_SHOWN = 3  # loads shown at each end of a long load sweep's terminal line
TWO_LEVELS = ("levels: 2 meshes give no error bar (the estimate needs 3) and cost a solve; give 1 for no "
              "error bar, or 3 to 8")


class StdoutError(Exception):
    """stdout could not take a line (a full disk, /dev/full); the message names stdout.
    Not an OSError: the line must not blame --out."""


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
    if handle_signals:
        install_interrupts(speak=first_rank_by_environment())
    try:
        code = _dispatch(args)
    except KeyboardInterrupt:  # without handle_signals: a test calling in
        sys.stderr.write(stop_line(signal.SIGINT) + "\n")
        return 130
    yield_to_stop()  # a signal's stop, once begun, ends the process with its own status
    return code


def _dispatch(args: argparse.Namespace) -> int:
    """Do the command; a failure becomes one line on stderr (rank 0) and its exit status:
    2 bad input or an output folder that cannot be written, 3 the computation failed.
    Under more than one MPI rank a failure on any rank ends the run on all of them
    (pipeline.runtime.rankfailure)."""
    from mpi4py import MPI

    from geometry.part import GeometryError
    from pipeline.errors import InputError, NumericalError
    from pipeline.runtime.outdir import OutputError
    from pipeline.runtime.rankfailure import RankFailures
    rank0 = MPI.COMM_WORLD.rank == 0
    new_command()
    with RankFailures(MPI.COMM_WORLD) as failures:
        try:
            with contextlib.ExitStack() as stack:  # clean-ups that last as long as this command
                if args.command == "sweep":
                    return _sweep(args, rank0)
                return _run_or_converge(args, rank0, stack)
        except OutputError as exc:  # before InputError and OSError: it is both an output and an OS failure
            code, line = 2, f"error: {_one_line(exc)}; {exc.outcome or declared_outcome()}"
        except StdoutError as exc:
            code, line = 2, f"error: {_one_line(exc)}; {declared_outcome()}"
        except InputError as exc:
            code, line = 2, f"error: {_one_line(exc)}"
        except (NumericalError, GeometryError) as exc:
            code, line = 3, f"numerical failure: {_one_line(exc)}; {declared_outcome()}"
        except OSError as exc:  # disk full, permission, ... outside the output folder (the cache, say)
            code, line = 2, f"error: {_os_failure(exc)}; {declared_outcome()}"
        except Exception as exc:  # a failure no check foresaw: still one line, and what became of the output
            if os.environ.get("CROSSHEAD_TRACEBACK"):
                raise
            code, line = 3, (f"failure: {type(exc).__name__}: {_one_line(exc)}; {declared_outcome()} "
                             "(set CROSSHEAD_TRACEBACK=1 for the traceback)")
        return failures.fail(code, line)


def _run_or_converge(args: argparse.Namespace, rank0: bool, stack: contextlib.ExitStack) -> int:
    """The run and converge commands: the case and the output folder are checked before
    any work, then pipeline.commands does it and rank 0 prints the summary. Clean-ups
    that must last until the command ends go on ``stack``."""
    case, loads = _case_of(args)
    if rank0:  # before any form is compiled; the other ranks wait for rank 0's compiles
        _guard_form_cache(stack)
    _check_memory(args, case, rank0)
    from pipeline.runtime.outdir import check_out, default_out
    out = args.out if args.out is not None else default_out(
        case.name if args.command == "run" else f"{case.name}-converge")
    check_out(out)  # refused before any work; checked again under the lock
    say = (lambda s: None) if (args.quiet or not rank0) else _progress
    _announce(args, case, say, rank0)
    if args.command == "run":
        from pipeline.commands import execute_run
        execute_run(case, out, levels=args.levels, ratio=args.ratio, progress=say,
                    write_fields=not args.no_fields, loads=loads if len(loads) > 1 else None,
                    quarter_fields=args.quarter_fields, sensitivity=not args.no_sensitivity, to_tolerance=True)
    else:
        from pipeline.commands import execute_converge
        execute_converge(case, out, levels=args.levels, ratio=args.ratio, progress=say)
    if rank0 and not args.quiet:
        _summary(Path(out))
    return 0


def _case_of(args: argparse.Namespace) -> tuple[Case, list[float]]:
    """The checked case the options describe (--size or --case with the options'
    overrides) and the loads of --load (N, empty when not given). Every load of a list
    passes the same checks as the first; raises InputError otherwise."""
    from dataclasses import replace

    from pipeline.inputs.case import check, resolve
    from pipeline.errors import InputError
    overrides = {k: getattr(args, k) for k in CASE_KEYS}
    overrides.update({f"dims.{k}": v for k, v in args.dim})
    overrides.update({f"sensitivity.{k}": v for k, v in getattr(args, "vary", [])})
    twice = given_twice(k for k, _ in getattr(args, "document", []))
    if twice:
        raise InputError(f"document: {', '.join(twice)} given twice")
    overrides.update({f"document.{k}": v for k, v in getattr(args, "document", [])})
    overrides["tolerance_pct"] = getattr(args, "tolerance_pct", None)
    loads = args.loads or []
    if loads:
        overrides["load_N"] = loads[0]
    for q in loads[1:]:  # every load of a sweep must pass the same checks as the first
        check(replace(resolve(args.size, args.case, overrides), load_N=q))
    if args.size is None and args.case is None:
        raise InputError("size: give --size (hook number) or --case (case file)")
    case = _bearing_at(args, resolve(args.size, args.case, overrides))
    _check_levels(args, case)
    return case, loads


def _bearing_at(args: argparse.Namespace, case: Case) -> Case:
    """The case with --bearing-at applied: the bearing band's centre (and, unless given,
    its length) at that hand formula's own load position (pipeline.inputs.case.formula_bearing);
    refused beside --bearing-centre, which names another position."""
    from dataclasses import replace

    from pipeline.inputs.case import check, formula_bearing
    from pipeline.errors import InputError
    if getattr(args, "bearing_at", None) is None:
        return case
    if args.bearing_centre_mm is not None:
        raise InputError("bearing_at: --bearing-at sets the bearing centre; give it or --bearing-centre, not both")
    span = case.approximate_span_mm if args.bearing_at == "approximate" else case.exact_span_mm
    centre, length = formula_bearing(case.dims, args.bearing_at, case.bearing_length_mm, span)
    return check(replace(case, bearing_centre_mm=centre, bearing_length_mm=length))


def _check_levels(args: argparse.Namespace, case: Case) -> None:
    """Refuse (InputError) --levels outside 1..8 and --ratio outside [1.1, 3]; a convergence
    study needs at least 4 meshes at a ratio >= 1.3 and one load; its finest mesh, and the
    coarsest error-bar mesh of a run, must pass the case's mesh checks too."""
    from dataclasses import replace

    from pipeline.inputs.case import check, check_error_bar_meshes
    from pipeline.errors import InputError
    if args.levels < 1 or args.levels > 8:
        raise InputError(f"levels: must lie in 1..8, got {args.levels}")
    if args.levels == 2:
        raise InputError(TWO_LEVELS)
    if args.command == "converge" and (args.levels < 4 or args.ratio < 1.3):
        raise InputError("levels/ratio: a convergence study needs at least 4 meshes and ratio >= 1.3")
    if args.command == "converge" and len(args.loads or []) > 1:
        raise InputError("load_N: a convergence study takes one load (a run or a sweep takes several)")
    if not 1.1 <= args.ratio <= 3:
        raise InputError(f"ratio: must lie in [1.1, 3], got {args.ratio:g}")
    if args.command != "converge":
        check_error_bar_meshes(case, args.levels, args.ratio)
    else:  # the study's finest mesh must pass the case's mesh checks too
        finest = case.mesh_factor / args.ratio ** max(args.levels - 3, 0)
        try:
            check(replace(case, mesh_factor=finest))
        except InputError as exc:
            raise InputError(f"levels: the finest mesh of this study (mesh factor {case.mesh_factor:g} / "
                             f"{args.ratio:g}^{args.levels - 3} = {finest:.3g}) is not allowed: {exc}") from None


def _guard_form_cache(stack: contextlib.ExitStack) -> None:
    """Rank 0, before any form is compiled: remove the form-cache claims that interrupted
    compiles left, and have this command remove its own if it is stopped (on ``stack``)."""
    from pipeline.cache.forms import claims_since, jit_cache_dir, remove_interrupted
    from pipeline.runtime.interrupts import on_stop
    cache, started = jit_cache_dir(), time.time()
    # A compile cut short by Ctrl-C leaves its claim, and every later run needing
    # that form would wait for it and time out: a stopped run removes its own.
    stack.enter_context(on_stop(lambda: [c.unlink(missing_ok=True) for c in claims_since(cache, started)]))
    for stale in remove_interrupted(cache):
        _progress(f"removed {stale.name} from the form cache (an interrupted compile)")


def _check_memory(args: argparse.Namespace, case: Case, rank0: bool) -> None:
    """Refuse a command whose meshes would not fit in memory (--memory-limit, GiB; raises
    InputError), and warn that a large one's meshing alone may take minutes."""
    from pipeline.runtime.resources import check_fits, factors_of
    est = check_fits(case, factors_of(case, args.command, args.levels, args.ratio), args.memory_limit)
    if est is not None and est.tets > 3e5 and rank0 and not args.quiet:
        _progress(f"a large run: the finest mesh has about {est.tets:.1e} tets, {est.dofs:.1e} DOFs, "
                  f"{est.bytes / 1024 ** 3:.1f} GiB; meshing alone may take minutes")


def _announce(args: argparse.Namespace, case: Case, say: Callable[[str], None], rank0: bool) -> None:
    """The first progress lines: which refinement --want skips, then the import time (s)
    and the case (hook number, load in N, model, support, element order)."""
    if case.want != "both":
        other = "global (fillet)" if case.want == "critical" else "critical (bore ligament)"
        say(f"want = {case.want}: skipping the refinement for the {other} peak"
            + (" (fillet elements at the bore edges' size; the bore edges refined where the dimensions put them, "
               "no pilot solve)"
               if case.want == "critical" else " (the pilot refines the fillet only)")
            + "; that peak is shown without a verdict")
    _progress(f"imports {time.perf_counter() - T_START:.2f} s; case {case.name}: hook No. {case.size}, "
              f"Q = {case.load_N:g} N, {case.model} model, {case.support} support, P{case.order}"
              + (" (a scaled row: NOT DIN 15412 dimensions)" if is_scaled_row(case.source) else "")) \
        if not args.quiet and rank0 else None
    if case.mesh_factor > 1.3 and case.want != "critical":
        say(f"note: mesh factor {case.mesh_factor:g} > 1.3: the global (fillet) peak is not resolved on meshes "
            "this coarse (README, Known limits); its value and verdict are rough")


def _sweep(args, rank0: bool) -> int:
    """The sweep command: a grid from --dim/--load (or a study file), then pipeline.study.sweep."""
    from pipeline.errors import InputError
    from pipeline.runtime.outdir import default_out
    from pipeline.study.plan import read_study
    from pipeline.inputs.valuelist import MOST_DIM_VALUES, parse_loads, parse_values
    from pipeline.study.sweep import execute_sweep
    from pipeline.inputs.case import read_case_file
    if args.bearing_at is not None:
        raise InputError("bearing_at: a sweep takes --bearing-centre (and --bearing-length), not --bearing-at")
    study = read_study(args.study) if args.study else {}
    size = args.size or study.get("size")
    case_file = args.case or (Path(study["case"]) if "case" in study else None)
    sizes = None
    if args.sizes:
        from geometry.table import load_table
        table = list(load_table())
        if args.size is not None or "size" in study:
            raise InputError("size: give --size (or a study file's size) or --sizes, not both")
        sizes = table if args.sizes == "all" else [s.strip() for s in args.sizes.split(",")]
        if "" in sizes:
            raise InputError(f"sizes: {args.sizes!r} has an empty item")
        unknown = [s for s in sizes if s not in table]
        if unknown or not sizes:
            raise InputError(f"sizes: unknown hook number(s) {', '.join(unknown) or '(none given)'}; "
                             f"known: {', '.join(table)}")
        twice = given_twice(sizes)
        if twice:
            raise InputError(f"sizes: {', '.join(twice)} given twice")
        size = size or sizes[0]
    if size is None and case_file is None:
        raise InputError("size: give --size, --case or a study file with size = ...")
    names = [k for k, _ in args.dim]
    twice = given_twice(names)
    if twice:
        raise InputError(f"dim: {', '.join(twice)} given twice; give each dimension's values in one --dim")
    dims = dict(study.get("dims", {}))
    dims.update(dict(args.dim))  # the command line overrides the study file
    axes = {f"dims.{k}": parse_values(str(v), f"dims.{k}", MOST_DIM_VALUES) for k, v in dims.items()}
    loads = args.loads or (parse_loads(str(study["load"])) if "load" in study else [])
    base = {k: getattr(args, k) for k in CASE_KEYS if getattr(args, k) is not None}
    if "mesh_factor" in study and "mesh_factor" not in base:
        base["mesh_factor"] = float(study["mesh_factor"])
    # The command line overrides the study file, which overrides the defaults.
    levels = args.levels if args.levels is not None else int(study.get("levels", SWEEP_DEFAULTS["levels"]))
    ratio = args.ratio if args.ratio is not None else float(study.get("ratio", SWEEP_DEFAULTS["ratio"]))
    if not 1 <= levels <= 8 or not 1.1 <= ratio <= 3:
        raise InputError("levels/ratio: levels must lie in 1..8 and ratio in [1.1, 3]")
    if levels == 2:
        raise InputError(TWO_LEVELS)
    if not axes and len(loads) < 2 and not sizes:
        raise InputError("dim: a sweep needs at least one --dim NAME=VALUES, several loads or --sizes")
    out = args.out or (Path(study["out"]) if "out" in study else default_out(f"sweep-{size or Path(case_file).stem}"))
    screen = args.screen or bool(study.get("screen", False))
    if screen and "allowable_MPa" not in base and not (
            case_file is not None and "allowable_MPa" in read_case_file(case_file)):
        raise InputError("screen: a screened study decides against an allowable; give --allowable MPa "
                         "(or allowable_MPa in the case file), or leave screening off for the full analysis")
    say = (lambda s: None) if args.quiet else _progress
    res = execute_sweep(size, case_file, base, axes, loads, out, levels, ratio, say, sizes=sizes,
                        memory_limit_gb=args.memory_limit, sensitivity=args.sensitivity, screen=screen)
    if rank0 and res is not None and not args.quiet:
        from pipeline.study.table import passing_count
        c = res["counts"]
        # With several loads a row is a case (a variant at one load), and the counts are of cases.
        n = sum(c.values())
        cases = f"{n} cases ({n // len(loads)} variants at {len(loads)} loads): " if len(loads) > 1 else ""
        _print(f"sweep: {cases}{c['done']} done, {c['invalid']} invalid, {c['failed']} failed; "
               f"{passing_count(res['rows'])} of {c['done']} pass {res['allowable_MPa']:g} MPa with every peak; "
               f"{len(res['crossings'])} crossing(s) of the allowable; written to {out}/ (sweep.csv, sweep.json, report.md)")
    return 0


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def _os_failure(exc: OSError) -> str:
    """The thing an OSError met outside the output folder, named for the failure line:
    the cache (compiled forms, meshes kept for later runs) or the file itself."""
    from pipeline.runtime.environment import CACHE_HOME
    reason = exc.strerror or _one_line(exc)
    if exc.filename is None:
        return f"a file operation failed ({reason})"
    path = Path(os.fsdecode(exc.filename))
    if CACHE_HOME == path or CACHE_HOME in path.parents:
        runs = CACHE_HOME / "runs"  # the run cache can be turned off; the form compiler's cannot
        hint = "; CROSSHEAD_NO_CACHE=1 runs without it" if runs == path or runs in path.parents else ""
        return f"cache: cannot use {path} ({reason}{hint})"
    return f"{path}: {reason}"


def _progress(msg: str) -> None:
    """A progress line on stderr, stamped with the seconds since the program started: stdout
    carries only the results, so ``crosshead run ... > results.txt`` keeps them apart. A
    stderr that cannot take it loses the line, never the run (pipeline.runtime.streams)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"[{time.perf_counter() - T_START:7.2f} s] {msg}\n")
        sys.stderr.flush()


def _print(line: str) -> None:
    """Print a line. A closed pipe (``| head``) silences the rest and the run goes on: the
    reader wanted no more. Any other failure (a full disk, /dev/full) is the command's:
    StdoutError, and the rest silenced so that the exit does not try again."""
    try:
        print(line, flush=True)
    except (BrokenPipeError, ValueError):  # ValueError: a stream closed in this process
        silence_stdout()
    except OSError as exc:
        if threading.current_thread() is not threading.main_thread():
            return  # the meshing heartbeat's: the main thread's next line meets the failure and reports it
        silence_stdout()
        raise StdoutError(f"stdout: cannot write ({exc.strerror or exc})") from None



def _summary(out: Path) -> None:
    """The run's closing lines, from the results.json it wrote (not from what it holds in
    memory: the lines say what the file says)."""
    import json

    from pipeline.output.report import accuracy_text, error_bar_text, feature_text, no_safety_factor_reason, pm
    res = json.loads((out / "results.json").read_text(encoding="utf-8"))
    fe = res["fe"]
    for name, key in (("global peak  ", "peak"), ("critical peak", "critical")):
        _print(f"{name} {fe[key]['value_MPa']:8.2f} MPa  {error_bar_text(fe[key])}  [{feature_text(fe[key])}]")
    if fe.get("accuracy"):
        _print(accuracy_text(fe["accuracy"]))
    an = res["analytic"]

    def sf(key: str) -> str:
        return f"{fe[key]:.2f}" if fe[key] is not None else f"none ({no_safety_factor_reason(fe, key)})"
    _print(f"formulas: approximate {an['approximate_MPa']:.2f} MPa, exact {an['exact_MPa']:.2f} MPa; "
           f"safety factor {sf('safety_factor')} (global), {sf('critical_safety_factor')} (critical)")
    if res.get("load_sweep"):
        rows = res["load_sweep"]
        texts = [f"{r['load_N']:g} N {pm(r['peak_MPa'], r.get('peak_band_MPa'))} / "
                 f"{pm(r['critical_peak_MPa'], r.get('critical_band_MPa'))}" for r in rows]
        long = len(rows) > 2 * LOADS_SHOWN  # a line a person can read: the ends, the rest in the files
        if long:
            texts = texts[:LOADS_SHOWN] + [f"… {len(rows) - 2 * LOADS_SHOWN} more in results.json …"] + texts[-LOADS_SHOWN:]
        _print(f"the lines above are at Q = {res['case']['load_N']:g} N; {f'{len(rows)} loads' if long else 'every load'} "
               "(global / critical peak, MPa): " + "; ".join(texts))
    summ = res.get("sensitivity_summary")
    if summ:
        _print(f"sensitivity: {summ['sentence']}")
    named = res.get("files") or {"results": "results.json"}
    files = [named[k] for k in ("report", "results") if k in named] + \
        [f for k, f in named.items() if k not in ("report", "results")]
    # The seconds since the program started, as the progress lines count them (the run's own
    # total in results.json starts after the imports).
    _print(f"written to {out}/ ({', '.join(files[:4])}{', ...' if len(files) > 4 else ''}) "
           f"in {time.perf_counter() - T_START:.1f} s")

