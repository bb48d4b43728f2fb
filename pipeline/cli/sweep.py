"""crosshead sweep: a design study over a grid of dimensions, loads or sizes, each variant a
run (pipeline.study), spread over the MPI ranks and resumable."""
from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from geometry.table import load_table
from pipeline.cli.options import CASE_KEYS, add_case_options, integer, number
from pipeline.cli.terminal import progress, quiet
from pipeline.cli.terminal import say as say_wrapped
from pipeline.errors import InputError, given_twice
from pipeline.inputs.case import given_keys
from pipeline.inputs.valuelist import MOST_DIM_VALUES, parse_loads, parse_values
from pipeline.runtime.folders import default_out
from pipeline.study.plan import Study, read_study

# A study's defaults when neither the command line nor the study file sets them (None in
# the parser, so that a study file's value is not overridden by a default).
SWEEP_DEFAULTS = {"levels": 3, "ratio": 1.3}
EPILOG = """\
examples:
  crosshead sweep --size 05 --dim rf=0.5:2:4                the fillet radius from 0.5 to 2 mm
  crosshead sweep --size 05 --dim rf=1,2 --dim dj=16,18,20   a grid of six variants
  crosshead sweep --study cases/sweep-rf.toml
  python -m pipeline.runtime.launch 2 sweep --size 05 --dim rf=1:2:3         variants spread over 2 ranks
A re-run with the same --out skips the variants already finished.
"""


def dimension_values(text: str) -> tuple[str, str]:
    """--dim NAME=VALUES for a sweep: VALUES is START:STOP:COUNT or v1,v2,..."""
    from pipeline.cli.options import DIMENSIONS
    k, sep, v = text.partition("=")
    if not sep or k not in DIMENSIONS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=START:STOP:COUNT or NAME=v1,v2 with NAME one of "
                                         f"{', '.join(DIMENSIONS)}")
    return k, v


def add_parser(sub, description: str, epilog: str) -> None:
    """The sweep command's options."""
    sweep = sub.add_parser("sweep", help="design study: a grid of dimensions and loads, each variant with its error bar",
                           description=description, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_case_options(sweep, dim_type=dimension_values, command="sweep")
    sweep.add_argument("--sizes", metavar="LIST", help="hook numbers to sweep over, e.g. 05,1,2.5, or 'all' rows of "
                       "geometry/sizes.csv (each at its own rated load unless --load is given)")
    sweep.add_argument("--study", type=Path, help="a study file (TOML with a [sweep] table), e.g. cases/sweep-rf.toml")
    sweep.add_argument("--levels", type=integer, help="meshes per variant for its error bar (default 3; 1 = none; 2 is refused)")
    sweep.add_argument("--ratio", type=number, help="mesh-size ratio between them (default 1.3)")
    sweep.add_argument("--screen", action="store_true",
                       help="decide each variant with the least work: one coarse mesh first, the full error bar only "
                            "where its band holds the allowable (--allowable, the case file's, or the run's default "
                            "80 MPa) or the variant borders a crossing; at mesh factor 1 or finer, where its bands were measured")
    sweep.add_argument("--sensitivity", action="store_true",
                       help="each variant also varies its assumed inputs (dj, rf, seat, bearing load model) over "
                            "their ranges, and the table says which verdicts depend on one (about doubles a variant's "
                            "time)")


def _sizes(args: argparse.Namespace, study: dict) -> list[str] | None:
    """The hook numbers of --sizes, checked (InputError), or None."""
    if not args.sizes:
        return None
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
    return sizes


def execute(args: argparse.Namespace, rank0: bool, stack: contextlib.ExitStack) -> int:
    """The sweep command: a grid from --dim/--load (or a study file), then pipeline.study.sweep."""
    from pipeline.study.sweep import execute_sweep
    from pipeline.study.table import passing_count
    study = read_study(args.study) if args.study else {}
    size = args.size or study.get("size")
    case_file = args.case or (Path(study["case"]) if "case" in study else None)
    sizes = _sizes(args, study)
    size = size or (sizes[0] if sizes else None)
    if size is None and case_file is None:
        raise InputError("size: give --size, --case or a study file with size = ...")
    twice = given_twice([k for k, _ in args.dim])
    if twice:
        raise InputError(f"dim: {', '.join(twice)} given twice; give each dimension's values in one --dim")
    dims = dict(study.get("dims", {}))
    dims.update(dict(args.dim))  # the command line overrides the study file
    axes = {f"dims.{k}": parse_values(str(v), f"dims.{k}", MOST_DIM_VALUES) for k, v in dims.items()}
    loads = args.loads or (parse_loads(str(study["load"])) if "load" in study else [])
    base = {k: getattr(args, k) for k in CASE_KEYS if getattr(args, k) is not None}
    if "mesh_factor" in study and "mesh_factor" not in base:
        base["mesh_factor"] = float(study["mesh_factor"])
    # The command line overrides the study file, which overrides the defaults; the study's
    # levels and ratio are checked with the variants' options (pipeline.study.plan.plan).
    levels = args.levels if args.levels is not None else int(study.get("levels", SWEEP_DEFAULTS["levels"]))
    ratio = args.ratio if args.ratio is not None else float(study.get("ratio", SWEEP_DEFAULTS["ratio"]))
    if not axes and len(loads) < 2 and not sizes:
        raise InputError("dim: a sweep needs at least one --dim NAME=VALUES, several loads or --sizes")
    out = args.out or (Path(study["out"]) if "out" in study else default_out(f"sweep-{size or Path(case_file).stem}"))
    screen = args.screen or bool(study.get("screen", False))
    say = quiet if args.quiet else progress
    if screen and args.sensitivity:
        raise InputError("sensitivity: a screened study decides most variants on one coarse mesh, without the "
                         "sensitivity section, so --sensitivity would vary only some of them; give --screen or "
                         "--sensitivity, not both")
    given = frozenset(given_keys(case_file, base) | ({"ratio"} if args.ratio is not None else set()))
    study = Study(size, case_file, base, axes, loads, levels, ratio, sizes, args.sensitivity, screen, args.memory_limit,
                  given)
    res = execute_sweep(study, out, say)
    if rank0 and res is not None and not args.quiet:
        c = res["counts"]
        # With several loads a row is a case (a variant at one load), and the counts are of cases.
        n = sum(c.values())
        cases = f"{n} cases ({n // len(loads)} variants at {len(loads)} loads): " if len(loads) > 1 else ""
        for note in res.get("notes") or []:
            say_wrapped(f"note: {note}")
        say_wrapped(f"sweep: {cases}{c['done']} done, {c['invalid']} invalid, {c['failed']} failed; "
                    f"{passing_count(res['rows'])} of {c['done']} pass {res['allowable_MPa']:g} MPa with every peak; "
                    f"{len(res['crossings'])} crossing(s) of the allowable; written to {out}/ (report.html, "
                    "report.md, sweep.csv, sweep.json)")
    return 0
