"""3-D linear elasticity with DOLFINx 0.5.2 (units: mm, N, MPa).

Generic on purpose: the crosshead (pipeline.crosshead) and the verification problems of
the tests (Lamé cylinder, plate with a hole, beam, patch test) go through this same code.
Loads are surface tractions on tagged facets; constraints fix displacement components on
tagged facets or at points. Default solver "pmg": CG preconditioned by a two-level
p-multigrid (the P2 or P3 space in SBAIJ, smoothed by Chebyshev-Jacobi, over the P1
stiffness of the same mesh, where one V-cycle of GAMG with the rigid-body near-nullspace
does the coarse work).
"gamg" (GAMG straight on the P2 matrix, as in the DOLFINx elasticity demo), "hypre"
(BoomerAMG) and "mumps" (direct) on request.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx.mesh import CellType, meshtags
from dolfinx.fem.petsc import (apply_lifting, assemble_matrix, assemble_vector, create_matrix, set_bc)
from mpi4py import MPI
from petsc4py import PETSc

from .errors import NumericalError

SOLVERS = ("pmg", "gamg", "hypre", "mumps")


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material: Young's modulus E (MPa), Poisson's ratio nu."""

    E: float = 210_000.0
    nu: float = 0.3

    @property
    def lame(self) -> tuple[float, float]:
        """Lamé parameters (mu, lambda), MPa."""
        mu = self.E / (2 * (1 + self.nu))
        lam = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        return mu, lam


@dataclass
class Traction:
    """Surface load t (MPa, a UFL vector of x) on the facets marked ``marker``."""

    marker: int
    value: object


@dataclass
class Constraint:
    """u_component = value (mm) on facets marked ``marker`` or at ``points`` (n×3, mm).

    component None fixes all three components. ``points`` are matched to mesh nodes
    within ``tol`` mm; a point that matches no node is an error.
    """

    component: int | None
    value: float = 0.0
    marker: int | None = None
    points: np.ndarray | None = None
    tol: float = 1e-6


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
    timings: dict[str, float] = field(default_factory=dict)


def strain(u):
    """Small-strain tensor of displacement u (mm/mm)."""
    return ufl.sym(ufl.grad(u))


def stress(u, mat: Material):
    """Cauchy stress (MPa) of displacement u."""
    mu, lam = mat.lame
    return 2.0 * mu * strain(u) + lam * ufl.tr(strain(u)) * ufl.Identity(len(u))


def von_mises_expr(u, mat: Material):
    """Von Mises equivalent stress (MPa) as a UFL expression."""
    s = stress(u, mat)
    dev = s - ufl.tr(s) / 3 * ufl.Identity(len(u))
    return ufl.sqrt(1.5 * ufl.inner(dev, dev))


STRAIGHT, CURVED = 1, 2  # cell markers of the quadrature split (volume_measures)


def _local_cells(mesh) -> int:
    """Number of cells on this rank, owned and ghost (the rows of the cell dofmaps)."""
    cells = mesh.topology.index_map(mesh.topology.dim)
    return cells.size_local + cells.num_ghosts


def curved_cells(mesh) -> np.ndarray:
    """Per local cell (owned, then ghosts): True if its geometry map is not affine.

    A 10-node tet is affine when every mid-edge node sits at its edge's midpoint (to 1e-10
    of the cell's size); 4-node tets always are. Other cells count as curved.
    """
    n = _local_cells(mesh)
    nodes = mesh.geometry.dofmap.array.reshape(n, -1)
    if mesh.topology.cell_type != CellType.tetrahedron or nodes.shape[1] not in (4, 10):
        return np.ones(n, dtype=bool)
    if nodes.shape[1] == 4:
        return np.zeros(n, dtype=bool)
    x = mesh.geometry.x[nodes]
    # Mid-edge node k sits on the reference edge k (basix numbering: (2,3), (1,3), ...).
    a, b = np.array(basix.topology(basix.CellType.tetrahedron)[1]).T
    bow = np.abs(x[:, 4:] - 0.5 * (x[:, a] + x[:, b])).max(axis=(1, 2))
    size = np.abs(x[:, 1:4] - x[:, :1]).max(axis=(1, 2))
    return bow > 1e-10 * size


def volume_integral(integrand, measures: tuple[ufl.Measure, ufl.Measure]):
    """integrand·dx over the whole mesh, split into the two :func:`volume_measures`."""
    straight, curved = measures
    return integrand * straight + integrand * curved


