"""Solving the elasticity problem on one mesh: assembly, the Krylov solver and its
preconditioner (pmg, gamg, hypre or direct MUMPS), convergence checks, reactions.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import (
    apply_lifting,
    assemble_vector,
    set_bc,
)
from mpi4py import MPI
from petsc4py import PETSc

from pipeline.fe.assembly import assemble_aij, assemble_sbaij, constrained_diagonal, dirichlet_bc, rigid_body_nullspace
from pipeline.inputs.choices import SOLVERS
from pipeline.fe.elasticity import (
    Constraint,
    Material,
    Traction,
    strain,
    stress,
    volume_integral,
    volume_measures,
)
from pipeline.errors import NumericalError
from pipeline.runtime.interrupts import yield_to_stop
from pipeline.fe.pmultigrid import p_multigrid



@dataclass
class Solution:
    """Displacement (mm) and what the solver did: iterations, residuals, DOFs, times (s)."""

    u: fem.Function
    iterations: int
    reason: int
    residual_rel: float
    dofs: int
    solver: str
    bc_dofs: list[np.ndarray]
    reactions: list[np.ndarray]  # per Constraint: reaction force vector (N), summed
    reaction: np.ndarray | None = None  # R = K u - f at this rank's owned DOFs (N): section resultants
    timings: dict[str, float] = field(default_factory=dict)
    # Set when this is an earlier solve scaled to a new load or E (pipeline/cache/solutions.py):
    # that solve's load_N (N) and E_MPa (MPa).
    scaled_from: dict | None = None
    # The solutions of further load sets on the same operator (solve's ``more``), in order.
    more: list["Solution"] = field(default_factory=list)


# GAMG on an elasticity matrix: smoothed aggregation, threshold, aggressive coarsening on
# the first two levels, Chebyshev-Jacobi smoothing. Shared by "gamg" (on the P2 matrix)
# and "pmg" (on the P1 coarse level, under the prefix mg_coarse_).
_GAMG = {"pc_type": "gamg", "pc_gamg_type": "agg", "pc_gamg_agg_nsmooths": 1,
         "pc_gamg_threshold": 0.02, "pc_gamg_square_graph": 2,
         "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
         "mg_levels_ksp_chebyshev_esteig_steps": 20}


def solver_options(name: str, rtol: float) -> dict[str, object]:
    """PETSc options for the named solver ("pmg" also needs :func:`p_multigrid`)."""
    cg = {"ksp_type": "cg", "ksp_rtol": rtol, "ksp_max_it": 1000,
          "ksp_norm_type": "unpreconditioned"}
    if name == "pmg":
        # Why: GAMG on the P2 matrix spends half its time in set-up (Galerkin products of a
        # matrix with ~80 entries per row); the P1 matrix of the same mesh has 1/7 of the
        # rows, and the two-level cycle takes fewer iterations (docs/decisions/0001-p-multigrid-default-solver.md).
        return {**cg, "pc_type": "mg",
                "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
                "mg_levels_ksp_chebyshev_esteig_steps": 20,
                "mg_coarse_ksp_type": "preonly",
                **{f"mg_coarse_{k}": v for k, v in _GAMG.items()}}
    if name == "gamg":
        # Stop on the true (unpreconditioned) residual: the same norm solve() checks after.
        # Smoothed aggregation (nsmooths 1) keeps the iterations flat under refinement
        # (tests/fe/test_conditioning.py); unsmoothed aggregation is faster per solve but its
        # iterations grow with the mesh (docs/decisions/0001-p-multigrid-default-solver.md).
        return {**cg, **_GAMG}
    if name == "hypre":
        return {**cg, "pc_type": "hypre", "pc_hypre_type": "boomeramg",
                "pc_hypre_boomeramg_strong_threshold": 0.7,
                "pc_hypre_boomeramg_nodal_coarsen": 6,
                "pc_hypre_boomeramg_vec_interp_variant": 3,
                "pc_hypre_boomeramg_agg_nl": 2}
    if name == "mumps":
        # Cholesky (LDL^T), not LU: the stiffness matrix stays symmetric with the boundary
        # conditions applied (rows and columns zeroed): half the factorisation work.
        return {"ksp_type": "preonly", "pc_type": "cholesky",
                "pc_factor_mat_solver_type": "mumps"}
    raise ValueError(f"solver must be one of {SOLVERS}, got {name!r}")


def constrained(V, facet_tags, constraints: Sequence[Constraint]) -> tuple[list, list[np.ndarray]]:
    """The DirichletBCs of the constraints on space V and, per Constraint, the (V-numbered,
    blocked-by-component) DOFs it fixes: where its reaction is summed."""
    bcs, bc_dofs = [], []
    for c in constraints:
        b_, d_ = dirichlet_bc(V, facet_tags, c)
        bcs += b_
        bc_dofs.append(np.concatenate(d_) if d_ else np.array([], dtype=np.int32))
    return bcs, bc_dofs


@dataclass
class _System:
    """The assembled linear system on space V, with what the reactions need again."""

    V: fem.FunctionSpace
    v: ufl.Argument  # test function
    dx_split: object  # the volume measures (elasticity.volume_measures)
    L_form: ufl.Form  # the load form (N)
    A: PETSc.Mat
    b: PETSc.Vec
    bcs: list
    bc_dofs: list[np.ndarray]
    a: object  # the compiled stiffness form (for the lifting of another load vector)
    diagonal: float  # the constrained rows' diagonal (MPa·mm)
    ds_data: object  # the facet tags the tractions' markers refer to


@dataclass(frozen=True)
class Loads:
    """What a solve carries: tractions (MPa) under constraints, and ``more`` sets of
    tractions under the same constraints (a load-model variant: only the right-hand side
    differs)."""

    tractions: Sequence[Traction]
    constraints: Sequence[Constraint]
    more: Sequence[Sequence[Traction]] = ()


@dataclass(frozen=True)
class Method:
    """How a system is solved: the displacement's element order, the solver (SOLVERS), its
    relative tolerance on the true residual, and the tolerance of the further right-hand
    sides (Loads.more; None: the same)."""

    order: int = 2
    solver: str = "pmg"
    rtol: float = 1e-10
    more_rtol: float | None = None


def solve(mesh, facet_tags, mat: Material, loads: Loads, method: Method = Method(),
          V: fem.FunctionSpace | None = None) -> Solution:
    """Solve div σ(u) = 0 with the given loads (on the vector Lagrange space V of the
    method's order, if the caller has made it already).

    ``loads.more`` are solved with the same matrix and preconditioner; their solutions,
    checked alike, are the result's ``more``.

    Checks the solver's converged reason and the true relative residual ‖b − A u‖/‖b‖
    (below max(1000·rtol, 1e-6) for iterative solvers, 1e-8 for MUMPS) and that u is finite.
    Reaction forces (N) at each Constraint come from the unconstrained residual.
    For P1, "pmg" has no lower order to go to and is plain GAMG.
    """
    if method.solver == "pmg" and method.order == 1:
        method = replace(method, solver="gamg")
    solver, rtol = method.solver, method.rtol
    more_rtol = method.more_rtol or rtol
    t0 = time.perf_counter()
    system = _assemble(mesh, facet_tags, mat, loads, method, V)
    t_assemble = time.perf_counter() - t0
    t0 = time.perf_counter()
    variants = [_variant(system, tractions_k) for tractions_k in loads.more]
    t_assemble += time.perf_counter() - t0
    t0 = time.perf_counter()
    solved = _krylov(system, mat, facet_tags, loads.constraints, method, more=variants)
    t_solve = time.perf_counter() - t0
    V = system.V
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    out = []
    for k, (sys_k, (uh, reason, its, res_rel)) in enumerate(zip([system, *variants], solved)):
        _check(uh, reason, its, res_rel, solver, rtol if k == 0 else more_rtol)
        t0 = time.perf_counter()
        reactions, reaction = _reactions(sys_k, uh, mat)
        t_assemble += time.perf_counter() - t0
        out.append(Solution(u=uh, iterations=its, reason=reason, residual_rel=float(res_rel), dofs=dofs,
                            solver=solver, bc_dofs=sys_k.bc_dofs, reactions=reactions, reaction=reaction))
    first = out[0]
    first.more = out[1:]
    first.timings = {"assemble": t_assemble, "solve": t_solve}
    return first


def _load_form(V, v, tractions: Sequence[Traction], ds: ufl.Measure) -> ufl.Form:
    """The load form (N) of the tractions, with a zero volume term so that it is a form
    even without tractions."""
    zero = fem.Constant(V.mesh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    L_form = ufl.inner(zero, v) * ufl.dx
    for t in tractions:
        L_form += ufl.inner(t.value, v) * ds(t.marker)
    return L_form


def _load_vector(L_form: ufl.Form, a, bcs: list, diagonal: float) -> PETSc.Vec:
    """The load vector (N) with the constraints applied: b = diagonal × g on a constrained row."""
    b = assemble_vector(fem.form(L_form))
    apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    set_bc(b, bcs, scale=diagonal)
    return b


def _variant(system: _System, tractions: Sequence[Traction]) -> _System:
    """The system of another set of tractions on the same matrix and constraints: only the
    load form and vector are new."""
    ds = ufl.Measure("ds", domain=system.V.mesh, subdomain_data=system.ds_data)
    L_form = _load_form(system.V, system.v, tractions, ds)
    b = _load_vector(L_form, system.a, system.bcs, system.diagonal)
    return _System(system.V, system.v, system.dx_split, L_form, system.A, b, system.bcs, system.bc_dofs,
                   system.a, system.diagonal, system.ds_data)


def _assemble(mesh, facet_tags, mat: Material, loads: Loads, method: Method,
              V: fem.FunctionSpace | None = None) -> _System:
    """Stiffness matrix (MPa·mm) and load vector (N) of the problem, constraints applied."""
    order, solver, tractions, constraints = method.order, method.solver, loads.tractions, loads.constraints
    V = V or fem.VectorFunctionSpace(mesh, ("Lagrange", order))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
    dx_split = volume_measures(mesh, order)  # once, for the stiffness and for the reactions
    a_form = volume_integral(ufl.inner(stress(u, mat), strain(v)), dx_split)
    L_form = _load_form(V, v, tractions, ds)
    bcs, bc_dofs = constrained(V, facet_tags, constraints)
    a = fem.form(a_form)
    # pmg multiplies with the fine matrix in SBAIJ (see assemble_sbaij, p_multigrid); the
    # others need AIJ.
    diagonal = constrained_diagonal(mat)
    A = assemble_sbaij(a, bcs, diagonal) if solver == "pmg" else assemble_aij(a, bcs, diagonal)
    b = _load_vector(L_form, a, bcs, diagonal)  # b = diagonal × g on a constrained row: u = g there
    if solver in ("gamg", "hypre"):  # pmg gives its coarse (P1) matrix its own
        A.setNearNullSpace(rigid_body_nullspace(V))
    return _System(V, v, dx_split, L_form, A, b, bcs, bc_dofs, a, diagonal, facet_tags)


def _krylov(system: _System, mat: Material, facet_tags, constraints: Sequence[Constraint], method: Method,
            more: Sequence[_System] = ()) -> list[tuple[fem.Function, int, int, float]]:
    """Solve A u = b with the named solver, for the system's b and then each of ``more``'s
    with the same set-up, an iterative solver starting from the first b's displacement (a
    further load moves the part little, so fewer iterations reach the tolerance): per b
    (u in mm, PETSc's converged reason, iterations, true relative residual ‖b − A u‖/‖b‖)."""
    solver, rtol = method.solver, method.rtol
    A, V = system.A, system.V
    ksp = PETSc.KSP().create(V.mesh.comm)
    prefix = f"crosshead_{ksp.handle}_"  # unique while this KSP lives (its options are removed after set-up)
    ksp.setOptionsPrefix(prefix)
    opts = PETSc.Options()
    options = solver_options(solver, rtol)
    mg_parts: tuple = ()
    try:
        try:
            for k, val in options.items():
                opts[prefix + k] = val
            ksp.setOperators(A)
            mg_parts = p_multigrid(ksp, V, mat, facet_tags, constraints, system.dx_split) if solver == "pmg" else ()
            ksp.setFromOptions()
            # PCSetUp reads the multigrid levels' options (mg_levels_*): set up before deleting them.
            ksp.setUp()
        finally:
            # The options database is the process's: a failed set-up must not leave them
            # to the next solve (a sweep goes on after a failed variant).
            for k in options:
                del opts[prefix + k]
        ksp.setMonitor(_let_threads_run)
        solved = []
        for k, b in enumerate([system.b, *(m.b for m in more)]):
            if k == 1 and method.more_rtol is not None and solver != "mumps":
                ksp.setTolerances(rtol=method.more_rtol)
            uh = fem.Function(V, name="displacement_mm")
            warm = k > 0 and solver != "mumps"  # a further load on the same part: start from the first's displacement
            if warm:
                uh.x.array[:] = solved[0][0].x.array
            ksp.setInitialGuessNonzero(warm)
            ksp.solve(b, uh.vector)
            uh.x.scatter_forward()
            reason, its = ksp.getConvergedReason(), ksp.getIterationNumber()
            r = b.duplicate()
            A.mult(uh.vector, r)
            r.axpy(-1.0, b)
            bnorm = b.norm()
            res_rel = r.norm() / bnorm if bnorm > 0 else r.norm()
            r.destroy()
            solved.append((uh, reason, its, res_rel))
    finally:
        ksp.destroy()
        for obj in mg_parts:
            obj.destroy()
    return solved


def _let_threads_run(ksp: PETSc.KSP, its: int, rnorm: float) -> None:
    """A KSP monitor that lets this process's other Python threads run once per iteration.

    Why: PETSc's solve holds the interpreter lock from start to end, so the stop watcher
    (pipeline/runtime/interrupts.py) and the progress heartbeat waited for the whole solve: a
    Ctrl-C during a long solve took effect only after it. Once a stop has begun, the solve
    waits here for it to end the process: taking the lock back for a whole iteration each
    time the watcher gave it up (at every file it removes) slowed the clean-up to seconds.
    An iteration of a Krylov solver takes milliseconds or more; giving up the lock costs
    microseconds (docs/decisions/0016-stops.md). A direct solve (MUMPS) has no iterations and still
    holds it throughout."""
    time.sleep(0)  # releases the interpreter lock, and takes it back after any waiting thread
    yield_to_stop()


def _check(uh: fem.Function, reason: int, its: int, res_rel: float, solver: str, rtol: float) -> None:
    """Raise NumericalError unless the solver converged, u is finite and the true residual
    is below max(1000·rtol, 1e-6) (iterative) or 1e-8 (MUMPS)."""
    if reason <= 0:
        raise NumericalError(f"solver {solver} did not converge (PETSc reason {reason}, {its} iterations)")
    if not np.all(np.isfinite(uh.x.array)) or not np.isfinite(res_rel):
        raise NumericalError("the displacement contains NaN or Inf")
    limit = 1e-8 if solver == "mumps" else max(1e3 * rtol, 1e-6)
    if res_rel > limit:
        raise NumericalError(f"true residual {res_rel:.3g} above {limit:.1g} after solve")


# Poisson's ratio from which an iterative solver's iterations grow towards its limit
# (about 17·sqrt(lambda/mu) for P2 with pmg on No. 05, docs/accuracy.md): a failure there
# is named as the material's.
NU_NEARLY_INCOMPRESSIBLE = 0.49


def failure_advice(solver: str, nu: float, small: Sequence[str]) -> str:
    """What to try after a solve failed, in words for the failure's one line: the part's
    extreme lengths (``small``, mm, see pipeline.inputs.case.small_features) and a nearly
    incompressible material (``nu``) make the stiffness matrix ill-conditioned; MUMPS, a
    direct solver, copes with more of it than the Krylov solvers. A finer mesh is not
    offered: at a seat edge 5e-5 mm from the bore pmg stops at its limit on the default
    mesh as on a coarse one (docs/accuracy.md)."""
    tips = []
    if small:
        tips.append(f"the part has a feature tiny relative to its size ({small[0]}"
                    + (f"; {len(small) - 1} more below 1e-3 of b6" if len(small) > 1 else "") + ")")
    if nu >= NU_NEARLY_INCOMPRESSIBLE and solver != "mumps":
        tips.append(f"Poisson's ratio {nu:g} is nearly incompressible")
    if solver != "mumps":
        todo = "try --solver mumps" + (", or check that dimension" if small else "")
    else:
        todo = "check that dimension" if small else "check the dimensions and the material (E, nu)"
    return "; ".join(tips + [todo])


def _reactions(system: _System, uh: fem.Function, mat: Material) -> tuple[list[np.ndarray], np.ndarray]:
    """Per constraint the summed reaction force (N, 3 components), and R = K u − f at this
    rank's owned DOFs (N): the residual of the unconstrained system at the fixed DOFs."""
    V, v = system.V, system.v
    R = fem.petsc.assemble_vector(fem.form(volume_integral(ufl.inner(stress(uh, mat), strain(v)), system.dx_split)
                                           - system.L_form))
    R.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    Ra = R.array_r
    reactions = []
    for d_ in system.bc_dofs:
        owned = d_[d_ < n_owned]
        f = np.zeros(3)
        for comp in range(3):
            sel = owned[owned % 3 == comp]
            f[comp] = Ra[sel].sum()
        reactions.append(V.mesh.comm.allreduce(f, op=MPI.SUM))
    return reactions, Ra[:n_owned].copy()
