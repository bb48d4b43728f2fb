"""One mesh level of an analysis: mesh -> loads -> solve -> peaks (mm, N, MPa)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from pipeline.inputs.case import BearingBand, Case, formula_bands, small_features
from pipeline.fe.elasticity import Material
from pipeline.errors import NumericalError
from pipeline.post.features import critical_region, fillet_region
from pipeline.fe.loads import LoadCase, crosshead_loads, equilibrium
from pipeline.fe.meshing import ImportedMesh, Mesher, make_mesh
from pipeline.post.peaks import MIDPOINT, UNAVERAGED, NodalPeak, averaged_von_mises, largest, nodal_peak, von_mises
from pipeline.post import formulas
from pipeline.post.sections import formula_load_sections, section_results
from pipeline.cache import runs as runcache
from pipeline.cache import solutions as solvecache
from pipeline.fe.solve import Solution, failure_advice, solve

Progress = Callable[[str], None]
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
    sections: dict | None = None  # section results (pipeline/post/sections.py), requested mesh only
    # solve_level's load_variants on this mesh, in order: (global peak, critical peak, sections)
    load_variants: list[tuple[NodalPeak, NodalPeak, dict | None]] = field(default_factory=list)


def peaks_of(case: Case, u: fem.Function, mat: Material) -> tuple[fem.Function, NodalPeak, NodalPeak]:
    """Von Mises (MPa, DG) of displacement u (mm) and the case's global and critical peaks,
    read as :func:`read_peaks` does: the one way every solver's result is read."""
    vm = von_mises(u, mat)
    return (vm, *read_peaks(case, vm, averaged_von_mises(u, mat)))


def read_peaks(case: Case, vm: fem.Function, averaged: tuple[np.ndarray, np.ndarray]
               ) -> tuple[NodalPeak, NodalPeak]:
    """The global and the critical peak (MPa), each feature read by its rule: the shoulder
    fillet by the midpoint of its unaveraged and averaged readings, everything else by the
    unaveraged one. Measured against independent references (docs/accuracy.md): at the
    fillet the unaveraged value lies above the reference and the averaged one below; at the
    bore edge both lie within 0.2 % and the averaged one's slower convergence would put a
    false trend into the error bar. The global peak is the largest over the features."""
    fillet = fillet_region(case)
    if fillet is None:
        pk = nodal_peak(vm, averaged, UNAVERAGED)
    else:
        pk = largest(nodal_peak(vm, averaged, MIDPOINT, fillet),
                     nodal_peak(vm, averaged, UNAVERAGED, lambda xyz: ~fillet(xyz)))
    return pk, nodal_peak(vm, averaged, UNAVERAGED, critical_region(case))


@dataclass
class Problem:
    """One mesh of a case with its material and loads: what any solver of the case needs
    (mm, N, MPa). ``loads_s``: the time spent turning the load into tractions (s)."""

    mesh: ImportedMesh
    material: Material
    loads: LoadCase
    loads_s: float


def set_up(case: Case, factor: float, msh_path: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
           hotspots: Hotspots = (), load_mesh: Callable[[], ImportedMesh] | None = None,
           mesher: Mesher | None = None) -> Problem:
    """The case's mesh at ``factor`` (made, or ``load_mesh()`` if given), its material and its
    load case: the first half of every solve, the pipeline's and the CalculiX peer's.
    Raises NumericalError if the mesh has an inverted element."""
    if load_mesh is None:
        m = make_mesh(case.dims, case.model, case.mesh_spec(factor, hotspots), comm=comm, msh_path=msh_path,
                      mesher=mesher)
    else:
        m = load_mesh()
    if not m.jacobian_ratio > 0:
        raise NumericalError(f"mesh: a curved element is inverted (worst det J ratio {m.jacobian_ratio:.3g}) "
                             f"at mesh factor {factor:.3g}; try a slightly different --mesh-factor")
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


def journal_load(shape: str, band: BearingBand) -> dict:
    """A journal load model as a cache key holds it (solutions.key's ``load_model``)."""
    return {"bearing_shape": shape, "band_mm": [band.start_mm, band.end_mm]}


