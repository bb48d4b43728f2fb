"""Earlier solutions of the same mesh and problem, scaled to a new hook load Q (N) or
Young's modulus E (MPa) instead of solved again.

Linear elasticity with traction loads: every load of the model is proportional to Q
(pipeline/fe/loads.py) and the stiffness to E, so u(Q, E) = (Q/Q0)·(E0/E)·u(Q0, E0) mm, and
the stresses (MPa) and reactions (N) scale by Q/Q0. Scaling both sides leaves the relative
residual ‖b − A u‖/‖b‖ unchanged, so the scaled field is exactly as accurate as the solve
it comes from.

A solution is stored node by node under the nodes' numbers in the mesher's output,
gathered from every rank: MPI's mesh partition differs from run to run, the mesh and its
node numbers do not. Each DOF node is a node of the (P1 or P2) geometry, so this works for
an element order up to the geometry's; a P3 solve is not kept. The key is everything else
that shapes the field: the numbers of nodes, cells and tagged boundary facets per tag,
the dimensions, model, support, ν, element order, solver and tolerance, and the source of
the code that assembles and solves. Entries live in the run cache (pipeline/cache/runs.py)
and follow its switch and size bound.

Nothing stored is taken on trust. Besides the entry's sha256, a reused solution must
match its mesh and loads: every DOF node's number and position (to 1e-6 mm) are the
stored ones, and the scaled field solves this mesh's system: its relative residual
‖b − A u‖/‖b‖, measured as the solver measures it (free rows K u − f, fixed rows the
diagonal × (u − g)) from one assembly of K u − f, lies within RESIDUAL_MARGIN × the
solver's tolerance rtol (but never below RESIDUAL_FLOOR; 1e-8 for MUMPS, whose own check
is that). The same vector
gives the reactions (N), so none is read from the entry. An entry that fails is dropped
with one line on stderr and the mesh is solved again.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from pipeline.cache import runs as runcache
from pipeline.inputs.case import Case
from pipeline.fe.assembly import constrained_diagonal
from pipeline.fe.elasticity import Material, strain, stress, volume_integral, volume_measures
from pipeline.fe.linearity import displacement_factor
from pipeline.fe.loads import LoadCase
from pipeline.fe.meshing import ImportedMesh
from pipeline.fe.solve import Solution, constrained

REDO = "solved again"
# × rtol: the residual a reused field may have. A converged solve stops below rtol (the
# unpreconditioned residual); recomputing it from another assembly only adds round-off.
RESIDUAL_MARGIN = 10.0
RESIDUAL_FLOOR = 1e-10  # below this the round-off of the two assemblies decides, not the solve


@dataclass
class Stored:
    """A solution at load ``load_N`` (N) and modulus ``E_MPa`` (MPa), node by node."""

    load_N: float
    E_MPa: float
    node_ids: np.ndarray  # (n,) the DOF nodes' numbers in the mesh as made, sorted
    nodes_mm: np.ndarray  # (n, 3) their positions
    u_mm: np.ndarray  # (n, 3) displacement at those nodes
    iterations: int
    reason: int
    residual_rel: float
    dofs: int
    solver: str


def node_ids(V, m: ImportedMesh) -> np.ndarray | None:
    """The mesher's node number of each of this rank's DOF nodes of V (ghosts included):
    the same whatever the partition. None when V has more DOF nodes per cell than the
    geometry (P3 on a P2 mesh). Lagrange DOFs and geometry nodes share their order in a
    cell (vertices first, then edges), so a P1 space takes the first four."""
    geo = m.mesh.geometry
    gdm = geo.dofmap.array.reshape(geo.dofmap.num_nodes, -1)
    vdm = V.dofmap.list.array.reshape(V.dofmap.list.num_nodes, -1)
    if vdm.shape[1] > gdm.shape[1] or vdm.shape[0] != gdm.shape[0]:
        return None
    ids = np.full(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, -1, dtype=np.int64)
    ids[vdm] = np.asarray(geo.input_global_indices, dtype=np.int64)[gdm[:, :vdm.shape[1]]]
    return ids


def _gather(comm: MPI.Comm, a: np.ndarray) -> np.ndarray | None:
    """Every rank's rows of ``a`` stacked on rank 0 (None elsewhere)."""
    parts = comm.gather(np.ascontiguousarray(a), root=0)
    return np.concatenate(parts) if comm.rank == 0 else None


