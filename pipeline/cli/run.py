"""crosshead run: one case with its error bar, sections, verdicts and what the verdict
rests on (the sensitivity section); results.json, report, fields and pictures."""
from __future__ import annotations

import argparse
import contextlib

from pipeline.cli.options import add_case_options, document, integer, number, request_of, vary


def add_parser(sub, description: str, epilog: str) -> None:
    """The run command's options."""
    run = sub.add_parser("run", help="analyse one case and write results, report, fields, picture",
                         description=description, epilog=epilog, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(run)
    run.add_argument("--levels", type=integer, default=3,
                     help="meshes solved for the error bar: the requested one and coarser ones "
                          "(default 3, up to 8; 1 = no error bar; 2 is refused)")
    run.add_argument("--ratio", type=number, default=1.3, help="mesh-size ratio between those meshes (default 1.3)")
    run.add_argument("--tolerance", type=number, dest="tolerance_pct", metavar="PCT",
                     help="the accuracy asked: each wanted peak's error-bar band at most PCT %% of its value; the run "
                          "adds meshes (a smaller step, then finer ones) until it is, but never refines past a given "
                          "--mesh-factor (default 1; docs/design.md §5)")
    run.add_argument("--no-fields", action="store_true", help="skip ParaView files, picture and report (benchmarks)")
    run.add_argument("--no-sensitivity", action="store_true",
                     help="skip varying the assumed inputs (dj, rf, seat, the bearing load model) over their "
                          "plausible ranges; a run with --want skips it too")
    run.add_argument("--vary", type=vary, action="append", default=[], metavar="NAME=LOW:HIGH",
                     help="the range (mm) over which the sensitivity section varies NAME (dj rf seat_inner "
                          "seat_outer bearing_centre_mm bearing_length_mm), instead of its default; varies it "
                          "even when --dim or a --bearing option sets it; repeatable")
    run.add_argument("--document", type=document, action="append", default=[], metavar="FIELD=TEXT",
                     help="a field of the report's title block (part, number, revision, author, checker), as a "
                          "case file's [document] gives it; it overrides the case file's; repeatable")
    run.add_argument("--quarter-fields", action="store_true",
                     help="picture and both .vtu files of the quarter model only (default: mirrored to the whole part)")


def execute(args: argparse.Namespace, rank0: bool, stack: contextlib.ExitStack) -> int:
    """Check the request and the output folder before any work, run and write it, and say
    the answer (rank 0)."""
    from pipeline.api import RunContext, write_run
    from pipeline.cli.preflight import prepare
    from pipeline.cli.summary import run_summary
    case, options = request_of(args)
    out, say = prepare(args, case, options, rank0, stack)
    write_run(case, options, out, RunContext(say=say))
    if rank0 and not args.quiet:
        run_summary(out)
    return 0