def volume_measures(mesh, order: int, like: tuple[ufl.Measure, ufl.Measure] | None = None
                    ) -> tuple[ufl.Measure, ufl.Measure]:
    """dx over the straight cells, with degree 2(k−1), and dx over the curved ones.

    Why: on an affine tet the stiffness integrand of Pk is a polynomial of degree 2(k−1),
    which that degree integrates exactly; UFL picks degree 5 for P2 on the curved (P2
    geometry) mesh, for every cell. On No. 05 x1, 77 % of the tets are straight (those
    not touching the fillet, bore and journal surfaces). Measured there, P2, one core,
    median of 5: assembly 1.68 s split against 2.12 s with degree 5 everywhere (x1.3: 0.93
    against 1.19 s). Curved cells keep UFL's degree; the peaks changed by 1e-13.
    ``like``: measures of this mesh made before, whose cell split is reused (it costs 0.03 s
    at x1.3).
    """
    if like is not None:
        tags = like[0].subdomain_data()
    else:
        curved = curved_cells(mesh)
        cells = np.arange(len(curved), dtype=np.int32)
        tags = meshtags(mesh, mesh.topology.dim, cells,
                        np.where(curved, CURVED, STRAIGHT).astype(np.int32))
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=tags)
    exact = {"quadrature_degree": max(2 * (order - 1), 0)}
    return dx(STRAIGHT, metadata=exact), dx(CURVED)


def _assemble_aij(a, bcs) -> PETSc.Mat:
    """The matrix of bilinear form ``a`` with ``bcs`` applied, as an AIJ matrix (bs 3).

    Why through BAIJ: DOLFINx inserts each element matrix into a 3×3-block matrix faster
    than into AIJ, by enough to pay for the conversion (No. 05 x1, P2, one core: 1.18
    against 1.63 s, median of 5; 0.70 against 0.94 s on 2 ranks). GAMG and hypre need AIJ;
    "pmg" converts to SBAIJ instead (:func:`_assemble_sbaij`).
    """
    A = _assemble_baij(a, bcs)
    A.convert("aij")  # in place (petsc4py converts self when no target is given)
    return A


def _assemble_baij(a, bcs) -> PETSc.Mat:
    """The matrix of bilinear form ``a`` with ``bcs`` applied, as a BAIJ matrix (3×3 blocks)."""
    A = create_matrix(a, "baij")
    assemble_matrix(A, a, bcs=bcs)
    A.assemble()
    return A


def _assemble_sbaij(a, bcs) -> PETSc.Mat:
    """The matrix of the symmetric bilinear form ``a`` with ``bcs`` applied (rows and columns
    zeroed: still symmetric), stored as its upper triangle in 3×3 blocks (SBAIJ).

    Why: the product with a vector, most of pmg's time, reads half the matrix: 5.5 against
    6.7 ms with BAIJ and 10.3 ms with AIJ at No. 05 x1.3 (median of 30). The conversion from
    BAIJ costs 0.04 s there. Interleaved in one process, medians of 7: assembly + solve 2.27
    -> 2.09 s at x1.3 (one rank), the same iterations and peaks to the printed 9 digits;
    on 2 ranks 1.40 -> 1.34 s at x1.3 and 2.81 / 2.83 s at x1.
    """
    A = _assemble_baij(a, bcs)
    A.convert("sbaij")  # in place, as in _assemble_aij
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


def _dirichlet(V, facet_tags, c: Constraint):
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


# GAMG on an elasticity matrix: smoothed aggregation, threshold, aggressive coarsening on
# the first two levels, Chebyshev-Jacobi smoothing. Shared by "gamg" (on the P2 matrix)
# and "pmg" (on the P1 coarse level, under the prefix mg_coarse_).
_GAMG = {"pc_type": "gamg", "pc_gamg_type": "agg", "pc_gamg_agg_nsmooths": 1,
         "pc_gamg_threshold": 0.02, "pc_gamg_square_graph": 2,
         "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
         "mg_levels_ksp_chebyshev_esteig_steps": 20}


