"""What a command that analyses does before its work, on every rank: the form cache's
claims that interrupted compiles left are removed, a run that cannot fit in memory is
refused, the output folder is checked, and the first progress lines say what is run."""
from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

from geometry.table import is_scaled_row
from pipeline.analysis.memory import check_fits
from pipeline.analysis.words import coarse_mesh_note
from pipeline.cache.forms import claims_since, jit_cache_dir, remove_interrupted
from pipeline.cli.terminal import T_START, progress, quiet
from pipeline.inputs.case import Case
from pipeline.inputs.options import RunOptions
from pipeline.runtime.interrupts import on_stop
from pipeline.runtime.folders import default_out
from pipeline.runtime.outdir import check_out


def prepare(args: argparse.Namespace, case: Case, options: RunOptions, rank0: bool,
            stack: contextlib.ExitStack) -> tuple[Path, "callable"]:
    """The output folder (checked, refused before any work) and the progress sink of a run
    or converge command; clean-ups that last the command go on ``stack``."""
    if rank0:  # before any form is compiled; the other ranks wait for rank 0's compiles
        guard_form_cache(stack)
    est = check_fits(case, options.factors(case), options.memory_limit_gb, drawing=options.outputs.fields)
    say = quiet if (args.quiet or not rank0) else progress
    if est is not None and est.tets > 3e5:
        say(f"a large run: the finest mesh has about {est.tets:.1e} tets, {est.dofs:.1e} DOFs, "
            f"{est.bytes / 1024 ** 3:.1f} GiB; meshing alone may take minutes")
    out = args.out if args.out is not None else default_out(
        case.name if args.command == "run" else f"{case.name}-converge")
    check_out(out)  # refused before any work; checked again under the lock
    announce(case, say)
    return out, say


def guard_form_cache(stack: contextlib.ExitStack) -> None:
    """Rank 0, before any form is compiled: remove the form-cache claims that interrupted
    compiles left, and have this command remove its own if it is stopped (on ``stack``)."""
    cache, started = jit_cache_dir(), time.time()
    # A compile cut short by Ctrl-C leaves its claim, and every later run needing
    # that form would wait for it and time out: a stopped run removes its own.
    stack.enter_context(on_stop(lambda: [c.unlink(missing_ok=True) for c in claims_since(cache, started)]))
    for stale in remove_interrupted(cache):
        progress(f"removed {stale.name} from the form cache (an interrupted compile)")


def announce(case: Case, say) -> None:
    """The first progress lines: which refinement --want skips, then the import time (s)
    and the case (hook number, load in N, model, support, element order), and the note on
    a mesh too coarse for the fillet."""
    if case.want != "both":
        other = "global (fillet)" if case.want == "critical" else "critical (bore ligament)"
        say(f"want = {case.want}: skipping the refinement for the {other} peak"
            + (" (fillet elements at the bore edges' size; the bore edges refined where the dimensions put them, "
               "no pilot solve)"
               if case.want == "critical" else " (the pilot refines the fillet only)")
            + "; that peak is shown without a verdict")
    say(f"imports {time.perf_counter() - T_START:.2f} s; case {case.name}: hook No. {case.size}, "
        f"Q = {case.load_N:g} N, {case.model} model, {case.support} support, P{case.order}"
        + (" (a scaled row: NOT DIN 15412 dimensions)" if is_scaled_row(case.source) else ""))
    note = coarse_mesh_note(case)
    if note:
        say(f"note: {note}")
