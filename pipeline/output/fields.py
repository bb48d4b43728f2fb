"""The ParaView field file of a run, ``fields.vtu`` (into the staging folder that
pipeline.runtime.outdir puts in place when the run is complete); what it holds and how to
read a peak from it: docs/design.md §7.

The part on its curved 10-node tets (a quarter model mirrored to the whole part, the
symmetry planes' nodes shared, so the part is one connected mesh), with
- point data: displacement_mm, the nodal-averaged stress tensor stress_MPa (xx, yy, zz, xy,
  yz, xz), its von Mises von_mises_averaged_MPa and principal stresses
  principal_stress_1/2/3_MPa (largest first);
- cell data: von_mises_unaveraged_MPa, each tet's own von Mises at its four vertices (in the
  cell's vertex order): the element-node values the unaveraged peak is the largest of.

VTK XML, not XDMF: DOLFINx 0.5.2's XDMF writer drops P2 mid-edge values and cannot place DG
values on this curved mesh. Points and values are Float32 (7 significant digits).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.fe.elasticity import Material
from pipeline.output.mirror import mirror_quarter
from pipeline.output.vtu import write_vtu
from pipeline.post.peaks import averaged_stress, von_mises_of

FILE = "fields.vtu"
TENSOR_ORDER = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]  # VTK's symmetric-tensor components


def write_fields(folder: Path, u, vm, mat: Material, whole_part: bool = False) -> dict[str, str]:
    """Write fields.vtu of displacement ``u`` (mm), its element-node von Mises ``vm`` (MPa) and
    the nodal-averaged stress of ``u`` in material ``mat`` into ``folder``, mirrored to the
    whole part when ``whole_part``. Returns the file names by key. Collective; rank 0 writes."""
    part = _gather_p2_grid(u, averaged_stress(u, mat))
    unaveraged = _gather_element_nodes(vm)
    if u.function_space.mesh.comm.rank == 0:
        points, cells, point_data = part
        if whole_part:
            points, cells, point_data, _ = mirror_quarter(points, cells, point_data)
            # The reflected copies' cells list their vertices 0, 2, 1, 3 (orientation).
            unaveraged = np.vstack([unaveraged, unaveraged[:, [0, 2, 1, 3]], unaveraged[:, [0, 2, 1, 3]], unaveraged])
        write_vtu(Path(folder) / FILE, points, cells, "tetra10", _with_invariants(point_data),
                  {"von_mises_unaveraged_MPa": unaveraged.astype(np.float32)}, points_dtype=np.float32)
    return {"fields": FILE}


def _with_invariants(point_data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The point arrays to write (Float32): displacement, the stress tensor in VTK's
    six-component order, its von Mises and principal stresses (MPa)."""
    s = point_data["stress_MPa"].reshape(-1, 3, 3)
    s = 0.5 * (s + s.transpose(0, 2, 1))
    principal = np.linalg.eigvalsh(s)[:, ::-1]
    out = {"displacement_mm": point_data["displacement_mm"],
           "stress_MPa": np.column_stack([s[:, i, j] for i, j in TENSOR_ORDER]),
           "von_mises_averaged_MPa": von_mises_of(s),
           "principal_stress_1_MPa": principal[:, 0],
           "principal_stress_2_MPa": principal[:, 1],
           "principal_stress_3_MPa": principal[:, 2]}
    return {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in out.items()}


# VTK's 10-node tet from DOLFINx's (basix) node order: basix numbers the mid-edge nodes of
# edges (2,3), (1,3), (1,2), (0,3), (0,2), (0,1); VTK of (0,1), (1,2), (2,0), (0,3), (1,3), (2,3).
VTK_TET10 = [0, 1, 2, 3, 9, 6, 8, 7, 5, 4]


def _p2(mesh, f, shape: str):
    """``f`` in continuous P2 of its value shape (exact for P2 and for CG1 data)."""
    from dolfinx import fem
    space = {"vector": fem.VectorFunctionSpace, "tensor": fem.TensorFunctionSpace}[shape](mesh, ("CG", 2))
    if f.function_space.ufl_element().degree() == 2 and f.function_space.ufl_element().family() in ("P", "Q"):
        return f
    g = fem.Function(space)
    g.interpolate(f)
    return g


def _gather_p2_grid(u, stress):
    """(points, 10-node tets in VTK order, {displacement_mm, stress_MPa (9 components)}) on
    continuous P2 nodes, on rank 0 (None elsewhere). Nodes shared between cells and ranks
    are written once."""
    mesh = u.function_space.mesh
    u = _p2(mesh, u, "vector")
    s = _p2(mesh, stress, "tensor")
    V = u.function_space
    imap = V.dofmap.index_map
    n_owned, n_local = imap.size_local, imap.size_local + imap.num_ghosts
    to_global = imap.local_to_global(np.arange(n_local, dtype=np.int32))
    n_cells = mesh.topology.index_map(3).size_local
    cells = to_global[V.dofmap.list.array.reshape(-1, 10)[:n_cells]][:, VTK_TET10]
    xyz = V.tabulate_dof_coordinates()[:n_owned]
    # The tensor space's nodes are the vector space's (same element and mesh), node by node.
    sval = s.x.array.reshape(-1, 9)[:n_owned]
    disp = u.x.array.reshape(-1, 3)[:n_owned]
    parts = mesh.comm.gather((to_global[:n_owned], xyz, disp, sval, cells), root=0)
    if mesh.comm.rank != 0:
        return None
    n = imap.size_global
    points, d, t = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 9))
    for idx, p, dd, ss, _ in parts:
        points[idx], d[idx], t[idx] = p, dd, ss
    return points, np.vstack([c[-1] for c in parts]), {"displacement_mm": d, "stress_MPa": t}


def _gather_element_nodes(vm) -> np.ndarray | None:
    """(cells, 4): each owned cell's von Mises (MPa) at its four vertices, gathered on rank 0
    in the order of :func:`_gather_p2_grid`'s cells (None elsewhere). vm is DG1 (P2), or DG0
    / DG2 (P1, P3), sampled at the vertices then (exact for DG0)."""
    from dolfinx import fem
    W = vm.function_space
    mesh = W.mesh
    if W.ufl_element().degree() != 1:
        v1 = fem.Function(fem.FunctionSpace(mesh, ("DG", 1)))
        v1.interpolate(vm)
        return _gather_element_nodes(v1)
    n_cells = mesh.topology.index_map(3).size_local
    # DG1's cell dofs follow the cell's vertices, as P2's first four nodes (and VTK's) do.
    vals = vm.x.array[W.dofmap.list.array.reshape(-1, 4)[:n_cells]]
    parts = mesh.comm.gather(vals, root=0)
    return None if parts is None else np.vstack(parts)
