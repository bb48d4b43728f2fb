"""Writing a run's files: results.json and the ParaView fields (into the staging folder
that pipeline.outdir puts in place when the run is complete)."""
from __future__ import annotations

import json
import os
from pathlib import Path

from mpi4py import MPI

from .jsonio import json_safe
from .mirror import mirror_quarter


def write_json(path: Path, data: dict, comm=MPI.COMM_WORLD) -> None:
    """Write results as indented strict JSON (rank 0), whole or not at all: a reader (the
    picture process) never sees half a file."""
    if comm.rank == 0:
        path = Path(path)
        part = path.with_name(path.name + ".part")
        part.write_text(json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n", encoding="utf-8")
        os.replace(part, path)


def write_fields(folder: Path, u, vm, whole_part: bool = False) -> dict[str, str]:
    """Fields for ParaView: displacement (full P2, mm) and von Mises (DG, MPa).

    displacement.pvd: the P2 displacement of the model (DOLFINx VTKFile). von_mises.vtu:
    the element-node von Mises values the peaks were taken from and the displacement at
    the same nodes (use Warp By Vector), mirrored to the whole part when ``whole_part``.
    Uncompressed: zlib on the whole part's four copies is slow (docs/performance.md).
    VTK, not XDMF: DOLFINx 0.5.2's XDMF writer drops P2 mid-edge values and cannot place
    DG values on this curved mesh.
    """
    from dolfinx import io
    comm = u.function_space.mesh.comm
    files = {"displacement": "displacement.pvd", "von_mises": "von_mises.vtu"}
    with io.VTKFile(comm, str(Path(folder) / files["displacement"]), "w") as f:
        f.write_function(u)
    grid = _gather_dg_grid(vm, u)
    if comm.rank == 0:
        import meshio
        points, cells, vals, disp = mirror_quarter(*grid) if whole_part else grid
        meshio.write(Path(folder) / files["von_mises"],
                     meshio.Mesh(points, [("tetra", cells)],
                                 point_data={"von_mises_MPa": vals, "displacement_mm": disp}),
                     binary=True, compression=None)
    return files


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
