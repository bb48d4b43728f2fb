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
the code that assembles and solves; every node's position is compared with the stored
one (to 1e-6 mm) before an entry is used. Entries live in the run cache
(pipeline/cache/runs.py) and follow its switch and size bound.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from pipeline.cache import runs as runcache
from pipeline.inputs.case import Case
from pipeline.fe.loads import LoadCase
from pipeline.fe.meshing import ImportedMesh
from pipeline.fe.solve import Solution, constrained



@dataclass
class Stored:
    """A solution at load ``load_N`` (N) and modulus ``E_MPa`` (MPa), node by node."""

    load_N: float
    E_MPa: float
    node_ids: np.ndarray  # (n,) the DOF nodes' numbers in the mesh as made, sorted
    nodes_mm: np.ndarray  # (n, 3) their positions
    u_mm: np.ndarray  # (n, 3) displacement at those nodes
    reaction_N: np.ndarray  # (n, 3) R = K u − f at those nodes
    reactions: list[np.ndarray]  # per Constraint: its summed reaction force (N)
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


def key(case: Case, m: ImportedMesh, V) -> str:
    """The run-cache key of the case's solution on mesh m with space V: the same on every
    rank and every partition. The mesh enters by its numbers of DOF nodes, cells and tagged
    facets per tag (not by positions, whose last bits depend on the partition); a
    different mesh that matches them all is caught when its positions are compared."""
    comm = m.mesh.comm
    nodes = comm.allreduce(V.dofmap.index_map.size_local, op=MPI.SUM)
    cells = comm.allreduce(m.mesh.topology.index_map(3).size_local, op=MPI.SUM)
    tags, counts = np.unique(m.facet_tags.values[m.facet_tags.indices < m.mesh.topology.index_map(2).size_local],
                             return_counts=True)
    facets: dict[int, int] = {}
    for d in comm.allgather(dict(zip(tags.tolist(), counts.tolist()))):
        for t, n in d.items():
            facets[t] = facets.get(t, 0) + n
    return runcache.key("solution", nodes=nodes, cells=cells, facets=sorted(facets.items()), dims=case.dims,
                        model=case.model, support=case.support, nu=case.nu, order=case.order,
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
    r = _gather(comm, sol.reaction.reshape(-1, 3))
    if comm.rank == 0:
        order = np.argsort(own)
        runcache.store(name, Stored(case.load_N, case.E_MPa, own[order], nodes[order], u[order], r[order],
                                    sol.reactions, sol.iterations, sol.reason, sol.residual_rel, sol.dofs,
                                    sol.solver))


def earlier(name: str, comm: MPI.Comm) -> Stored | None:
    """The stored solution ``name`` on every rank of ``comm``, or None on every rank."""
    entry = runcache.load(name) if comm.rank == 0 else None
    if not (isinstance(entry, Stored) and entry.load_N != 0.0):
        entry = None
    return comm.bcast(entry, root=0)


def stored_rows(entry: Stored, ids: np.ndarray, nodes_mm: np.ndarray, tol_mm: float) -> np.ndarray | None:
    """For each DOF node (numbers ``ids``, positions ``nodes_mm``) its row in the entry;
    None if one is missing or lies more than ``tol_mm`` from the stored position."""
    rows = np.searchsorted(entry.node_ids, ids)
    if np.any(rows >= len(entry.node_ids)) or np.any(entry.node_ids[np.minimum(rows, len(entry.node_ids) - 1)] != ids):
        return None
    if np.abs(entry.nodes_mm[rows] - nodes_mm).max(initial=0.0) > tol_mm:
        return None
    return rows


def scaled(entry: Stored, m: ImportedMesh, V, ids: np.ndarray, lc: LoadCase, case: Case) -> Solution | None:
    """The stored solution scaled to the case's load and E, as a Solution on space V of mesh
    m whose solver figures (iterations, residual) are those of the solve it comes from; None
    (on every rank) if some rank's DOF nodes are not all among the stored ones, at their
    stored positions to 1e-6 mm."""
    comm = m.mesh.comm
    rows = stored_rows(entry, ids, V.tabulate_dof_coordinates(), 1e-6)
    if not comm.allreduce(rows is not None, op=MPI.LAND):
        return None
    force = case.load_N / entry.load_N
    u = fem.Function(V, name="displacement_mm")
    u.x.array[:] = (force * (entry.E_MPa / case.E_MPa) * entry.u_mm[rows]).ravel()
    n_own = V.dofmap.index_map.size_local
    _, bc_dofs = constrained(V, m.facet_tags, lc.constraints)
    return Solution(u=u, iterations=entry.iterations, reason=entry.reason, residual_rel=entry.residual_rel,
                    dofs=entry.dofs, solver=entry.solver, bc_dofs=bc_dofs,
                    reactions=[force * r for r in entry.reactions],
                    reaction=(force * entry.reaction_N[rows[:n_own]]).ravel(),
                    scaled_from={"load_N": entry.load_N, "E_MPa": entry.E_MPa})
