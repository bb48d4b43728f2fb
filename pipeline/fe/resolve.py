"""Solving the elasticity problem of one mesh again after its nodes moved (pipeline.fe.morph)
or its loads changed, without setting anything up anew (mm, N, MPa).

Why: a sensitivity variant made by moving the nominal mesh's nodes has the nominal mesh's
topology: its function space, DOF numbering, compiled forms, matrix sparsity, constraints
and the p-multigrid's interpolation are the same; only the matrices' values, the load
vector and the coarse solver's set-up change. And the nominal displacement is a close first
guess (docs/decisions/0034-sensitivity-variants-by-morphing.md).

What it does is what pipeline.fe.solve.solve does with solver "pmg" (the same forms,
quadrature, constraints, options and checks), split into a set-up made once per mesh
(:class:`Resolver`) and a :meth:`Resolver.solve` per geometry and load.
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

from pipeline.fe.assembly import constrained_diagonal, dirichlet_bc, rigid_body_nullspace
from pipeline.fe.elasticity import Constraint, Material, Traction, strain, stress, volume_integral, volume_measures
from pipeline.fe.pmultigrid import p1_interpolation
from pipeline.fe.solve import Solution, _check, _load_form, _load_vector, _reactions, _System, constrained, solver_options


@dataclass
class ResolveOptions:
    """How a :class:`Resolver` reuses its set-up between solves.

    warm_start: start CG from the last solution (mm) instead of zero; the stopping test stays
    ‖b − A u‖ <= rtol·‖b‖ (PETSc's default, unpreconditioned norm), so the answer is held
    to the same residual. reuse_coarse: keep the coarse (P1) GAMG hierarchy's
    interpolation, made for the first geometry, and only form its Galerkin products again.
    rtol: the relative residual (None: the caller's)."""

    warm_start: bool = True
    reuse_coarse: bool = False
    rtol: float | None = None


class Resolver:
    """The P2 elasticity problem on one mesh, set up once and solved again for each geometry
    of that mesh (its nodes moved in place) and each set of tractions, by CG with the
    two-level p-multigrid of pipeline.fe.pmultigrid (mm, N, MPa).

    The constraints must be the same for every solve (they are located once: by facet tag,
    or at points that the moves leave in place). Call :meth:`close` (or use ``with``) to free
    the PETSc objects."""

    def __init__(self, mesh, facet_tags, order: int, mat: Material, constraints: Sequence[Constraint],
                 rtol: float, options: ResolveOptions | None = None) -> None:
        self.options = options or ResolveOptions()
        self.rtol = self.options.rtol or rtol
        self.mat, self.facet_tags, self.constraints = mat, facet_tags, list(constraints)
        self.V = fem.VectorFunctionSpace(mesh, ("Lagrange", order))
        V = self.V
        u, self.v = ufl.TrialFunction(V), ufl.TestFunction(V)
        self.ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
        self.dx_split = volume_measures(mesh, order)
        self.a = fem.form(volume_integral(ufl.inner(stress(u, mat), strain(self.v)), self.dx_split))
        self.bcs, self.bc_dofs = constrained(V, facet_tags, constraints)
        self.diagonal = constrained_diagonal(mat)
        self.A_baij = create_matrix(self.a, "baij")
        self.A: PETSc.Mat | None = None
        # The coarse level: P1 on the same mesh, its constraints and the interpolation (which
        # depends on the reference element only, not on where the nodes are).
        V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
        self.V1 = V1
        u1, v1 = ufl.TrialFunction(V1), ufl.TestFunction(V1)
        self.bcs1 = [bc for c in constraints for bc in dirichlet_bc(V1, facet_tags, c)[0]]
        self.a1 = fem.form(volume_integral(ufl.inner(stress(u1, mat), strain(v1)),
                                           volume_measures(mesh, 1, like=self.dx_split)))
        self.Ac_baij = create_matrix(self.a1, "baij")
        self.Ac: PETSc.Mat | None = None
        self.P = p1_interpolation(V1, V)
        free = self.P.createVecRight()
        free.set(1.0)
        n_owned = V1.dofmap.index_map.size_local * V1.dofmap.index_map_bs
        for bc in self.bcs1:
            dofs = bc.dof_indices()[0]
            free.array[dofs[dofs < n_owned]] = 0.0
        self.P.diagonalScale(None, free)
        free.destroy()
        self.ksp: PETSc.KSP | None = None
        self.last: fem.Function | None = None
        self.solves = 0
        self.last_timings: dict[str, float] = {}

    def __enter__(self) -> "Resolver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.ksp, self.A, self.A_baij, self.Ac, self.Ac_baij, self.P):
            if obj is not None:
                obj.destroy()
        self.ksp = self.A = self.Ac = None

    def _assemble(self) -> None:
        """The fine (SBAIJ) and coarse (AIJ) matrices of the mesh as its nodes are now, into
        the matrices of the first solve (same sparsity)."""
        for M, form, bcs, kind, attr in ((self.A_baij, self.a, self.bcs, "sbaij", "A"),
                                         (self.Ac_baij, self.a1, self.bcs1, "aij", "Ac")):
            M.zeroEntries()
            assemble_matrix(M, form, bcs=bcs, diagonal=self.diagonal)
            M.assemble()
            out = getattr(self, attr)
            setattr(self, attr, M.convert(kind, out) if out is not None else M.convert(kind, PETSc.Mat()))
        if self.ksp is None or not self.options.reuse_coarse:
            self.Ac.setNearNullSpace(rigid_body_nullspace(self.V1))

    def _set_up_ksp(self) -> None:
        """The KSP with pmg's options (solve.solver_options), made on the first solve."""
        ksp = PETSc.KSP().create(self.V.mesh.comm)
        prefix = f"crosshead_{ksp.handle}_"
        ksp.setOptionsPrefix(prefix)
        opts = PETSc.Options()
        options = dict(solver_options("pmg", self.rtol))
        if self.options.reuse_coarse:
            options["mg_coarse_pc_gamg_reuse_interpolation"] = True
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
            ksp.setUp()
        finally:
            for k in options:
                del opts[prefix + k]
        self.ksp = ksp

    def solve(self, tractions: Sequence[Traction]) -> Solution:
        """The displacement (mm) under ``tractions`` on the mesh as its nodes are now, checked
        like solve.solve's (converged, finite, true residual), with its reactions (N).
        ``last_timings`` then holds the wall time (s) of each step of this solve."""
        clock = _Clock()
        self._assemble()
        clock.lap("matrices")
        L_form = _load_form(self.V, self.v, tractions, self.ds)
        b = _load_vector(L_form, self.a, self.bcs, self.diagonal)
        clock.lap("load vector")
        if self.ksp is None:
            self._set_up_ksp()
        else:
            self.ksp.setOperators(self.A)
            self.ksp.getPC().getMGCoarseSolve().setOperators(self.Ac)
            self.ksp.setUp()
        clock.lap("preconditioner set-up")
        uh = fem.Function(self.V, name="displacement_mm")
        warm = self.options.warm_start and self.last is not None
        if warm:
            uh.x.array[:] = self.last.x.array
        self.ksp.setInitialGuessNonzero(warm)
        self.ksp.solve(b, uh.vector)
        uh.x.scatter_forward()
        reason, its = self.ksp.getConvergedReason(), self.ksp.getIterationNumber()
        r = b.duplicate()
        self.A.mult(uh.vector, r)
        r.axpy(-1.0, b)
        bnorm = b.norm()
        res_rel = r.norm() / bnorm if bnorm > 0 else r.norm()
        r.destroy()
        clock.lap("CG iterations")
        _check(uh, reason, its, res_rel, "pmg", self.rtol)
        system = _System(self.V, self.v, self.dx_split, L_form, self.A, b, self.bcs, self.bc_dofs, self.a,
                         self.diagonal, self.facet_tags)
        reactions, reaction = _reactions(system, uh, self.mat)
        clock.lap("reactions")
        b.destroy()
        self.last = uh
        self.solves += 1
        self.last_timings = clock.laps
        t = clock.laps
        dofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs
        return Solution(u=uh, iterations=its, reason=reason, residual_rel=float(res_rel), dofs=dofs, solver="pmg",
                        bc_dofs=self.bc_dofs, reactions=reactions, reaction=reaction,
                        timings={"assemble": t["matrices"] + t["load vector"] + t["reactions"],
                                 "solve": t["preconditioner set-up"] + t["CG iterations"]})


class _Clock:
    """Wall-time laps (s) by name."""

    def __init__(self) -> None:
        self.t = time.perf_counter()
        self.laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = self.laps.get(name, 0.0) + now - self.t
        self.t = now


def same_answer(a: Solution, b: Solution) -> float:
    """The largest difference of two displacements of one space, relative to the larger's
    largest component (for checks)."""
    scale = max(np.abs(a.u.x.array).max(), np.abs(b.u.x.array).max(), 1e-300)
    return float(np.abs(a.u.x.array - b.u.x.array).max() / scale)
