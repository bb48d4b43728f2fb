"""The options every command shares (what to analyse, mesh and solver) and the one place
that turns a command line into a checked case and its run options: the same rules and
messages as a case file's keys (pipeline.inputs.case), since the options become the case
file's keys before they are checked (mm, N, MPa)."""
from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from geometry.table import Dimensions
from pipeline.errors import InputError, given_option, given_twice
from pipeline.inputs.case import DOCUMENT_KEYS, SENSITIVITY_KEYS, Case, check, given_keys, resolve
from pipeline.inputs.choices import BEARING_AT, BEARING_SHAPES, MODELS, SOLVERS, SUPPORTS, WANTS
from pipeline.inputs.options import Outputs, RunOptions, check_options, converge_options
from pipeline.inputs.valuelist import as_integer, as_number, parse_loads

DIMENSIONS = list(Dimensions.__dataclass_fields__)
# The options that set a field of the case (the case file's keys of the same names).
CASE_KEYS = ("want", "support", "model", "E_MPa", "nu", "allowable_MPa", "approximate_span_mm",
             "exact_span_mm", "order", "mesh_factor", "size_body_mm", "size_feature_mm",
             "size_fillet_mm", "grading_mm", "solver", "rtol", "bearing_shape", "bearing_length_mm",
             "bearing_centre_mm", "bearing_at")
OUT_HELP = {"run": "output folder (default results/<case name>)",
            "converge": "output folder (default results/<case name>-converge)",
            "sweep": "output folder (default results/sweep-<size or case file name>, or the study file's out)"}


def number(text: str) -> float:
    """An option's number, as an engineer writes it (pipeline.inputs.valuelist.as_number: no
    "1_0"); its range is checked with the case (pipeline/inputs/case.py), so that a case
    file's value and the option's are refused alike."""
    try:
        return as_number(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def integer(text: str) -> int:
    """An option's whole number (--levels, --order): digits 0-9 with an optional sign."""
    return as_integer(text)  # ValueError: argparse says "invalid integer value"




def gib(text: str) -> float:
    """--memory-limit: a finite amount of memory > 0, GiB."""
    v = number(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"memory_limit: must be a finite number of GiB > 0, got {text!r}")
    return v


def loads(text: str) -> list[float]:
    """--load: one value, a comma list (5000,10000) or a range START:STOP:COUNT, in N
    (pipeline.inputs.valuelist, the grammar study files use too)."""
    try:
        return parse_loads(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def dimension(text: str) -> tuple[str, float]:
    """--dim NAME=MM."""
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=VALUE with NAME one of {', '.join(DIMENSIONS)}")
    k, v = text.split("=", 1)
    if k not in DIMENSIONS:
        raise argparse.ArgumentTypeError(f"unknown dimension {k!r}; known: {', '.join(DIMENSIONS)}")
    try:
        return k, number(v)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{k}: {exc}") from None


def vary(text: str) -> tuple[str, list[float]]:
    """--vary NAME=LOW:HIGH: a sensitivity range in mm (checked with the case: low < high)."""
    k, sep, v = text.partition("=")
    lo, sep2, hi = v.partition(":")
    if not sep or not sep2 or k not in SENSITIVITY_KEYS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=LOW:HIGH in mm with NAME one of "
                                         f"{', '.join(SENSITIVITY_KEYS)}")
    try:
        return k, [number(lo), number(hi)]
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"vary {k}: {exc}") from None


def document(text: str) -> tuple[str, str]:
    """--document FIELD=TEXT: a field of the report's title block (the case file's [document])."""
    k, sep, v = text.partition("=")
    if not sep or k not in DOCUMENT_KEYS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected FIELD=TEXT with FIELD one of {', '.join(DOCUMENT_KEYS)}")
    return k, v  # its text is checked with the case file's (pipeline.inputs.case.user_text): the same line


