"""One mesh level of an analysis: mesh -> loads -> solve -> peaks (mm, N, MPa)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

from dolfinx import fem

from pipeline.analysis.context import Progress, RunContext, quiet
from pipeline.errors import NumericalError
from pipeline.fe.elasticity import Material
from pipeline.fe.loads import LoadCase, crosshead_loads, equilibrium
from pipeline.fe.meshing import ImportedMesh, make_mesh
from pipeline.fe.solve import Loads, Method, Solution, failure_advice, solve
from pipeline.inputs.case import BearingBand, Case, formula_bands, small_features
from pipeline.post import formulas as formulas_module
from pipeline.post.features import critical_region, fillet_region
from pipeline.post.peaks import NodalPeak, NodeReadings, node_peak, node_readings
from pipeline.post.sections import FormulaLoad, formula_load_sections, section_results

Hotspots = Sequence[tuple[float, float, float]]


@dataclass
class Level:
    """The result of one mesh: peaks (MPa, mm), sizes, solver data, times (s)."""

    factor: float
    dofs: int
    cells: int
    peak: NodalPeak
    critical: NodalPeak
    iterations: int
    residual_rel: float
    seat_force_N: float
    support_force_N: float
    equilibrium_error_N: float
    constraint_reaction_N: float
    jacobian_ratio: float
    timings: dict[str, float]
    scaled_from: dict | None = None  # see solve.Solution.scaled_from
    fields: tuple | None = None  # (u, von_mises) on the requested mesh only
    readings: NodeReadings | None = None  # von Mises at the nodes, both ways and reported: with fields
    sections: dict | None = None  # section results (pipeline/post/sections.py), requested mesh only
    msh: bytes | None = None  # the gmsh file of the requested mesh, on rank 0, when asked
    # solve_level's load_variants on this mesh, in order: (global peak, critical peak, sections)
    load_variants: list[tuple[NodalPeak, NodalPeak, dict | None]] = field(default_factory=list)


def peaks_of(case: Case, u: fem.Function, mat: Material) -> tuple[NodeReadings, NodalPeak, NodalPeak]:
    """Von Mises (MPa) of displacement u (mm) read at the nodes by the case's reading rule,
    and the case's global and critical peaks, read as :func:`read_peaks` does: the one way
    every solver's result is read."""
    readings = node_readings(u, mat, fillet_region(case))
    return (readings, *read_peaks(case, readings))


def read_peaks(case: Case, readings: NodeReadings) -> tuple[NodalPeak, NodalPeak]:
    """The global and the critical peak (MPa): the nodes of the largest reported value over
    the part and over the critical region. ``readings`` carry the reading rule at each node
    (pipeline.post.peaks.node_readings with the case's fillet region): on the shoulder
    fillet the midpoint of the node's unaveraged and averaged readings, everywhere else its
    unaveraged one. Measured against independent references (docs/accuracy.md): at the
    fillet the unaveraged value lies above the reference and the averaged one below; at the
    bore edge both lie within 0.2 % and the averaged one's slower convergence would put a
    false trend into the error bar. Node by node, so that the field file's reported array
    holds each reported value at its place
    (docs/decisions/0035-reported-value-node-by-node.md)."""
    return node_peak(readings), node_peak(readings, critical_region(case))


@dataclass(frozen=True)
class LevelTask:
    """What one mesh is asked (mm): its factor and refined places; whether its fields
    (displacement, von Mises) and its gmsh file are kept (the requested mesh's); whether its
    sections are read; the further right-hand sides on its operator (the journal load at
    each hand formula's position; cases that differ from the run's only in the journal load
    model); whether an earlier run's solution may be scaled instead of solving."""

    factor: float
    hotspots: Hotspots = ()
    keep_fields: bool = False
    keep_msh: bool = False
    sections: bool = False
    formula_loads: bool = False
    load_variants: tuple[Case, ...] = ()
    reuse: bool = True

    def spec(self, case: Case):
        """The MeshSpec of this mesh of the case."""
        return case.mesh_spec(self.factor, self.hotspots)


@dataclass
class Problem:
    """One mesh of a case with its material and loads: what any solver of the case needs
    (mm, N, MPa). ``loads_s``: the time spent turning the load into tractions (s)."""

    mesh: ImportedMesh
    material: Material
    loads: LoadCase
    loads_s: float


def set_up(case: Case, task: LevelTask, ctx: RunContext = RunContext(),
           load_mesh: Callable[[], ImportedMesh] | None = None) -> Problem:
    """The case's mesh for ``task`` (made with ctx's mesher, or ``load_mesh()`` if given), its
    material and its load case: the first half of every solve, the pipeline's and the
    CalculiX peer's. Raises NumericalError if the mesh has an inverted element."""
    if load_mesh is None:
        m = make_mesh(case.dims, case.model, task.spec(case), comm=ctx.comm, keep_msh=task.keep_msh,
                      mesher=ctx.mesher)
    else:
        m = load_mesh()
    if not m.jacobian_ratio > 0:
        raise NumericalError(f"mesh: a curved element is inverted (worst det J ratio {m.jacobian_ratio:.3g}) "
                             f"at mesh factor {task.factor:.3g}; try a slightly different --mesh-factor")
    t0 = time.perf_counter()
    lc = crosshead_loads(m, case.dims, case.load_N, case.support, shape=case.bearing_shape,
                         band=case.bearing_band(), order=case.order)
    return Problem(m, Material(E=case.E_MPa, nu=case.nu), lc, time.perf_counter() - t0)


