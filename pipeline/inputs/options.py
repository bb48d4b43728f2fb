"""How a run is asked to work, beside what it analyses (the Case): its meshes, whether it
meets a tolerance, varies the assumed inputs, which loads it reports and which files it
writes. One frozen object, built once from the command line (or a study file) and
checked here, for run, converge and a study's variants alike (mm, N, MPa)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from pipeline.errors import InputError
from pipeline.inputs.case import Case, check

MAX_LEVELS = 8
RATIO_RANGE = (1.1, 3.0)
TWO_LEVELS = ("levels: 2 meshes give no error bar (the estimate needs 3) and cost a solve; give 1 for no "
              "error bar, or 3 to 8")


@dataclass(frozen=True)
class Outputs:
    """The files a run writes besides results.json: ``fields`` the ParaView file, the
    pictures and the report; ``mesh`` mesh.msh; ``quarter_fields`` the quarter model's
    fields instead of the whole part's."""

    fields: bool = True
    mesh: bool = True
    quarter_fields: bool = False


@dataclass(frozen=True)
class RunOptions:
    """What a run does with its case.

    ``levels`` meshes for the error bar (the requested one and coarser ones by ``ratio``);
    ``finer`` of them below the case's own mesh (a convergence study's; negative: the
    finest that many steps above it, a screened study's steps on the error bar's coarser
    meshes, pipeline.study.screening); ``to_tolerance``:
    more meshes until each wanted peak's band is within the case's tolerance;
    ``sensitivity``: vary the assumed inputs (when both peaks are wanted);
    ``formula_loads``: solve the journal load at each hand formula's position too (the
    report's like-with-like sections); ``loads`` (N): the hook loads to report, solved at
    the case's and scaled (empty: the case's load alone); ``memory_limit_gb``: refuse a
    run estimated to need more (None: the memory free); ``convergence``: a convergence
    study's figures too (each mesh's error against the extrapolated value); ``outputs``:
    the files."""

    levels: int = 3
    ratio: float = 1.3
    finer: int = 0
    to_tolerance: bool = True
    sensitivity: bool = True
    formula_loads: bool = True
    loads: tuple[float, ...] = ()
    memory_limit_gb: float | None = None
    convergence: bool = False
    outputs: Outputs = field(default_factory=Outputs)

    def factors(self, case: Case) -> list[float]:
        """The mesh factors of the error bar, finest first."""
        finest = case.mesh_factor / self.ratio ** self.finer
        return [finest * self.ratio ** k for k in range(self.levels)]


def converge_options(levels: int, ratio: float, memory_limit_gb: float | None = None) -> RunOptions:
    """A convergence study's options: ``levels`` meshes, the case's own mesh the third
    finest, no tolerance loop, no sensitivity section."""
    return RunOptions(levels=levels, ratio=ratio, finer=max(levels - 3, 0), to_tolerance=False, sensitivity=False,
                      memory_limit_gb=memory_limit_gb, convergence=True)


