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


def check_options(case: Case, options: RunOptions, command: str = "run") -> RunOptions:
    """``options`` if the case can be run with them, else InputError naming the first rule
    broken: levels in 1..8 and not 2, ratio in [1.1, 3]; a convergence study needs at least
    4 meshes at a ratio >= 1.3 and one load; every mesh it would solve passes the case's
    mesh checks; a sensitivity range needs the sensitivity section and both peaks."""
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
