"""Solving the elasticity problem of one mesh again after its nodes moved (pipeline.fe.morph)
or its loads changed, without setting anything up anew (mm, N, MPa).

Why: a sensitivity variant made by moving the nominal mesh's nodes has the nominal mesh's
topology: its function space, DOF numbering, compiled forms, matrix sparsity, constraints
and the p-multigrid's interpolation are the same; only the matrices' values and the load
vector change. The nominal displacement is a close first guess, and the nominal geometry's
preconditioner still a good one (docs/decisions/0036-sensitivity-variants-by-morphing.md).

What it solves is what pipeline.fe.solve.solve solves with solver "pmg" (the same forms,
quadrature split, constraints, options, checks and reactions), split into a set-up made
once per mesh (:class:`Resolver`) and :meth:`Resolver.solve` per geometry and load.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix, create_matrix
from petsc4py import PETSc

from pipeline.errors import NumericalError
from pipeline.fe.assembly import constrained_diagonal, dirichlet_bc, rigid_body_nullspace
from pipeline.fe.elasticity import Constraint, Material, Traction, strain, stress, volume_integral, volume_measures
from pipeline.fe.pmultigrid import p1_interpolation
from pipeline.fe.solve import Solution, _check, _load_form, _load_vector, _reactions, _System, constrained, solver_options


@dataclass(frozen=True)
class ResolveOptions:
    """How a :class:`Resolver` carries one solve over to the next.

    warm_start: CG starts from the last solution (or the guess given to solve) instead of
    zero; it stops at the same ‖b − A u‖ <= rtol·‖b‖ (PETSc's default test, unpreconditioned
    norm) either way. reuse_preconditioner: the p-multigrid set up for the first geometry
    (the smoother's diagonal and eigenvalue bounds, the coarse P1 matrix and its GAMG
    hierarchy) preconditions the later ones too, only the fine matrix being assembled anew;
    a solve that fails on it is done again on a new set-up, which is then kept. rtol: the
    relative residual CG stops at (None: the one the Resolver is made with)."""

    warm_start: bool = True
    reuse_preconditioner: bool = False
    rtol: float | None = None


class Resolver:
    """The P2 elasticity problem on one mesh, set up once and solved for each geometry of
    that mesh (its nodes moved in place, pipeline.fe.morph.Mover) and each set of
    tractions, by CG with pipeline.fe.pmultigrid's two-level p-multigrid (mm, N, MPa). A
    solve on the nodes of the last one (another load: a load-model variant) assembles only
    its load vector.

    The constraints are located once (by facet tag, or at points that the moves leave in
    place) and hold for every solve. ``with Resolver(...) as r:``, or :meth:`close`, frees
    the PETSc objects."""

    def __init__(self, mesh, facet_tags, order: int, mat: Material, constraints: Sequence[Constraint],
                 rtol: float, options: ResolveOptions | None = None) -> None:
        self.options = options or ResolveOptions()
        self.rtol = self.options.rtol or rtol
        self.mat, self.facet_tags = mat, facet_tags
        V = fem.VectorFunctionSpace(mesh, ("Lagrange", order))
        self.V = V
        u, self.v = ufl.TrialFunction(V), ufl.TestFunction(V)
        self.ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
        # The straight/curved split of the nominal mesh: a move keeps straight tets straight.
        self.dx_split = volume_measures(mesh, order)
        self.a = fem.form(volume_integral(ufl.inner(stress(u, mat), strain(self.v)), self.dx_split))
        self.bcs, self.bc_dofs = constrained(V, facet_tags, constraints)
        self.diagonal = constrained_diagonal(mat)
        self.A_baij = create_matrix(self.a, "baij")
        self.A = PETSc.Mat()  # SBAIJ, filled by _assemble
        # The coarse level: P1 on the same mesh with the same constraints; the interpolation
        # depends on the reference element only, not on where the nodes are.
        V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
        self.V1 = V1
        u1, v1 = ufl.TrialFunction(V1), ufl.TestFunction(V1)
        self.bcs1 = [bc for c in constraints for bc in dirichlet_bc(V1, facet_tags, c)[0]]
        self.a1 = fem.form(volume_integral(ufl.inner(stress(u1, mat), strain(v1)),
                                           volume_measures(mesh, 1, like=self.dx_split)))
        self.Ac_baij = create_matrix(self.a1, "baij")
        self.Ac = PETSc.Mat()  # AIJ
        self.P = p1_interpolation(V1, V)
        free = self.P.createVecRight()
        free.set(1.0)
        n_owned = V1.dofmap.index_map.size_local * V1.dofmap.index_map_bs
        for bc in self.bcs1:
            dofs = bc.dof_indices()[0]
            free.array[dofs[dofs < n_owned]] = 0.0
        self.P.diagonalScale(None, free)  # columns: a coarse correction never moves a constrained DOF
        free.destroy()
        self.ksp: PETSc.KSP | None = None
        self.last: np.ndarray | None = None
        self.assembled_at: np.ndarray | None = None  # the node positions the matrices were assembled at (mm)
        self.set_ups = 0  # preconditioner set-ups so far
        self.last_timings: dict[str, float] = {}  # the last solve's steps, wall time (s)
        self.last_cpu_timings: dict[str, float] = {}  # and CPU time (s)

    def __enter__(self) -> "Resolver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.ksp, self.A, self.A_baij, self.Ac, self.Ac_baij, self.P):
            if obj is not None:
                obj.destroy()
        self.ksp = None

    def _matrix(self, M: PETSc.Mat, form, bcs, kind: str, out: PETSc.Mat) -> None:
        """Assemble ``form`` into BAIJ ``M`` (same sparsity every time), converted into ``out``."""
        M.zeroEntries()
        assemble_matrix(M, form, bcs=bcs, diagonal=self.diagonal)
        M.assemble()
        M.convert(kind, out)

    def _set_up(self) -> None:
        """The coarse matrix of the geometry as it is now, and the KSP with pmg's options
        (solve.solver_options) set up on both matrices."""
        self._matrix(self.Ac_baij, self.a1, self.bcs1, "aij", self.Ac)
        self.Ac.setNearNullSpace(rigid_body_nullspace(self.V1))
        if self.ksp is None:
            ksp = PETSc.KSP().create(self.V.mesh.comm)
            prefix = f"crosshead_{ksp.handle}_"
            ksp.setOptionsPrefix(prefix)
            opts = PETSc.Options()
            options = solver_options("pmg", self.rtol)
            try:
                for k, val in options.items():
                    opts[prefix + k] = val
                ksp.setOperators(self.A)
                pc = ksp.getPC()
                pc.setType("mg")
                pc.setMGLevels(2)
                pc.setMGType(PETSc.PC.MGType.MULTIPLICATIVE)
                pc.setMGInterpolation(1, self.P)
                pc.getMGCoarseSolve().setOperators(self.Ac)
                ksp.setFromOptions()
                # PCSetUp reads the levels' options (mg_levels_*): before deleting them.
                ksp.setUp()
            finally:
                for k in options:
                    del opts[prefix + k]
            self.ksp = ksp
        else:
            pc = self.ksp.getPC()
            pc.setReusePreconditioner(False)
            self.ksp.setOperators(self.A)
            pc.getMGCoarseSolve().setOperators(self.Ac)
            self.ksp.setUp()
        self.ksp.getPC().setReusePreconditioner(self.options.reuse_preconditioner)
        self.set_ups += 1

    def _cg(self, b: PETSc.Vec, guess: np.ndarray | None) -> tuple[fem.Function, int, int, float]:
        """CG on the KSP as set up: (u in mm, PETSc's converged reason, iterations, true
        relative residual ‖b − A u‖/‖b‖)."""
        uh = fem.Function(self.V, name="displacement_mm")
        start = guess if guess is not None else self.last if self.options.warm_start else None
        if start is not None:
            uh.x.array[:] = start
        self.ksp.setInitialGuessNonzero(start is not None)
        self.ksp.solve(b, uh.vector)
        uh.x.scatter_forward()
        r = b.duplicate()
        self.A.mult(uh.vector, r)
        r.axpy(-1.0, b)
        bnorm = b.norm()
        res_rel = r.norm() / bnorm if bnorm > 0 else r.norm()
        r.destroy()
        return uh, self.ksp.getConvergedReason(), self.ksp.getIterationNumber(), float(res_rel)

    def solve(self, tractions: Sequence[Traction], guess: np.ndarray | None = None) -> Solution:
        """The displacement (mm) under ``tractions`` on the mesh as its nodes are now, checked
        like solve.solve's (converged, finite, true residual), with its reactions (N).
        ``guess``: where CG starts (this rank's DOF values, mm; default: the last solution
        with warm_start). ``last_timings`` and ``last_cpu_timings`` then hold each step's wall
        and CPU time (s)."""
        clock = _Clock()
        x = self.V.mesh.geometry.x
        moved = self.assembled_at is None or not np.array_equal(x, self.assembled_at)
        if moved:  # same nodes: the matrices and the preconditioner stand (another load)
            self._matrix(self.A_baij, self.a, self.bcs, "sbaij", self.A)
            self.assembled_at = x.copy()
        clock.lap("fine matrix")
        L_form = _load_form(self.V, self.v, tractions, self.ds)
        b = _load_vector(L_form, self.a, self.bcs, self.diagonal)
        clock.lap("load vector")
        reused = self.ksp is not None and (self.options.reuse_preconditioner or not moved)
        if not reused:
            self._set_up()
        clock.lap("coarse matrix, preconditioner set-up")
        uh, reason, its, res_rel = self._cg(b, guess)
        clock.lap("CG iterations")
        try:
            _check(uh, reason, its, res_rel, "pmg", self.rtol)
        except NumericalError:
            if not reused:
                raise
            self._set_up()  # the first geometry's preconditioner did not serve this one
            clock.lap("coarse matrix, preconditioner set-up")
            uh, reason, its, res_rel = self._cg(b, guess)
            clock.lap("CG iterations")
            _check(uh, reason, its, res_rel, "pmg", self.rtol)
        system = _System(self.V, self.v, self.dx_split, L_form, self.A, b, self.bcs, self.bc_dofs, self.a,
                         self.diagonal, self.facet_tags)
        reactions, reaction = _reactions(system, uh, self.mat)
        clock.lap("reactions")
        b.destroy()
        self.last = uh.x.array.copy()
        self.last_timings, self.last_cpu_timings = clock.laps, clock.cpu_laps
        t = clock.laps
        dofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs
        return Solution(u=uh, iterations=its, reason=reason, residual_rel=res_rel, dofs=dofs, solver="pmg",
                        bc_dofs=self.bc_dofs, reactions=reactions, reaction=reaction,
                        timings={"assemble": t["fine matrix"] + t["load vector"] + t["reactions"],
                                 "solve": t["coarse matrix, preconditioner set-up"] + t["CG iterations"]})


class _Clock:
    """Wall-time and CPU-time laps (s) by name, summed when a name comes again."""

    def __init__(self) -> None:
        self.t, self.c = time.perf_counter(), time.process_time()
        self.laps: dict[str, float] = {}
        self.cpu_laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now, cpu = time.perf_counter(), time.process_time()
        self.laps[name] = self.laps.get(name, 0.0) + now - self.t
        self.cpu_laps[name] = self.cpu_laps.get(name, 0.0) + cpu - self.c
        self.t, self.c = now, cpu