def solver_options(name: str, rtol: float) -> dict[str, object]:
    """PETSc options for the named solver ("pmg" also needs :func:`_p_multigrid`)."""
    cg = {"ksp_type": "cg", "ksp_rtol": rtol, "ksp_max_it": 1000,
          "ksp_norm_type": "unpreconditioned"}
    if name == "pmg":
        # Why: GAMG on the P2 matrix spent half its time in set-up (Galerkin products of a
        # matrix with ~80 entries per row: 3.8 s of 6.2 s at No. 05 x1 on 2 ranks). The P1
        # matrix of the same mesh has 1/7 of the rows (it was then formed as the product
        # with the interpolation P1 -> P2; now assembled, see _p_multigrid). Same mesh, same
        # rtol: 35 iterations in 3.0 s against GAMG's 52 in 6.2 s, peaks equal to 1e-9
        # (measured, 2 ranks; make bench of 0b7f5ac: 1.8 against 7.8 s of solve).
        return {**cg, "pc_type": "mg",
                "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
                "mg_levels_ksp_chebyshev_esteig_steps": 20,
                "mg_coarse_ksp_type": "preonly",
                **{f"mg_coarse_{k}": v for k, v in _GAMG.items()}}
    if name == "gamg":
        # Stop on the true (unpreconditioned) residual: the same norm solve() checks after.
        # Smoothed aggregation (nsmooths 1) keeps the iterations flat under refinement
        # (tests/test_conditioning.py). Unsmoothed (0) solved the default No. 05 mesh (167 k
        # DOFs) in 7.6 s instead of 16.0 s, but its iterations grew 1.4x over 3x the DOFs.
        return {**cg, **_GAMG}
    if name == "hypre":
        return {**cg, "pc_type": "hypre", "pc_hypre_type": "boomeramg",
                "pc_hypre_boomeramg_strong_threshold": 0.7,
                "pc_hypre_boomeramg_nodal_coarsen": 6,
                "pc_hypre_boomeramg_vec_interp_variant": 3,
                "pc_hypre_boomeramg_agg_nl": 2}
    if name == "mumps":
        # Cholesky (LDL^T), not LU: the stiffness matrix stays symmetric with the boundary
        # conditions applied (rows and columns zeroed). Half the factorisation work: P3 on
        # No. 05 x2.5 (115 k DOFs) solved in 6.0 s instead of 8.6 s, peaks identical.
        return {"ksp_type": "preonly", "pc_type": "cholesky",
                "pc_factor_mat_solver_type": "mumps"}
    raise ValueError(f"solver must be one of {SOLVERS}, got {name!r}")


def p1_interpolation(V1, V) -> PETSc.Mat:
    """The interpolation matrix from V1 (vector P1) to V (vector Pk) on the same mesh, bs 3.

    Each Pk node takes the P1 basis values at its reference point, as DOLFINx's
    interpolation_matrix does (tests/test_verification.py checks the two are equal), but
    vectorised: DOLFINx's took 0.28 s at No. 05 x1.3 on one core, for every solve.
    Rows: the Pk nodes this rank owns; columns: global P1 numbering.
    """
    n_cells = _local_cells(V.mesh)
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


def _p_multigrid(ksp: PETSc.KSP, V, mat: Material, facet_tags, constraints: Sequence[Constraint],
                 measures: tuple[ufl.Measure, ufl.Measure]) -> tuple[PETSc.Mat, PETSc.Mat]:
    """Make ksp's preconditioner a two-level p-multigrid over P1 on V's mesh.

    Coarse operator: the P1 stiffness matrix of the same mesh and material, with the same
    constraints (``measures``: V's :func:`volume_measures`, whose cell split it reuses); it
    gets the rigid-body near-nullspace of P1 for GAMG. The interpolation P
    (P1 -> V) has its columns at constrained P1 DOFs zeroed, so a coarse correction never
    moves a constrained DOF: the constrained rows of the P1 matrix are identity rows, and
    without the zeroing CG did not converge (1000 iterations at No. 05 x1.3).

    Why not the Galerkin product P^T A P (used up to commit c40a1a4): PETSc forms it only
    for AIJ, and the fine matrix in AIJ cost a BAIJ -> AIJ conversion (0.24 s at No. 05
    x1.3) and a slower product with a vector in every smoothing step (10.3 against 6.7 ms
    in BAIJ, median of 30; see also :func:`_assemble_sbaij`). Measured at No. 05 P2 with the
    fine matrix in BAIJ, interleaved in one process, medians of 3-5: assembly + solve 3.58
    -> 2.45 s at x1.3 (31 -> 30 iterations), 8.17 -> 5.50 s at x1 (35 both), 4.88 -> 3.07 s
    at x1 on 2 ranks; peaks changed by <= 1e-8 relative. Returns (P, coarse matrix), to be
    destroyed after the solve.
    """
    mesh = V.mesh
    V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
    u1, v1 = ufl.TrialFunction(V1), ufl.TestFunction(V1)
    bcs1 = [bc for c in constraints for bc in _dirichlet(V1, facet_tags, c)[0]]
    Ac = _assemble_aij(fem.form(volume_integral(ufl.inner(stress(u1, mat), strain(v1)),
                                                volume_measures(mesh, 1, like=measures))), bcs1)
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


_counter = [0]