def formula_load_cases(case: Case, prob: Problem) -> dict[str, tuple[BearingBand, float, LoadCase | None]]:
    """Per hand formula (support "bearing" only): the bearing band at its own load position
    (pipeline.inputs.case.formula_bands), that position (mm), and the load case with the
    band on the problem's mesh, or None when the band is the case's own (its solve serves)."""
    if case.support != "bearing":
        return {}
    out = {}
    own = case.bearing_band()
    for which, (band, position) in formula_bands(case).items():
        same = band == own or (band.whole and own.whole)
        lc = None if same else crosshead_loads(prob.mesh, case.dims, case.load_N, case.support,
                                               shape=case.bearing_shape, band=band, order=case.order)
        out[which] = (band, position, lc)
    return out


# A further right-hand side on a problem's operator: its journal load model (shape and band,
# mm: the cache key's) and its load case on the problem's mesh.
MoreLoad = tuple[dict, LoadCase]
# The further right-hand sides' relative tolerance (a hand formula's load position, a load
# model's variant): what they give are section integrals and the sensitivity section's
# ratios, which move by a few 1e-4 MPa from 1e-8's, in two thirds of the iterations
# (docs/decisions/0036-sensitivity-variants-by-morphing.md).
MORE_RTOL = 1e-5


def more_rtol(case: Case) -> float:
    """The tolerance of the case's further right-hand sides: MORE_RTOL, or the case's own
    when that is looser."""
    return max(case.rtol, MORE_RTOL)


def journal_load(shape: str, band: BearingBand) -> dict:
    """A journal load model as a cache key holds it (solutions.key's ``load_model``)."""
    return {"bearing_shape": shape, "band_mm": [band.start_mm, band.end_mm]}


@dataclass
class MoreLoads:
    """The further right-hand sides a task solves on its problem's operator: per hand
    formula its band, position and load case (None: the case's own load serves;
    :func:`formula_load_cases`), and every further load case in the order they are solved
    (the formula bands' that differ from the case's, then the load-model variants')."""

    formulas: dict[str, tuple[BearingBand, float, LoadCase | None]]
    loads: list[MoreLoad]

    @property
    def formula_count(self) -> int:
        return sum(lc is not None for _, _, lc in self.formulas.values())


def more_loads(case: Case, task: LevelTask, prob: Problem) -> MoreLoads:
    """The task's further right-hand sides on ``prob`` (the formula positions only when its
    sections are read)."""
    formulas = formula_load_cases(case, prob) if task.sections and task.formula_loads else {}
    extra = [(journal_load(case.bearing_shape, band), lc) for band, _, lc in formulas.values() if lc is not None]
    m = prob.mesh
    mine = [(journal_load(v.bearing_shape, v.bearing_band()),
             crosshead_loads(m, v.dims, v.load_N, v.support, shape=v.bearing_shape, band=v.bearing_band(),
                             order=v.order)) for v in task.load_variants]
    return MoreLoads(formulas, extra + mine)


def new_solution(case: Case, prob: Problem, more: Sequence[LoadCase] = (), V=None) -> Solution:
    """A new solve of the case's load on the problem's operator, and of ``more`` (the
    result's ``more``, in order); ``V`` the displacement space, if made already."""
    m = prob.mesh
    try:
        loads = Loads(prob.loads.tractions, prob.loads.constraints, [lc_k.tractions for lc_k in more])
        method = Method(case.order, case.solver, case.rtol, more_rtol=more_rtol(case))
        return solve(m.mesh, m.facet_tags, prob.material, loads, method, V)
    except NumericalError as exc:  # the one line says what to try, from what this case makes hard
        raise NumericalError(f"{exc}; {failure_advice(case.solver, case.nu, small_features(case.dims))}") from None


def formula_load_table(case: Case, formulas: dict, sol: Solution, mat: Material, sym_idx: int | None
                       ) -> dict[str, dict]:
    """The like-with-like rows (pipeline.post.sections.formula_load_sections): per formula,
    the FE sections of the solve with the journal load at its position, ``sol`` itself
    or one of its ``more`` in the order of ``formulas``' load cases."""
    hand = formulas_module.hand_results(case.dims, case.load_N, case.approximate_span_mm, case.exact_span_mm)
    others = iter(sol.more)
    rows = {}
    for which, (band, position, lc_k) in formulas.items():
        sol_k = sol if lc_k is None else next(others)
        formula = (hand.approximate if which == "approximate" else hand.exact).sigma_MPa
        at_fe = formulas_module.sigma_at_span(case.dims, case.load_N, which, 2 * band.centre_mm)
        rows[which] = formula_load_sections(sol_k, mat, case, sym_idx,
                                            FormulaLoad(which, formula, at_fe, (band.start_mm, band.end_mm), position))
    return rows