def check_options(case: Case, options: RunOptions, command: str = "run",
                  given: frozenset[str] = frozenset()) -> RunOptions:
    """``options`` if the case can be run with them, else InputError naming the first rule
    broken: levels in 1..8 and not 2, ratio in [1.1, 3]; a convergence study needs at least
    4 meshes at a ratio >= 1.3 and one load; every mesh it would solve passes the case's
    mesh checks; and every input ``given`` (the case file's keys, "levels" and "ratio",
    from a file or an option) takes effect (:func:`check_given`). The one check of run,
    converge and a study's variants (``command``: "run", "converge", "sweep")."""
    check_given(case, options, command, given)
    o = options
    if not 1 <= o.levels <= MAX_LEVELS:
        raise InputError(f"levels: must lie in 1..{MAX_LEVELS}, got {o.levels}")
    if o.levels == 2:
        raise InputError(TWO_LEVELS)
    if command == "converge" and (o.levels < 4 or o.ratio < 1.3):
        raise InputError("levels/ratio: a convergence study needs at least 4 meshes and ratio >= 1.3")
    if command == "converge" and len(o.loads) > 1:
        raise InputError("load_N: a convergence study takes one load (a run or a sweep takes several)")
    if not RATIO_RANGE[0] <= o.ratio <= RATIO_RANGE[1]:
        raise InputError(f"ratio: must lie in [{RATIO_RANGE[0]:g}, {RATIO_RANGE[1]:g}], got {o.ratio:g}")
    factors = o.factors(case)
    if o.finer:
        _check_factor(case, factors[0], f"levels: the finest mesh of this study (mesh factor {case.mesh_factor:g} / "
                                        f"{o.ratio:g}^{o.finer} = {factors[0]:.3g}) is not allowed: ", "")
    if command != "converge":
        _check_factor(case, factors[-1], f"levels: the coarsest error-bar mesh (mesh factor {case.mesh_factor:g} x "
                                         f"{o.ratio:g}^{o.levels - 1} = {factors[-1]:.3g}) is not allowed: ",
                      "; use fewer levels or a smaller ratio")
    return o


def _check_factor(case: Case, factor: float, head: str, tail: str) -> None:
    """InputError (``head`` + the case's own line + ``tail``) unless the case passes its
    checks at mesh ``factor``."""
    try:
        check(replace(case, mesh_factor=factor))
    except InputError as exc:
        raise InputError(f"{head}{exc}{tail}") from None


def check_given(case: Case, options: RunOptions, command: str, given: frozenset[str]) -> None:
    """InputError naming the first input given (a case file's key, an option) that the run
    could not use, and why: an option accepted is an option used, and nothing is recorded
    that was not. A sensitivity range needs the sensitivity section (a run with both peaks,
    without --no-sensitivity; a study with --sensitivity; not converge); a tolerance needs
    the tolerance loop (a run with an error bar); a ratio needs a second mesh; the quarter
    model's field files need the fields and the quarter model."""
    vary = options.sensitivity and case.want == "both"
    ranges = sorted(k for k in given if k.startswith("sensitivity."))
    if ranges and not vary:
        why = ("a convergence study has no sensitivity section" if command == "converge" else
               "a study's variants vary their inputs only with --sensitivity" if command == "sweep"
               and not options.sensitivity else
               "--no-sensitivity skips the sensitivity section" if not options.sensitivity else
               f"want = {case.want} skips the sensitivity section (a run for one peak varies nothing)")
        raise InputError(f"{ranges[0]}: a sensitivity range (--vary, or the case file's [sensitivity]) takes "
                         f"effect in the sensitivity section only, and {why}")
    if command == "sweep" and options.sensitivity and case.want != "both":
        raise InputError(f"sensitivity: --sensitivity varies the assumed inputs of a case that wants both peaks; "
                         f"want = {case.want} varies nothing")
    if "tolerance_pct" in given and not (options.to_tolerance and options.levels >= 3):
        why = ("a convergence study solves its meshes without a tolerance" if command == "converge" else
               "a study's variants solve their meshes without a tolerance" if command == "sweep" else
               f"--levels {options.levels} gives no error bar to hold to it")
        raise InputError(f"tolerance_pct: the accuracy asked (--tolerance, or the case file's [mesh] tolerance_pct) "
                         f"cannot take effect: {why}")
    if "ratio" in given and options.levels == 1:
        raise InputError("ratio: --ratio sets the step between the error bar's meshes, and --levels 1 solves one "
                         "mesh; leave --ratio out")
    if options.outputs.quarter_fields and not options.outputs.fields:
        raise InputError("quarter_fields: --quarter-fields chooses the field files and the picture, which "
                         "--no-fields skips; give one of them")
    if options.outputs.quarter_fields and case.model != "quarter":
        raise InputError(f"quarter_fields: --quarter-fields keeps the quarter model's fields, and model = "
                         f"{case.model} has no quarter; leave it out")