def add_case_options(p: argparse.ArgumentParser, dim_type=dimension, command: str = "run") -> None:
    """Options shared by every command: what to analyse and how finely."""
    g = p.add_argument_group("what to analyse")
    g.add_argument("--size", help="hook number from geometry/sizes.csv, e.g. 05, 1.6, 10")
    g.add_argument("--case", type=Path, help="case file (TOML), e.g. cases/05.toml")
    g.add_argument("--load", type=loads, dest="loads", metavar="N",
                   help="hook load Q in N (default: the size's rated load); a list 5000,10000 or a range "
                        "5000:20000:4 is solved once and scaled (linear elasticity)")
    g.add_argument("--dim", type=dim_type, action="append", default=[], metavar="NAME=MM",
                   help="override one dimension in mm (b1 b2 b6 d14 d2 h3 dj rf seat_inner seat_outer); repeatable")
    g.add_argument("--support", choices=SUPPORTS,
                   help="journal support: cosine bearing pressure (default) or rigid u_z = 0 (singular edges)")
    g.add_argument("--bearing-shape", choices=BEARING_SHAPES, dest="bearing_shape",
                   help="bearing pressure on each journal's lower half: p0·cos θ (default) or uniform "
                        "(uniform over the projected area); support bearing only")
    g.add_argument("--bearing-length", type=number, dest="bearing_length_mm", metavar="MM",
                   help="loaded length along each journal, mm: the side plate's thickness (default: the whole "
                        "journal from the fillet's end b1/2 + rf to the tip b6/2)")
    g.add_argument("--bearing-centre", type=number, dest="bearing_centre_mm", metavar="MM",
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
    g.add_argument("--E", type=number, dest="E_MPa", metavar="MPA", help="Young's modulus, MPa (default 210000)")
    g.add_argument("--nu", type=number, metavar="NU", help="Poisson's ratio (default 0.3)")
    g.add_argument("--allowable", type=number, dest="allowable_MPa", metavar="MPA",
                   help="allowable stress for the safety factor, MPa (default 80)")
    g.add_argument("--span-approximate", type=number, dest="approximate_span_mm", metavar="MM",
                   help="span l of the approximate formula, mm (default b1 + b2, as the paper)")
    g.add_argument("--span-exact", type=number, dest="exact_span_mm", metavar="MM",
                   help="span l of the exact formula, mm (default b6, as the paper)")
    m = p.add_argument_group("mesh and solver")
    m.add_argument("--order", type=integer, help="element order of the displacement: 1, 2 (default) or 3")
    m.add_argument("--mesh-factor", type=number, dest="mesh_factor", metavar="F",
                   help="multiply every mesh size by F (<1 finer, >1 coarser; default 1)")
    m.add_argument("--size-body", type=number, dest="size_body_mm", metavar="MM", help="element size away from features, mm")
    m.add_argument("--size-feature", type=number, dest="size_feature_mm", metavar="MM",
                   help="element size at bore and seat edges, mm")
    m.add_argument("--size-fillet", type=number, dest="size_fillet_mm", metavar="MM",
                   help="element size on the shoulder fillets, mm")
    m.add_argument("--grading", type=number, dest="grading_mm", metavar="MM", help="distance over which sizes grow, mm")
    m.add_argument("--solver", choices=SOLVERS,
                   help="CG + p-multigrid over P1 with GAMG (default), CG + GAMG, CG + BoomerAMG, or direct MUMPS")
    m.add_argument("--rtol", type=number, help="relative tolerance of the iterative solver on the true residual (default 1e-8)")
    m.add_argument("--memory-limit", type=gib, dest="memory_limit", metavar="GB",
                   help="refuse a run estimated to need more memory than this, GiB (default: what the machine has free)")
    p.add_argument("--out", type=Path, help=OUT_HELP[command])
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def named_once(what: str, pairs: list[tuple[str, object]]) -> dict[str, object]:
    """The NAME=VALUE pairs of a repeatable option (--dim, --vary, --document) as a dict;
    InputError when a name is given twice: the last would win silently."""
    twice = given_twice(k for k, _ in pairs)
    if twice:
        raise InputError(f"{what}: {', '.join(twice)} given twice; give each once")
    return dict(pairs)


def overrides_of(args: argparse.Namespace) -> dict:
    """The case file's keys the options set (None where an option was not given)."""
    out = {k: getattr(args, k, None) for k in CASE_KEYS}
    out.update({f"dims.{k}": v for k, v in named_once("dim", args.dim).items()})
    out.update({f"sensitivity.{k}": v for k, v in named_once("vary", getattr(args, "vary", [])).items()})
    out.update({f"document.{k}": v for k, v in named_once("document", getattr(args, "document", [])).items()})
    out["tolerance_pct"] = getattr(args, "tolerance_pct", None)
    return out


def request_of(args: argparse.Namespace) -> tuple[Case, RunOptions]:
    """The checked case and run options of a run or converge command line: --size or --case
    with the options' overrides; every load of a --load list passes the same checks as
    the first. Raises InputError naming the first rule broken."""
    over = overrides_of(args)
    loads_N = args.loads or []
    if loads_N:
        over["load_N"] = loads_N[0]
    if args.size is None and args.case is None:
        raise InputError("size: give --size (hook number) or --case (case file)")
    case = resolve(args.size, args.case, over)
    for q in loads_N[1:]:  # every load of a sweep must pass the same checks as the first
        check(replace(case, load_N=q))
    more = tuple(loads_N) if len(loads_N) > 1 else ()
    if args.command == "converge":
        options = replace(converge_options(args.levels, args.ratio, args.memory_limit), loads=more)
    else:
        options = RunOptions(levels=args.levels, ratio=args.ratio, sensitivity=not args.no_sensitivity, loads=more,
                             memory_limit_gb=args.memory_limit,
                             outputs=Outputs(fields=not args.no_fields, quarter_fields=args.quarter_fields))
    given = given_keys(args.case, over) | {k for k in ("levels", "ratio") if given_option(args, k)}
    return case, check_options(case, options, args.command, given)
