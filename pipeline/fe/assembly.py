"""Assembling the stiffness matrix and the constraints: PETSc matrix formats, Dirichlet
conditions on named facets and at points, the rigid-body near-nullspace.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import (
    assemble_matrix,
    create_matrix,
)
from mpi4py import MPI
from petsc4py import PETSc

from pipeline.fe.elasticity import Constraint, Material
from pipeline.errors import NumericalError


def assemble_aij(a, bcs, diagonal: float = 1.0) -> PETSc.Mat:
    """The matrix of bilinear form ``a`` with ``bcs`` applied, as an AIJ matrix (bs 3).

    Why through BAIJ: DOLFINx inserts each element matrix into a 3×3-block matrix faster
    than into AIJ, by enough to pay for the conversion
    (docs/decisions/0002-fine-matrix-sbaij-coarse-operator-assembled.md). GAMG and hypre need AIJ;
    "pmg" converts to SBAIJ instead (:func:`assemble_sbaij`).
    """
    A = assemble_baij(a, bcs, diagonal)
    A.convert("aij")  # in place (petsc4py converts self when no target is given)
    return A


def constrained_diagonal(mat: Material) -> float:
    """The diagonal entry of a constrained row (its row and column are zeroed), MPa·mm:
    E × 1 mm, of the order of the stiffness entries (E × element size).

    Why not 1 (DOLFINx's default): with a large E the other entries stand so far above
    the constrained rows' 1 that the p-multigrid's CG stopped on an indefinite
    preconditioner (docs/decisions/0018-constrained-rows-diagonal.md). The load vector carries this value × the imposed
    displacement on those rows (solve._assemble), so the solution does not depend on it."""
    return float(mat.E)


def assemble_baij(a, bcs, diagonal: float = 1.0) -> PETSc.Mat:
    """The matrix of bilinear form ``a`` with ``bcs`` applied (``diagonal`` on the
    constrained rows: :func:`constrained_diagonal`), as a BAIJ matrix (3×3 blocks)."""
    A = create_matrix(a, "baij")
    assemble_matrix(A, a, bcs=bcs, diagonal=diagonal)
    A.assemble()
    return A


def assemble_sbaij(a, bcs, diagonal: float = 1.0) -> PETSc.Mat:
    """The matrix of the symmetric bilinear form ``a`` with ``bcs`` applied (rows and columns
    zeroed: still symmetric), stored as its upper triangle in 3×3 blocks (SBAIJ).

    Why: the product with a vector, most of pmg's time, reads half the matrix; the
    conversion from BAIJ is cheap (docs/decisions/0002-fine-matrix-sbaij-coarse-operator-assembled.md).
    """
    A = assemble_baij(a, bcs, diagonal)
    A.convert("sbaij")  # in place, as in assemble_aij
    return A


def _point_dofs(V, Vc, component: int, points: np.ndarray, tol: float) -> np.ndarray:
    """Local DOFs of ``component`` at the given points (pairs: V's, and Vc's, the collapsed
    component space)."""

    def marker(x):
        hit = np.zeros(x.shape[1], dtype=bool)
        for p in points:
            hit |= np.linalg.norm(x.T - p[None, :], axis=1) < tol
        return hit

    return fem.locate_dofs_geometrical((V.sub(component), Vc), marker)


def dirichlet_bc(V, facet_tags, c: Constraint):
    """A DirichletBC and the (V-numbered) DOFs it fixes, for one Constraint."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    comps = [0, 1, 2] if c.component is None else [c.component]
    bcs, dofs_all = [], []
    for comp in comps:
        Vc, _ = V.sub(comp).collapse()
        if c.points is not None:
            dofs = _point_dofs(V, Vc, comp, np.asarray(c.points, dtype=float), c.tol)
            n = mesh.comm.allreduce(len(dofs[0]), op=MPI.SUM)
            if n < len(c.points):
                raise NumericalError(f"constraint point(s) {c.points.tolist()} not found among the mesh nodes")
        else:
            facets = facet_tags.indices[facet_tags.values == c.marker]
            dofs = fem.locate_dofs_topological((V.sub(comp), Vc), fdim, facets)
        g = fem.Function(Vc)
        g.x.array[:] = c.value
        bcs.append(fem.dirichletbc(g, dofs, V.sub(comp)))
        dofs_all.append(dofs[0])
    return bcs, dofs_all


def rigid_body_nullspace(V) -> PETSc.NullSpace:
    """The six rigid-body modes of the vector space V as a PETSc near-nullspace.

    Built from the owned node coordinates (mm); PETSc orthonormalises them.
    """
    n_owned = V.dofmap.index_map.size_local
    xyz = V.tabulate_dof_coordinates()[:n_owned].reshape(-1).copy()
    coords = PETSc.Vec().createWithArray(xyz, bsize=3, comm=V.mesh.comm)
    return PETSc.NullSpace().createRigidBody(coords)
