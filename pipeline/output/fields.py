"""The ParaView fields of a run (into the staging folder that pipeline.runtime.outdir puts in place
when the run is complete)."""
from __future__ import annotations

from pathlib import Path

from pipeline.output.mirror import mirror_quarter
from pipeline.output.vtu import write_vtu


def write_fields(folder: Path, u, vm, whole_part: bool = False) -> dict[str, str]:
    """Fields for ParaView, mirrored to the whole part when ``whole_part``: displacement
    (continuous, mm) and von Mises (element-node values, MPa).

    displacement.vtu: the displacement at the nodes of 10-node curved tets (P2 exactly;
    a P1 or P3 solution interpolated into P2). von_mises.vtu: the element-node von Mises
    values the peaks were taken from and the displacement at the same nodes (use Warp By
    Vector). Raw binary, uncompressed: zlib on the whole part's four copies is slow and
    base64 slows the reader (docs/performance.md). VTK, not XDMF: DOLFINx 0.5.2's XDMF writer drops P2 mid-edge
    values and cannot place DG values on this curved mesh.
    """
    comm = u.function_space.mesh.comm
    files = {"displacement": "displacement.vtu", "von_mises": "von_mises.vtu"}
    grids = {"displacement": _gather_p2_grid(u), "von_mises": _gather_dg_grid(vm, u)}
    if comm.rank == 0:
        for key, kind in (("displacement", "tetra10"), ("von_mises", "tetra")):
            points, cells, vals, disp = mirror_quarter(*grids[key]) if whole_part else grids[key]
            data = {"displacement_mm": disp} if vals is None else {"von_mises_MPa": vals, "displacement_mm": disp}
            write_vtu(Path(folder) / files[key], points, cells, kind, data)
    return files


# VTK's 10-node tet from DOLFINx's (basix) node order: basix numbers the mid-edge nodes of
# edges (2,3), (1,3), (1,2), (0,3), (0,2), (0,1); VTK of (0,1), (1,2), (2,0), (0,3), (1,3), (2,3).
VTK_TET10 = [0, 1, 2, 3, 9, 6, 8, 7, 5, 4]


def _gather_p2_grid(u):
    """(points, 10-node tets in VTK order, None, displacement) of u in continuous P2, on
    rank 0 (None elsewhere). Nodes shared between cells and ranks are written once."""
    import numpy as np
    from dolfinx import fem
    V = u.function_space
    if V.ufl_element().degree() != 2:
        V = fem.VectorFunctionSpace(V.mesh, ("CG", 2))
        u2 = fem.Function(V)
        u2.interpolate(u)
        u = u2
    mesh, imap = V.mesh, V.dofmap.index_map
    n_owned, n_local = imap.size_local, imap.size_local + imap.num_ghosts
    to_global = imap.local_to_global(np.arange(n_local, dtype=np.int32))
    n_cells = mesh.topology.index_map(3).size_local
    cells = to_global[V.dofmap.list.array.reshape(-1, 10)[:n_cells]][:, VTK_TET10]
    xyz = V.tabulate_dof_coordinates()[:n_owned]
    disp = u.x.array.reshape(-1, 3)[:n_owned]
    parts = mesh.comm.gather((to_global[:n_owned], xyz, disp, cells), root=0)
    if mesh.comm.rank != 0:
        return None
    points, values = np.zeros((imap.size_global, 3)), np.zeros((imap.size_global, 3))
    for idx, p, d, _ in parts:
        points[idx], values[idx] = p, d
    return points, np.vstack([c for *_, c in parts]).astype(np.int64), None, values


def _gather_dg_grid(vm, u):
    """(points, linear tets, von Mises, displacement) of the DG space of vm, on rank 0.

    Each cell has its own nodes (discontinuous); the geometry uses the cell vertices.
    """
    import numpy as np
    from dolfinx import fem
    W = vm.function_space
    mesh = W.mesh
    comm = mesh.comm
    degree = W.ufl_element().degree()
    if degree == 1:
        Wv = fem.VectorFunctionSpace(mesh, ("DG", 1))
        ud = fem.Function(Wv)
        ud.interpolate(u)
        n_cells = mesh.topology.index_map(3).size_local
        dofs = W.dofmap.list.array.reshape(-1, 4)[:n_cells]
        xyz = W.tabulate_dof_coordinates()
        points = xyz[dofs.ravel()]
        vals = vm.x.array[dofs.ravel()]
        disp = ud.x.array.reshape(-1, 3)[Wv.dofmap.list.array.reshape(-1, 4)[:n_cells].ravel()]
    else:
        # DG0 (P1) or DG2 (P3): draw each cell's vertices with the cell's value at
        # its nearest DG node; exact for DG0, a vertex sample for DG2.
        W1 = fem.FunctionSpace(mesh, ("DG", 1))
        v1 = fem.Function(W1)
        v1.interpolate(vm)
        return _gather_dg_grid(v1, u)
    parts = comm.gather((points, vals, disp), root=0)
    if comm.rank != 0:
        return None
    points = np.vstack([p[0] for p in parts])
    vals = np.concatenate([p[1] for p in parts])
    disp = np.vstack([p[2] for p in parts])
    cells = np.arange(points.shape[0], dtype=np.int64).reshape(-1, 4)
    return points, cells, vals, disp