def key(case: Case, m: ImportedMesh, V, load_model: dict | None = None) -> str:
    """The run-cache key of the case's solution on mesh m with space V: the same on every
    rank and every partition. The mesh enters by its numbers of DOF nodes, cells and tagged
    facets per tag (not by positions, whose last bits depend on the partition); a
    different mesh that matches them all is caught when its positions are compared.
    ``load_model``: the journal load of a further right-hand side solved on the case's
    operator (its shape and band, mm), instead of the case's own (Case.load_model)."""
    comm = m.mesh.comm
    nodes = comm.allreduce(V.dofmap.index_map.size_local, op=MPI.SUM)
    cells = comm.allreduce(m.mesh.topology.index_map(3).size_local, op=MPI.SUM)
    tags, counts = np.unique(m.facet_tags.values[m.facet_tags.indices < m.mesh.topology.index_map(2).size_local],
                             return_counts=True)
    facets: dict[int, int] = {}
    for d in comm.allgather(dict(zip(tags.tolist(), counts.tolist()))):
        for t, n in d.items():
            facets[t] = facets.get(t, 0) + n
    bearing = case.load_model() if load_model is None else load_model
    return runcache.key("solution", nodes=nodes, cells=cells, facets=sorted(facets.items()), dims=case.dims,
                        model=case.model, support=case.support, bearing=bearing, nu=case.nu, order=case.order,
                        solver=case.solver, rtol=case.rtol)


def store(name: str, sol: Solution, ids: np.ndarray, case: Case) -> None:
    """Keep ``sol`` (solved at the case's load and E), gathered node by node under the
    nodes' numbers ``ids``, under ``name``."""
    V = sol.u.function_space
    comm = V.mesh.comm
    n_own = V.dofmap.index_map.size_local
    own = _gather(comm, ids[:n_own])
    nodes = _gather(comm, V.tabulate_dof_coordinates()[:n_own])
    u = _gather(comm, sol.u.x.array.reshape(-1, 3)[:n_own])
    if comm.rank == 0:
        order = np.argsort(own)
        meta = {"load_N": case.load_N, "E_MPa": case.E_MPa, "iterations": int(sol.iterations),
                "reason": int(sol.reason), "residual_rel": float(sol.residual_rel), "dofs": int(sol.dofs),
                "solver": sol.solver}
        if runcache.finite(*(v for k, v in meta.items() if k != "solver")):
            runcache.store(name, runcache.Entry(meta, {"node_ids": own[order].astype(np.int64),
                                                       "nodes_mm": nodes[order], "u_mm": u[order]}))


def earlier(name: str, comm: MPI.Comm) -> Stored | None:
    """The stored solution ``name`` on every rank of ``comm``, or None on every rank (a
    failed entry is dropped, with one line). Read and checked for form on rank 0."""
    entry = None
    if comm.rank == 0:
        loaded = runcache.load(name, REDO)
        entry = None if loaded is None else as_stored(loaded)
        if loaded is not None and entry is None:
            runcache.reject(name, "arrays or numbers not those of a solution", REDO)
    return comm.bcast(entry, root=0)


def as_stored(e: runcache.Entry) -> Stored | None:
    """The Stored of an entry, or None if its arrays and numbers are not a solution's."""
    m, a = e.meta, e.arrays
    try:
        ids, nodes, u = a["node_ids"], a["nodes_mm"], a["u_mm"]
        numbers = [m[k] for k in ("load_N", "E_MPa", "iterations", "reason", "residual_rel", "dofs")]
        ok = (ids.ndim == 1 and ids.dtype == np.int64 and nodes.shape == u.shape == (len(ids), 3)
              and nodes.dtype == u.dtype == np.float64 and bool(np.all(np.diff(ids) > 0))
              and runcache.finite(*numbers) and m["load_N"] != 0.0 and m["E_MPa"] > 0
              and isinstance(m["solver"], str) and bool(np.all(np.isfinite(u)) and np.all(np.isfinite(nodes))))
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    if not ok:
        return None
    return Stored(m["load_N"], m["E_MPa"], ids, nodes, u, int(m["iterations"]), int(m["reason"]),
                  m["residual_rel"], int(m["dofs"]), m["solver"])


def stored_rows(entry: Stored, ids: np.ndarray, nodes_mm: np.ndarray, tol_mm: float) -> np.ndarray | None:
    """For each DOF node (numbers ``ids``, positions ``nodes_mm``) its row in the entry;
    None if one is missing or lies more than ``tol_mm`` from the stored position."""
    rows = np.searchsorted(entry.node_ids, ids)
    if np.any(rows >= len(entry.node_ids)) or np.any(entry.node_ids[np.minimum(rows, len(entry.node_ids) - 1)] != ids):
        return None
    if np.abs(entry.nodes_mm[rows] - nodes_mm).max(initial=0.0) > tol_mm:
        return None
    return rows


@dataclass
class Residual:
    """A field checked against its system: ‖b − A u‖/‖b‖ as the solver measures it, and
    R = K u − f at this rank's owned DOFs (N) with its sum per Constraint (N)."""

    relative: float
    reaction: np.ndarray
    reactions: list[np.ndarray]