def solve(mesh, facet_tags, order: int, mat: Material, tractions: Sequence[Traction],
          constraints: Sequence[Constraint], solver: str = "pmg", rtol: float = 1e-10,
          progress: Callable[[str], None] | None = None) -> Solution:
    """Solve div σ(u) = 0 with the given tractions and constraints.

    Checks the solver's converged reason and the true relative residual ‖b − A u‖/‖b‖
    (must be below 1e-6 for iterative solvers, 1e-8 for MUMPS) and that u is finite.
    Reaction forces (N) at each Constraint come from the unconstrained residual.
    For P1, "pmg" has no lower order to go to and is plain GAMG.
    """
    if solver == "pmg" and order == 1:
        solver = "gamg"
    t0 = time.perf_counter()
    V = fem.VectorFunctionSpace(mesh, ("Lagrange", order))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
    dx_split = volume_measures(mesh, order)  # once, for the stiffness and for the reactions
    a_form = volume_integral(ufl.inner(stress(u, mat), strain(v)), dx_split)
    zero = fem.Constant(mesh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    L_form = ufl.inner(zero, v) * ufl.dx
    for t in tractions:
        L_form += ufl.inner(t.value, v) * ds(t.marker)
    bcs, bc_dofs = [], []
    for c in constraints:
        b_, d_ = _dirichlet(V, facet_tags, c)
        bcs += b_
        bc_dofs.append(np.concatenate(d_) if d_ else np.array([], dtype=np.int32))
    a = fem.form(a_form)
    L = fem.form(L_form)
    # pmg multiplies with the fine matrix in SBAIJ (see _assemble_sbaij, _p_multigrid); the
    # others need AIJ.
    A = _assemble_sbaij(a, bcs) if solver == "pmg" else _assemble_aij(a, bcs)
    b = assemble_vector(L)
    apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    set_bc(b, bcs)
    if solver in ("gamg", "hypre"):  # pmg gives its coarse (P1) matrix its own
        A.setNearNullSpace(rigid_body_nullspace(V))
    t_assemble = time.perf_counter() - t0

    t0 = time.perf_counter()
    ksp = PETSc.KSP().create(mesh.comm)
    _counter[0] += 1
    prefix = f"crosshead_{_counter[0]}_"
    ksp.setOptionsPrefix(prefix)
    opts = PETSc.Options()
    for k, val in solver_options(solver, rtol).items():
        opts[prefix + k] = val
    ksp.setOperators(A)
    mg_parts = _p_multigrid(ksp, V, mat, facet_tags, constraints, dx_split) if solver == "pmg" else ()
    ksp.setFromOptions()
    # PCSetUp reads the multigrid levels' options (mg_levels_*): set up before deleting them.
    ksp.setUp()
    for k in solver_options(solver, rtol):
        del opts[prefix + k]
    uh = fem.Function(V, name="displacement_mm")
    ksp.solve(b, uh.vector)
    uh.x.scatter_forward()
    reason, its = ksp.getConvergedReason(), ksp.getIterationNumber()
    r = b.duplicate()
    A.mult(uh.vector, r)
    r.axpy(-1.0, b)
    bnorm = b.norm()
    res_rel = r.norm() / bnorm if bnorm > 0 else r.norm()
    t_solve = time.perf_counter() - t0
    if reason <= 0:
        raise NumericalError(f"solver {solver} did not converge (PETSc reason {reason}, {its} iterations)")
    if not np.all(np.isfinite(uh.x.array)) or not np.isfinite(res_rel):
        raise NumericalError("the displacement contains NaN or Inf")
    limit = 1e-8 if solver == "mumps" else max(1e3 * rtol, 1e-6)
    if res_rel > limit:
        raise NumericalError(f"true residual {res_rel:.3g} above {limit:.1g} after solve")

    # Reactions: residual of the unconstrained system, R = K u - f, at the fixed DOFs.
    t0 = time.perf_counter()
    R = fem.petsc.assemble_vector(fem.form(volume_integral(ufl.inner(stress(uh, mat), strain(v)), dx_split)
                                           - L_form))
    R.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    Ra = R.array_r
    reactions = []
    for d_ in bc_dofs:
        owned = d_[d_ < n_owned]
        f = np.zeros(3)
        for comp in range(3):
            sel = owned[owned % 3 == comp]
            f[comp] = Ra[sel].sum()
        reactions.append(mesh.comm.allreduce(f, op=MPI.SUM))
    t_assemble += time.perf_counter() - t0
    ksp.destroy()
    for obj in mg_parts:
        obj.destroy()
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    return Solution(u=uh, iterations=its, reason=reason, residual_rel=float(res_rel), dofs=dofs,
                    solver=solver, bc_dofs=bc_dofs, reactions=reactions,
                    timings={"assemble": t_assemble, "solve": t_solve})