def solve_or_scale(case: Case, prob: Problem, reuse: bool = True, more: Sequence[MoreLoad] = ()) -> Solution:
    """The displacement of the problem: with ``reuse`` and the run cache on, an earlier
    solve of the same mesh and problem at another load or E, scaled
    (pipeline/cache/solutions.py: exact in linear elasticity), or else a new solve, which is
    then kept for the next run; without them, a new solve. ``more``: further load cases
    under the same constraints (a load model's variants), the result's ``more`` in order:
    each scaled from an earlier solve of its own load model on this mesh or, with the ones
    not found, solved on the same operator, and kept alike."""
    m, lc = prob.mesh, prob.loads
    V = fem.VectorFunctionSpace(m.mesh, ("Lagrange", case.order)) if reuse and runcache.enabled() else None
    ids = None if V is None else solvecache.node_ids(V, m)
    keep = m.mesh.comm.allreduce(ids is not None, op=MPI.LAND)
    t0 = time.perf_counter()
    if not keep:
        return _solve(case, prob, V, lc, [lc_k for _, lc_k in more])

    def earlier(name: str, lc_k: LoadCase) -> Solution | None:
        entry = solvecache.earlier(name, m.mesh.comm)
        return None if entry is None else solvecache.scaled(entry, m, V, ids, lc_k, case, prob.material, name)

    names = [solvecache.key(case, m, V)] + [solvecache.key(case, m, V, model) for model, _ in more]
    loads = [lc] + [lc_k for _, lc_k in more]
    found = [earlier(n, lc_k) for n, lc_k in zip(names, loads)]
    t_key = time.perf_counter() - t0
    missing = [k for k, s in enumerate(found) if s is None]
    timings = {"assemble": 0.0, "solve": 0.0}
    if missing:
        new = _solve(case, prob, V, loads[missing[0]], [loads[k] for k in missing[1:]])
        timings = dict(new.timings)
        t0 = time.perf_counter()
        for k, s in zip(missing, [new, *new.more]):
            s.more = []
            solvecache.store(names[k], s, ids, case)
            found[k] = s
        timings["solve"] += time.perf_counter() - t0
    sol = found[0]
    sol.more = found[1:]
    timings["solve"] += t_key
    sol.timings = timings
    return sol


def _solve(case: Case, prob: Problem, V, first: LoadCase, more: Sequence[LoadCase]) -> Solution:
    """A new solve of the load case ``first`` on the problem's operator, and of ``more``
    (the result's ``more``)."""
    m = prob.mesh
    try:
        return solve(m.mesh, m.facet_tags, case.order, prob.material, first.tractions, first.constraints,
                     solver=case.solver, rtol=case.rtol, V=V, more=[lc_k.tractions for lc_k in more])
    except NumericalError as exc:  # the one line says what to try, from what this case makes hard
        raise NumericalError(f"{exc}; {failure_advice(case.solver, case.nu, small_features(case.dims))}") from None


def formula_load_table(case: Case, variants: dict, sol: Solution, mat: Material, share: float,
                       sym_idx: int | None) -> dict[str, dict]:
    """The like-with-like rows (pipeline.post.sections.formula_load_sections): per formula,
    the FE sections of the solve with the journal load at its position, ``sol`` itself
    or one of its ``more`` in the order of ``variants``' load cases."""
    hand = formulas.hand_results(case.dims, case.load_N, case.approximate_span_mm, case.exact_span_mm)
    others = iter(sol.more)
    rows = {}
    for which, (band, position, lc_k) in variants.items():
        sol_k = sol if lc_k is None else next(others)
        formula = (hand.approximate if which == "approximate" else hand.exact).sigma_MPa
        at_fe = formulas.sigma_at_span(case.dims, case.load_N, which, 2 * band.centre_mm)
        rows[which] = formula_load_sections(sol_k, mat, case.dims, share, sym_idx, formula, at_fe, which,
                                            (band.start_mm, band.end_mm), position)
    return rows


