"""The default preconditioner: two-level p-multigrid, Pk smoothed by Chebyshev-Jacobi over P1
on the same mesh (one GAMG V-cycle there).
"""
from __future__ import annotations

from typing import Sequence

import basix
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from pipeline.fe.assembly import assemble_aij, constrained_diagonal, dirichlet_bc, rigid_body_nullspace
from pipeline.fe.elasticity import (
    Constraint,
    Material,
    local_cells,
    strain,
    stress,
    volume_integral,
    volume_measures,
)
from pipeline.errors import NumericalError


def p1_interpolation(V1, V) -> PETSc.Mat:
    """The interpolation matrix from V1 (vector P1) to V (vector Pk) on the same mesh, bs 3.

    Each Pk node takes the P1 basis values at its reference point, as DOLFINx's
    interpolation_matrix does (tests/verification/test_verification.py checks the two are equal), but
    vectorised: DOLFINx's took 0.28 s at No. 05 x1.3 on one core, for every solve.
    Rows: the Pk nodes this rank owns; columns: global P1 numbering.
    """
    n_cells = local_cells(V.mesh)
    p1 = basix.create_element(basix.ElementFamily.P, basix.CellType.tetrahedron, 1)
    weights = p1.tabulate(0, V.element.interpolation_points())[0, :, :, 0]   # (Pk nodes, 4)
    nodes_k = V.dofmap.list.array.reshape(n_cells, -1)
    nodes_1 = V1.dofmap.list.array.reshape(n_cells, -1)
    n_k = nodes_k.shape[1]
    # Every node once, from the first cell that has it; only the nodes owned here.
    rows, first = np.unique(nodes_k.ravel(), return_index=True)
    owned = rows < V.dofmap.index_map.size_local
    rows, first = rows[owned], first[owned]
    if len(rows) != V.dofmap.index_map.size_local:  # row i of the matrix is owned node i
        raise NumericalError("p-multigrid: an owned node is in no cell of this rank")
    w = weights[first % n_k]                                                   # (rows, 4)
    cols = V1.dofmap.index_map.local_to_global(nodes_1[first // n_k].ravel()).reshape(-1, 4)
    keep = np.abs(w) > 1e-14
    # Scalar rows 3r + c take columns 3j + c: the same weights for each component c.
    col = 3 * cols[:, None, :] + np.arange(3)[None, :, None]                 # (rows, 3, 4)
    val = np.broadcast_to(w[:, None, :], col.shape)
    mask = np.broadcast_to(keep[:, None, :], col.shape)
    order = np.argsort(np.where(mask, col, np.iinfo(np.int64).max), axis=2, kind="stable")
    col = np.take_along_axis(col, order, axis=2)
    val = np.take_along_axis(val, order, axis=2)
    mask = np.take_along_axis(mask, order, axis=2)
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=2).ravel())]).astype(PETSc.IntType)
    size = ((3 * len(rows), 3 * V.dofmap.index_map.size_global),
            (3 * V1.dofmap.index_map.size_local, 3 * V1.dofmap.index_map.size_global))
    P = PETSc.Mat().createAIJ(size=size, bsize=3, comm=V.mesh.comm,
                              csr=(indptr, col[mask].astype(PETSc.IntType), val[mask].copy()))
    P.assemble()
    return P


def p_multigrid(ksp: PETSc.KSP, V, mat: Material, facet_tags, constraints: Sequence[Constraint],
                 measures: tuple[ufl.Measure, ufl.Measure]) -> tuple[PETSc.Mat, PETSc.Mat]:
    """Make ksp's preconditioner a two-level p-multigrid over P1 on V's mesh.

    Coarse operator: the P1 stiffness matrix of the same mesh and material, with the same
    constraints (``measures``: V's :func:`volume_measures`, whose cell split it reuses); it
    gets the rigid-body near-nullspace of P1 for GAMG. The interpolation P
    (P1 -> V) has its columns at constrained P1 DOFs zeroed, so a coarse correction never
    moves a constrained DOF: the constrained rows of the P1 matrix are identity rows, and
    without the zeroing CG did not converge (1000 iterations at No. 05 x1.3).

    Why not the Galerkin product P^T A P: PETSc forms it only for AIJ matrices, and keeping
    the fine matrix in AIJ costs a conversion and a slower product with a vector in every
    smoothing step
    (docs/decisions/0002-fine-matrix-sbaij-coarse-operator-assembled.md). Returns (P, coarse matrix), to be destroyed after
    the solve.
    """
    mesh = V.mesh
    V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
    u1, v1 = ufl.TrialFunction(V1), ufl.TestFunction(V1)
    bcs1 = [bc for c in constraints for bc in dirichlet_bc(V1, facet_tags, c)[0]]
    Ac = assemble_aij(fem.form(volume_integral(ufl.inner(stress(u1, mat), strain(v1)),
                                                volume_measures(mesh, 1, like=measures))), bcs1,
                      constrained_diagonal(mat))
    Ac.setNearNullSpace(rigid_body_nullspace(V1))
    P = p1_interpolation(V1, V)
    free = Ac.createVecRight()
    free.set(1.0)
    n_owned = V1.dofmap.index_map.size_local * V1.dofmap.index_map_bs
    for bc in bcs1:
        dofs = bc.dof_indices()[0]
        free.array[dofs[dofs < n_owned]] = 0.0
    P.diagonalScale(None, free)  # columns
    free.destroy()
    pc = ksp.getPC()
    pc.setType("mg")
    pc.setMGLevels(2)
    pc.setMGType(PETSc.PC.MGType.MULTIPLICATIVE)
    pc.setMGInterpolation(1, P)
    pc.getMGCoarseSolve().setOperators(Ac)
    return P, Ac