def residual(u: fem.Function, m: ImportedMesh, lc: LoadCase, mat: Material, order: int,
             bc_dofs: list[np.ndarray]) -> Residual:
    """The residual of displacement u (mm) in the problem of mesh m, loads lc and material
    mat: one assembly of K u − f (the form the solver's reactions use) and one of f. Collective.

    The solver's system has the constrained rows replaced by diagonal × (u − g), so its
    residual is K u − f on the free rows and that on the fixed ones; ‖b‖ is f on the free
    rows and diagonal × g on the fixed ones."""
    V = u.function_space
    v = ufl.TestFunction(V)
    mesh = m.mesh
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=m.facet_tags)
    zero = fem.Constant(mesh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    L_form = ufl.inner(zero, v) * ufl.dx
    for t in lc.tractions:
        L_form += ufl.inner(t.value, v) * ds(t.marker)
    dx_split = volume_measures(mesh, order)
    R = fem.petsc.assemble_vector(fem.form(volume_integral(ufl.inner(stress(u, mat), strain(v)), dx_split) - L_form))
    f = fem.petsc.assemble_vector(fem.form(L_form))
    for vec in (R, f):
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    Ra, fa, ua = R.array_r[:n_owned].copy(), f.array_r[:n_owned], u.x.array[:n_owned]
    R.destroy()
    f.destroy()
    fixed = np.zeros(n_owned, dtype=bool)
    g = np.zeros(n_owned)
    reactions = []
    for c, d_ in zip(lc.constraints, bc_dofs, strict=True):
        owned = d_[d_ < n_owned]
        fixed[owned] = True
        g[owned] = c.value
        total = np.array([Ra[owned[owned % 3 == comp]].sum() for comp in range(3)])
        reactions.append(mesh.comm.allreduce(total, op=MPI.SUM))
    diag = constrained_diagonal(mat)
    r2 = float(np.sum(Ra[~fixed] ** 2) + np.sum((diag * (ua[fixed] - g[fixed])) ** 2))
    b2 = float(np.sum(fa[~fixed] ** 2) + np.sum((diag * g[fixed]) ** 2))
    r2, b2 = mesh.comm.allreduce(r2, op=MPI.SUM), mesh.comm.allreduce(b2, op=MPI.SUM)
    rel = math.sqrt(r2) / math.sqrt(b2) if b2 > 0 else math.sqrt(r2)
    return Residual(relative=rel if math.isfinite(rel) else math.inf, reaction=Ra, reactions=reactions)


def residual_limit(case: Case) -> float:
    """The largest relative residual a reused field of the case may have (see the module)."""
    return 1e-8 if case.solver == "mumps" else max(RESIDUAL_MARGIN * case.rtol, RESIDUAL_FLOOR)


@dataclass(frozen=True)
class Target:
    """Where a stored solution is put: mesh m, its displacement space V and the mesher's
    number of each of this rank's DOF nodes (:func:`node_ids`)."""

    m: ImportedMesh
    V: object
    ids: np.ndarray


def scaled(entry: Stored, target: Target, lc: LoadCase, case: Case, mat: Material, name: str) -> Solution | None:
    """The stored solution ``name`` scaled to the case's load and E, as a Solution on space
    V of mesh m whose solver figures (iterations, residual) are those of the solve it comes
    from and whose reactions come from its own residual; None (on every rank) if some
    rank's DOF nodes are not all among the stored ones at their stored positions to 1e-6
    mm, or if the scaled field does not solve the problem (the entry is then dropped, with
    one line)."""
    m, V, ids = target.m, target.V, target.ids
    comm = m.mesh.comm
    rows = stored_rows(entry, ids, V.tabulate_dof_coordinates(), 1e-6)
    if not comm.allreduce(rows is not None, op=MPI.LAND):
        if comm.rank == 0:
            runcache.reject(name, "its nodes are not this mesh's", REDO)
        return None
    u = fem.Function(V, name="displacement_mm")
    u.x.array[:] = (displacement_factor(case.load_N, case.E_MPa, entry.load_N, entry.E_MPa) * entry.u_mm[rows]).ravel()
    _, bc_dofs = constrained(V, m.facet_tags, lc.constraints)
    res = residual(u, m, lc, mat, case.order, bc_dofs)
    limit = residual_limit(case)
    if not res.relative <= limit:
        if comm.rank == 0:
            runcache.reject(name, f"relative residual {res.relative:.3g} on this mesh, above {limit:.1g}", REDO)
        return None
    return Solution(u=u, iterations=entry.iterations, reason=entry.reason, residual_rel=entry.residual_rel,
                    dofs=entry.dofs, solver=entry.solver, bc_dofs=bc_dofs, reactions=res.reactions,
                    reaction=res.reaction, scaled_from={"load_N": entry.load_N, "E_MPa": entry.E_MPa})
