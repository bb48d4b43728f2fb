"""crosshead converge: a mesh convergence study of one case (at least four meshes, the
case's own among them), its extrapolation, GCI and plot."""
from __future__ import annotations

import argparse
import contextlib

from pipeline.cli.options import add_case_options, integer, number, request_of


def add_parser(sub, description: str, epilog: str) -> None:
    """The converge command's options."""
    conv = sub.add_parser("converge", help="mesh convergence study: >= 4 meshes, extrapolation, GCI, plot",
                          description=description, epilog=epilog, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(conv, command="converge")
    conv.add_argument("--levels", type=integer, default=5,
                      help="number of meshes (default 5, at least 4); the finest is the case's mesh / ratio^(levels-3)")
    conv.add_argument("--ratio", type=number, default=1.3, help="mesh-size ratio between meshes, >= 1.3 (default 1.3)")


def execute(args: argparse.Namespace, rank0: bool, stack: contextlib.ExitStack) -> int:
    """Check the request and the output folder before any work, run the study and write it,
    and say the answer (rank 0)."""
    from pipeline.api import RunContext, write_run
    from pipeline.cli.preflight import prepare
    from pipeline.cli.summary import run_summary
    case, options = request_of(args)
    out, say = prepare(args, case, options, rank0, stack)
    write_run(case, options, out, RunContext(say=say))
    if rank0 and not args.quiet:
        run_summary(out)
    return 0