def solve_level(case: Case, factor: float, msh_path: Path | None = None,
                keep_fields: bool = False, with_sections: bool = False, comm: MPI.Comm = MPI.COMM_WORLD,
                progress: Progress | None = None, hotspots: Hotspots = (),
                load_mesh: Callable[[], ImportedMesh] | None = None,
                mesher: Mesher | None = None, problem: Problem | None = None, reuse: bool = True,
                load_variants: Sequence[Case] = (), formula_loads: bool = True) -> Level:
    """Build, mesh and solve the case with every mesh size times ``factor``; find the peaks.

    ``load_mesh``: that mesh made already (see :func:`analyse`); factor, msh_path and
    hotspots are then only the mesh's description. ``problem``: mesh, material and loads
    set up already (:func:`set_up`), when another solver gets the same ones. ``mesher``: this process's
    meshing.Mesher of the case's part, if it has one. ``reuse``: take an earlier solve of
    this mesh scaled to the case's load and E, and keep this one (:func:`solve_or_scale`).
    ``load_variants``: cases that differ from ``case`` only in the journal load model, solved
    on the same operator and preconditioner (a new right-hand side each); their peaks and
    sections are the level's ``load_variants``. ``formula_loads``: with the sections, also
    the journal load at each hand formula's position (sections' ``formula_load``). Raises
    NumericalError if the mesh has
    an inverted element, the solver fails, the result is not finite, or the loads do not
    balance to 1e-6·Q.
    """
    say = progress or (lambda s: None)
    prob = problem or set_up(case, factor, msh_path=msh_path, comm=comm, hotspots=hotspots, load_mesh=load_mesh,
                             mesher=mesher)
    m, mat, lc = prob.mesh, prob.material, prob.loads
    say(f"mesh ×{factor:.3g}: {m.mesh.topology.index_map(3).size_global} tets, "
        f"geometry {m.timings['geometry']:.2f} s, mesh {m.timings['mesh']:.2f} s, "
        f"import {m.timings['import']:.2f} s")
    variants = formula_load_cases(case, prob) if with_sections and formula_loads else {}
    extra = [(journal_load(case.bearing_shape, band), lc_k) for band, _, lc_k in variants.values() if lc_k is not None]
    mine = [(journal_load(v.bearing_shape, v.bearing_band()),
             crosshead_loads(m, v.dims, v.load_N, v.support, shape=v.bearing_shape, band=v.bearing_band(),
                             order=v.order)) for v in load_variants]
    sol = solve_or_scale(case, prob, reuse, more=extra + mine)
    # The formula bands' solutions first (formula_load_table takes them in order), then these.
    mine_sols = sol.more[len(extra):]
    sol.more = sol.more[:len(extra)]
    limit = 1e-6 * case.load_N
    for lc_k, sol_k in zip([lc, *(x for _, x in extra), *(x for _, x in mine)], [sol, *sol.more, *mine_sols]):
        support_k, eq_err, point_r = equilibrium(lc_k, sol_k.reactions)
        if not (eq_err <= limit and point_r <= limit):
            raise NumericalError(f"loads out of balance: equilibrium error {eq_err:.3g} N, "
                                 f"constraint reaction {point_r:.3g} N (limit {limit:.3g} N)")
    support, eq_err, point_r = equilibrium(lc, sol.reactions)
    t0 = time.perf_counter()
    vm, pk, crit = peaks_of(case, sol.u, mat)
    sections = None
    if with_sections:
        sym_x = m.facet_ids.get("symmetry_x")
        sym_idx = next((i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == sym_x
                        and sym_x is not None), None)
        share = 0.25 if case.model == "quarter" else 1.0
        sections = section_results(sol, mat, case.dims, case.load_N, share,
                                   sym_idx, pk.value_MPa, bearing_centre_mm=case.bearing_band().centre_mm)
        if variants:
            sections["formula_load"] = formula_load_table(case, variants, sol, mat, share, sym_idx)
            for row in sections["formula_load"].values():
                row["mesh_factor"] = factor  # the mesh it was solved on (analyse: not always the requested)
    load_readings = []
    for v, sol_k in zip(load_variants, mine_sols):
        _, v_pk, v_crit = peaks_of(v, sol_k.u, mat)
        load_readings.append((v_pk, v_crit, None if not with_sections else section_results(
            sol_k, mat, v.dims, v.load_N, 0.25 if v.model == "quarter" else 1.0, sym_idx, v_pk.value_MPa,
            bearing_centre_mm=v.bearing_band().centre_mm)))
    t_post = time.perf_counter() - t0
    timings = dict(m.timings, **sol.timings, post=t_post)
    how = (f"{sol.iterations} iterations ({case.solver}), assemble {sol.timings['assemble']:.2f} s, "
           f"solve {sol.timings['solve']:.2f} s" if sol.scaled_from is None else
           f"the solve at Q = {sol.scaled_from['load_N']:g} N, E = {sol.scaled_from['E_MPa']:g} MPa scaled "
           f"({sol.timings['solve']:.2f} s)")
    say(f"solve ×{factor:.3g}: {sol.dofs} DOFs, {how}; "
        f"peak {pk.value_MPa:.2f} MPa, critical {crit.value_MPa:.2f} MPa")
    return Level(factor=factor, dofs=sol.dofs, cells=m.mesh.topology.index_map(3).size_global,
                 peak=pk, critical=crit, iterations=sol.iterations,
                 residual_rel=sol.residual_rel, seat_force_N=lc.seat_force_z_N,
                 support_force_N=support, equilibrium_error_N=eq_err,
                 constraint_reaction_N=point_r, jacobian_ratio=m.jacobian_ratio,
                 timings=timings, scaled_from=sol.scaled_from, fields=(sol.u, vm) if keep_fields else None,
                 sections=sections, load_variants=load_readings)