def read_level(case: Case, task: LevelTask, prob: Problem, sol: Solution, more: MoreLoads,
               say: Progress = quiet) -> Level:
    """The level of a solved mesh: every load case's balance checked, both peaks read, the
    sections (and the formula positions' and variants') when the task asks. ``sol.more``
    holds the further solutions in ``more.loads``' order. Raises NumericalError if the loads
    do not balance to 1e-6·Q."""
    m, mat, lc = prob.mesh, prob.material, prob.loads
    n_formula = more.formula_count
    formula_sols, variant_sols = sol.more[:n_formula], sol.more[n_formula:]
    sol.more = formula_sols   # formula_load_table takes them in order
    limit = 1e-6 * case.load_N
    for lc_k, sol_k in zip([lc, *(x for _, x in more.loads)], [sol, *formula_sols, *variant_sols]):
        support_k, eq_err, point_r = equilibrium(lc_k, sol_k.reactions)
        if not (eq_err <= limit and point_r <= limit):
            raise NumericalError(f"loads out of balance: equilibrium error {eq_err:.3g} N, "
                                 f"constraint reaction {point_r:.3g} N (limit {limit:.3g} N)")
    support, eq_err, point_r = equilibrium(lc, sol.reactions)
    t0 = time.perf_counter()
    readings, pk, crit = peaks_of(case, sol.u, mat)
    sections = None
    sym_x = m.facet_ids.get("symmetry_x")
    sym_idx = next((i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == sym_x
                    and sym_x is not None), None)
    if task.sections:
        sections = section_results(sol, mat, case, sym_idx, pk.value_MPa)
        if more.formulas:
            sections["formula_load"] = formula_load_table(case, more.formulas, sol, mat, sym_idx)
            for row in sections["formula_load"].values():
                row["mesh_factor"] = task.factor  # the mesh it was solved on (not always the requested)
    load_readings = []
    for v, sol_k in zip(task.load_variants, variant_sols):
        _, v_pk, v_crit = peaks_of(v, sol_k.u, mat)
        load_readings.append((v_pk, v_crit, section_results(sol_k, mat, v, sym_idx, v_pk.value_MPa)
                              if task.sections else None))
    t_post = time.perf_counter() - t0
    timings = dict(m.timings, **sol.timings, post=t_post)
    how = (f"{sol.iterations} iterations ({case.solver}), assemble {sol.timings['assemble']:.2f} s, "
           f"solve {sol.timings['solve']:.2f} s" if sol.scaled_from is None else
           f"the solve at Q = {sol.scaled_from['load_N']:g} N, E = {sol.scaled_from['E_MPa']:g} MPa scaled "
           f"({sol.timings['solve']:.2f} s)")
    say(f"solve ×{task.factor:.3g}: {sol.dofs} DOFs, {how}; "
        f"peak {pk.value_MPa:.2f} MPa, critical {crit.value_MPa:.2f} MPa")
    return Level(factor=task.factor, dofs=sol.dofs, cells=m.mesh.topology.index_map(3).size_global,
                 peak=pk, critical=crit, iterations=sol.iterations,
                 residual_rel=sol.residual_rel, seat_force_N=lc.seat_force_z_N,
                 support_force_N=support, equilibrium_error_N=eq_err,
                 constraint_reaction_N=point_r, jacobian_ratio=m.jacobian_ratio,
                 timings=timings, scaled_from=sol.scaled_from,
                 fields=(sol.u, readings.vm) if task.keep_fields else None,
                 readings=readings if task.keep_fields else None,
                 msh=m.msh, sections=sections, load_variants=load_readings)


def say_mesh(prob: Problem, factor: float, say: Progress) -> None:
    """The progress line of a mesh made or loaded: its tets and the stages' times (s)."""
    m = prob.mesh
    say(f"mesh ×{factor:.3g}: {m.mesh.topology.index_map(3).size_global} tets, "
        f"geometry {m.timings['geometry']:.2f} s, mesh {m.timings['mesh']:.2f} s, "
        f"import {m.timings['import']:.2f} s")


def solve_level(case: Case, task: LevelTask, ctx: RunContext = RunContext(),
                load_mesh: Callable[[], ImportedMesh] | None = None, problem: Problem | None = None) -> Level:
    """One mesh of the case, made (or ``load_mesh()``, or ``problem`` set up already: another
    solver gets the same ones), solved anew and read: its peaks, and what ``task`` asks.
    No earlier run's solution is used (pipeline.analysis.reuse.level does that). Raises
    NumericalError if the mesh has an inverted element, the solver fails, the result is not
    finite, or the loads do not balance to 1e-6·Q."""
    prob = problem or set_up(case, task, ctx, load_mesh)
    say_mesh(prob, task.factor, ctx.say)
    more = more_loads(case, task, prob)
    sol = new_solution(case, prob, [lc for _, lc in more.loads])
    return read_level(case, task, prob, sol, more, ctx.say)
